/* tests/scene_schema.c -- see scene_schema.h. */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <cmocka.h>

#include "scene_schema.h"

#define MESH "mesh: {shape: bar, resolution: 1}"
#define REGIONS "regions: {handles: [{driver: none}]}"
#define TCP_DEVICE "devices: [{name: d, kind: tcp, address: 'h:1'}]"
#define CHANNEL "{channel: 0, vertex: 0, axis: x, min: 0, max: 1}"

/* Where each section is written in a scene: `doc` with %s where the
 * section's mapping content goes, `path` its key path in messages, and
 * off, size: where its struct lies in iso_scene. */
#define AT(member) offsetof(iso_scene, member), sizeof(((iso_scene *)0)->member)
#define WHOLE 0, sizeof(iso_scene)
static const struct place places[] = {
    {"", "", "{%s}", WHOLE},
    {"mesh", "mesh", "{mesh: {%s}, " REGIONS "}", AT(mesh_src)},
    {"devices[]", "devices[0]", "{" MESH ", devices: [{%s}], " REGIONS "}", AT(devices[0])},
    {"regions", "regions", "{" MESH ", regions: {%s}}", WHOLE},
    {"regions.handles[]", "regions.handles[0]", "{" MESH ", regions: {handles: [{%s}]}}",
     AT(handles[0])},
    {"selection", "regions.fixed", "{" MESH ", regions: {fixed: {%s}, handles: [{driver: none}]}}",
     AT(fixed.sel[0])},
    {"selection.box", "regions.fixed.box",
     "{" MESH ", regions: {fixed: {box: {%s}}, handles: [{driver: none}]}}", AT(fixed.sel[0])},
    {"selection.sphere", "regions.fixed.sphere",
     "{" MESH ", regions: {fixed: {sphere: {%s}}, handles: [{driver: none}]}}", AT(fixed.sel[0])},
    {"selection.beyond", "regions.fixed.beyond",
     "{" MESH ", regions: {fixed: {beyond: {%s}}, handles: [{driver: none}]}}", AT(fixed.sel[0])},
    {"regions.handles[].driver", "regions.handles[0].driver",
     "{" MESH ", " TCP_DEVICE ", regions: {handles: [{driver: {%s}}]}}", AT(handles[0].driver)},
    {"regions.handles[].driver.mapping", "regions.handles[0].driver.mapping",
     "{" MESH ", " TCP_DEVICE ", regions: {handles: [{driver: {device: d, mapping: {%s}}}]}}",
     AT(handles[0].driver.map)},
    {"regions.handles[].driver.screw", "regions.handles[0].driver.screw",
     "{" MESH ", regions: {handles: [{driver: {screw: {%s}}}]}}", AT(handles[0].driver)},
    {"regions.handles[].driver.keyframes[]", "regions.handles[0].driver.keyframes[0]",
     "{" MESH ", regions: {handles: [{driver: {keyframes: [{%s}]}}]}}",
     AT(handles[0].driver.keys[0])},
    {"solver", "solver", "{" MESH ", " REGIONS ", solver: {%s}}", AT(solver)},
    {"solver.restore", "solver.restore", "{" MESH ", " REGIONS ", solver: {restore: {%s}}}",
     AT(solver)},
    {"integrator", "integrator", "{" MESH ", " REGIONS ", integrator: {%s}}", WHOLE},
    {"sinks", "sinks", "{" MESH ", " REGIONS ", sinks: {%s}}", WHOLE},
    {"sinks.display", "sinks.display", "{" MESH ", " REGIONS ", sinks: {display: {%s}}}",
     AT(display)},
    {"sinks.ply", "sinks.ply", "{" MESH ", " REGIONS ", sinks: {ply: {%s}}}", AT(ply)},
    {"sinks.actuators", "sinks.actuators", "{" MESH ", " REGIONS ", sinks: {actuators: {%s}}}",
     AT(actuators)},
    {"sinks.actuators.link", "sinks.actuators.link",
     "{" MESH ", " REGIONS ", sinks: {actuators: {channels: [" CHANNEL "], link: {%s}}}}",
     AT(actuators)},
    {"sinks.actuators.channels[]", "sinks.actuators.channels[0]",
     "{" MESH ", " REGIONS ", sinks: {actuators: {link: emulated, channels: [{%s}]}}}",
     AT(actuators.ch[0])},
};

