/* controller/cli_dev_map.c -- the device mapping's options, which `isoshape
 * record` and `isoshape replay` share: how a device's six axes become a
 * handle's twist. A table fragment whose rows' values go into an
 * iso_dev_map_opts. The numbers' ranges are devices/'s (iso_dev_map_check),
 * the ones a scene file's mapping is held to, so they are checked there and
 * not repeated here. */
#include "internal.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* --sensitivity L,A: m/s on the three translation axes, rad/s on the
 * three rotation axes, at full deflection. */
static int set_sensitivity(const iso_cli__opt *o, void *dst, const char *val, char *why, size_t cap)
{
    iso_dev_map_opts *m = dst;
    double l, a;
    char tail;
    (void)o;
    if (sscanf(val, "%lf,%lf%c", &l, &a, &tail) != 2) {
        snprintf(why, cap, "expected L,A (m/s and rad/s at full scale)");
        return -1;
    }
    if (iso_dev_map_check("sensitivity", l, why, cap) != 0 ||
        iso_dev_map_check("sensitivity", a, why, cap) != 0)
        return -1;
    for (int k = 0; k < 3; k++) {
        m->sensitivity[k] = l;
        m->sensitivity[k + 3] = a;
    }
    return 0;
}

/* --dead-zone F and --curve E: one number (the row checked it is one) for
 * all six axes; the scene key is the option's name with '_' for '-'. */
static int set_every_axis(const iso_cli__opt *o, void *dst, const char *val, char *why, size_t cap)
{
    double *axes = dst, v = strtod(val, NULL);
    char field[32];
    snprintf(field, sizeof field, "%s", o->name);
    for (char *c = field; *c; c++)
        *c = *c == '-' ? '_' : *c;
    if (iso_dev_map_check(field, v, why, cap) != 0)
        return -1;
    for (int k = 0; k < 6; k++)
        axes[k] = v;
    return 0;
}

/* --remap A,B,C,D,E,F: output axis i reads the input axis given i-th
 * (iso_dev_map_init checks they are axes). */
static int set_remap(const iso_cli__opt *o, void *dst, const char *val, char *why, size_t cap)
{
    int *remap = dst, m[6];
    char tail;
    (void)o;
    if (sscanf(val, "%d,%d,%d,%d,%d,%d%c", &m[0], &m[1], &m[2], &m[3], &m[4], &m[5], &tail) != 6) {
        snprintf(why, cap, "expected six input axes, e.g. 0,2,1,3,5,4");
        return -1;
    }
    memcpy(remap, m, sizeof m);
    return 0;
}

/* An axis of iso_dev_axis_names ("tx" .. "rz"); "x", "y" and "z" stand
 * for "tx", "ty" and "tz" (what this option took before scenes named them). */
static int axis_index(const char *s, size_t n)
{
    char word[4];
    if (n < 1 || n > 2)
        return -1;
    snprintf(word, sizeof word, "%s%.*s", n == 1 ? "t" : "", (int)n, s);
    return iso_names_find(iso_dev_axis_names, word);
}

/* --invert AXES: a comma list; each option adds to the axes inverted. */
static int set_invert(const iso_cli__opt *o, void *dst, const char *val, char *why, size_t cap)
{
    int *invert = dst;
    (void)o;
    for (const char *p = val; *p;) {
        size_t n = strcspn(p, ",");
        int a = axis_index(p, n);
        if (a < 0) {
            snprintf(why, cap, "'%.*s' is not one of tx,ty,tz,rx,ry,rz", (int)n, p);
            return -1;
        }
        invert[a] = 1;
        p += n + (p[n] == ',');
    }
    return 0;
}

const iso_cli__opt iso_cli__dev_map_options[] = {
    {"handles", ISO_CLI_OPT_INT, ISO_CLI_INT_AT(iso_dev_map_opts, n_handles), "N",
     .help = "handles the devices drive, %R (default 1; a 'next handle' button cycles)",
     ISO_CLI_GE(1), ISO_CLI_LE(ISO_DEV_MAX_HANDLES)},
    {"sensitivity", ISO_CLI_OPT_CALL, 0, "L,A",
     .help = "at full deflection: L m/s and A rad/s (default 0.1,0.5)", .set = set_sensitivity},
    {"dead-zone", ISO_CLI_OPT_DOUBLE, offsetof(iso_dev_map_opts, dead_zone), "F",
     .help = "fraction of full scale that maps to 0 (default 0.05)", .set = set_every_axis},
    {"curve", ISO_CLI_OPT_DOUBLE, offsetof(iso_dev_map_opts, curve), "E",
     .help = "response exponent (1 linear, 2 quadratic; default 1)", .set = set_every_axis},
    {"remap", ISO_CLI_OPT_CALL, offsetof(iso_dev_map_opts, remap), "A,B,C,D,E,F",
     .help = "output axis i reads input axis (0..5: tx ty tz rx ry rz)", .set = set_remap},
    {"invert", ISO_CLI_OPT_CALL, offsetof(iso_dev_map_opts, invert), "AXES",
     .help = "comma list of axes to negate: tx,ty,tz,rx,ry,rz (or x,y,z)", .set = set_invert},
    {"dominant", ISO_CLI_OPT_FLAG, ISO_CLI_INT_AT(iso_dev_map_opts, dominant), NULL,
     .help = "keep only the largest axis", .flag = 1},
    {"lock", ISO_CLI_OPT_ENUM, ISO_CLI_INT_AT(iso_dev_map_opts, lock), NULL,
     .help = "translation or rotation: that motion only (default none)",
     .names = iso_dev_lock_names},
    {"frame", ISO_CLI_OPT_ENUM, ISO_CLI_INT_AT(iso_dev_map_opts, frame), NULL,
     .help = "axes along the world's (default) or along the handle's own (device)",
     .names = iso_dev_frame_names},
    {"deadman", ISO_CLI_OPT_FLAG, ISO_CLI_INT_AT(iso_dev_map_opts, clutch_is_deadman), NULL,
     .help = "move only while the clutch is held (default: held = hold still)", .flag = 1},
    {0}};
