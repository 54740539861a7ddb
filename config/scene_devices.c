/* config/scene_devices.c -- the scene's `devices:` list. Each device is
 * {name, kind, ...}; its kind says which other keys it takes, and a key of
 * another kind is an error (a tty's `address` would otherwise be silently
 * ignored). */
#include "internal.h"

#include <string.h>

#include "iso_dev_rec.h"
#include "iso_fb_mcu.h" /* ISO_FB_BOARD_BAUD */
#include "iso_names.h"

#define STR_(x) #x
#define STR(x) STR_(x)

/* By iso_scene_dev_backend value, from ISO_SCENE_DEV_HIDAPI (1). */
static const char *const backend_names[] = {"hid",  "spnav",  "tty",  "tcp", "serialport",
                                            "gpio", "replay", "view", NULL};

const char *iso_scene_backend_name(int b)
{
    return b >= 1 ? iso_names_get(backend_names, b - 1) : "?";
}

/* Kept as "host:port" (a resolved form would hide what was written). */
static int store_address(scene_ctx *c, const scene_key *k, fnode *v, const char *key, void *obj)
{
    iso_scene_device *d = obj;
    char host[ISO_SCENE_NAME_MAX];
    int port, rc = iso_scene__host_port(c, v, key, host, sizeof host, &port);
    (void)k;
    if (rc == ISO_OK)
        snprintf(d->address, sizeof d->address, "%s:%d", host, port);
    return rc;
}

/* stale_ms right after kind: the likely mistake, said first. */
static const scene_key device_keys[] = {
    {"name", SK_STRING, FIELD(iso_scene_device, name), SK_REQUIRED,
     .help = "the name drivers refer to"},
    {"kind", SK_ENUM, FIELD(iso_scene_device, backend), SK_REQUIRED | SK_SELECTOR,
     .names = backend_names, .first = ISO_SCENE_DEV_HIDAPI, .help = "the backend that reads it"},
    {"stale_ms", SK_INT, FIELD(iso_scene_device, stale_ms),
     IN(ISO_SCENE_STALE_MS_MIN, ISO_SCENE_STALE_MS_MAX), .with = "tty tcp serialport replay view",
     .help = "a twist or target stream this long without a sample stops moving its handle",
     .dflt = STR(ISO_SCENE_STALE_MS_DEFAULT) ", a view " STR(ISO_SCENE_STALE_MS_VIEW_DEFAULT)},
    {"path", SK_STRING, FIELD(iso_scene_device, path), .with = "hid tty", .need = "tty",
     .help = "the device node (hid: a hidraw node; tty: e.g. /dev/ttyUSB0)",
     .dflt = "hid: the first 3D mouse"},
    {"address", SK_STRING, 0, 0, .with = "tcp", .need = "tcp", .store = store_address,
     .type = "host:port", .help = "the bridge's host:port"},
    {"port", SK_STRING, FIELD(iso_scene_device, path), .with = "serialport", .need = "serialport",
     .help = "the serial port's name (libserialport), e.g. /dev/ttyUSB0"},
    /* ISO_FB_BOARD_BAUD as SCENES.md spells it (test_scene holds it to what loads) */
    {"baud", SK_INT, FIELD(iso_scene_device, baud), IN(50, 12000000), .with = "tty serialport",
     .help = "the line's rate", .dflt = "115200"},
    {"vid", SK_INT, FIELD(iso_scene_device, vid), IN(0, 0xffff), .with = "hid",
     .help = "the USB vendor id", .dflt = "0 (any)"},
    {"pid", SK_INT, FIELD(iso_scene_device, pid), IN(0, 0xffff), .with = "hid",
     .help = "the USB product id", .dflt = "0 (any)"},
    {"chip", SK_STRING, FIELD(iso_scene_device, chip), .with = "gpio", .need = "gpio",
     .help = "a GPIO chip such as gpiochip0"},
    {"clutch_line", SK_INT, FIELD(iso_scene_device, gpio.clutch_line), IN(-1, 1023), .with = "gpio",
     .help = "the clutch button's line", .dflt = "-1 (none)"},
    {"estop_line", SK_INT, FIELD(iso_scene_device, gpio.estop_line), IN(-1, 1023), .with = "gpio",
     .help = "the emergency stop's line", .dflt = "-1 (none)"},
    {"pulse_line", SK_INT, FIELD(iso_scene_device, gpio.pulse_line), IN(-1, 1023), .with = "gpio",
     .help = "a pulse input's line", .dflt = "-1 (none)"},
    {"active_low", SK_BOOL, FIELD(iso_scene_device, gpio.active_low), .with = "gpio",
     .help = "the lines read 0 when active", .dflt = "false"},
    {"debounce_us", SK_INT, FIELD(iso_scene_device, gpio.debounce_us), IN(0, 1000000),
     .with = "gpio", .help = "the lines' debounce time in microseconds", .dflt = "0"},
    {"file", SK_FILE, FIELD(iso_scene_device, path), .with = "replay", .need = "replay",
     .help = "a recording (.isorec)"},
    {.key = NULL},
};

