/* tests/test_fb_mcu.c -- the firmware's logic (iso_fb_mcu.c, the same
 * source the Cortex-M build uses) on a simulated clock, and the host link
 * endpoint talking to it through an in-memory transport: HELLO, setpoint
 * echoes, rate limit and clamping, the link watchdog, DIAG, samples,
 * reconnect after a lost link. */
#include <string.h>
#include <time.h>

#include "iso_fb_host.h"
#include "iso_fb_mcu.h"
#include "testutil.h"

/* ---- an in-memory transport wired to an iso_fb_mcu -------------------- */
typedef struct fake_link {
    iso_link base;
    iso_fb_mcu *mcu;
    uint8_t out[1 << 16]; /* MCU -> host bytes not read yet */
    size_t out_len, out_pos;
    int fail_next_read, fail_reopens, reopens, mute_to_mcu;
} fake_link;

static int fake_read(iso_link *l, uint8_t *buf, size_t cap, int timeout_ms, iso_err *err)
{
    fake_link *f = (fake_link *)l;
    (void)timeout_ms;
    if (f->fail_next_read) {
        f->fail_next_read = 0;
        return iso_err_set(err, ISO_EIO, -1, "fake: unplugged");
    }
    size_t n = f->out_len - f->out_pos;
    if (n > cap)
        n = cap;
    memcpy(buf, f->out + f->out_pos, n);
    f->out_pos += n;
    if (f->out_pos == f->out_len)
        f->out_pos = f->out_len = 0;
    return (int)n;
}

static int fake_write(iso_link *l, const uint8_t *buf, size_t n, int timeout_ms, iso_err *err)
{
    fake_link *f = (fake_link *)l;
    (void)timeout_ms;
    (void)err;
    if (!f->mute_to_mcu)
        iso_fb_mcu_rx(f->mcu, buf, n);
    return ISO_OK;
}

static int fake_poll_fd(iso_link *l)
{
    (void)l;
    return -1;
}

static int fake_reopen(iso_link *l, iso_err *err)
{
    fake_link *f = (fake_link *)l;
    if (f->fail_reopens > 0) {
        f->fail_reopens--;
        return iso_err_set(err, ISO_EIO, -1, "fake: still unplugged");
    }
    f->reopens++;
    return ISO_OK;
}

static void fake_close(iso_link *l)
{
    (void)l;
}

static const iso_link_ops fake_ops = {"fake",       fake_read,   fake_write,
                                      fake_poll_fd, fake_reopen, fake_close};

static void mcu_out(void *ctx, const uint8_t *b, size_t n)
{
    fake_link *f = ctx;
    assert_true(f->out_len + n <= sizeof f->out);
    memcpy(f->out + f->out_len, b, n);
    f->out_len += n;
}

/* Decodes everything the MCU wrote so far (and consumes it). */
typedef struct decoded {
    int count[ISO_FB_TYPE_COUNT];
    iso_fb_hello hello;
    iso_fb_ack ack;
    iso_fb_nak nak;
    iso_fb_fault fault;
    iso_fb_sample samples[64];
    int n_samples;
} decoded;

static void drain(fake_link *f, iso_fb_parser *p, decoded *d)
{
    memset(d, 0, sizeof *d);
    for (size_t i = f->out_pos; i < f->out_len; i++) {
        iso_fb_view v;
        if (iso_fb_parser_feed(p, f->out[i], &v) != ISO_FB_FRAME)
            continue;
        d->count[v.type]++;
        switch (v.type) {
        case ISO_FB_HELLO:
            assert_int_equal(iso_fb_hello_unpack(&d->hello, v.payload, v.len), 0);
            break;
        case ISO_FB_ACK: assert_int_equal(iso_fb_ack_unpack(&d->ack, v.payload, v.len), 0); break;
        case ISO_FB_NAK: assert_int_equal(iso_fb_nak_unpack(&d->nak, v.payload, v.len), 0); break;
        case ISO_FB_FAULT:
            assert_int_equal(iso_fb_fault_unpack(&d->fault, v.payload, v.len), 0);
            break;
        case ISO_FB_HANDLE_SAMPLE:
            if (d->n_samples < 64)
                assert_int_equal(
                    iso_fb_sample_unpack(&d->samples[d->n_samples++], v.payload, v.len), 0);
            break;
        default: break;
        }
    }
    f->out_pos = f->out_len = 0;
}

