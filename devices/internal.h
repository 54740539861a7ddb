/* devices/internal.h -- what the devices/ files share and nobody else sees:
 * each hardware backend's part of iso_dev_enumerate() and whether it is
 * built. Not installed. */
#ifndef ISO_DEV_INTERNAL_H
#define ISO_DEV_INTERNAL_H

#include "iso_dev.h"

/* Each appends at most cap entries and returns how many. */
size_t iso_dev__hid_enumerate(iso_dev_found *out, size_t cap);
size_t iso_dev__serialport_enumerate(iso_dev_found *out, size_t cap);
size_t iso_dev__gpiod_enumerate(iso_dev_found *out, size_t cap);
size_t iso_dev__usb_enumerate(iso_dev_found *out, size_t cap);
/* 1 running, 0 not, -1 not built. */
int iso_dev__spnav_running(void);

/* Whether each optional backend is compiled in (1) or out (0): set in the
 * backend's own file by the #ifdef that selects its code. */
extern const int iso_dev__hidapi_built;
extern const int iso_dev__serialport_built;
extern const int iso_dev__gpiod_built;
extern const int iso_dev__libusb_built;
extern const int iso_dev__spnav_built;

#endif
