/* common/iso_fd.h -- raw descriptors and TCP, for every part that talks
 * through a file descriptor: the firmware bridge's tty and TCP links, the
 * devices' TCP source, the live view's server and the MCU emulator. One
 * connect with a timeout, one read and one write with poll(), so that a
 * port or a socket behaves the same whichever part opened it.
 * Internal to the library: not installed, not exported (CMakeLists.txt,
 * iso_add_part INTERNAL). */
#ifndef ISO_FD_H
#define ISO_FD_H

#include <stddef.h>
#include <stdint.h>

#include "iso_err.h"

/* Makes fd non-blocking and close-on-exec. 0, or -1 with errno set. */
int iso_fd_nonblock(int fd);

/* Resolves host (a name or a numeric address) and port, and connects to the
 * first address that answers within timeout_ms (each address gets the whole
 * timeout): a non-blocking connect, then poll. On success *fd is a
 * non-blocking, close-on-exec stream socket with Nagle off (small frames must
 * leave at once). Errors are ISO_EIO and name "host:port": "cannot resolve:
 * <reason>" or "cannot connect: <strerror>" (ETIMEDOUT for the timeout). */
ISO_NODISCARD int iso_fd_tcp_connect(const char *host, const char *port, int timeout_ms, int *fd,
                                     iso_err *err);

/* Checks `host`, an address to listen on: a numeric IPv4 or IPv6 address
 * (IPv6 also in brackets, as in a URL: [::1]) or localhost; never a name
 * that would need a resolver when the socket is bound. Returns 1 for a
 * loopback address, 0 for one that other machines can reach (0.0.0.0, ::,
 * a LAN address), or -1 with a phrase in why: "'example.com' is not a
 * numeric IPv4 or IPv6 address or localhost". Scene files check the live
 * view's host with it before anything runs. */
int iso_fd_listen_host(const char *host, char *why, size_t cap);

/* Waits up to timeout_ms (0: not at all) for fd to be readable, then reads
 * at most cap bytes. Returns the count, 0 when nothing came in time (or a
 * signal woke the wait), or ISO_EIO: "<what>: peer closed the link" at end
 * of file, "<what>: read: <strerror>", "<what>: link is closed" for fd < 0. */
int iso_fd_read(int fd, const char *what, uint8_t *buf, size_t cap, int timeout_ms, iso_err *err);

/* Writes all n bytes, waiting with poll() while the descriptor is full, for
 * at most timeout_ms in all. is_socket: send() with MSG_NOSIGNAL, so that a
 * vanished peer is an error here and not a SIGPIPE for the whole process.
 * ISO_OK, or ISO_EIO naming `what`: a write error, or "write timed out after
 * T ms (D of N bytes)". */
ISO_NODISCARD int iso_fd_write_all(int fd, const char *what, const uint8_t *buf, size_t n,
                                   int timeout_ms, int is_socket, iso_err *err);

#endif
