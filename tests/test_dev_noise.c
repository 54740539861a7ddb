/* tests/test_dev_noise.c -- noise on a device is counted and said, costs a
 * tick a bounded drain, and is capped in a recording without changing what
 * the recording replays:
 *  - every byte of 2 MB of random bytes (and of 2 MB of 0xFF, a line at the
 *    wrong baud rate) is counted as garbage, delimiters aside;
 *  - good frames after noise count one resync;
 *  - a source that delivers only noise for ISO_DEV_NOISE_NOTICE_NS gets one
 *    message with a hint, and one when good input is back;
 *  - a recording of a serial source flooded with noise keeps at most
 *    ISO_DEV_REC_NOISE_CAP noise bytes a second, and its replay gives the
 *    same tick commands, counters and messages as the live run, bit for
 *    bit, frames cut across noise chunks included;
 *  - a tick drains at most ISO_DEV_DRAIN_MAX bytes of a source. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>

#include <cmocka.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "iso_dev_decode.h"
#include "iso_dev_hub.h"
#include "iso_dev_map.h"
#include "iso_dev_rec.h"
#include "iso_dev_source.h"
#include "iso_fb.h"
#include "testutil.h"

#define MS 1000000LL
#define TICK_NS 16666667LL

/* The test's state: a fixed LCG for the noise, the messages each hub said. */
static struct {
    unsigned lcg;
    char msgs[2][64][700];
    int nmsg[2];
    uint16_t pushed[20000]; /* live_run: the length of every chunk, in order */
    size_t npushed;
} g = {12345u, {{{0}}}, {0}, {0}, 0};

static void push(iso_dev_source *s, int64_t t, const uint8_t *p, size_t n)
{
    assert_int_equal(iso_dev_fake_push(s, t, p, n), ISO_OK);
    assert_true(g.npushed < sizeof g.pushed / sizeof g.pushed[0]);
    g.pushed[g.npushed++] = (uint16_t)n;
}

static uint8_t rnd(void)
{
    g.lcg = g.lcg * 1103515245u + 12345u;
    return (uint8_t)(g.lcg >> 16);
}

static void note(void *ctx, const char *msg)
{
    int which = *(const int *)ctx;
    if (g.nmsg[which] < 64)
        snprintf(g.msgs[which][g.nmsg[which]], sizeof g.msgs[0][0], "%s", msg);
    g.nmsg[which]++;
}

static iso_dev_info serial_info(void)
{
    iso_dev_info in;
    memset(&in, 0, sizeof in);
    in.kind = ISO_DEV_KIND_SERIAL;
    in.baud = 115200;
    in.data_bits = 8;
    in.parity = 'N';
    in.stop_bits = 1;
    snprintf(in.name, sizeof in.name, "/dev/ttyACM0");
    return in;
}

/* One HANDLE_SAMPLE twist frame, x velocity vx µm/s; returns its length. */
static size_t twist_frame(uint8_t *dst, uint16_t seq, int32_t vx)
{
    iso_fb_sample s;
    memset(&s, 0, sizeof s);
    s.t_us = seq * 1000u;
    s.kind = ISO_FB_SAMPLE_TWIST;
    s.v[0] = vx;
    uint8_t pl[64];
    int n = iso_fb_sample_pack(pl, sizeof pl, &s);
    assert_true(n > 0);
    int w = iso_fb_frame_encode(dst, ISO_FB_FRAME_MAX, ISO_FB_HANDLE_SAMPLE, seq, pl, (size_t)n);
    assert_true(w > 0);
    return (size_t)w;
}

static void feed(iso_dev_decoder *d, const uint8_t *p, size_t n)
{
    static iso_dev_event ev[ISO_DEV_EVENTS_PER_CHUNK];
    for (size_t i = 0; i < n; i += ISO_DEV_CHUNK_MAX) {
        iso_dev_chunk c;
        memset(&c, 0, sizeof c);
        c.type = ISO_DEV_CHUNK_DATA;
        c.t_ns = (int64_t)i;
        c.len = (uint16_t)(n - i < ISO_DEV_CHUNK_MAX ? n - i : ISO_DEV_CHUNK_MAX);
        memcpy(c.data, p + i, c.len);
        iso_dev_decode(d, &c, ev, ISO_DEV_EVENTS_PER_CHUNK);
    }
}