static int device_begin(scene_ctx *c, scene_map *m)
{
    iso_scene_device *d = m->obj;
    (void)c;
    d->stale_ms = 0; /* the source's kind's default (controller/loop_devices.c) */
    return ISO_OK;
}

/* Only a stream of twist or target samples can go stale; a 3D mouse reports the
 * state of its cap, and one held still may send nothing new. Said before
 * the kind's other keys are checked, since it is the likely mistake. */
static int device_kind(scene_ctx *c, scene_map *m)
{
    iso_scene_device *d = m->obj;
    const scene_key *k = iso_scene__row(&iso_scene__device, "stale_ms");
    fnode *v = iso_scene__get(m->node, "stale_ms");
    char key[ISO_SCENE_KEY_MAX], kinds[128];
    if (v && !iso_scene__in_words(k->with, m->variant))
        return iso_scene__fail(
            c, v, ISO_EPARSE, iso_scene__join(key, sizeof key, m->key, k->key),
            "only twist and target streams time out (kinds %s); a %s device reports a "
            "state and is not timed out",
            iso_scene__words_list(k->with, ", ", kinds, sizeof kinds), m->variant);
    /* A serial device carries the firmware bridge's stream (devices/decode.c):
     * its line runs at the bridge board's rate unless the scene says. */
    if (d->backend == ISO_SCENE_DEV_TTY || d->backend == ISO_SCENE_DEV_SERIALPORT)
        d->baud = ISO_FB_BOARD_BAUD;
    if (d->backend == ISO_SCENE_DEV_GPIOD) {
        d->gpio.chip = d->chip;
        d->gpio.clutch_line = d->gpio.estop_line = d->gpio.pulse_line = -1;
    }
    return ISO_OK;
}

static int device_end(scene_ctx *c, scene_map *m)
{
    const iso_scene_device *d = m->obj, *all = d - m->item; /* the list's first */
    char key[ISO_SCENE_KEY_MAX];
    if (d->backend == ISO_SCENE_DEV_REPLAY && m->count > 1)
        return iso_scene__fail(c, iso_scene__get(m->node, "kind"), ISO_EINVAL,
                               iso_scene__join(key, sizeof key, m->key, "kind"),
                               "'replay' stands for every device it recorded and cannot be "
                               "combined with other devices (the list has %d)",
                               m->count);
    if (d->backend == ISO_SCENE_DEV_REPLAY && c->check_files) {
        /* run reads the recording's header first thing: so does check */
        iso_dev_rec_reader r;
        iso_err e;
        iso_err_clear(&e);
        int rc = iso_dev_rec_reader_load(&r, d->path, &e);
        if (rc != ISO_OK)
            return iso_scene__fail(c, iso_scene__get(m->node, "file"), rc,
                                   iso_scene__join(key, sizeof key, m->key, "file"), "%s", e.msg);
        iso_dev_rec_reader_deinit(&r);
    }
    for (int j = 0; j < m->item; j++) {
        if (strcmp(all[j].name, d->name) == 0)
            return iso_scene__fail(c, iso_scene__get(m->node, "name"), ISO_EPARSE, m->key,
                                   "device name '%s' is used twice", d->name);
        if (d->backend == ISO_SCENE_DEV_VIEW && all[j].backend == ISO_SCENE_DEV_VIEW)
            return iso_scene__fail(c, iso_scene__get(m->node, "kind"), ISO_EPARSE, m->key,
                                   "device '%s' is a second view device (one page commands one "
                                   "device; '%s' is it)",
                                   d->name, all[j].name);
    }
    return ISO_OK;
}

const scene_section iso_scene__device = {.name = "devices[]",
                                         .what = "a device {name, kind, ...}",
                                         .keys = device_keys,
                                         .begin = device_begin,
                                         .chosen = device_kind,
                                         .end = device_end};

int iso_scene_device_stale_ms(const iso_scene_device *d, int source_kind)
{
    if (d->stale_ms > 0)
        return d->stale_ms;
    return source_kind == ISO_DEV_KIND_VIEW ? ISO_SCENE_STALE_MS_VIEW_DEFAULT
                                            : ISO_SCENE_STALE_MS_DEFAULT;
}