static void send_to(iso_fb_mcu *m, uint8_t type, uint16_t seq, const uint8_t *p, int len)
{
    assert_true(len >= 0);
    uint8_t wire[ISO_FB_FRAME_MAX];
    int n = iso_fb_frame_encode(wire, sizeof wire, type, seq, p, (size_t)len);
    assert_true(n > 0);
    iso_fb_mcu_rx(m, wire, (size_t)n);
}

static void send_hello(iso_fb_mcu *m, uint16_t seq)
{
    iso_fb_hello h;
    memset(&h, 0, sizeof h);
    h.proto_version = ISO_FB_VERSION;
    uint8_t p[ISO_FB_MAX_PAYLOAD];
    send_to(m, ISO_FB_HELLO, seq, p, iso_fb_hello_pack(p, sizeof p, &h));
}

static void send_setpoints(iso_fb_mcu *m, uint16_t seq, uint32_t tick, const int16_t *v, uint8_t n)
{
    iso_fb_setpoints s;
    s.tick = tick;
    s.n = n;
    memcpy(s.value, v, n * sizeof *v);
    uint8_t p[ISO_FB_MAX_PAYLOAD];
    send_to(m, ISO_FB_SETPOINTS, seq, p, iso_fb_setpoints_pack(p, sizeof p, &s));
}

typedef struct rig {
    fake_link link;
    iso_fb_mcu mcu;
    iso_fb_parser p;
    decoded d;
} rig;

static rig *rig_new(uint32_t sample_ms)
{
    static rig r; /* one at a time; large buffers stay off the stack */
    memset(&r, 0, sizeof r);
    r.link.base.ops = &fake_ops;
    r.link.mcu = &r.mcu;
    iso_fb_mcu_config cfg;
    iso_fb_mcu_config_default(&cfg, 3);
    cfg.ch[2].min = 0;
    cfg.ch[2].max = 500;
    cfg.ch[2].safe = 100;
    cfg.sample_ms = sample_ms;
    assert_int_equal(iso_fb_mcu_init(&r.mcu, &cfg, mcu_out, &r.link, 1000), 0);
    iso_fb_parser_init(&r.p);
    return &r;
}

/* ---- the MCU logic ------------------------------------------------------- */
static void mcu_boots_unarmed_and_announces(void **state)
{
    (void)state;
    rig *r = rig_new(0);
    drain(&r->link, &r->p, &r->d);
    assert_int_equal(r->d.count[ISO_FB_HELLO], 1);
    assert_true(r->d.hello.flags & ISO_FB_HELLO_BOOT);
    assert_int_equal(r->d.hello.n_channels, 3);
    assert_int_equal(r->d.hello.ch[2].max, 500);
    assert_int_equal(iso_fb_mcu_position(&r->mcu, 2), 100); /* safe position */
    const int16_t v[3] = {1, 2, 3};
    send_setpoints(&r->mcu, 1, 1, v, 3);
    drain(&r->link, &r->p, &r->d);
    assert_int_equal(r->d.count[ISO_FB_NAK], 1);
    assert_int_equal(r->d.nak.reason, ISO_FB_NAK_NOT_ARMED);
    assert_int_equal(r->mcu.state, ISO_FB_STATE_IDLE);
}