static void noise_is_counted_byte_for_byte(void **state)
{
    (void)state;
    const size_t n = 2u << 20;
    uint8_t *buf = malloc(n);
    assert_non_null(buf);
    iso_dev_info in = serial_info();
    /* random bytes: every byte that is not a delimiter is garbage */
    size_t zeros = 0;
    for (size_t i = 0; i < n; i++)
        zeros += (buf[i] = rnd()) == 0;
    iso_dev_decoder d;
    assert_int_equal(iso_dev_decoder_init(&d, &in, 0, NULL), ISO_OK);
    feed(&d, buf, n);
    iso_dev_frame_drops drops;
    iso_dev_decoder_drops(&d, &drops);
    assert_int_equal(d.n.reports, 0);
    assert_int_equal(d.n.garbage + d.fb_pending, n - zeros);
    assert_true(d.n.bad_frames > zeros / 2); /* a stretch between zeros is one bad frame */
    assert_int_equal(d.n.resyncs, 0);
    /* then a good frame: one resync, one report */
    uint8_t fr[ISO_FB_FRAME_MAX];
    size_t w = twist_frame(fr, 1, 1000);
    uint32_t g0 = d.n.garbage;
    feed(&d, fr, w);
    assert_int_equal(d.n.reports, 1);
    assert_int_equal(d.n.resyncs, 1);
    assert_true(d.n.garbage >= g0);
    /* 0xFF (a line at the wrong baud rate often reads as it): no delimiter
     * at all, one overflow, and still every byte is counted */
    memset(buf, 0xFF, n);
    assert_int_equal(iso_dev_decoder_init(&d, &in, 0, NULL), ISO_OK);
    feed(&d, buf, n);
    assert_int_equal(d.n.bad_frames, 1);
    assert_int_equal(d.n.garbage + d.fb_pending, n);
    print_message("2 MB of 0xFF: %u garbage bytes, %u bad frame\n",
                  (unsigned)(d.n.garbage + d.fb_pending), (unsigned)d.n.bad_frames);
    free(buf);
}

/* A hub over one fake source, ticking at 60 Hz. */
typedef struct rig {
    iso_dev_hub *h;
    iso_dev_map m;
    iso_dev_source *s;
    int which;
} rig;

static void rig_open(rig *r, int which, const iso_dev_info *in)
{
    memset(r, 0, sizeof *r);
    r->which = which;
    g.nmsg[which] = 0;
    assert_int_equal(iso_dev_hub_create(note, &r->which, &r->h, NULL), ISO_OK);
    assert_int_equal(iso_dev_fake_open(in, &r->s, NULL), ISO_OK);
    assert_int_equal(iso_dev_hub_add(r->h, r->s, NULL, NULL, NULL), ISO_OK);
    iso_dev_map_opts mo;
    iso_dev_map_opts_default(&mo);
    assert_int_equal(iso_dev_map_init(&r->m, &mo, NULL), ISO_OK);
}

static void rig_tick(rig *r, int64_t t, iso_dev_tick *out)
{
    iso_pose P[ISO_DEV_MAX_HANDLES];
    for (unsigned i = 0; i < ISO_DEV_MAX_HANDLES; i++)
        iso_pose_identity(&P[i]);
    iso_err err;
    iso_err_clear(&err);
    assert_int_equal(iso_dev_hub_tick(r->h, &r->m, t, TICK_NS * 1e-9, P, out, &err), ISO_OK);
}

static int said(int which, const char *what)
{
    int n = 0;
    for (int i = 0; i < g.nmsg[which] && i < 64; i++)
        n += strstr(g.msgs[which][i], what) != NULL;
    return n;
}

