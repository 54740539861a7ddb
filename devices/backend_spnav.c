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
 * HID device.
 *
 * The axes it records are the device's own, as hidraw has them: spacenavd's
 * swap and rescale are undone, and a relative device's rest, which
 * spacenavd never hears, is inferred from silence (iso_dev_axes.h). */
#include "internal.h"
#include "iso_dev_axes.h"
#include "iso_dev_enum.h"
#include "iso_dev_source.h"

#include <ctype.h>
#include <errno.h>
#include <glob.h>
#include <poll.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <unistd.h>

/* ---- spacenavd's axes back to the device's (always built) --------------- */

int iso_dev_spnav_swaps_yz(uint16_t vid, uint16_t pid)
{
    /* spacenavd 1.1's device table: every 3Dconnexion (256f) device, and
     * these under Logitech's id; the rest of 046d keeps its axes. */
    static const uint16_t logi[] = {0xc623, 0xc625, 0xc626, 0xc627, 0xc628, 0xc629, 0xc62b};
    if (vid == 0 || vid == 0x256f)
        return 1;
    if (vid == 0x046d)
        for (size_t i = 0; i < sizeof logi / sizeof logi[0]; i++)
            if (pid == logi[i])
                return 1;
    return 0;
}

static long long ceil_div(long long num, long long den)
{
    return num >= 0 ? (num + den - 1) / den : -(-num / den);
}

void iso_dev_spnav_to_device(const iso_dev_spnav_layout *l, const int v[6], int16_t out[6])
{
    /* spacenavd: rescale (absolute), then swap and negate Y/Z, then its
     * dead zone. Undone in the other order; the rescale was
     * r' = floor((r - lo) * 1000 / range) - 500, whose inverse on integers
     * is r = lo + ceil((r' + 500) * range / 1000) (exact while range <= 1000,
     * else the least r of those that map to r'). */
    static const int from[6] = {0, 2, 1, 3, 5, 4};
    for (int i = 0; i < 6; i++) {
        long long r = l->swap_yz ? (i == 0 || i == 3 ? v[i] : -(long long)v[from[i]]) : v[i];
        if (l->absolute && l->hi > l->lo)
            r = l->lo + ceil_div((r + 500) * ((long long)l->hi - l->lo), 1000);
        out[i] = (int16_t)(r > 32767 ? 32767 : r < -32768 ? -32768 : r);
    }
}

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

/* The connection's state: how spacenavd sees the device, and what it
 * last said (for the rest a relative device never reports). */
typedef struct spn {
    iso_dev_spnav_layout layout;
    int relative;    /* rest is inferred from silence */
    int raw[6];      /* spacenavd's last motion, as it sent it */
    int kept[6];     /* what it kept at the last inferred rest */
    unsigned masked; /* bit per axis still showing its kept value */
    int moving;      /* the last motion recorded was not rest */
    int64_t t_motion;
    char socket[ISO_DEV_NAME_MAX];
} spn;

static uint8_t *put_motion(uint8_t *p, const int16_t d[6], unsigned period)
{
    p[0] = 'M';
    for (int i = 0; i < 6; i++)
        put16(p + 1 + 2 * i, d[i]);
    put16(p + 13, (int)(period & 0x7fff));
    return p + 15;
}

/* One motion event: the device's axes. Relative: an axis that still shows
 * the value spacenavd kept at the last rest counts as 0 until it changes. */
static void motion(spn *c, const spnav_event *ev, int16_t d[6])
{
    const int v[6] = {ev->motion.x,  ev->motion.y,  ev->motion.z,
                      ev->motion.rx, ev->motion.ry, ev->motion.rz};
    int u[6];
    for (int i = 0; i < 6; i++) {
        c->raw[i] = v[i];
        if ((c->masked & (1u << i)) && v[i] != c->kept[i])
            c->masked &= ~(1u << i);
        u[i] = (c->masked & (1u << i)) ? 0 : v[i];
    }
    iso_dev_spnav_to_device(&c->layout, u, d);
    c->moving = 0;
    for (int i = 0; i < 6; i++)
        c->moving |= d[i] != 0;
    c->t_motion = iso_clock_ns();
}

