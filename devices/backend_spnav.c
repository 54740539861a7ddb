/* devices/backend_spnav.c -- 3D mice through the spacenavd daemon (libspnav),
 * the usual way Linux users run one. libspnav hands out events, not bytes,
 * so this backend encodes them (RECORDING.md: 'M' and 'B' records) and the
 * spnav decoder reads them back: recordings and replays stay byte-based.
 * libspnav keeps one connection per process: open one spnav source. */
#include "internal.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <unistd.h>

#ifdef ISO_DEV_WITH_SPNAV
#include <spnav.h>

/* spacenavd's socket (SOCK_NAME in spacenavd and libspnav) accepts a connection. */
static int daemon_listens(void)
{
    int fd = socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);
    if (fd < 0)
        return 0;
    struct sockaddr_un a;
    memset(&a, 0, sizeof a);
    a.sun_family = AF_UNIX;
    snprintf(a.sun_path, sizeof a.sun_path, "%s", "/var/run/spnav.sock");
    int ok = connect(fd, (struct sockaddr *)&a, sizeof a) == 0;
    close(fd);
    return ok;
}

static int spnav_fd_of(iso_dev_source *s)
{
    (void)s;
    return spnav_fd();
}

static void put16(uint8_t *p, int v)
{
    if (v > 32767)
        v = 32767;
    if (v < -32768)
        v = -32768;
    p[0] = (uint8_t)((unsigned)v & 0xff);
    p[1] = (uint8_t)(((unsigned)v >> 8) & 0xff);
}

static int spnav_read_chunk(iso_dev_source *s, int64_t until, iso_dev_chunk *out, iso_err *err)
{
    (void)until;
    out->len = 0;
    spnav_event ev;
    while ((unsigned)out->len + 15u <= ISO_DEV_CHUNK_MAX) {
        int type = spnav_poll_event(&ev);
        if (type == 0)
            break;
        uint8_t *p = out->data + out->len;
        if (type == SPNAV_EVENT_MOTION) {
            p[0] = 'M';
            const int v[6] = {ev.motion.x,  ev.motion.y,  ev.motion.z,
                              ev.motion.rx, ev.motion.ry, ev.motion.rz};
            for (int i = 0; i < 6; i++)
                put16(p + 1 + 2 * i, v[i]);
            put16(p + 13, (int)(ev.motion.period & 0x7fff));
            out->len += 15;
        } else if (type == SPNAV_EVENT_BUTTON) {
            p[0] = 'B';
            p[1] = (uint8_t)ev.button.bnum;
            p[2] = ev.button.press ? 1 : 0;
            out->len += 3;
        }
    }
    if (out->len) {
        out->t_ns = iso_dev_now_ns();
        return 1;
    }
    if (spnav_fd() < 0)
        return iso_err_set(err, ISO_EIO, -1, "spacenavd: the connection was lost");
    (void)s;
    return 0;
}

static void spnav_close_source(iso_dev_source *s)
{
    spnav_close();
    free(s);
}

static const iso_dev_source_ops spnav_ops = {"spnav", spnav_fd_of, spnav_read_chunk, NULL,
                                             spnav_close_source};

int iso_dev_spnav_open(iso_dev_source **out, iso_err *err)
{
    *out = NULL;
    /* Ask the socket first: libspnav 1.0 leaks a little on every failed
     * spnav_open, and a loop retrying an absent daemon would pile it up. */
    if (!daemon_listens() || spnav_open() == -1) {
        return iso_err_set(err, ISO_EIO, -1,
                           "spacenavd is not running (no socket to connect to): start it, or "
                           "read the 3D mouse through hidapi");
    }
    iso_dev_source *s = calloc(1, sizeof *s);
    if (!s) {
        spnav_close();
        return iso_err_set(err, ISO_ENOMEM, -1, "spacenavd: out of memory");
    }
    s->ops = &spnav_ops;
    s->info.kind = ISO_DEV_KIND_SPNAV;
    snprintf(s->info.name, sizeof s->info.name, "spacenavd");
    *out = s;
    return ISO_OK;
}

int iso_dev__spnav_running(void)
{
    return daemon_listens();
}

#else

int iso_dev_spnav_open(iso_dev_source **out, iso_err *err)
{
    *out = NULL;
    return iso_err_set(err, ISO_ENOTSUP, -1,
                       "spacenavd: this build has no libspnav backend (install libspnav-dev "
                       "and rebuild)");
}

int iso_dev__spnav_running(void)
{
    return -1;
}
#endif
