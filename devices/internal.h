/* devices/internal.h -- what the devices/ files share and nobody else sees:
 * each hardware backend's part of iso_dev_enumerate(). Not installed. */
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

#endif
