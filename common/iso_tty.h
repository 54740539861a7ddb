/* common/iso_tty.h -- a terminal device opened raw, for every part that
 * talks to a serial port: the devices' tty input source and the firmware
 * bridge's tty link, so that a port behaves the same in both. Internal to
 * the library: not installed, not exported (iso_add_part INTERNAL). */
#ifndef ISO_TTY_H
#define ISO_TTY_H

#include <stdint.h>

#include "iso_err.h"

/* Opens a terminal device (a serial adapter, a pseudo-terminal, an
 * emulator's UART) non-blocking in raw 8N1 mode at a standard baud rate and
 * stores the descriptor in *fd (-1 on failure). Errors name the path: a
 * rate that is not standard, a failed open (with the dialout-group hint on
 * EACCES), "not a terminal", a failed tcsetattr. */
ISO_NODISCARD int iso_tty_open_raw(const char *path, uint32_t baud, int *fd, iso_err *err);

#endif