/* Records the rest of a relative device that went quiet, once: a motion
 * record of zeros, quiet_ms in its period field; the values spacenavd
 * keeps from now on count as 0 until they change. */
static void rest(spn *c, iso_dev_chunk *out, unsigned quiet_ms)
{
    if ((unsigned)out->len + 15u > ISO_DEV_CHUNK_MAX)
        return;
    static const int16_t zero[6] = {0};
    put_motion(out->data + out->len, zero, quiet_ms);
    out->len += 15;
    memcpy(c->kept, c->raw, sizeof c->kept);
    c->masked = 0;
    for (int i = 0; i < 6; i++)
        c->masked |= c->raw[i] ? 1u << i : 0;
    c->moving = 0;
}

/* Quiet for ISO_DEV_SPNAV_REST_NS since the last read that brought motion
 * (each read drains every event it can, so the device was silent at
 * least that long): at rest. */
static void rest_if_due(spn *c, iso_dev_chunk *out, int64_t now)
{
    if (c->relative && c->moving && now - c->t_motion >= ISO_DEV_SPNAV_REST_NS)
        rest(c, out, (unsigned)((now - c->t_motion) / 1000000));
}

static int spnav_read_chunk(iso_dev_source *s, int64_t until, iso_dev_chunk *out, iso_err *err)
{
    (void)until;
    spn *c = s->impl;
    out->len = 0;
    const char *why = NULL;
    spnav_event ev;
    while ((unsigned)out->len + 30u <= ISO_DEV_CHUNK_MAX) { /* a rest and a motion */
        int st = socket_state(spnav_fd(), &why);
        if (st <= 0)
            break;
        int type = spnav_poll_event(&ev);
        if (type == 0)
            break;
        uint8_t *p = out->data + out->len;
        if (type == SPNAV_EVENT_MOTION) {
            /* spacenavd's period is the time since its previous motion
             * event: a silence this long came before this one, however
             * late this read (a slow tick) sees it. */
            if (c->relative && c->moving && ev.motion.period >= ISO_DEV_SPNAV_REST_NS / 1000000)
                rest(c, out, ev.motion.period);
            int16_t d[6];
            motion(c, &ev, d);
            put_motion(out->data + out->len, d, ev.motion.period);
            out->len += 15;
        } else if (type == SPNAV_EVENT_BUTTON) {
            /* a button after the silence: the rest came first */
            rest_if_due(c, out, iso_clock_ns());
            p = out->data + out->len;
            p[0] = 'B';
            p[1] = (uint8_t)ev.button.bnum;
            p[2] = ev.button.press ? 1 : 0;
            out->len += 3;
        }
    }
    int64_t now = iso_clock_ns();
    rest_if_due(c, out, now);
    /* Events that came before the end are handed out first; the end is
     * still there at the next read. */
    if (out->len) {
        out->t_ns = now;
        return 1;
    }
    if (why)
        return iso_err_set(err, ISO_EIO, -1, "spacenavd at %s: %s", c->socket, why);
    return 0;
}

static void spnav_close_source(iso_dev_source *s)
{
    spnav_close();
    iso_dev__source_free(s);
}

static const iso_dev_source_ops spnav_ops = {"spnav", spnav_fd_of,        spnav_read_chunk,
                                             NULL,    spnav_close_source, NULL};

/* The first line of a sysfs file, or "" (cap > 0). */
static void sysfs_line(const char *path, char *buf, size_t cap)
{
    buf[0] = '\0';
    FILE *f = fopen(path, "r");
    if (!f)
        return;
    if (!fgets(buf, (int)cap, f))
        buf[0] = '\0';
    fclose(f);
}

/* The six axes' bits (0..5) of a capabilities file: hex words, the lowest
 * bits last. */
static int axis_bits(const char *dir, const char *kind)
{
    char path[320], line[512];
    snprintf(path, sizeof path, "%s/capabilities/%s", dir, kind);
    sysfs_line(path, line, sizeof line);
    const char *last = strrchr(line, ' ');
    return (int)(strtoul(last ? last + 1 : line, NULL, 16) & 0x3f);
}

/* A hex id from sysfs (id/vendor, id/product), or -1. */
static long sysfs_hex(const char *dir, const char *name)
{
    char path[320], line[32];
    snprintf(path, sizeof path, "%s/id/%s", dir, name);
    sysfs_line(path, line, sizeof line);
    return line[0] ? strtol(line, NULL, 16) : -1;
}

