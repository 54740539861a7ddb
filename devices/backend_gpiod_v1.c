/* devices/backend_gpiod_v1.c -- the clutch and emergency-stop inputs and the
 * per-tick trigger output through libgpiod v1 (Debian 12 ships 1.6).
 *
 * Lines are requested for both edges; each edge becomes a (role, level) pair
 * stamped with the kernel's event time (CLOCK_MONOTONIC since Linux 5.7), and
 * the first read gives both lines' initial levels. libgpiod v1 has no
 * debounce: the GPIO decoder does it, from those timestamps, so it replays.
 * The two event descriptors sit in one epoll set: one descriptor to poll. */
#include "internal.h"
#include "iso_dev_enum.h"
#include "iso_dev_source.h"

#include <errno.h>
#include <glob.h>
#include <poll.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/epoll.h>
#include <unistd.h>

#ifdef ISO_DEV_WITH_GPIOD
#include <gpiod.h>

const int iso_dev__gpiod_built = 1;

typedef struct gp {
    struct gpiod_chip *chip;
    struct gpiod_line *in[ISO_DEV_GPIO_ROLES]; /* NULL when not configured */
    struct gpiod_line *pulse;
    int ep;
    int initial_done;
} gp;

static int gp_fd(iso_dev_source *s)
{
    return ((gp *)s->impl)->ep;
}

static int gp_read(iso_dev_source *s, int64_t until, iso_dev_chunk *out, iso_err *err)
{
    (void)until;
    gp *g = s->impl;
    out->len = 0;
    if (!g->initial_done) {
        g->initial_done = 1;
        for (int r = 0; r < ISO_DEV_GPIO_ROLES; r++) {
            if (!g->in[r])
                continue;
            int v = gpiod_line_get_value(g->in[r]);
            if (v < 0)
                return iso_err_set(err, ISO_EIO, -1, "%s: cannot read line %u: %s", s->info.name,
                                   gpiod_line_offset(g->in[r]), strerror(errno));
            out->data[out->len++] = (uint8_t)r;
            out->data[out->len++] = (uint8_t)v;
        }
        out->t_ns = iso_clock_ns();
        return out->len ? 1 : 0;
    }
    for (int r = 0; r < ISO_DEV_GPIO_ROLES; r++) {
        if (!g->in[r])
            continue;
        struct pollfd p = {gpiod_line_event_get_fd(g->in[r]), POLLIN, 0};
        if (poll(&p, 1, 0) != 1)
            continue;
        if (p.revents & (POLLERR | POLLHUP | POLLNVAL))
            return iso_err_set(err, ISO_EIO, -1, "%s: the GPIO chip went away", s->info.name);
        struct gpiod_line_event ev;
        if (gpiod_line_event_read(g->in[r], &ev) != 0)
            return iso_err_set(err, ISO_EIO, -1, "%s: cannot read an edge of line %u: %s",
                               s->info.name, gpiod_line_offset(g->in[r]), strerror(errno));
        out->data[0] = (uint8_t)r;
        out->data[1] = ev.event_type == GPIOD_LINE_EVENT_RISING_EDGE; /* active-low applied */
        out->len = 2;
        out->t_ns = (int64_t)ev.ts.tv_sec * 1000000000 + ev.ts.tv_nsec;
        return 1;
    }
    return 0;
}

static int gp_write_level(iso_dev_source *s, int level, iso_err *err)
{
    gp *g = s->impl;
    if (!g->pulse)
        return iso_err_set(err, ISO_ENOTSUP, -1, "%s: no trigger output line", s->info.name);
    if (gpiod_line_set_value(g->pulse, level ? 1 : 0) != 0)
        return iso_err_set(err, ISO_EIO, -1, "%s: cannot set the trigger line: %s", s->info.name,
                           strerror(errno));
    return ISO_OK;
}

static void gp_close(iso_dev_source *s)
{
    gp *g = s->impl;
    if (g->ep >= 0)
        close(g->ep);
    gpiod_chip_close(g->chip); /* releases every requested line */
    iso_dev__source_free(s);
}

/* The e-stop line's level by ioctl on its request descriptor: no state of
 * libgpiod's changes, so it may run on the actuators' sender thread while
 * the loop reads edges from the same line (active-low is applied by the
 * request flag). */
static int gp_estop_level(iso_dev_source *s)
{
    struct gpiod_line *l = ((gp *)s->impl)->in[ISO_DEV_GPIO_ESTOP];
    if (!l)
        return ISO_ENOTSUP;
    int v = gpiod_line_get_value(l);
    return v < 0 ? ISO_EIO : v != 0;
}

static const iso_dev_source_ops gp_ops = {"gpiod",        gp_fd,    gp_read,
                                          gp_write_level, gp_close, gp_estop_level};