static void noise_is_said_once_with_a_hint(void **state)
{
    (void)state;
    iso_dev_info in = serial_info();
    rig r;
    rig_open(&r, 0, &in);
    uint8_t chunk[200];
    /* 3 s of noise, a chunk every 10 ms, then good frames */
    for (int64_t t = 0; t < 3000 * MS; t += 10 * MS) {
        for (size_t i = 0; i < sizeof chunk; i++)
            chunk[i] = rnd();
        assert_int_equal(iso_dev_fake_push(r.s, t, chunk, sizeof chunk), ISO_OK);
    }
    uint8_t fr[ISO_FB_FRAME_MAX];
    for (int k = 0; k < 10; k++) {
        size_t w = twist_frame(fr, (uint16_t)(k + 1), 500);
        assert_int_equal(iso_dev_fake_push(r.s, 3000 * MS + k * 10 * MS, fr, w), ISO_OK);
    }
    iso_dev_tick out;
    int64_t told_at = -1;
    for (int64_t k = 1; k * TICK_NS < 3200 * MS; k++) {
        int before = said(0, "not one valid frame");
        rig_tick(&r, k * TICK_NS, &out);
        if (told_at < 0 && said(0, "not one valid frame") > before)
            told_at = k * TICK_NS;
    }
    assert_int_equal(said(0, "not one valid frame"), 1);
    assert_int_equal(said(0, "check the baud rate (this end reads 115200 8N1"), 1);
    assert_int_equal(said(0, "valid input again"), 1);
    /* said in the first tick whose noise spans the notice time */
    assert_true(told_at >= ISO_DEV_NOISE_NOTICE_NS);
    assert_true(told_at < ISO_DEV_NOISE_NOTICE_NS + 10 * MS + TICK_NS);
    iso_dev_source_stats st;
    assert_int_equal(iso_dev_hub_source_stats(r.h, 0, &st), ISO_OK);
    assert_int_equal(st.dec.resyncs, 1);
    assert_int_equal(st.dec.reports, 10);
    print_message("%s\n", g.msgs[0][0]);
    iso_dev_hub_destroy(r.h);

    /* a HID device whose reports this build cannot read */
    iso_dev_info hid;
    memset(&hid, 0, sizeof hid);
    hid.kind = ISO_DEV_KIND_HID;
    snprintf(hid.name, sizeof hid.name, "/dev/hidraw9");
    rig_open(&r, 0, &hid);
    const uint8_t odd[8] = {0x42, 1, 2, 3, 4, 5, 6, 7};
    for (int64_t t = 0; t < 2500 * MS; t += 8 * MS)
        assert_int_equal(iso_dev_fake_push(r.s, t, odd, sizeof odd), ISO_OK);
    for (int64_t k = 1; k * TICK_NS < 2600 * MS; k++)
        rig_tick(&r, k * TICK_NS, &out);
    assert_int_equal(said(0, "not one valid report"), 1);
    assert_int_equal(said(0, "is this a 3D mouse"), 1);
    iso_dev_hub_destroy(r.h);
}

/* Live: 3 s of a serial source that sends a good twist frame every tick
 * inside a flood of noise (~15 kB a tick), some frames cut across two noise
 * chunks, one tick of 40 kB; recorded. Returns the recording's size. */
static long live_run(const char *path, iso_dev_tick *cmds, int *nticks, iso_dev_counters *n_out,
                     iso_dev_frame_drops *d_out, size_t *noise_bytes, long *max_drained)
{
    iso_dev_info in = serial_info();
    rig r;
    rig_open(&r, 0, &in);
    iso_err err;
    iso_err_clear(&err);
    assert_int_equal(iso_dev_hub_record_start(r.h, path, &err), ISO_OK);
    uint8_t chunk[ISO_DEV_CHUNK_MAX], fr[ISO_FB_FRAME_MAX];
    const int ticks = 180;
    *noise_bytes = 0;
    for (int k = 0; k < ticks; k++) {
        int64_t t0 = k * TICK_NS;
        int pieces = k == 90 ? 160 : 60; /* one tick of 40 kB */
        size_t w = twist_frame(fr, (uint16_t)(k + 1), 1000 * (k % 7));
        int cut_at = k % 3 == 0 ? pieces / 2 : -1; /* this frame straddles two chunks */
        for (int i = 0; i < pieces; i++) {
            size_t n = 0;
            if (i == cut_at + 1 && cut_at >= 0) { /* the frame's second half, then noise */
                memcpy(chunk, fr + w / 2, w - w / 2);
                n = w - w / 2;
            }
            size_t noise = i == cut_at ? 250 - w / 2 : 250 - n;
            for (size_t j = 0; j < noise; j++)
                chunk[n++] = rnd();
            *noise_bytes += noise;
            if (i == cut_at) { /* noise, then the frame's first half */
                memcpy(chunk + n, fr, w / 2);
                n += w / 2;
            }
            if (cut_at < 0 && i == pieces / 2) /* a whole frame of its own */
                push(r.s, t0 + i * 100000, fr, w);
            push(r.s, t0 + i * 100000 + 1, chunk, n);
        }
    }
    *max_drained = 0;
    iso_dev_source_stats st;
    uint32_t chunks0 = 0;
    for (int k = 1; k <= ticks + 10; k++) {
        rig_tick(&r, k * TICK_NS, &cmds[k - 1]);
        assert_int_equal(iso_dev_hub_source_stats(r.h, 0, &st), ISO_OK);
        long drained = 0; /* the bytes of the chunks this tick decoded */
        for (uint32_t c = chunks0; c < st.dec.chunks; c++)
            drained += g.pushed[c];
        if (drained > *max_drained)
            *max_drained = drained;
        chunks0 = st.dec.chunks;
    }
    assert_int_equal(chunks0, g.npushed); /* all of it, in the end */
    *nticks = ticks + 10;
    assert_int_equal(iso_dev_hub_record_stop(r.h, &err), ISO_OK);
    *n_out = st.dec;
    *d_out = st.drops;
    iso_dev_hub_destroy(r.h);
    struct stat sb;
    assert_int_equal(stat(path, &sb), 0);
    return (long)sb.st_size;
}

