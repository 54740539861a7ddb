/* firmware-bridge/link_serialport.c -- libserialport backend for real
 * USB-serial adapters, with enumeration (VID/PID/description). Without
 * libserialport (ISO_HAVE_SERIALPORT unset) the functions say so. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "internal.h"

#ifdef ISO_HAVE_SERIALPORT
#include <libserialport.h>

typedef struct sp_link {
    iso_link base;
    struct sp_port *port;
    int baud;
    char what[160];
} sp_link;

/* Wraps every sp_* failure at the boundary: its own message, then ours. */
static int sp_fail(iso_err *err, const char *what, const char *call, enum sp_return r)
{
    char *m = r == SP_ERR_FAIL ? sp_last_error_message() : NULL;
    int rc = iso_err_set(err,
                         r == SP_ERR_MEM    ? ISO_ENOMEM
                         : r == SP_ERR_SUPP ? ISO_ENOTSUP
                                            : ISO_EIO,
                         -1, "%s: %s: %s", what, call,
                         m                  ? m
                         : r == SP_ERR_ARG  ? "bad argument"
                         : r == SP_ERR_SUPP ? "not supported"
                                            : "failed");
    if (m)
        sp_free_error_message(m);
    return rc;
}

static int sp_connect(sp_link *s, iso_err *err)
{
    enum sp_return r;
    if ((r = sp_open(s->port, SP_MODE_READ_WRITE)) != SP_OK)
        return sp_fail(err, s->what, "open", r);
    if ((r = sp_set_baudrate(s->port, s->baud)) != SP_OK ||
        (r = sp_set_bits(s->port, 8)) != SP_OK ||
        (r = sp_set_parity(s->port, SP_PARITY_NONE)) != SP_OK ||
        (r = sp_set_stopbits(s->port, 1)) != SP_OK ||
        (r = sp_set_flowcontrol(s->port, SP_FLOWCONTROL_NONE)) != SP_OK) {
        int rc = sp_fail(err, s->what, "configure 8N1", r);
        sp_close(s->port);
        return rc;
    }
    return ISO_OK;
}

static int spl_read(iso_link *l, uint8_t *buf, size_t cap, int timeout_ms, iso_err *err)
{
    sp_link *s = (sp_link *)l;
    /* sp_blocking_read_next's timeout 0 means forever: poll instead. */
    enum sp_return r = timeout_ms > 0
                           ? sp_blocking_read_next(s->port, buf, cap, (unsigned)timeout_ms)
                           : sp_nonblocking_read(s->port, buf, cap);
    if (r < 0)
        return sp_fail(err, s->what, "read", r);
    return (int)r;
}

static int spl_write(iso_link *l, const uint8_t *buf, size_t n, int timeout_ms, iso_err *err)
{
    sp_link *s = (sp_link *)l;
    enum sp_return r =
        sp_blocking_write(s->port, buf, n, timeout_ms > 0 ? (unsigned)timeout_ms : 1u);
    if (r < 0)
        return sp_fail(err, s->what, "write", r);
    if ((size_t)r != n)
        return iso_err_set(err, ISO_EIO, -1, "%s: write timed out after %d ms (%d of %zu bytes)",
                           s->what, timeout_ms, (int)r, n);
    return ISO_OK;
}

static int spl_poll_fd(iso_link *l)
{
    sp_link *s = (sp_link *)l;
    int fd = -1;
    return sp_get_port_handle(s->port, &fd) == SP_OK ? fd : -1;
}

static int spl_reopen(iso_link *l, iso_err *err)
{
    sp_link *s = (sp_link *)l;
    sp_close(s->port);
    return sp_connect(s, err);
}

static void spl_close(iso_link *l)
{
    sp_link *s = (sp_link *)l;
    sp_close(s->port);
    sp_free_port(s->port);
    free(s);
}

static const iso_link_ops sp_ops = {"serialport", spl_read,   spl_write,
                                    spl_poll_fd,  spl_reopen, spl_close};

int iso_link_sp_open(const char *name, int baud, iso_link **out, iso_err *err)
{
    if (out)
        *out = NULL;
    if (!name || !out || baud <= 0)
        return iso_err_set(err, ISO_EINVAL, -1, "serialport link: NULL name/out or baud %d", baud);
    sp_link *s = calloc(1, sizeof *s);
    if (!s)
        return iso_err_set(err, ISO_ENOMEM, -1, "serialport %s: out of memory", name);
    s->base.ops = &sp_ops;
    s->baud = baud;
    snprintf(s->what, sizeof s->what, "serialport %s", name);
    enum sp_return r = sp_get_port_by_name(name, &s->port);
    if (r != SP_OK) {
        int rc = sp_fail(err, s->what, "find port", r);
        free(s);
        return rc;
    }
    int rc = sp_connect(s, err);
    if (rc != ISO_OK) {
        sp_free_port(s->port);
        free(s);
        return rc;
    }
    *out = &s->base;
    return ISO_OK;
}

int iso_link_sp_list(iso_link_sp_port *ports, size_t cap, iso_err *err)
{
    struct sp_port **list = NULL;
    enum sp_return r = sp_list_ports(&list);
    if (r != SP_OK)
        return sp_fail(err, "serialport", "list ports", r);
    int n = 0;
    for (; list[n]; n++) {
        if ((size_t)n >= cap || !ports)
            continue;
        iso_link_sp_port *p = &ports[n];
        const char *nm = sp_get_port_name(list[n]);
        const char *desc = sp_get_port_description(list[n]);
        snprintf(p->name, sizeof p->name, "%s", nm ? nm : "");
        snprintf(p->description, sizeof p->description, "%s", desc ? desc : "");
        p->usb_vid = p->usb_pid = -1;
        int vid = 0, pid = 0;
        if (sp_get_port_transport(list[n]) == SP_TRANSPORT_USB &&
            sp_get_port_usb_vid_pid(list[n], &vid, &pid) == SP_OK) {
            p->usb_vid = vid;
            p->usb_pid = pid;
        }
    }
    sp_free_port_list(list);
    return n;
}

#else

int iso_link_sp_open(const char *name, int baud, iso_link **out, iso_err *err)
{
    (void)baud;
    if (out)
        *out = NULL;
    return iso_err_set(err, ISO_ENOTSUP, -1,
                       "serialport %s: isoshape was built without libserialport",
                       name ? name : "(null)");
}

int iso_link_sp_list(iso_link_sp_port *ports, size_t cap, iso_err *err)
{
    (void)ports;
    (void)cap;
    return iso_err_set(err, ISO_ENOTSUP, -1,
                       "serialport: isoshape was built without libserialport");
}

#endif
