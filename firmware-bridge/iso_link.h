/* firmware-bridge/iso_link.h -- a byte transport under the firmware-bridge
 * link: one vtable-style interface, one file per backend (hidapi's manner).
 *
 *   link_tty.c         POSIX tty: real UARTs, ptys, QEMU's -serial pty
 *   link_tcp.c         TCP client: QEMU's -serial tcp, ser2net, a proxy
 *   link_serialport.c  libserialport: USB-serial adapters, with enumeration
 *   link_usb.c         USB bulk endpoints of a vendor-class bridge; the
 *                      transfer code runs on an iso_link_usb_io, which
 *                      link_libusb.c provides from libusb (tests: a fake)
 *
 * Every backend returns a heap handle that iso_link_close() frees; errors
 * come back as ISO_E* codes with a sentence in iso_err. Not thread-safe:
 * one thread per link. */
#ifndef ISO_LINK_H
#define ISO_LINK_H

#include <stddef.h>
#include <stdint.h>

#include "iso_err.h"

typedef struct iso_link iso_link;

typedef struct iso_link_ops {
    const char *name;
    /* Reads up to cap bytes, waiting at most timeout_ms (0: do not wait).
     * Returns the count (0: nothing arrived), or ISO_EIO when the link is
     * lost (peer closed, device unplugged). */
    int (*read)(iso_link *l, uint8_t *buf, size_t cap, int timeout_ms, iso_err *err);
    /* Writes all n bytes within timeout_ms; returns ISO_OK or ISO_EIO. */
    int (*write)(iso_link *l, const uint8_t *buf, size_t n, int timeout_ms, iso_err *err);
    /* A file descriptor for poll()/select(), or -1 where there is none (USB). */
    int (*poll_fd)(iso_link *l);
    /* Closes and opens the same device or address again after a loss.
     * NULL where a backend cannot. */
    int (*reopen)(iso_link *l, iso_err *err);
    void (*close)(iso_link *l);
} iso_link_ops;

struct iso_link {
    const iso_link_ops *ops; /* every backend struct starts with this */
};

ISO_API ISO_NODISCARD int iso_link_read(iso_link *l, uint8_t *buf, size_t cap, int timeout_ms,
                                        iso_err *err);
ISO_API ISO_NODISCARD int iso_link_write(iso_link *l, const uint8_t *buf, size_t n, int timeout_ms,
                                         iso_err *err);
ISO_API int iso_link_poll_fd(iso_link *l);
/* ISO_ENOTSUP where the backend cannot reopen. */
ISO_API ISO_NODISCARD int iso_link_reopen(iso_link *l, iso_err *err);
ISO_API void iso_link_close(iso_link *l); /* NULL is a no-op */

/* ---- POSIX tty ---------------------------------------------------------- */
/* Opens path raw (8N1, no flow control, no echo) at baud (e.g. 115200; a
 * pty ignores it). */
ISO_API ISO_NODISCARD int iso_link_tty_open(const char *path, int baud, iso_link **out,
                                            iso_err *err);

/* ---- TCP client --------------------------------------------------------- */
ISO_API ISO_NODISCARD int iso_link_tcp_open(const char *host, int port, int timeout_ms,
                                            iso_link **out, iso_err *err);

/* ---- libserialport ------------------------------------------------------ */
typedef struct iso_link_sp_port {
    char name[128]; /* what iso_link_sp_open takes, e.g. /dev/ttyUSB0 */
    char description[128];
    int usb_vid, usb_pid; /* -1 when not a USB port */
} iso_link_sp_port;
/* Lists serial ports into ports[cap]; returns how many exist (may exceed
 * cap), or ISO_EIO / ISO_ENOTSUP (built without libserialport). */
ISO_API ISO_NODISCARD int iso_link_sp_list(iso_link_sp_port *ports, size_t cap, iso_err *err);
ISO_API ISO_NODISCARD int iso_link_sp_open(const char *name, int baud, iso_link **out,
                                           iso_err *err);

/* ---- USB bulk ----------------------------------------------------------- */
/* The transfer primitive the USB backend runs on: libusb_bulk_transfer's
 * contract (returns 0 or an ISO_LINK_USB_* code, *transferred set even on
 * timeout). link_libusb.c fills it from libusb; tests fill it with a fake. */
enum {
    ISO_LINK_USB_OK = 0,
    ISO_LINK_USB_EIO = -1,
    ISO_LINK_USB_NO_DEVICE = -4,
    ISO_LINK_USB_TIMEOUT = -7,
    ISO_LINK_USB_OVERFLOW = -8,
    ISO_LINK_USB_PIPE = -9
}; /* equal to LIBUSB_ERROR_* (checked in link_libusb.c) */
typedef struct iso_link_usb_io {
    int (*bulk)(void *ctx, uint8_t endpoint, uint8_t *data, int length, int *transferred,
                unsigned timeout_ms);
    int (*clear_halt)(void *ctx, uint8_t endpoint); /* may be NULL */
    int (*reopen)(void *ctx, iso_err *err);         /* may be NULL: cannot reopen */
    void (*close)(void *ctx);                       /* may be NULL */
    void *ctx;
} iso_link_usb_io;
/* Wraps io as a link; the link owns io->ctx from here on (closes it through
 * io->close, also when this fails). ep_in has bit 7 set; max_packet is the
 * endpoints' wMaxPacketSize (64 full speed, 512 high speed). Reads ask for
 * whole packets (no overflow); a write whose length is a multiple of
 * max_packet ends with a zero-length packet. */
ISO_API ISO_NODISCARD int iso_link_usb_open_io(const iso_link_usb_io *io, uint8_t ep_in,
                                               uint8_t ep_out, uint16_t max_packet, iso_link **out,
                                               iso_err *err);
/* Opens the first device with vid:pid through libusb, claims its first
 * vendor-class interface and finds its bulk endpoints. ISO_ENOTSUP without
 * libusb. */
ISO_API ISO_NODISCARD int iso_link_usb_open(uint16_t vid, uint16_t pid, iso_link **out,
                                            iso_err *err);

#endif
