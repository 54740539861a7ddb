/* tests/vm/check_rec.c -- the host's check of a recording made in the VM
 * against the sequence the scripted SpaceMouse played (a .seq file of data/):
 *
 *   check_rec SEQ REC TICKS [LIN ROT]
 *
 * REC is the recording, TICKS what `isoshape replay REC --fast
 * --print-ticks --sensitivity LIN,ROT` printed for it (one line a tick,
 * twists in %a); LIN and ROT are that sensitivity (default 0.1, 0.5).
 *
 *  1. Decoded through this library's decoders, the recording's axes and
 *     button states must pass through every state the sequence holds, in
 *     its order, and end at its last. Between them only the states a
 *     report at a time makes (a new translation beside the old rotation)
 *     may appear. This holds for hidraw (the raw reports) and, after the
 *     backend's documented mapping back to the device's axes and counts,
 *     for spacenavd.
 *  2. Each tick's twist is the closed form, under the default mapping (350
 *     counts full scale, 5 % dead zone, linear, LIN m/s and ROT rad/s at
 *     full scale, world frame), of the state the recording holds at that
 *     tick's TICK record (every record before it is drained in it), computed
 *     here without the library (twist_is says how a rotation about the
 *     handle enters); zero while the clutch (button 0) is held or the
 *     device is gone. The last tick is at rest.
 * Prints what it compared; exits 0 when all holds.
 *
 *   check_rec --events REC
 *
 * prints the recording's GPIO levels, GONE and BACK records with their
 * CLOCK_MONOTONIC times (the kernel's edge times for GPIO), one a line. */
#define _POSIX_C_SOURCE 200809L
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "iso_dev_decode.h"
#include "iso_dev_rec.h"

#define MAX_STATES 20000

typedef struct state {
    int16_t a[6];
    uint32_t b;
} state;

static state seq[256], dec[MAX_STATES], at_tick[MAX_STATES];
static int n_seq, n_dec, n_ticks;
static int failures;
static double sens_lin = 0.1, sens_rot = 0.5;

static int same(const state *x, const state *y)
{
    return memcmp(x->a, y->a, sizeof x->a) == 0 && x->b == y->b;
}

static void fail(const char *what)
{
    printf("FAIL: %s\n", what);
    failures++;
}

static void print_state(const char *label, const state *s)
{
    printf("%s axes %d %d %d  %d %d %d  buttons %x\n", label, s->a[0], s->a[1], s->a[2], s->a[3],
           s->a[4], s->a[5], s->b);
}

static int load_seq(const char *path)
{
    FILE *f = fopen(path, "r");
    if (!f)
        return -1;
    state cur = {{0}, 0};
    char line[256];
    while (fgets(line, sizeof line, f) && n_seq < 256) {
        int v[7];
        unsigned m;
        if (sscanf(line, "axes %d %d %d %d %d %d %d", &v[0], &v[1], &v[2], &v[3], &v[4], &v[5],
                   &v[6]) == 7) {
            for (int i = 0; i < 6; i++)
                cur.a[i] = (int16_t)v[i];
        } else if (sscanf(line, "buttons %x %d", &m, &v[0]) == 2) {
            cur.b = m;
        } else {
            continue;
        }
        if (n_seq == 0 || !same(&seq[n_seq - 1], &cur))
            seq[n_seq++] = cur;
    }
    fclose(f);
    return 0;
}

