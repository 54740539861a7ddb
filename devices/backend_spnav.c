/* devices/backend_spnav.c -- 3D mice through the spacenavd daemon (libspnav),
 * the usual way Linux users run one. libspnav hands out events, not bytes,
 * so this backend encodes them (RECORDING.md: 'M' and 'B' records) and the
 * spnav decoder reads them back: recordings and replays stay byte-based.
 * libspnav keeps one connection per process: open one spnav source.
 *
 * libspnav (1.0 and 1.1) does not notice a daemon that goes away: its read
 * of 0 bytes at EOF looks like "no event", and spnav_fd() stays valid. So
 * this backend watches the socket itself (a peek for EOF before each event)
 * and reports the source gone; the hub then retries as for an unplugged
 * HID device. */
#include "internal.h"

#include <ctype.h>
#include <errno.h>
#include <poll.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <unistd.h>

#ifdef ISO_DEV_WITH_SPNAV
#include <spnav.h>

const int iso_dev__spnav_built = 1;

#define SPNAV_DEFAULT_SOCKET "/var/run/spnav.sock"

/* 1 if something accepts a connection on the unix socket at path. */
static int listens_at(const char *path)
{
    struct sockaddr_un a;
    if (!path || !path[0] || strlen(path) >= sizeof a.sun_path)
        return 0;
    int fd = socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);
    if (fd < 0)
        return 0;
    memset(&a, 0, sizeof a);
    a.sun_family = AF_UNIX;
    memcpy(a.sun_path, path, strlen(path) + 1);
    int ok = connect(fd, (struct sockaddr *)&a, sizeof a) == 0;
    close(fd);
    return ok;
}

/* The `socket = PATH` line of /etc/spnavrc, the daemon's own setting. */
static int spnavrc_socket(char *buf, size_t cap)
{
    FILE *f = fopen("/etc/spnavrc", "r");
    if (!f)
        return 0;
    char line[512];
    int found = 0;
    while (!found && fgets(line, sizeof line, f)) {
        char *p = line;
        while (isspace((unsigned char)*p))
            p++;
        if (strncmp(p, "socket", 6) != 0 || !(p = strchr(p, '=')))
            continue;
        p++;
        while (isspace((unsigned char)*p))
            p++;
        size_t n = strlen(p);
        while (n && isspace((unsigned char)p[n - 1]))
            p[--n] = '\0';
        if (n && n < cap) {
            memcpy(buf, p, n + 1);
            found = 1;
        }
    }
    fclose(f);
    return found;
}

/* The socket libspnav will connect to, found the way it looks (SPNAV_SOCKET,
 * then `socket =` in /etc/spnavrc, then the default), each candidate taken
 * only if a daemon accepts on it. Returns 1 and that path, or 0 and the
 * first candidate (for the message). */
static int daemon_socket(char path[ISO_DEV_NAME_MAX])
{
    char cand[3][ISO_DEV_NAME_MAX];
    int n = 0;
    const char *env = getenv("SPNAV_SOCKET");
    if (env && env[0] && strlen(env) < ISO_DEV_NAME_MAX)
        memcpy(cand[n++], env, strlen(env) + 1);
    if (spnavrc_socket(cand[n], sizeof cand[n]))
        n++;
    memcpy(cand[n++], SPNAV_DEFAULT_SOCKET, sizeof SPNAV_DEFAULT_SOCKET);
    for (int i = 0; i < n; i++) {
        if (listens_at(cand[i])) {
            memcpy(path, cand[i], ISO_DEV_NAME_MAX);
            return 1;
        }
    }
    memcpy(path, cand[0], ISO_DEV_NAME_MAX);
    return 0;
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

/* Is there input on the daemon's socket, and is it data or the end?
 * Returns 1 data, 0 nothing now, -1 the daemon closed or the socket failed
 * (why says which). The peek leaves the bytes for libspnav to read. */
static int socket_state(int fd, const char **why)
{
    if (fd < 0) {
        *why = "the connection was closed";
        return -1;
    }
    struct pollfd p = {fd, POLLIN, 0};
    if (poll(&p, 1, 0) <= 0)
        return 0;
    if (p.revents & POLLNVAL) {
        *why = "the connection was closed";
        return -1;
    }
    char b;
    ssize_t k = recv(fd, &b, 1, MSG_PEEK | MSG_DONTWAIT);
    if (k > 0)
        return 1;
    if (k == 0) {
        *why = "the daemon closed the connection (stopped or restarted?)";
        return -1;
    }
    if (errno == EAGAIN || errno == EWOULDBLOCK || errno == EINTR)
        return 0;
    *why = strerror(errno);
    return -1;
}

static int spnav_read_chunk(iso_dev_source *s, int64_t until, iso_dev_chunk *out, iso_err *err)
{
    (void)until;
    out->len = 0;
    const char *why = NULL;
    spnav_event ev;
    while ((unsigned)out->len + 15u <= ISO_DEV_CHUNK_MAX) {
        int st = socket_state(spnav_fd(), &why);
        if (st <= 0)
            break;
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
    /* Events that came before the end are handed out first; the end is
     * still there at the next read. */
    if (out->len) {
        out->t_ns = iso_clock_ns();
        return 1;
    }
    if (why)
        return iso_err_set(err, ISO_EIO, -1, "spacenavd at %s: %s", s->detail, why);
    return 0;
}

static void spnav_close_source(iso_dev_source *s)
{
    spnav_close();
    free(s);
}

static const iso_dev_source_ops spnav_ops = {"spnav", spnav_fd_of,        spnav_read_chunk,
                                             NULL,    spnav_close_source, NULL};

int iso_dev_spnav_open(iso_dev_source **out, iso_err *err)
{
    *out = NULL;
    /* Ask the socket first: libspnav 1.0 leaks a little on every failed
     * spnav_open, and a loop retrying an absent daemon would pile it up. */
    char path[ISO_DEV_NAME_MAX];
    if (!daemon_socket(path) || spnav_open() == -1) {
        return iso_err_set(err, ISO_EIO, -1,
                           "spacenavd is not running (nothing accepts on %s; SPNAV_SOCKET or "
                           "/etc/spnavrc choose another socket): start it, or read the 3D mouse "
                           "through hidapi",
                           path);
    }
    iso_dev_source *s = calloc(1, sizeof *s);
    if (!s) {
        spnav_close();
        return iso_err_set(err, ISO_ENOMEM, -1, "spacenavd: out of memory");
    }
    s->ops = &spnav_ops;
    s->info.kind = ISO_DEV_KIND_SPNAV;
    snprintf(s->info.name, sizeof s->info.name, "spacenavd");
    snprintf(s->detail, sizeof s->detail, "%s", path);
    *out = s;
    return ISO_OK;
}

int iso_dev__spnav_running(void)
{
    char path[ISO_DEV_NAME_MAX];
    return daemon_socket(path);
}

#else

const int iso_dev__spnav_built = 0;

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