static void mcu_hello_arms_then_setpoints_echo_clamp_and_ramp(void **state)
{
    (void)state;
    rig *r = rig_new(0);
    drain(&r->link, &r->p, &r->d);
    send_hello(&r->mcu, 0);
    drain(&r->link, &r->p, &r->d);
    assert_int_equal(r->d.count[ISO_FB_HELLO], 1);
    assert_false(r->d.hello.flags & ISO_FB_HELLO_BOOT);
    assert_int_equal(r->mcu.state, ISO_FB_STATE_ARMED);

    const int16_t v[3] = {900, -5000, 9999};
    send_setpoints(&r->mcu, 1, 4242, v, 3);
    drain(&r->link, &r->p, &r->d);
    assert_int_equal(r->d.count[ISO_FB_ACK], 1);
    assert_int_equal(r->d.ack.tick, 4242);
    assert_int_equal(r->d.ack.seq, 1);
    assert_memory_equal(r->d.ack.value, v, sizeof v); /* echoed as received */
    assert_int_equal(r->mcu.clamped, 2);
    /* 2000 milli-units/s: 100 ms moves 200 on ch0; ch1 is clamped to -1000 */
    for (uint32_t t = 1001; t <= 1100; t++) {
        if (t % 50 == 0)
            send_setpoints(&r->mcu, (uint16_t)(t / 50), t, v, 3);
        iso_fb_mcu_tick(&r->mcu, t);
    }
    assert_int_equal(iso_fb_mcu_position(&r->mcu, 0), 200);
    assert_int_equal(iso_fb_mcu_position(&r->mcu, 1), -200);
    assert_int_equal(iso_fb_mcu_position(&r->mcu, 2), 300); /* 100 + 200, clamp 500 not reached */
    /* wrong channel count */
    send_setpoints(&r->mcu, 100, 1, v, 2);
    drain(&r->link, &r->p, &r->d);
    assert_int_equal(r->d.nak.reason, ISO_FB_NAK_CHANNELS);
    /* a frame of an MCU-to-host type is refused */
    uint8_t p[4] = {0};
    send_to(&r->mcu, ISO_FB_HEARTBEAT, 101, p, 0);
    drain(&r->link, &r->p, &r->d);
    assert_int_equal(r->d.nak.reason, ISO_FB_NAK_REFUSED);
}

static void mcu_watchdog_safe_state_within_timeout_plus_one_tick(void **state)
{
    (void)state;
    rig *r = rig_new(0);
    send_hello(&r->mcu, 0);
    const int16_t v[3] = {500, 500, 400};
    send_setpoints(&r->mcu, 1, 1, v, 3);
    drain(&r->link, &r->p, &r->d);
    uint32_t t = 1000;
    while (r->mcu.state == ISO_FB_STATE_ARMED && t < 2000)
        iso_fb_mcu_tick(&r->mcu, ++t);
    drain(&r->link, &r->p, &r->d);
    assert_int_equal(t, 1000 + 100 + 1); /* default watchdog 100 ms, one tick later */
    assert_int_equal(r->mcu.state, ISO_FB_STATE_SAFE);
    assert_int_equal(r->d.count[ISO_FB_FAULT], 1);
    assert_int_equal(r->d.fault.reason, ISO_FB_FAULT_WATCHDOG);
    assert_int_equal(r->d.fault.detail, 101);
    assert_int_equal(iso_fb_mcu_position(&r->mcu, 0), 0);
    assert_int_equal(iso_fb_mcu_position(&r->mcu, 2), 100);
    /* no motion until a fresh HELLO */
    send_setpoints(&r->mcu, 2, 2, v, 3);
    drain(&r->link, &r->p, &r->d);
    assert_int_equal(r->d.nak.reason, ISO_FB_NAK_NOT_ARMED);
    iso_fb_mcu_tick(&r->mcu, t + 50);
    assert_int_equal(iso_fb_mcu_position(&r->mcu, 0), 0);
    send_hello(&r->mcu, 3);
    send_setpoints(&r->mcu, 4, 3, v, 3);
    iso_fb_mcu_tick(&r->mcu, t + 60);
    assert_int_equal(r->mcu.state, ISO_FB_STATE_ARMED);
    assert_int_equal(iso_fb_mcu_position(&r->mcu, 0), 20);
}