static int load_rec(const char *path)
{
    iso_dev_rec_reader r;
    iso_err err;
    iso_err_clear(&err);
    if (iso_dev_rec_reader_load(&r, path, &err) != ISO_OK) {
        printf("FAIL: %s\n", err.msg);
        return -1;
    }
    static iso_dev_decoder d[ISO_DEV_MAX_SOURCES];
    for (size_t i = 0; i < r.n_sources; i++)
        if (iso_dev_decoder_init(&d[i], &r.infos[i], (uint8_t)i, &err) != ISO_OK)
            return -1;
    iso_dev_chunk c;
    static iso_dev_event ev[ISO_DEV_EVENTS_PER_CHUNK];
    state cur = {{0}, 0};
    long gone = 0, back = 0;
    dec[n_dec++] = cur; /* decoders start at rest, as the device does */
    while (iso_dev_rec_next(&r, &c, NULL)) {
        if (c.type == ISO_DEV_CHUNK_TICK && n_ticks < MAX_STATES)
            at_tick[n_ticks++] = cur;
        if (c.type == ISO_DEV_CHUNK_GONE || c.type == ISO_DEV_CHUNK_BACK) {
            int is_gone = c.type == ISO_DEV_CHUNK_GONE;
            gone += is_gone;
            back += !is_gone;
            printf("%s src %u at %lld ns\n", is_gone ? "GONE" : "BACK", c.source,
                   (long long)c.t_ns);
            /* the mapping holds a gone source's handles still: its axes
             * count as rest until it reports again */
            if (is_gone) {
                memset(&cur, 0, sizeof cur);
                if (n_dec < MAX_STATES && !same(&dec[n_dec - 1], &cur))
                    dec[n_dec++] = cur;
            }
        }
        if (c.type != ISO_DEV_CHUNK_DATA || c.source >= r.n_sources)
            continue;
        size_t n = iso_dev_decode(&d[c.source], &c, ev, ISO_DEV_EVENTS_PER_CHUNK);
        for (size_t k = 0; k < n; k++) {
            if (ev[k].kind == ISO_DEV_EV_AXES)
                memcpy(cur.a, ev[k].axes, sizeof cur.a);
            else if (ev[k].kind == ISO_DEV_EV_BUTTONS)
                cur.b = ev[k].buttons;
            else
                continue;
            if (n_dec < MAX_STATES && (n_dec == 0 || !same(&dec[n_dec - 1], &cur)))
                dec[n_dec++] = cur;
        }
    }
    printf("recording %s: %zu source(s), %ld records, %d distinct decoded states, %ld gone, %ld "
           "back%s\n",
           path, r.n_sources, r.records, n_dec, gone, back, r.torn ? ", torn" : "");
    iso_dev_rec_reader_deinit(&r);
    return 0;
}

/* Part 1: the sequence's states, in order, within the decoded ones. */
static void check_states(void)
{
    int j = 0;
    for (int i = 0; i < n_dec && j < n_seq; i++)
        if (same(&dec[i], &seq[j]))
            j++;
    /* The recording starts at rest: the first step is often not a report. */
    if (j < n_seq) {
        print_state("  missing:", &seq[j]);
        for (int i = 0; i < n_dec && i < 60; i++)
            print_state("  decoded:", &dec[i]);
        fail("the decoded states do not pass through every state of the sequence");
    } else {
        printf("decoded states pass through all %d states of the sequence in order\n", n_seq);
    }
    if (n_dec == 0 || !same(&dec[n_dec - 1], &seq[n_seq - 1]))
        fail("the last decoded state is not the sequence's last");
}

/* The default mapping in closed form: output i from axis i. */
static void closed_form(const state *s, double w[3], double v[3])
{
    for (int i = 0; i < 6; i++) {
        double x = s->a[i] / 350.0, a = fabs(x) > 1 ? 1 : fabs(x);
        double u = a <= 0.05 ? 0 : (a - 0.05) / (1 - 0.05);
        u = (x < 0 ? -u : u) * (i < 3 ? sens_lin : sens_rot);
        if (i < 3)
            v[i] = u;
        else
            w[i - 3] = u;
    }
}

/* Whether a tick's twist is the mapping of state s. The rotation must be
 * the closed form's exactly; so must the velocity when there is no
 * rotation. With one, the handle turns about where it is (p), so the
 * velocity is the closed form's minus w x p, which this cannot know: the
 * difference must be perpendicular to w. */
static int twist_is(const double w[3], const double v[3], const state *s)
{
    double cw[3], cv[3], d[3];
    closed_form(s, cw, cv);
    for (int i = 0; i < 3; i++)
        if (cw[i] != w[i])
            return 0;
    for (int i = 0; i < 3; i++)
        d[i] = v[i] - cv[i];
    if (!cw[0] && !cw[1] && !cw[2])
        return !d[0] && !d[1] && !d[2];
    double dot = d[0] * w[0] + d[1] * w[1] + d[2] * w[2];
    double nd = sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
    double nw = sqrt(w[0] * w[0] + w[1] * w[1] + w[2] * w[2]);
    return fabs(dot) <= 1e-12 * nd * nw;
}