static int fail(gp *g, iso_dev_source *s, iso_err *err, const char *chip, const char *what,
                int line)
{
    int e = errno;
    iso_err_set(err, ISO_EIO, -1, "%s: %s %d: %s%s", chip, what, line, strerror(e),
                e == EACCES ? " (udev rule: SUBSYSTEM==\"gpio\", KERNEL==\"gpiochip*\", "
                              "GROUP=\"gpio\", MODE=\"0660\"; add yourself to group gpio)"
                            : "");
    if (g->ep >= 0)
        close(g->ep);
    if (g->chip)
        gpiod_chip_close(g->chip);
    iso_dev__source_free(s);
    return ISO_EIO;
}

int iso_dev_gpiod_open(const iso_dev_gpio_opts *o, iso_dev_source **out, iso_err *err)
{
    *out = NULL;
    if (o->clutch_line < 0 && o->estop_line < 0)
        return iso_err_set(err, ISO_EINVAL, -1, "%s: neither a clutch nor an e-stop line given",
                           o->chip);
    iso_dev_source *s = iso_dev__source_new(&gp_ops, sizeof(gp));
    if (!s) {
        return iso_err_set(err, ISO_ENOMEM, -1, "%s: out of memory", o->chip);
    }
    gp *g = s->impl;
    g->ep = -1;
    g->chip = gpiod_chip_open_lookup(o->chip);
    if (!g->chip)
        return fail(g, s, err, o->chip, "cannot open the chip for line", o->clutch_line);
    g->ep = epoll_create1(EPOLL_CLOEXEC);
    const int lines[ISO_DEV_GPIO_ROLES] = {o->clutch_line, o->estop_line};
    int flags = o->active_low ? GPIOD_LINE_REQUEST_FLAG_ACTIVE_LOW : 0;
    for (int r = 0; r < ISO_DEV_GPIO_ROLES; r++) {
        if (lines[r] < 0)
            continue;
        g->in[r] = gpiod_chip_get_line(g->chip, (unsigned)lines[r]);
        if (!g->in[r] ||
            gpiod_line_request_both_edges_events_flags(g->in[r], "isoshape", flags) != 0)
            return fail(g, s, err, o->chip, "cannot request line", lines[r]);
        struct epoll_event ee = {.events = EPOLLIN, .data.u32 = (uint32_t)r};
        epoll_ctl(g->ep, EPOLL_CTL_ADD, gpiod_line_event_get_fd(g->in[r]), &ee);
    }
    if (o->pulse_line >= 0) {
        g->pulse = gpiod_chip_get_line(g->chip, (unsigned)o->pulse_line);
        if (!g->pulse || gpiod_line_request_output(g->pulse, "isoshape-trigger", 0) != 0)
            return fail(g, s, err, o->chip, "cannot request output line", o->pulse_line);
    }
    s->info.kind = ISO_DEV_KIND_GPIO;
    s->info.debounce_us = o->debounce_us;
    snprintf(s->info.name, sizeof s->info.name, "%s", o->chip);
    *out = s;
    return ISO_OK;
}

#else

const int iso_dev__gpiod_built = 0;

int iso_dev_gpiod_open(const iso_dev_gpio_opts *o, iso_dev_source **out, iso_err *err)
{
    *out = NULL;
    if (o->clutch_line < 0 && o->estop_line < 0)
        return iso_err_set(err, ISO_EINVAL, -1, "%s: neither a clutch nor an e-stop line given",
                           o->chip);
    return iso_err_set(err, ISO_ENOTSUP, -1,
                       "%s: this build has no libgpiod backend (install libgpiod-dev and rebuild)",
                       o->chip);
}
#endif

/* Listing needs no library: the character devices are there or not. */
size_t iso_dev__gpiod_enumerate(iso_dev_found *out, size_t cap)
{
    glob_t gl;
    size_t n = 0;
    if (glob("/dev/gpiochip*", 0, NULL, &gl) != 0)
        return 0;
    for (size_t i = 0; i < gl.gl_pathc && n < cap; i++) {
        iso_dev_found *f = &out[n++];
        memset(f, 0, sizeof *f);
        snprintf(f->backend, sizeof f->backend, "gpiod");
        snprintf(f->path, sizeof f->path, "%s", gl.gl_pathv[i]);
        snprintf(f->what, sizeof f->what, "GPIO chip");
        f->usable = access(f->path, R_OK | W_OK) == 0;
#ifndef ISO_DEV_WITH_GPIOD
        f->usable = 0;
        snprintf(f->why, sizeof f->why, "this build has no libgpiod backend");
#endif
        if (!f->usable && !f->why[0])
            snprintf(f->why, sizeof f->why,
                     "no read/write permission on %s: udev rule SUBSYSTEM==\"gpio\", "
                     "KERNEL==\"gpiochip*\", GROUP=\"gpio\", MODE=\"0660\", and add yourself "
                     "to group gpio",
                     f->path);
    }
    globfree(&gl);
    return n;
}