static void mcu_diag_hang_only_when_unarmed(void **state)
{
    (void)state;
    rig *r = rig_new(0);
    uint8_t p[8];
    iso_fb_diag d = {ISO_FB_DIAG_HANG_MAGIC}, bad = {1};
    send_hello(&r->mcu, 0);
    drain(&r->link, &r->p, &r->d);
    send_to(&r->mcu, ISO_FB_DIAG, 1, p, iso_fb_diag_pack(p, sizeof p, &d));
    drain(&r->link, &r->p, &r->d);
    assert_int_equal(r->d.nak.reason, ISO_FB_NAK_REFUSED);
    assert_false(r->mcu.hang_requested);
    iso_fb_mcu_tick(&r->mcu, 1200); /* watchdog -> SAFE */
    send_to(&r->mcu, ISO_FB_DIAG, 2, p, iso_fb_diag_pack(p, sizeof p, &bad));
    drain(&r->link, &r->p, &r->d);
    assert_int_equal(r->d.nak.reason, ISO_FB_NAK_BAD_PAYLOAD);
    send_to(&r->mcu, ISO_FB_DIAG, 3, p, iso_fb_diag_pack(p, sizeof p, &d));
    drain(&r->link, &r->p, &r->d);
    assert_int_equal(r->d.count[ISO_FB_ACK], 1);
    assert_int_equal(r->d.ack.type, ISO_FB_DIAG);
    assert_true(r->mcu.hang_requested);
}

/* SAFE (firmware 1.1): the brake of the watchdog, at once and in any state,
 * answered by FAULT(requested) carrying the cause; only HELLO re-arms. */
static void mcu_safe_brakes_at_once_in_any_state(void **state)
{
    (void)state;
    rig *r = rig_new(0);
    drain(&r->link, &r->p, &r->d);
    assert_true(r->d.hello.flags & ISO_FB_HELLO_CAN_SAFE); /* the boot HELLO offers it */
    uint8_t p[8];
    iso_fb_safe q = {ISO_FB_SAFE_ESTOP};
    /* idle: already at the safe positions; stays idle, still answers */
    send_to(&r->mcu, ISO_FB_SAFE, 1, p, iso_fb_safe_pack(p, sizeof p, &q));
    drain(&r->link, &r->p, &r->d);
    assert_int_equal(r->mcu.state, ISO_FB_STATE_IDLE);
    assert_int_equal(r->d.count[ISO_FB_FAULT], 1);
    assert_int_equal(r->d.fault.reason, ISO_FB_FAULT_REQUESTED);
    /* armed and moving: SAFE brakes before any MCU tick */
    send_hello(&r->mcu, 2);
    drain(&r->link, &r->p, &r->d);
    assert_true(r->d.hello.flags & ISO_FB_HELLO_CAN_SAFE);
    const int16_t v[3] = {500, -500, 400};
    send_setpoints(&r->mcu, 3, 1, v, 3);
    for (uint32_t t = 1001; t <= 1050; t++)
        iso_fb_mcu_tick(&r->mcu, t);
    assert_int_equal(iso_fb_mcu_position(&r->mcu, 0), 100); /* 50 ms at 2000/s */
    q.cause = ISO_FB_SAFE_LOOP_STALL;
    send_to(&r->mcu, ISO_FB_SAFE, 4, p, iso_fb_safe_pack(p, sizeof p, &q));
    drain(&r->link, &r->p, &r->d);
    assert_int_equal(r->mcu.state, ISO_FB_STATE_SAFE);
    assert_int_equal(iso_fb_mcu_position(&r->mcu, 0), 0);
    assert_int_equal(iso_fb_mcu_position(&r->mcu, 2), 100);
    assert_int_equal(r->d.count[ISO_FB_FAULT], 1);
    assert_int_equal(r->d.fault.reason, ISO_FB_FAULT_REQUESTED);
    assert_int_equal(r->d.fault.detail, ISO_FB_SAFE_LOOP_STALL);
    assert_int_equal(r->d.fault.uptime_ms, 1050);
    /* no motion until a fresh HELLO; the watchdog does not fault again */
    send_setpoints(&r->mcu, 5, 2, v, 3);
    for (uint32_t t = 1051; t <= 1300; t++)
        iso_fb_mcu_tick(&r->mcu, t);
    drain(&r->link, &r->p, &r->d);
    assert_int_equal(r->d.nak.reason, ISO_FB_NAK_NOT_ARMED);
    assert_int_equal(r->d.count[ISO_FB_FAULT], 0);
    assert_int_equal(iso_fb_mcu_position(&r->mcu, 0), 0);
    /* a broken SAFE is refused, and changes nothing */
    send_hello(&r->mcu, 6);
    uint8_t two[2] = {1, 2};
    send_to(&r->mcu, ISO_FB_SAFE, 7, two, 2);
    drain(&r->link, &r->p, &r->d);
    assert_int_equal(r->d.nak.reason, ISO_FB_NAK_BAD_PAYLOAD);
    assert_int_equal(r->mcu.state, ISO_FB_STATE_ARMED);
}