/* The evdev node's input device folder in sysfs for the 3D mouse
 * spacenavd serves: the node it named if it did, else the only known 3D
 * mouse with six axes among the input devices (the one it reads), of its
 * USB id when it gave one. 1 when found. */
static int find_input(const char *node, unsigned vid, unsigned pid, char dir[256])
{
    const char *ev = strrchr(node, '/');
    if (ev && strncmp(ev + 1, "event", 5) == 0) {
        snprintf(dir, 256, "/sys/class/input/%s/device", ev + 1);
        return 1;
    }
    glob_t gl;
    if (glob("/sys/class/input/event*", 0, NULL, &gl) != 0)
        return 0;
    int found = 0;
    for (size_t i = 0; i < gl.gl_pathc && found < 2; i++) {
        char d[256];
        snprintf(d, sizeof d, "%s/device", gl.gl_pathv[i]);
        long v = sysfs_hex(d, "vendor"), p = sysfs_hex(d, "product");
        if (v < 0 || p < 0 || !iso_dev_is_3dmouse((uint16_t)v, (uint16_t)p) ||
            (vid && (v != (long)vid || p != (long)pid)) ||
            (axis_bits(d, "abs") != 0x3f && axis_bits(d, "rel") != 0x3f))
            continue;
        if (found++ == 0)
            memcpy(dir, d, sizeof d);
    }
    globfree(&gl);
    return found == 1;
}

/* What spacenavd serves us: its USB id and evdev node (protocol 1), else
 * the one 3D mouse the input devices hold; from sysfs the node's axis kind
 * and the HID descriptor's range. The daemon's answers are not needed (an
 * old daemon, or one too busy to answer within libspnav's 400 ms after a
 * restart, gives none). Anything not learnt stays at the safe assumption:
 * swapped, relative. */
static void learn_layout(iso_dev_source *s, spn *c)
{
    unsigned vid = 0, pid = 0;
    char node[ISO_DEV_NAME_MAX] = "", dir[256];
    if (spnav_protocol() >= 1) {
        if (spnav_dev_usbid(&vid, &pid) == -1)
            vid = pid = 0;
        if (spnav_dev_path(node, sizeof node) == -1)
            node[0] = '\0';
    }
    c->relative = 1;
    int known = find_input(node, vid, pid, dir);
    if (known && !vid) {
        vid = (unsigned)sysfs_hex(dir, "vendor");
        pid = (unsigned)sysfs_hex(dir, "product");
    }
    s->info.vid = (uint16_t)vid;
    s->info.pid = (uint16_t)pid;
    c->layout.swap_yz = iso_dev_spnav_swaps_yz(s->info.vid, s->info.pid);
    if (!known)
        return;
    char path[320];
    snprintf(path, sizeof path, "%s/device/report_descriptor", dir);
    FILE *f = fopen(path, "rb");
    if (f) {
        s->info.desc_len = (uint16_t)fread(s->info.desc, 1, ISO_DEV_DESC_MAX, f);
        fclose(f);
    }
    if (axis_bits(dir, "abs") != 0x3f)
        return; /* relative axes, or none the daemon could use */
    iso_dev_hid_axes_info ax;
    c->layout.absolute = 1;
    c->layout.lo = -350; /* the family's range when the descriptor says none */
    c->layout.hi = 350;
    if (iso_dev_hid_axes(s->info.desc, s->info.desc_len, &ax) == ISO_OK && ax.hi > ax.lo) {
        c->layout.lo = ax.lo;
        c->layout.hi = ax.hi;
    }
    c->relative = 0;
}

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
    iso_dev_source *s = iso_dev__source_new(&spnav_ops, sizeof(spn));
    if (!s) {
        spnav_close();
        return iso_err_set(err, ISO_ENOMEM, -1, "spacenavd: out of memory");
    }
    spn *c = s->impl;
    s->info.kind = ISO_DEV_KIND_SPNAV;
    snprintf(s->info.name, sizeof s->info.name, "spacenavd");
    snprintf(c->socket, sizeof c->socket, "%s", path);
    learn_layout(s, c);
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
