/* config/scene_sinks.c -- the scene's `sinks:` section: the live view
 * (display), PLY frames, and the actuators over the firmware bridge, with
 * their link and channels. */
#include "internal.h"

#include <ctype.h>
#include <libfyaml.h>
#include <stdlib.h>
#include <string.h>

#include "iso_actuators.h" /* iso_act_emu_names, ISO_ACT_MAX_CHANNELS */
#include "iso_fb_mcu.h"    /* ISO_FB_BOARD_BAUD */
#include "iso_fd.h"        /* iso_fd_listen_host */
#include "iso_names.h"

/* ------------------------------------------------------------------------ */
/* display, ply                                                              */
/* ------------------------------------------------------------------------ */

static int store_ticks(scene_ctx *c, const scene_key *k, fnode *v, const char *key, void *obj)
{
    iso_scene_display *d = obj;
    int n, rc;
    if ((rc = iso_scene__list_count(c, k, v, key, &n)))
        return rc;
    void *it = NULL;
    fnode *e;
    while ((e = fy_node_sequence_iterate(v, &it))) {
        double t;
        if ((rc = iso_scene__number(c, k, e, key, &t)))
            return rc;
        d->snapshot_ticks[d->n_snapshots++] = (long)t;
    }
    return ISO_OK;
}

static const scene_key display_keys[] = {
    {"host", SK_STRING, FIELD(iso_scene_display, host),
     .help = "the address served on (beyond loopback only with allow_remote)", .dflt = "127.0.0.1"},
    {"port", SK_INT, FIELD(iso_scene_display, port), IN(1, 65535), .help = "the TCP port",
     .dflt = "8080"},
    {"allow_remote", SK_BOOL, FIELD(iso_scene_display, allow_remote),
     .help = "a host beyond loopback may be served on (with a warning)", .dflt = "false"},
    {"snapshot_ticks", SK_LIST, FIELD(iso_scene_display, snapshot_ticks), IN(0, 1L << 40),
     .max_items = ISO_SCENE_MAX_SNAPSHOTS, .store = store_ticks, .noun = "tick numbers",
     .type = "list of integers", .help = "ticks at which a PNG snapshot is taken", .dflt = "none"},
    {"snapshot_dir", SK_PATH, FIELD(iso_scene_display, snapshot_dir),
     .help = "the folder for the snapshots", .dflt = "the working folder"},
    {.key = NULL},
};

static int enable_display(scene_ctx *c, scene_map *m)
{
    (void)c;
    ((iso_scene_display *)m->obj)->enabled = 1;
    return ISO_OK;
}

/* The host the live view will bind, checked by the rule the view's server
 * binds by (a numeric address or localhost; beyond loopback only with
 * allow_remote), so that `check` refuses what `run` would. */
static int display_end(scene_ctx *c, scene_map *m)
{
    const iso_scene_display *d = m->obj;
    char why[160], key[ISO_SCENE_KEY_MAX];
    fnode *host = iso_scene__get(m->node, "host");
    int loopback = iso_fd_listen_host(d->host, why, sizeof why);
    iso_scene__join(key, sizeof key, m->key, "host");
    if (loopback < 0)
        return iso_scene__fail(c, host ? host : m->node, ISO_EINVAL, key,
                               "%s (the live view binds it; a name would need a resolver)", why);
    if (!loopback && !d->allow_remote)
        return iso_scene__fail(c, host, ISO_EINVAL, key,
                               "'%s' can be reached from other machines and the view has no "
                               "password; set allow_remote: true to serve on it anyway",
                               d->host);
    return ISO_OK;
}

static const scene_section display = {
    .name = "sinks.display",
    .what = "a mapping (host, port, allow_remote, snapshot_ticks, snapshot_dir)",
    .keys = display_keys,
    .begin = enable_display,
    .end = display_end};

