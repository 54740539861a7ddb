/* devices/backend_libusb.c -- libusb for hotplug arrival and removal of
 * known devices (so a replugged 3D mouse is retried at once, not at the next
 * retry interval) and for listing them with their bus address. Reading stays
 * with hidraw: claiming the interface here would take it from spacenavd.
 * The libusb context is the watcher's own: no library-wide state of ours. */
#include "internal.h"
#include "iso_dev_enum.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#ifdef ISO_HAVE_LIBUSB
#include <libusb.h>

const int iso_dev__libusb_built = 1;

static const uint16_t known_vids[] = {0x046d, 0x256f};

struct iso_dev_usb_watch {
    libusb_context *ctx;
    libusb_hotplug_callback_handle h[2];
    int nh;
    int events;
};

static int LIBUSB_CALL on_hotplug(libusb_context *ctx, libusb_device *dev, libusb_hotplug_event ev,
                                  void *user)
{
    (void)ctx;
    (void)ev;
    struct libusb_device_descriptor d;
    if (libusb_get_device_descriptor(dev, &d) == 0 && iso_dev_is_3dmouse(d.idVendor, d.idProduct))
        ((iso_dev_usb_watch *)user)->events++;
    return 0; /* stay registered */
}

int iso_dev_usb_watch_create(iso_dev_usb_watch **out, iso_err *err)
{
    *out = NULL;
    iso_dev_usb_watch *w = calloc(1, sizeof *w);
    if (!w)
        return iso_err_set(err, ISO_ENOMEM, -1, "libusb: out of memory");
    int rc = libusb_init(&w->ctx);
    if (rc != 0) {
        free(w);
        return iso_err_set(err, ISO_EIO, -1, "libusb: cannot initialise: %s", libusb_strerror(rc));
    }
    if (!libusb_has_capability(LIBUSB_CAP_HAS_HOTPLUG)) {
        libusb_exit(w->ctx);
        free(w);
        return iso_err_set(err, ISO_ENOTSUP, -1,
                           "libusb: no hotplug support here; replugged devices are found by "
                           "the retry interval");
    }
    for (int i = 0; i < 2; i++) {
        rc = libusb_hotplug_register_callback(
            w->ctx, LIBUSB_HOTPLUG_EVENT_DEVICE_ARRIVED | LIBUSB_HOTPLUG_EVENT_DEVICE_LEFT, 0,
            known_vids[i], LIBUSB_HOTPLUG_MATCH_ANY, LIBUSB_HOTPLUG_MATCH_ANY, on_hotplug, w,
            &w->h[i]);
        if (rc != LIBUSB_SUCCESS) {
            iso_dev_usb_watch_destroy(w);
            return iso_err_set(err, ISO_EIO, -1, "libusb: cannot watch for hotplug: %s",
                               libusb_strerror(rc));
        }
        w->nh++;
    }
    *out = w;
    return ISO_OK;
}

int iso_dev_usb_watch_poll(iso_dev_usb_watch *w)
{
    struct timeval zero = {0, 0};
    libusb_handle_events_timeout_completed(w->ctx, &zero, NULL);
    int n = w->events;
    w->events = 0;
    return n;
}

void iso_dev_usb_watch_destroy(iso_dev_usb_watch *w)
{
    if (!w)
        return;
    for (int i = 0; i < w->nh; i++)
        libusb_hotplug_deregister_callback(w->ctx, w->h[i]);
    libusb_exit(w->ctx);
    free(w);
}