static void mcu_samples_while_armed(void **state)
{
    (void)state;
    rig *r = rig_new(20);
    for (uint32_t t = 1001; t <= 1100; t++)
        iso_fb_mcu_tick(&r->mcu, t);
    drain(&r->link, &r->p, &r->d);
    assert_int_equal(r->d.n_samples, 0); /* unarmed: none */
    assert_int_equal(r->d.count[ISO_FB_HEARTBEAT], 1);
    send_hello(&r->mcu, 0);
    const int16_t v[3] = {0, 0, 100};
    for (uint32_t t = 1101; t <= 1200; t++) {
        if (t % 20 == 0)
            send_setpoints(&r->mcu, (uint16_t)t, t, v, 3);
        iso_fb_mcu_tick(&r->mcu, t);
    }
    drain(&r->link, &r->p, &r->d);
    assert_int_equal(r->d.n_samples, 5);
    for (int i = 0; i < r->d.n_samples; i++) {
        iso_fb_sample want;
        iso_fb_mcu_synth_sample(r->d.samples[i].t_us, &want);
        assert_memory_equal(&r->d.samples[i].v, &want.v, sizeof want.v);
        assert_int_equal(r->d.samples[i].buttons, want.buttons);
    }
}

static void mcu_rejects_bad_config(void **state)
{
    (void)state;
    iso_fb_mcu m;
    iso_fb_mcu_config cfg;
    iso_fb_mcu_config_default(&cfg, 0);
    assert_int_equal(iso_fb_mcu_init(&m, &cfg, mcu_out, NULL, 0), ISO_FB_EARG);
    iso_fb_mcu_config_default(&cfg, ISO_FB_MAX_CHANNELS + 1);
    assert_int_equal(iso_fb_mcu_init(&m, &cfg, mcu_out, NULL, 0), ISO_FB_EARG);
    iso_fb_mcu_config_default(&cfg, 2);
    cfg.ch[1].safe = 2000; /* outside its limits */
    assert_int_equal(iso_fb_mcu_init(&m, &cfg, mcu_out, NULL, 0), ISO_FB_EARG);
}

/* ---- the host endpoint against the MCU logic -------------------------- */
typedef struct seen {
    int samples, bad_samples, acks, bad_echo, faults, hellos;
    uint32_t last_fault_detail;
} seen;

static void on_sample(void *ctx, const iso_fb_sample *s)
{
    seen *z = ctx;
    iso_fb_sample want;
    iso_fb_mcu_synth_sample(s->t_us, &want);
    z->samples++;
    z->bad_samples += memcmp(want.v, s->v, sizeof want.v) != 0 || want.buttons != s->buttons;
}

static void on_ack(void *ctx, const iso_fb_ack *a)
{
    seen *z = ctx;
    z->acks++;
    /* the test streams value[i] = tick * (i + 1) % 1000 */
    for (unsigned i = 0; i < a->n; i++)
        z->bad_echo += a->value[i] != (int16_t)((a->tick * (i + 1)) % 1000u);
}

static void on_fault(void *ctx, const iso_fb_fault *f)
{
    seen *z = ctx;
    z->faults++;
    z->last_fault_detail = f->detail;
}

static void on_hello(void *ctx, const iso_fb_hello *h)
{
    (void)h;
    ((seen *)ctx)->hellos++;
}