static const scene_key ply_keys[] = {
    {"dir", SK_PATH, FIELD(iso_scene_ply, dir), SK_REQUIRED, .help = "a folder for the frames"},
    {"every", SK_INT, FIELD(iso_scene_ply, every), IN(1, 1000000),
     .help = "one frame per this many ticks", .dflt = "1"},
    {.key = NULL},
};

static int enable_ply(scene_ctx *c, scene_map *m)
{
    iso_scene_ply *p = m->obj;
    (void)c;
    p->enabled = 1;
    p->every = 1;
    return ISO_OK;
}

static const scene_section ply = {
    .name = "sinks.ply", .what = "{dir: FOLDER, every: N}", .keys = ply_keys, .begin = enable_ply};

/* ------------------------------------------------------------------------ */
/* actuators                                                                 */
/* ------------------------------------------------------------------------ */

#define LINK_FORMS                                                                                 \
    "{tty: PATH}, {tcp: host:port}, {serial: PORT}, {emulated: auto|qemu|native} or {usb: "        \
    "VID:PID}"

static int store_tcp(scene_ctx *c, const scene_key *k, fnode *v, const char *key, void *obj)
{
    iso_scene_actuators *a = obj;
    (void)k;
    return iso_scene__host_port(c, v, key, a->host, sizeof a->host, &a->port);
}

/* VID:PID in hex, as lsusb prints them ("1209:0001"). */
static int store_usb(scene_ctx *c, const scene_key *k, fnode *v, const char *key, void *obj)
{
    iso_scene_actuators *a = obj;
    (void)k;
    const char *t = iso_scene__is_null(c, v) ? NULL : iso_scene__scalar(c, v);
    char *end = NULL, found[80];
    unsigned long vid = t ? strtoul(t, &end, 16) : 0, pid = 0;
    int ok = t && isxdigit((unsigned char)t[0]) && end - t <= 4 && *end == ':' &&
             isxdigit((unsigned char)end[1]);
    if (ok) {
        const char *p = end + 1;
        pid = strtoul(p, &end, 16);
        ok = *end == '\0' && end - p <= 4 && (vid | pid) != 0;
    }
    if (!ok)
        return iso_scene__fail(c, v, ISO_EPARSE, key,
                               "expected VID:PID, the USB ids in hex as lsusb prints them "
                               "(e.g. 1209:0001), found %s",
                               iso_scene__found(c, v, found, sizeof found));
    a->vid = (int)vid;
    a->pid = (int)pid;
    return ISO_OK;
}

static const scene_key link_keys[] = {
    {"tty", SK_STRING, FIELD(iso_scene_actuators, path), SK_ONE_OF, .help = "a TTY device"},
    {"tcp", SK_STRING, 0, 0, SK_ONE_OF, .store = store_tcp, .type = "host:port",
     .help = "the bridge's host:port"},
    {"serial", SK_STRING, FIELD(iso_scene_actuators, path), SK_ONE_OF,
     .help = "a serial port's name (libserialport)"},
    {"emulated", SK_ENUM, FIELD(iso_scene_actuators, emulation), SK_ONE_OF,
     .names = iso_act_emu_names,
     .help = "the MCU emulated: in QEMU, natively, or auto (QEMU when it and the ELF are there)"},
    {"usb", SK_STRING, 0, 0, SK_ONE_OF, .store = store_usb, .type = "VID:PID",
     .help = "a bridge on USB bulk endpoints, by its ids in hex (libusb)"},
    /* ISO_FB_BOARD_BAUD as SCENES.md spells it (test_scene holds it to what loads) */
    {"baud", SK_INT, FIELD(iso_scene_actuators, baud), IN(50, 12000000), .with = "tty serial",
     .help = "the line's rate", .dflt = "115200"},
    {.key = NULL},
};

static int link_begin(scene_ctx *c, scene_map *m)
{
    iso_scene_actuators *a = m->obj;
    (void)c;
    a->baud = (int)ISO_FB_BOARD_BAUD; /* the link is to the bridge board's UART */
    a->emulation = ISO_SCENE_EMU_AUTO;
    return ISO_OK;
}

