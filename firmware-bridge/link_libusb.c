/* firmware-bridge/link_libusb.c -- opens a vendor-class USB bridge through
 * libusb and hands its bulk endpoints to link_usb.c. Without libusb
 * (ISO_HAVE_LIBUSB unset) iso_link_usb_open says so. */
#include <stdlib.h>

#include "internal.h"

#ifdef ISO_HAVE_LIBUSB
#include <libusb.h>

_Static_assert((int)ISO_LINK_USB_EIO == (int)LIBUSB_ERROR_IO, "usb codes match libusb");
_Static_assert((int)ISO_LINK_USB_NO_DEVICE == (int)LIBUSB_ERROR_NO_DEVICE,
               "usb codes match libusb");
_Static_assert((int)ISO_LINK_USB_TIMEOUT == (int)LIBUSB_ERROR_TIMEOUT, "usb codes match libusb");
_Static_assert((int)ISO_LINK_USB_OVERFLOW == (int)LIBUSB_ERROR_OVERFLOW, "usb codes match libusb");
_Static_assert((int)ISO_LINK_USB_PIPE == (int)LIBUSB_ERROR_PIPE, "usb codes match libusb");

typedef struct lusb {
    libusb_context *ctx;
    libusb_device_handle *dev;
    int iface;
} lusb;

static int lusb_bulk(void *ctx, uint8_t ep, uint8_t *data, int length, int *transferred,
                     unsigned timeout_ms)
{
    lusb *u = ctx;
    return libusb_bulk_transfer(u->dev, ep, data, length, transferred, timeout_ms);
}

static int lusb_clear_halt(void *ctx, uint8_t ep)
{
    return libusb_clear_halt(((lusb *)ctx)->dev, ep);
}

static void lusb_close(void *ctx)
{
    lusb *u = ctx;
    if (u->dev) {
        libusb_release_interface(u->dev, u->iface);
        libusb_close(u->dev);
    }
    if (u->ctx)
        libusb_exit(u->ctx);
    free(u);
}

/* Finds the first vendor-specific interface with one bulk IN and one bulk
 * OUT endpoint. */
static int find_bulk(libusb_device *d, int *iface, uint8_t *ep_in, uint8_t *ep_out, uint16_t *mps)
{
    struct libusb_config_descriptor *cfg = NULL;
    if (libusb_get_active_config_descriptor(d, &cfg) != 0)
        return -1;
    int found = -1;
    for (int i = 0; i < cfg->bNumInterfaces && found < 0; i++) {
        if (cfg->interface[i].num_altsetting < 1)
            continue;
        const struct libusb_interface_descriptor *alt = &cfg->interface[i].altsetting[0];
        if (alt->bInterfaceClass != LIBUSB_CLASS_VENDOR_SPEC)
            continue;
        *ep_in = *ep_out = 0;
        for (int e = 0; e < alt->bNumEndpoints; e++) {
            const struct libusb_endpoint_descriptor *ep = &alt->endpoint[e];
            if ((ep->bmAttributes & 3) != LIBUSB_TRANSFER_TYPE_BULK)
                continue;
            if (ep->bEndpointAddress & LIBUSB_ENDPOINT_IN)
                *ep_in = ep->bEndpointAddress;
            else
                *ep_out = ep->bEndpointAddress;
            *mps = ep->wMaxPacketSize;
        }
        if (*ep_in && *ep_out) {
            *iface = alt->bInterfaceNumber;
            found = 0;
        }
    }
    libusb_free_config_descriptor(cfg);
    return found;
}

int iso_link_usb_open(uint16_t vid, uint16_t pid, iso_link **out, iso_err *err)
{
    if (out)
        *out = NULL;
    if (!out)
        return iso_err_set(err, ISO_EINVAL, -1, "usb link: NULL out");
    lusb *u = calloc(1, sizeof *u);
    if (!u)
        return iso_err_set(err, ISO_ENOMEM, -1, "usb %04x:%04x: out of memory", vid, pid);
    int rc = libusb_init(&u->ctx);
    if (rc != 0) {
        u->ctx = NULL;
        lusb_close(u);
        return iso_err_set(err, ISO_EIO, -1, "usb %04x:%04x: libusb_init: %s", vid, pid,
                           libusb_strerror(rc));
    }
    u->dev = libusb_open_device_with_vid_pid(u->ctx, vid, pid);
    if (!u->dev) {
        lusb_close(u);
        return iso_err_set(err, ISO_EIO, -1, "usb %04x:%04x: no such device (or no permission)",
                           vid, pid);
    }
    uint8_t ep_in = 0, ep_out = 0;
    uint16_t mps = 64;
    if (find_bulk(libusb_get_device(u->dev), &u->iface, &ep_in, &ep_out, &mps) != 0) {
        lusb_close(u);
        return iso_err_set(
            err, ISO_EIO, -1,
            "usb %04x:%04x: no vendor-class interface with bulk IN and OUT endpoints", vid, pid);
    }
    libusb_set_auto_detach_kernel_driver(u->dev, 1);
    rc = libusb_claim_interface(u->dev, u->iface);
    if (rc != 0) {
        int iface = u->iface;
        libusb_close(u->dev);
        u->dev = NULL;
        lusb_close(u);
        return iso_err_set(err, ISO_EIO, -1, "usb %04x:%04x: claim interface %d: %s", vid, pid,
                           iface, libusb_strerror(rc));
    }
    iso_link_usb_io io = {lusb_bulk, lusb_clear_halt, NULL, lusb_close, u};
    return iso_link_usb_open_io(&io, ep_in, ep_out, mps, out, err);
}

#else

int iso_link_usb_open(uint16_t vid, uint16_t pid, iso_link **out, iso_err *err)
{
    if (out)
        *out = NULL;
    return iso_err_set(err, ISO_ENOTSUP, -1, "usb %04x:%04x: isoshape was built without libusb",
                       vid, pid);
}

#endif