static uint32_t host_run(rig *r, iso_fb_host *h, uint32_t *t, uint32_t *tick, int steps, int send)
{
    uint32_t sent = 0;
    for (int i = 0; i < steps; i++) {
        int16_t v[3];
        for (unsigned c = 0; c < 3; c++)
            v[c] = (int16_t)((*tick * (c + 1)) % 1000u);
        if (send)
            sent += (uint32_t)iso_fb_host_step(h, *tick, v, 3) == 1;
        else
            iso_fb_host_poll(h, 0);
        (*tick)++;
        for (int k = 0; k < 10; k++) /* 100 Hz host, 1 kHz MCU */
            iso_fb_mcu_tick(&r->mcu, ++*t);
    }
    iso_fb_host_poll(h, 0);
    return sent;
}

static void host_streams_recovers_from_watchdog_and_link_loss(void **state)
{
    (void)state;
    rig *r = rig_new(20);
    seen z;
    memset(&z, 0, sizeof z);
    iso_fb_host_callbacks cb = {on_sample, on_ack, on_fault, on_hello, NULL, &z};
    iso_fb_host_opts opts = {0};
    opts.reopen_ms = 1;
    iso_fb_host h;
    iso_err err;
    iso_err_clear(&err);
    assert_int_equal(iso_fb_host_init(&h, &r->link.base, &opts, &cb, &err), ISO_OK);
    uint32_t t = 1000, tick = 0;
    host_run(r, &h, &t, &tick, 2, 1);
    assert_int_equal(h.state, ISO_FB_HOST_STREAMING);
    assert_int_equal(h.device.n_channels, 3);
    uint32_t sent = host_run(r, &h, &t, &tick, 300, 1);
    assert_true(sent >= 299);
    assert_int_equal(z.acks, (int)h.stats.acks);
    assert_true(z.acks >= 299);
    assert_int_equal(z.bad_echo, 0);
    assert_true(z.samples >= 140);
    assert_int_equal(z.bad_samples, 0);
    assert_true(h.stats.rtt_count >= 299);
    assert_int_equal(h.stats.rx.resyncs, 0);

    /* the host goes quiet: the MCU faults, the host re-handshakes and resumes */
    host_run(r, &h, &t, &tick, 20, 0);
    assert_int_equal(z.faults, 1);
    assert_true(z.last_fault_detail <= 101);
    assert_int_equal(r->mcu.state, ISO_FB_STATE_SAFE);
    assert_int_equal(h.state, ISO_FB_HOST_HANDSHAKE);
    host_run(r, &h, &t, &tick, 3, 1);
    assert_int_equal(h.state, ISO_FB_HOST_STREAMING);
    assert_int_equal(r->mcu.state, ISO_FB_STATE_ARMED);

    /* the transport drops: DOWN, a failed reopen, then back by itself */
    r->link.fail_next_read = 1;
    r->link.fail_reopens = 1;
    host_run(r, &h, &t, &tick, 1, 1);
    assert_int_equal(h.state, ISO_FB_HOST_DOWN);
    assert_string_equal(h.last_err.msg, "fake: unplugged");
    for (int i = 0; i < 200 && h.state != ISO_FB_HOST_STREAMING; i++) {
        struct timespec ts = {0, 2000000};
        nanosleep(&ts, NULL);
        host_run(r, &h, &t, &tick, 1, 1);
    }
    assert_int_equal(h.state, ISO_FB_HOST_STREAMING);
    assert_int_equal(r->link.reopens, 1);
    assert_int_equal(h.stats.link_losses, 1);
    assert_int_equal(z.bad_echo, 0);

    char line[512];
    assert_true(iso_fb_host_format_stats(&h, line, sizeof line) > 0);
    assert_non_null(strstr(line, "rtt avg"));
    assert_non_null(strstr(line, "link losses 1"));
    iso_fb_host_deinit(&h);
}

