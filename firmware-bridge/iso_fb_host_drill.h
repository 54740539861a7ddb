/* firmware-bridge/iso_fb_host_drill.h -- what the tests ask of the MCU to
 * prove its hardware watchdog: hang. Internal to the library's parts and
 * its white-box tests (not installed, not exported): a program driving
 * actuators never wants its MCU to stop answering. */
#ifndef ISO_FB_HOST_DRILL_H
#define ISO_FB_HOST_DRILL_H

#include "iso_fb_host.h"

/* Sends a DIAG hang request: the MCU stops feeding its hardware watchdog,
 * which must reset it into its safe state (firmware-bridge/PROTOCOL.md). */
ISO_NODISCARD int iso_fb_host_send_diag_hang(iso_fb_host *h, iso_err *err);

#endif