/* `link: emulated` is short for {emulated: auto}. */
static int link_word(scene_ctx *c, scene_map *m)
{
    static const char *const words[] = {"emulated", NULL};
    iso_scene_actuators *a = m->obj;
    const char *word = iso_scene__scalar(c, m->node);
    if (!word || !*word)
        return iso_scene__want_map(c, m->node, m->key, LINK_FORMS ", with baud for tty and serial");
    if (strcmp(word, "emulated") == 0)
        return (a->link = ISO_SCENE_LINK_EMULATED), ISO_OK;
    if (iso_scene__nearest(word, words))
        return iso_scene__fail(c, m->node, ISO_EPARSE, m->key,
                               "unknown link '%s'; did you mean 'emulated'? (expected " LINK_FORMS
                               ", or emulated alone)",
                               word);
    return iso_scene__fail(c, m->node, ISO_EPARSE, m->key,
                           "expected " LINK_FORMS ", or emulated alone; found '%s'", word);
}

_Static_assert(ISO_SCENE_LINK_TTY == 1 && ISO_SCENE_LINK_TCP == 2 && ISO_SCENE_LINK_SERIAL == 3 &&
                   ISO_SCENE_LINK_EMULATED == 4 && ISO_SCENE_LINK_USB == 5 &&
                   sizeof(iso_scene_link_kind) == sizeof(int),
               "link_keys' SK_ONE_OF rows are in iso_scene_link_kind's order (KIND_AT)");

static const scene_section actuator_link = {.name = "sinks.actuators.link",
                                            .what = LINK_FORMS ", with baud for tty and serial",
                                            .keys = link_keys,
                                            .begin = link_begin,
                                            .scalar = link_word,
                                            KIND_AT(iso_scene_actuators, link)};

/* fixed, or a handle by name. */
static int store_region(scene_ctx *c, const scene_key *k, fnode *v, const char *key, void *obj)
{
    iso_scene_channel *ch = obj;
    const iso_scene *s = c->s;
    const char *names[ISO_SCENE_MAX_HANDLES + 2];
    (void)k;
    names[0] = "fixed";
    for (int i = 0; i < s->n_handles; i++)
        names[i + 1] = s->handles[i].name;
    names[s->n_handles + 1] = NULL;
    int idx, rc = iso_scene__to_enum(c, v, key, names, &idx);
    if (rc == ISO_OK)
        ch->region = idx == 0 ? ISO_SCENE_REGION_FIXED : idx - 1;
    return rc;
}

_Static_assert(ISO_ACT_MAX_CHANNELS <= ISO_SCENE_MAX_CHANNELS,
               "a scene holds as many channels as a SETPOINTS frame carries");

static const char *const axes[] = {"x", "y", "z", NULL};

static const scene_key channel_keys[] = {
    {"channel", SK_INT, FIELD(iso_scene_channel, channel), SK_REQUIRED,
     IN(0, ISO_ACT_MAX_CHANNELS - 1),
     .help = "the actuator channel (a SETPOINTS frame's index), each once"},
    {"vertex", SK_INT, FIELD(iso_scene_channel, vertex), SK_ONE_OF, IN(0, 1L << 30),
     .help = "a vertex it follows"},
    {"region", SK_STRING, 0, 0, SK_ONE_OF, .store = store_region, .type = "fixed or a handle",
     .help = "or a region whose centroid it follows"},
    {"axis", SK_ENUM, FIELD(iso_scene_channel, axis), SK_REQUIRED, .names = axes,
     .help = "the coordinate it follows"},
    {"min", SK_NUMBER, FIELD(iso_scene_channel, min), SK_REQUIRED,
     .help = "the low limit (scene units)"},
    {"max", SK_NUMBER, FIELD(iso_scene_channel, max), SK_REQUIRED,
     .help = "the high limit (scene units), > min"},
    {"scale", SK_NUMBER, FIELD(iso_scene_channel, scale),
     .help = "scene units to actuator counts, not 0", .dflt = "1"},
    {.key = NULL},
};