/* Part 2: each tick's twist, against the state at its TICK record. */
static int check_ticks(const char *path)
{
    FILE *f = fopen(path, "r");
    if (!f)
        return -1;
    char line[512];
    long ticks = 0, moving = 0, clutched = 0, odd = 0;
    double w[3] = {0}, v[3] = {0};
    while (fgets(line, sizeof line, f)) {
        double t;
        int h;
        if (sscanf(line, "%lf h%d", &t, &h) != 2)
            continue;
        const char *pw = strstr(line, " w "), *pv = strstr(line, " v ");
        if (!pw || !pv)
            continue;
        char *e = (char *)pw + 3;
        for (int i = 0; i < 3; i++)
            w[i] = strtod(e, &e);
        e = (char *)pv + 3;
        for (int i = 0; i < 3; i++)
            v[i] = strtod(e, &e);
        int zero = !w[0] && !w[1] && !w[2] && !v[0] && !v[1] && !v[2];
        moving += !zero;
        if (ticks >= n_ticks) {
            ticks++;
            continue;
        }
        const state *s = &at_tick[ticks++];
        static const state rest = {{0}, 0};
        clutched += (s->b & 1) != 0;
        if (!twist_is(w, v, (s->b & 1) ? &rest : s) && odd++ < 5) {
            print_state("  state at the tick:", s);
            printf("  tick %ld at %.6f s has another twist: %s", ticks, t, line);
        }
    }
    fclose(f);
    printf("ticks: %ld (%d TICK records), %ld moving, %ld with the clutch held\n", ticks, n_ticks,
           moving, clutched);
    if (ticks == 0 || ticks != n_ticks)
        fail("the replay's ticks are not the recording's TICK records");
    if (odd)
        fail("ticks whose twist is not the mapping of the state the recording holds at them");
    if (w[0] || w[1] || w[2] || v[0] || v[1] || v[2])
        fail("the last tick still moves");
    int deflected = 0;
    for (int j = 0; j < n_seq; j++)
        for (int i = 0; i < 6; i++)
            deflected |= seq[j].a[i] != 0 && !(seq[j].b & 1);
    if (deflected && !moving)
        fail("the sequence deflects the cap but no tick moved the handle");
    return 0;
}

static int print_events(const char *path)
{
    iso_dev_rec_reader r;
    iso_err err;
    iso_err_clear(&err);
    if (iso_dev_rec_reader_load(&r, path, &err) != ISO_OK) {
        printf("FAIL: %s\n", err.msg);
        return 1;
    }
    iso_dev_chunk c;
    while (iso_dev_rec_next(&r, &c, NULL)) {
        if (c.type == ISO_DEV_CHUNK_GONE || c.type == ISO_DEV_CHUNK_BACK)
            printf("%lld %s src %u\n", (long long)c.t_ns,
                   c.type == ISO_DEV_CHUNK_GONE ? "GONE" : "BACK", c.source);
        if (c.type != ISO_DEV_CHUNK_DATA || c.source >= r.n_sources ||
            r.infos[c.source].kind != ISO_DEV_KIND_GPIO)
            continue;
        for (unsigned i = 0; i + 1 < c.len; i += 2)
            printf("%lld %s %u src %u\n", (long long)c.t_ns,
                   c.data[i] == ISO_DEV_GPIO_ESTOP ? "estop" : "clutch", c.data[i + 1], c.source);
    }
    iso_dev_rec_reader_deinit(&r);
    return 0;
}

int main(int argc, char **argv)
{
    if (argc == 3 && strcmp(argv[1], "--events") == 0)
        return print_events(argv[2]);
    if (argc != 4 && argc != 6) {
        fprintf(stderr, "usage: check_rec SEQ REC TICKS [LIN ROT]\n");
        return 2;
    }
    if (argc == 6) {
        sens_lin = strtod(argv[4], NULL);
        sens_rot = strtod(argv[5], NULL);
    }
    if (load_seq(argv[1]) != 0 || n_seq == 0) {
        printf("FAIL: cannot read the sequence %s\n", argv[1]);
        return 1;
    }
    if (load_rec(argv[2]) != 0)
        return 1;
    check_states();
    if (check_ticks(argv[3]) != 0) {
        printf("FAIL: cannot read %s\n", argv[3]);
        return 1;
    }
    printf("%s\n", failures ? "check_rec: FAILED" : "check_rec: the recording is the sequence");
    return failures ? 1 : 0;
}
