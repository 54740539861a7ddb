/* devices/iso_dev_enum.h -- discovery: what each built-in backend sees
 * connected and whether it can be opened now (if not, why and what fixes
 * it), which backends were compiled in, the udev rule that grants a
 * device, and libusb hotplug. Apart from the sources (iso_dev_source.h)
 * because it opens nothing: `isoshape devices` lists with it, the loop
 * watches for arrivals with it, and a backend's open function opens. */
#ifndef ISO_DEV_ENUM_H
#define ISO_DEV_ENUM_H

#include <stddef.h>
#include <stdint.h>

#include "iso_dev.h"
#include "iso_err.h"

/* ---- discovery ---------------------------------------------------------- */

typedef struct iso_dev_found {
    char backend[16]; /* "hidapi", "spnav", "serialport", "gpiod", "libusb" */
    char path[ISO_DEV_NAME_MAX];
    char what[ISO_DEV_NAME_MAX]; /* product or description */
    uint16_t vid, pid;
    int usable;    /* 1: can be opened now */
    char why[320]; /* when not usable: why, and what fixes it */
} iso_dev_found;

/* Lists what every built-in backend sees. Returns the count written (at most
 * cap); never fails: a backend that cannot look says so in an entry. */
ISO_API size_t iso_dev_enumerate(iso_dev_found *out, size_t cap);
/* 1 if (vid, pid) is a known 3D mouse (3Dconnexion 0x046d / 0x256f). */
ISO_API int iso_dev_is_3dmouse(uint16_t vid, uint16_t pid);
/* The udev rule that grants the logged-in user a device (uaccess). */
ISO_API void iso_dev_udev_rule(uint16_t vid, char *buf, size_t cap);
/* Which backends were compiled in, e.g. "fake replay tty tcp hidapi
 * serialport gpiod libusb spnav", written into buf (the names that fit in
 * cap, whole); returns buf. */
ISO_API const char *iso_dev_backends(char *buf, size_t cap);
/* 1 if the backend `name` ("hidapi", "serialport", "gpiod", "libusb",
 * "spnav", or one always built: "fake", "replay", "tty", "tcp") was compiled
 * in, 0 if it was compiled out (its open function then returns ISO_ENOTSUP),
 * -1 if there is no backend of that name. */
ISO_API int iso_dev_backend_built(const char *name);

/* libusb hotplug: a watcher whose fd set wakes the loop on arrival and
 * removal of known devices. iso_dev_usb_watch_poll returns how many events
 * arrived since the last call (each sets the hub's retry to "now"). */
typedef struct iso_dev_usb_watch iso_dev_usb_watch;
ISO_API ISO_NODISCARD int iso_dev_usb_watch_create(iso_dev_usb_watch **out, iso_err *err);
ISO_API int iso_dev_usb_watch_poll(iso_dev_usb_watch *w);
ISO_API void iso_dev_usb_watch_destroy(iso_dev_usb_watch *w);

#endif
