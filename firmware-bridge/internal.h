/* firmware-bridge/internal.h -- cross-file helpers of the host side; not
 * installed. */
#ifndef ISO_FB_INTERNAL_H
#define ISO_FB_INTERNAL_H

#include <stdint.h>

#include "iso_clock.h"
#include "iso_link.h"

/* read()/write() on a non-blocking fd with poll() and a timeout, shared by
 * the tty and TCP backends. `what` names the link in messages. */
int iso_fb__fd_read(int fd, const char *what, uint8_t *buf, size_t cap, int timeout_ms,
                    iso_err *err);
int iso_fb__fd_write(int fd, const char *what, const uint8_t *buf, size_t n, int timeout_ms,
                     int is_socket, iso_err *err);

#endif
