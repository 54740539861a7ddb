/* devices/backend_serialport.c -- real serial adapters through libserialport:
 * opened by name, enumerated with their USB VID/PID and description. (Debian
 * 12's libserialport 0.1.1 cannot open a pty: tests use backend_tty.c.) */
#include "internal.h"
#include "iso_dev_enum.h"
#include "iso_dev_source.h"

#include <poll.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#ifdef ISO_HAVE_SERIALPORT
#include <libserialport.h>

const int iso_dev__serialport_built = 1;

typedef struct ser {
    struct sp_port *port;
    int fd;
} ser;

/* libserialport's last error as our message, freed at once (never leaks up). */
static int sp_fail(iso_err *err, int code, const char *name, const char *what)
{
    char *m = sp_last_error_message();
    iso_err_set(err, code, -1, "%s: %s: %s", name, what, m ? m : "unknown error");
    sp_free_error_message(m);
    return code;
}

static int ser_fd(iso_dev_source *s)
{
    return ((ser *)s->impl)->fd;
}

static int ser_read(iso_dev_source *s, int64_t until, iso_dev_chunk *out, iso_err *err)
{
    (void)until;
    ser *p = s->impl;
    /* An unplugged USB adapter shows as a hang-up on its descriptor. */
    struct pollfd pf = {p->fd, POLLIN, 0};
    if (poll(&pf, 1, 0) == 1 && (pf.revents & (POLLHUP | POLLERR | POLLNVAL)))
        return iso_err_set(err, ISO_EIO, -1, "%s: the adapter hung up (unplugged?)", s->info.name);
    int n = sp_nonblocking_read(p->port, out->data, ISO_DEV_CHUNK_MAX);
    if (iso_dev__chunk_read(out, n))
        return 1;
    if (n == 0)
        return 0;
    return sp_fail(err, ISO_EIO, s->info.name, "read failed");
}

static void ser_close(iso_dev_source *s)
{
    ser *p = s->impl;
    sp_close(p->port);
    sp_free_port(p->port);
    iso_dev__source_free(s);
}

static const iso_dev_source_ops ser_ops = {"serialport", ser_fd, ser_read, NULL, ser_close, NULL};

int iso_dev_serialport_open(const char *name, uint32_t baud, iso_dev_source **out, iso_err *err)
{
    *out = NULL;
    struct sp_port *port = NULL;
    if (sp_get_port_by_name(name, &port) != SP_OK)
        return sp_fail(err, ISO_EIO, name, "no such serial port");
    if (sp_open(port, SP_MODE_READ_WRITE) != SP_OK) {
        sp_fail(err, ISO_EIO, name,
                "cannot open (for permission: add yourself to the dialout "
                "group)");
        sp_free_port(port);
        return ISO_EIO;
    }
    if (sp_set_baudrate(port, (int)baud) != SP_OK || sp_set_bits(port, 8) != SP_OK ||
        sp_set_parity(port, SP_PARITY_NONE) != SP_OK || sp_set_stopbits(port, 1) != SP_OK ||
        sp_set_flowcontrol(port, SP_FLOWCONTROL_NONE) != SP_OK) {
        sp_fail(err, ISO_EIO, name, "cannot set 8N1 at the baud rate");
        sp_close(port);
        sp_free_port(port);
        return ISO_EIO;
    }
    int fd = -1;
    sp_get_port_handle(port, &fd);
    iso_dev_source *s = iso_dev__source_new(&ser_ops, sizeof(ser));
    if (!s) {
        sp_close(port);
        sp_free_port(port);
        return iso_err_set(err, ISO_ENOMEM, -1, "%s: out of memory", name);
    }
    ser *p = s->impl;
    p->port = port;
    p->fd = fd;
    iso_dev__serial_info(&s->info, baud);
    int vid = 0, pid = 0;
    if (sp_get_port_transport(port) == SP_TRANSPORT_USB &&
        sp_get_port_usb_vid_pid(port, &vid, &pid) == SP_OK) {
        s->info.vid = (uint16_t)vid;
        s->info.pid = (uint16_t)pid;
    }
    snprintf(s->info.name, sizeof s->info.name, "%s", name);
    *out = s;
    return ISO_OK;
}

size_t iso_dev__serialport_enumerate(iso_dev_found *out, size_t cap)
{
    struct sp_port **ports = NULL;
    size_t n = 0;
    if (sp_list_ports(&ports) != SP_OK)
        return 0;
    for (size_t i = 0; ports[i] && n < cap; i++) {
        struct sp_port *p = ports[i];
        if (sp_get_port_transport(p) == SP_TRANSPORT_NATIVE)
            continue; /* on-board 8250 UARTs: dozens of ttyS* that lead nowhere */
        iso_dev_found *f = &out[n++];
        memset(f, 0, sizeof *f);
        snprintf(f->backend, sizeof f->backend, "serialport");
        snprintf(f->path, sizeof f->path, "%s", sp_get_port_name(p));
        const char *d = sp_get_port_description(p);
        snprintf(f->what, sizeof f->what, "%s", d ? d : "serial port");
        int vid = 0, pid = 0;
        if (sp_get_port_transport(p) == SP_TRANSPORT_USB &&
            sp_get_port_usb_vid_pid(p, &vid, &pid) == SP_OK) {
            f->vid = (uint16_t)vid;
            f->pid = (uint16_t)pid;
        }
        f->usable = access(f->path, R_OK | W_OK) == 0;
        if (!f->usable)
            snprintf(f->why, sizeof f->why,
                     "no read/write permission on %s: add yourself to the dialout group "
                     "('sudo usermod -aG dialout $USER', then log in again)",
                     f->path);
    }
    sp_free_port_list(ports);
    return n;
}

#else

const int iso_dev__serialport_built = 0;

int iso_dev_serialport_open(const char *name, uint32_t baud, iso_dev_source **out, iso_err *err)
{
    (void)baud;
    *out = NULL;
    return iso_err_set(err, ISO_ENOTSUP, -1,
                       "%s: this build has no libserialport backend (install libserialport-dev "
                       "and rebuild; plain ttys work through --tty)",
                       name);
}

size_t iso_dev__serialport_enumerate(iso_dev_found *out, size_t cap)
{
    (void)out;
    (void)cap;
    return 0;
}
#endif