/* Values for keys whose kind says too little to make one up. */
static const struct {
    const char *key, *value;
} examples[] = {
    {"mesh", "{shape: bar, resolution: 1}"},
    {"devices", "[{name: d, kind: spnav}]"},
    {"regions", "{handles: [{driver: none}]}"},
    {"solver", "{omega: 0.5}"},
    {"integrator", "{abm: pec}"},
    {"sinks", "{ply: {dir: out}}"},
    {"regions.fixed", "{vertices: [0]}"},
    {"regions.handles", "[{driver: none}]"},
    {"selection.vertices", "[0, 1]"},
    {"selection.box", "{min: [0, 0, 0], max: [1, 1, 1]}"},
    {"selection.sphere", "{center: [0, 0, 0], radius: 1}"},
    {"selection.beyond", "{point: [0, 0, 0], normal: [0, 0, 1]}"},
    {"regions.handles[].select", "[{vertices: [1]}]"},
    {"regions.handles[].driver", "none"},
    {"regions.handles[].driver.device", "d"},
    {"regions.handles[].driver.mapping", "{curve: 2}"},
    {"regions.handles[].driver.screw", "{duration: 1}"},
    {"regions.handles[].driver.keyframes", "[{t: 0}]"},
    {"regions.handles[].driver.mapping.remap", "{ty: tz}"},
    {"regions.handles[].driver.mapping.invert", "[tx]"},
    {"regions.handles[].driver.mapping.buttons", "[clutch]"},
    {"solver.restore", "off"},
    {"solver.restore.mu", "0"},
    {"devices[].address", "'h:1'"},
    {"sinks.display.host", "127.0.0.2"},
    {"sinks.display", "{port: 8081}"},
    {"sinks.display.snapshot_ticks", "[1]"},
    {"sinks.ply", "{dir: out}"},
    {"sinks.actuators", "{link: emulated, channels: [" CHANNEL "]}"},
    {"sinks.actuators.link", "emulated"},
    {"sinks.actuators.link.tcp", "'h:1'"},
    {"sinks.actuators.link.usb", "'1209:0001'"},
    {"sinks.actuators.channels", "[" CHANNEL "]"},
    {"sinks.actuators.channels[].region", "fixed"},
    {"sinks.actuators.channels[].min", "0"},
    {"sinks.actuators.channels[].max", "1"},
};

const struct place *place_of(const scene_section *sec)
{
    for (size_t i = 0; i < sizeof places / sizeof places[0]; i++)
        if (strcmp(places[i].section, sec->name) == 0)
            return &places[i];
    fail_msg("test_scene: no place for section '%s' in places[]", sec->name);
    return NULL;
}

/* Every section once, from the top: n of them into all. */
int all_sections(const scene_section **all, int cap)
{
    int n = 0;
    all[n++] = &iso_scene__schema;
    for (int i = 0; i < n; i++)
        for (const scene_key *k = all[i]->keys; k->key; k++) {
            int seen = !k->sub;
            for (int j = 0; j < n && !seen; j++)
                seen = all[j] == k->sub;
            if (!seen && n < cap)
                all[n++] = k->sub;
        }
    return n;
}

const char *const *names_of(const scene_key *k)
{
    return k->names ? k->names : k->names_fn ? k->names_fn() : NULL;
}