static void capped_recording_replays_the_same(void **state)
{
    (void)state;
    char path[1024];
    iso_test_tmp(path, sizeof path, "dev_noise.isorec");
    static iso_dev_tick live[256], rep[256];
    int n_live = 0;
    iso_dev_counters nl;
    iso_dev_frame_drops dl;
    size_t noise = 0;
    long drained = 0;
    long size = live_run(path, live, &n_live, &nl, &dl, &noise, &drained);
    int live_msgs = g.nmsg[0];

    /* the replay */
    iso_dev_rec_reader rr;
    iso_err err;
    iso_err_clear(&err);
    assert_int_equal(iso_dev_rec_reader_load(&rr, path, &err), ISO_OK);
    char cut[400];
    assert_int_equal(iso_dev_rec_reader_cut(&rr, cut, sizeof cut, NULL), 0);
    rig p;
    memset(&p, 0, sizeof p);
    p.which = 1;
    g.nmsg[1] = 0;
    assert_int_equal(iso_dev_hub_create(note, &p.which, &p.h, NULL), ISO_OK);
    iso_dev_source *src;
    assert_int_equal(iso_dev_replay_open(&rr, &src, NULL), ISO_OK);
    assert_int_equal(iso_dev_hub_add(p.h, src, NULL, NULL, NULL), ISO_OK);
    iso_dev_map_opts mo;
    iso_dev_map_opts_default(&mo);
    assert_int_equal(iso_dev_map_init(&p.m, &mo, NULL), ISO_OK);
    int n_rep = 0;
    for (int64_t t; (t = iso_dev_hub_next_tick(p.h, TICK_NS)) != INT64_MAX && n_rep < 256;)
        rig_tick(&p, t, &rep[n_rep++]);
    assert_int_equal(n_rep, n_live);
    for (int k = 0; k < n_live; k++)
        assert_memory_equal(&live[k], &rep[k], sizeof live[k]);
    iso_dev_source_stats st;
    assert_int_equal(iso_dev_hub_source_stats(p.h, 0, &st), ISO_OK);
    assert_memory_equal(&st.dec, &nl, sizeof nl);
    assert_memory_equal(&st.drops, &dl, sizeof dl);
    assert_int_equal(g.nmsg[1], live_msgs);
    for (int i = 0; i < live_msgs && i < 64; i++)
        assert_string_equal(g.msgs[0][i], g.msgs[1][i]);
    iso_dev_hub_destroy(p.h);
    iso_dev_rec_reader_deinit(&rr);

    /* every good frame got through, live and replayed */
    assert_int_equal(nl.reports, 180);
    assert_true(nl.unrecorded > 0);
    /* the cap: 3.2 s of stream time is four windows of ISO_DEV_REC_NOISE_CAP;
     * the rest is the frames' chunks (recorded whole, noise and all: 250 +
     * 17 bytes each, 180 of them, some split in two) and at most a SKIP and
     * a TICK record a tick */
    long bound = 2000 + 4L * ISO_DEV_REC_NOISE_CAP + 2L * 180 * (250 + 17 + 30) +
                 (long)n_live * (17 + 2 * (17 + 150));
    assert_true(size <= bound);
    /* the budget, and the chunk that crosses it */
    assert_true(drained < (long)ISO_DEV_DRAIN_MAX + ISO_DEV_CHUNK_MAX);
    print_message("%zu noise bytes live, recording %ld bytes (bound %ld), %u left out; at most "
                  "%ld bytes drained in one tick; %d ticks replayed bit for bit\n",
                  noise, size, bound, nl.unrecorded, drained, n_rep);
}

int main(void)
{
    const struct CMUnitTest t[] = {cmocka_unit_test(noise_is_counted_byte_for_byte),
                                   cmocka_unit_test(noise_is_said_once_with_a_hint),
                                   cmocka_unit_test(capped_recording_replays_the_same)};
    return cmocka_run_group_tests_name("dev_noise", t, NULL, NULL);
}
