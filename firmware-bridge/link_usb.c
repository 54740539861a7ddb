/* firmware-bridge/link_usb.c -- the USB bulk transport's transfer code, on
 * top of an iso_link_usb_io (libusb in link_libusb.c, a fake in the tests).
 * libusb_bulk_transfer's rules drive the design: a timeout of 0 waits
 * forever, a timeout may still have moved bytes, and an IN transfer must
 * ask for whole packets or risk LIBUSB_ERROR_OVERFLOW. */
#include <stdlib.h>
#include <string.h>

#include "internal.h"

#define USB_RX_BUF 4096u

typedef struct usb_link {
    iso_link base;
    iso_link_usb_io io;
    uint8_t ep_in, ep_out;
    uint16_t mps;
    size_t rx_pos, rx_len;
    uint8_t rx[USB_RX_BUF];
} usb_link;

static const char *usb_code_name(int rc)
{
    switch (rc) {
    case ISO_LINK_USB_OK: return "ok";
    case ISO_LINK_USB_EIO: return "I/O error";
    case ISO_LINK_USB_NO_DEVICE: return "device gone";
    case ISO_LINK_USB_TIMEOUT: return "timeout";
    case ISO_LINK_USB_OVERFLOW: return "overflow";
    case ISO_LINK_USB_PIPE: return "endpoint stalled";
    default: return "error";
    }
}

static unsigned usb_timeout(int timeout_ms)
{
    return timeout_ms <= 0 ? 1u : (unsigned)timeout_ms; /* 0 would mean "forever" */
}

static int usb_read(iso_link *l, uint8_t *buf, size_t cap, int timeout_ms, iso_err *err)
{
    usb_link *u = (usb_link *)l;
    if (u->rx_pos == u->rx_len) {
        int want = (int)(sizeof u->rx / u->mps * u->mps);
        int got = 0;
        int rc = u->io.bulk(u->io.ctx, u->ep_in, u->rx, want, &got, usb_timeout(timeout_ms));
        if (got < 0 || got > want)
            got = 0;
        u->rx_pos = 0;
        u->rx_len = (size_t)got;
        if (rc == ISO_LINK_USB_PIPE) {
            if (u->io.clear_halt)
                u->io.clear_halt(u->io.ctx, u->ep_in);
        } else if (rc != ISO_LINK_USB_OK && rc != ISO_LINK_USB_TIMEOUT) {
            return iso_err_set(err, ISO_EIO, -1, "usb endpoint 0x%02x: bulk read: %s (%d)",
                               (unsigned)u->ep_in, usb_code_name(rc), rc);
        }
    }
    size_t n = u->rx_len - u->rx_pos;
    if (n > cap)
        n = cap;
    memcpy(buf, u->rx + u->rx_pos, n);
    u->rx_pos += n;
    return (int)n;
}

/* One OUT transfer, retried on timeouts and partial moves until the
 * deadline; a stall is cleared once. */
static int usb_out(usb_link *u, const uint8_t *buf, size_t n, uint64_t deadline, int timeout_ms,
                   iso_err *err)
{
    size_t done = 0;
    int stalls = 0;
    do {
        uint64_t now = iso_clock_us();
        int left = now >= deadline ? 1 : (int)((deadline - now + 999u) / 1000u);
        int got = 0;
        int rc = u->io.bulk(u->io.ctx, u->ep_out, (uint8_t *)(uintptr_t)(buf + done),
                            (int)(n - done), &got, usb_timeout(left));
        if (got > 0 && (size_t)got <= n - done)
            done += (size_t)got;
        if (rc == ISO_LINK_USB_OK && n == 0)
            return ISO_OK;
        if (rc == ISO_LINK_USB_PIPE && stalls++ == 0 && u->io.clear_halt) {
            u->io.clear_halt(u->io.ctx, u->ep_out);
            continue;
        }
        if (rc != ISO_LINK_USB_OK && rc != ISO_LINK_USB_TIMEOUT)
            return iso_err_set(err, ISO_EIO, -1, "usb endpoint 0x%02x: bulk write: %s (%d)",
                               (unsigned)u->ep_out, usb_code_name(rc), rc);
        if (done < n && iso_clock_us() >= deadline)
            return iso_err_set(
                err, ISO_EIO, -1,
                "usb endpoint 0x%02x: bulk write timed out after %d ms (%zu of %zu bytes)",
                (unsigned)u->ep_out, timeout_ms, done, n);
    } while (done < n);
    return ISO_OK;
}

static int usb_write(iso_link *l, const uint8_t *buf, size_t n, int timeout_ms, iso_err *err)
{
    usb_link *u = (usb_link *)l;
    if (n == 0)
        return ISO_OK;
    uint64_t deadline = iso_clock_us() + (uint64_t)(timeout_ms < 0 ? 0 : timeout_ms) * 1000u;
    int rc = usb_out(u, buf, n, deadline, timeout_ms, err);
    /* A transfer that fills its last packet needs a zero-length packet, or
     * a device that reads until a short packet waits for more. */
    if (rc == ISO_OK && n % u->mps == 0)
        rc = usb_out(u, buf, 0, deadline, timeout_ms, err);
    return rc;
}

static int usb_poll_fd(iso_link *l)
{
    (void)l;
    return -1;
}

static int usb_reopen(iso_link *l, iso_err *err)
{
    usb_link *u = (usb_link *)l;
    if (!u->io.reopen)
        return iso_err_set(err, ISO_ENOTSUP, -1, "usb link: this device cannot be reopened");
    u->rx_pos = u->rx_len = 0;
    return u->io.reopen(u->io.ctx, err);
}

static void usb_close(iso_link *l)
{
    usb_link *u = (usb_link *)l;
    if (u->io.close)
        u->io.close(u->io.ctx);
    free(u);
}

static const iso_link_ops usb_ops = {"usb",       usb_read,   usb_write,
                                     usb_poll_fd, usb_reopen, usb_close};

int iso_link_usb_open_io(const iso_link_usb_io *io, uint8_t ep_in, uint8_t ep_out,
                         uint16_t max_packet, iso_link **out, iso_err *err)
{
    if (out)
        *out = NULL;
    if (!io || !io->bulk || !out || !(ep_in & 0x80u) || (ep_out & 0x80u) || max_packet == 0 ||
        max_packet > USB_RX_BUF) {
        if (io && io->close)
            io->close(io->ctx);
        return iso_err_set(err, ISO_EINVAL, -1,
                           "usb link: bad io, endpoints 0x%02x/0x%02x or packet size %u",
                           (unsigned)ep_in, (unsigned)ep_out, (unsigned)max_packet);
    }
    usb_link *u = calloc(1, sizeof *u);
    if (!u) {
        if (io->close)
            io->close(io->ctx);
        return iso_err_set(err, ISO_ENOMEM, -1, "usb link: out of memory");
    }
    u->base.ops = &usb_ops;
    u->io = *io;
    u->ep_in = ep_in;
    u->ep_out = ep_out;
    u->mps = max_packet;
    *out = &u->base;
    return ISO_OK;
}