size_t iso_dev__usb_enumerate(iso_dev_found *out, size_t cap)
{
    libusb_context *ctx = NULL;
    if (libusb_init(&ctx) != 0)
        return 0;
    libusb_device **list = NULL;
    ssize_t nd = libusb_get_device_list(ctx, &list);
    size_t n = 0;
    for (ssize_t i = 0; i < nd && n < cap; i++) {
        struct libusb_device_descriptor d;
        if (libusb_get_device_descriptor(list[i], &d) != 0 ||
            !iso_dev_is_3dmouse(d.idVendor, d.idProduct))
            continue;
        iso_dev_found *f = &out[n++];
        memset(f, 0, sizeof *f);
        snprintf(f->backend, sizeof f->backend, "libusb");
        snprintf(f->path, sizeof f->path, "usb:%03u:%03u", libusb_get_bus_number(list[i]),
                 libusb_get_device_address(list[i]));
        snprintf(f->what, sizeof f->what, "USB device %04x:%04x (read through hidraw)", d.idVendor,
                 d.idProduct);
        f->vid = d.idVendor;
        f->pid = d.idProduct;
        f->usable = 1; /* listing only: reading goes through hidapi */
    }
    if (nd >= 0)
        libusb_free_device_list(list, 1);
    libusb_exit(ctx);
    return n;
}

#else

const int iso_dev__libusb_built = 0;

struct iso_dev_usb_watch {
    int unused;
};

int iso_dev_usb_watch_create(iso_dev_usb_watch **out, iso_err *err)
{
    *out = NULL;
    return iso_err_set(err, ISO_ENOTSUP, -1,
                       "this build has no libusb backend (install libusb-1.0-0-dev and "
                       "rebuild); replugged devices are found by the retry interval");
}
int iso_dev_usb_watch_poll(iso_dev_usb_watch *w)
{
    (void)w;
    return 0;
}
void iso_dev_usb_watch_destroy(iso_dev_usb_watch *w)
{
    free(w);
}
size_t iso_dev__usb_enumerate(iso_dev_found *out, size_t cap)
{
    (void)out;
    (void)cap;
    return 0;
}
#endif

/* ---- discovery, across backends ----------------------------------------- */

int iso_dev_is_3dmouse(uint16_t vid, uint16_t pid)
{
    /* 3Dconnexion's own vendor ID: every product is an input device of ours. */
    if (vid == 0x256f)
        return 1;
    /* Under Logitech's ID: SpaceMouse Plus/Classic, SpaceBall 5000,
     * SpaceTraveler, SpacePilot, SpaceNavigator (and for notebooks),
     * SpaceExplorer, SpacePilot Pro, SpaceMouse Pro. */
    static const uint16_t logi[] = {0xc603, 0xc605, 0xc606, 0xc621, 0xc623, 0xc625,
                                    0xc626, 0xc627, 0xc628, 0xc629, 0xc62b};
    if (vid == 0x046d)
        for (size_t i = 0; i < sizeof logi / sizeof logi[0]; i++)
            if (pid == logi[i])
                return 1;
    return 0;
}

void iso_dev_udev_rule(uint16_t vid, char *buf, size_t cap)
{
    snprintf(buf, cap,
             "KERNEL==\"hidraw*\", ATTRS{idVendor}==\"%04x\", MODE=\"0660\", TAG+=\"uaccess\"",
             vid);
}

size_t iso_dev_enumerate(iso_dev_found *out, size_t cap)
{
    size_t n = 0;
    n += iso_dev__hid_enumerate(out + n, cap - n);
    int sp = iso_dev__spnav_running();
    if (n < cap) {
        iso_dev_found *f = &out[n++];
        memset(f, 0, sizeof *f);
        snprintf(f->backend, sizeof f->backend, "spnav");
        snprintf(f->path, sizeof f->path, "spacenavd");
        snprintf(f->what, sizeof f->what, "3D mouse daemon");
        f->usable = sp == 1;
        if (sp == 0)
            snprintf(f->why, sizeof f->why,
                     "spacenavd is not running (systemctl start spacenavd); 3D mice are read "
                     "through hidapi instead");
        else if (sp < 0)
            snprintf(f->why, sizeof f->why, "this build has no libspnav backend");
    }
    n += iso_dev__serialport_enumerate(out + n, cap - n);
    n += iso_dev__gpiod_enumerate(out + n, cap - n);
    n += iso_dev__usb_enumerate(out + n, cap - n);
    return n;
}