static void host_rehellos_when_mcu_reboots(void **state)
{
    (void)state;
    rig *r = rig_new(0);
    iso_fb_host h;
    assert_int_equal(iso_fb_host_init(&h, &r->link.base, NULL, NULL, NULL), ISO_OK);
    uint32_t t = 1000, tick = 0;
    host_run(r, &h, &t, &tick, 3, 1);
    assert_int_equal(h.state, ISO_FB_HOST_STREAMING);
    /* a reboot: fresh node, unarmed, sequence restarting at 0 */
    iso_fb_mcu_config cfg = r->mcu.cfg;
    assert_int_equal(iso_fb_mcu_init(&r->mcu, &cfg, mcu_out, &r->link, t), 0);
    host_run(r, &h, &t, &tick, 3, 1);
    assert_int_equal(h.state, ISO_FB_HOST_STREAMING);
    assert_int_equal(r->mcu.state, ISO_FB_STATE_ARMED);
    assert_int_equal(h.stats.handshakes, 2);
    assert_int_equal(h.stats.rx.out_of_order, 0);
}

/* The host sends SAFE only to an MCU whose HELLO offered it; the answer
 * drops it to HANDSHAKE like any FAULT. */
static void host_sends_safe_only_when_offered(void **state)
{
    (void)state;
    rig *r = rig_new(0);
    seen z;
    memset(&z, 0, sizeof z);
    iso_fb_host_callbacks cb = {NULL, NULL, on_fault, NULL, NULL, &z};
    iso_fb_host h;
    iso_err err;
    iso_err_clear(&err);
    assert_int_equal(iso_fb_host_init(&h, &r->link.base, NULL, &cb, &err), ISO_OK);
    uint32_t t = 1000, tick = 0;
    host_run(r, &h, &t, &tick, 3, 1);
    assert_int_equal(h.state, ISO_FB_HOST_STREAMING);
    assert_true(iso_fb_host_can_safe(&h));
    assert_int_equal(iso_fb_host_send_safe(&h, ISO_FB_SAFE_ESTOP, &err), ISO_OK);
    assert_int_equal(r->mcu.state, ISO_FB_STATE_SAFE); /* the fake link delivers at once */
    iso_fb_host_poll(&h, 0);
    assert_int_equal(z.faults, 1);
    assert_int_equal(z.last_fault_detail, ISO_FB_SAFE_ESTOP);
    assert_int_equal(h.state, ISO_FB_HOST_HANDSHAKE);
    /* an MCU with firmware 1.0 offers no SAFE: nothing is sent */
    host_run(r, &h, &t, &tick, 3, 1);
    assert_int_equal(h.state, ISO_FB_HOST_STREAMING);
    h.device.flags &= (uint8_t)~ISO_FB_HELLO_CAN_SAFE;
    h.device.fw_version = 0x0100;
    uint64_t tx = h.stats.tx_frames;
    iso_err_clear(&err);
    assert_int_equal(iso_fb_host_send_safe(&h, ISO_FB_SAFE_ESTOP, &err), ISO_ENOTSUP);
    assert_non_null(strstr(err.msg, "firmware 1.0"));
    assert_int_equal(h.stats.tx_frames, tx);
    assert_int_equal(r->mcu.state, ISO_FB_STATE_ARMED);
    iso_fb_host_deinit(&h);
}

int main(void)
{
    const struct CMUnitTest t[] = {
        cmocka_unit_test(mcu_boots_unarmed_and_announces),
        cmocka_unit_test(mcu_hello_arms_then_setpoints_echo_clamp_and_ramp),
        cmocka_unit_test(mcu_watchdog_safe_state_within_timeout_plus_one_tick),
        cmocka_unit_test(mcu_diag_hang_only_when_unarmed),
        cmocka_unit_test(mcu_safe_brakes_at_once_in_any_state),
        cmocka_unit_test(mcu_samples_while_armed),
        cmocka_unit_test(mcu_rejects_bad_config),
        cmocka_unit_test(host_streams_recovers_from_watchdog_and_link_loss),
        cmocka_unit_test(host_rehellos_when_mcu_reboots),
        cmocka_unit_test(host_sends_safe_only_when_offered),
    };
    return cmocka_run_group_tests_name("fb_mcu", t, NULL, NULL);
}