/* A value of k's range (or of the devices layer's, for dev). */
double number_in_range(const scene_key *k)
{
    static const double tries[] = {1, 0.5, 0.1, 2, 10, 350};
    char why[128];
    if (k->dev) {
        for (size_t i = 0; i < sizeof tries / sizeof tries[0]; i++)
            if (iso_dev_map_check(k->dev, tries[i], why, sizeof why) == 0)
                return tries[i];
        fail_msg("%s: no value in the devices layer's range", k->key);
    }
    iso_range r;
    if (!iso_scene__range(k, &r))
        return 1;
    if (!r.hi_end)
        return r.lo + 1;
    return r.lo_end ? (r.lo + r.hi) / 2 : r.hi - 1;
}

/* A value for row k of sec, as YAML, into buf. */
const char *sample(const scene_section *sec, const scene_key *k, const char *variant, char *buf,
                   size_t cap)
{
    char key[ISO_SCENE_KEY_MAX];
    iso_scene__join(key, sizeof key, sec->name, k->key);
    for (size_t i = 0; i < sizeof examples / sizeof examples[0]; i++)
        if (strcmp(examples[i].key, key) == 0)
            return examples[i].value;
    switch (k->kind) {
    case SK_NUMBER: snprintf(buf, cap, "%.17g", number_in_range(k)); return buf;
    case SK_INT: {
        iso_range r;
        iso_scene__range(k, &r);
        snprintf(buf, cap, "%ld", (long)r.lo + (r.lo_end == ISO_RANGE_OPEN));
        return buf;
    }
    case SK_BOOL: return "true";
    case SK_STRING: return "x";
    case SK_FILE: return "f.txt";
    case SK_PATH: return "out";
    case SK_ENUM: return (k->flags & SK_SELECTOR) && variant ? variant : names_of(k)[0];
    case SK_VEC3: return "[0, 0, 1]";
    default: fail_msg("test_scene: no example for %s in examples[]", key);
    }
    return NULL;
}

int required_for(const scene_key *k, const char *variant)
{
    return (k->flags & SK_REQUIRED) ||
           (k->need && variant && iso_scene__in_words(k->need, variant));
}

/* The variant that row k needs: its first `with`, itself if SK_ONE_OF, or
 * the section's first (SK_ONE_OF key or selector's name). */
const char *variant_for(const scene_section *sec, const scene_key *k, char *buf, size_t cap)
{
    if (k && k->with) {
        snprintf(buf, cap, "%s", k->with);
        buf[strcspn(buf, " ")] = '\0';
        return buf;
    }
    if (k && (k->flags & SK_ONE_OF))
        return k->key;
    for (const scene_key *o = sec->keys; o->key; o++)
        if (o->flags & SK_ONE_OF)
            return o->key;
        else if (o->flags & SK_SELECTOR)
            return names_of(o)[0];
    return NULL;
}

/* The smallest content of sec that holds row k with `value`, into buf.
 * value NULL: k only chooses the variant and is left out. */
const char *content(const scene_section *sec, const scene_key *k, const char *value, char *buf,
                    size_t cap)
{
    char vbuf[64], sbuf[64];
    const char *variant = variant_for(sec, k, vbuf, sizeof vbuf);
    size_t n = 0;
    buf[0] = '\0';
    for (const scene_key *r = sec->keys; r->key; r++) {
        int one_of = (r->flags & SK_ONE_OF) && variant && strcmp(r->key, variant) == 0;
        if (r == k && !value)
            continue;
        if (r != k && !required_for(r, variant) && !one_of && !(r->flags & SK_SELECTOR))
            continue;
        const char *v = r == k ? value : sample(sec, r, variant, sbuf, sizeof sbuf);
        n += (size_t)snprintf(buf + n, cap - n, "%s%s: %s", n ? ", " : "", r->key, v);
        assert_true(n < cap);
    }
    return buf;
}

int load_section(const scene_section *sec, const char *what, iso_scene **s, iso_err *err)
{
    static char doc[8192];
    iso_scene_opts o = {.flags = ISO_SCENE_PARSE_ONLY};
    snprintf(doc, sizeof doc, place_of(sec)->doc, what);
    iso_err_clear(err);
    *s = NULL;
    return iso_scene_load_mem(doc, strlen(doc), "schema.yaml", &o, s, err);
}