static int channel_begin(scene_ctx *c, scene_map *m)
{
    iso_scene_channel *ch = m->obj;
    (void)c;
    iso_scene__mark(m->node, &ch->line, &ch->col);
    ch->scale = 1;
    ch->vertex = -1;
    ch->region = ISO_SCENE_REGION_NONE;
    return ISO_OK;
}

static int channel_end(scene_ctx *c, scene_map *m)
{
    const iso_scene_channel *ch = m->obj, *all = ch - m->item; /* the list's first */
    char key[ISO_SCENE_KEY_MAX];
    if (!(ch->min < ch->max))
        return iso_scene__fail(c, iso_scene__get(m->node, "max"), ISO_EINVAL,
                               iso_scene__join(key, sizeof key, m->key, "max"),
                               "expected max > min, found min %g, max %g", ch->min, ch->max);
    if (ch->scale == 0)
        return iso_scene__fail(c, iso_scene__get(m->node, "scale"), ISO_EINVAL,
                               iso_scene__join(key, sizeof key, m->key, "scale"),
                               "'0' is out of range: expected a number other than 0 (every "
                               "position would give the same setpoint)");
    for (int j = 0; j < m->item; j++)
        if (all[j].channel == ch->channel)
            return iso_scene__fail(c, iso_scene__get(m->node, "channel"), ISO_EPARSE, m->key,
                                   "channel %d is used twice", ch->channel);
    return ISO_OK;
}

static const scene_section channel = {.name = "sinks.actuators.channels[]",
                                      .what =
                                          "a channel {channel, vertex or region, axis, min, max}",
                                      .keys = channel_keys,
                                      .begin = channel_begin,
                                      .end = channel_end};

static const scene_key actuators_keys[] = {
    {"link", SK_SECTION, 0, 0, SK_REQUIRED, .sub = &actuator_link, .type = "emulated or mapping",
     .help = LINK_FORMS},
    {"channels", SK_LIST, FIELD(iso_scene_actuators, ch), SK_REQUIRED,
     .count_off = offsetof(iso_scene_actuators, n_ch), .stride = sizeof(iso_scene_channel),
     .min_items = 1, .max_items = ISO_ACT_MAX_CHANNELS, .sub = &channel, .noun = "channels",
     .type = "list of channels", .help = "a list of channels"},
    /* the loop watchdog may be widened or narrowed, never switched off */
    {"loop_timeout_ms", SK_INT, FIELD(iso_scene_actuators, loop_timeout_ms), IN(20, 60000),
     .help = "the loop watchdog's bound: no progress this long and the actuators go SAFE",
     .dflt = "max(250, 5 tick periods)"},
    {.key = NULL},
};

static int enable_actuators(scene_ctx *c, scene_map *m)
{
    (void)c;
    ((iso_scene_actuators *)m->obj)->enabled = 1;
    return ISO_OK;
}

static const scene_section actuators = {.name = "sinks.actuators",
                                        .what = "{link, channels}",
                                        .keys = actuators_keys,
                                        .begin = enable_actuators};

static const scene_key sinks_keys[] = {
    {"display", SK_SECTION, FIELD(iso_scene, display), .sub = &display,
     .help = "the live view, in a browser", .dflt = "off"},
    {"ply", SK_SECTION, FIELD(iso_scene, ply), .sub = &ply, .help = "the shape as PLY frames",
     .dflt = "off"},
    {"actuators", SK_SECTION, FIELD(iso_scene, actuators), .sub = &actuators,
     .help = "actuator setpoints over the firmware bridge", .dflt = "off"},
    {.key = NULL},
};

const scene_section iso_scene__sinks = {
    .name = "sinks", .what = "a mapping with display, ply or actuators", .keys = sinks_keys};
