/* firmware-bridge/iso_fb_mcu.c -- see iso_fb_mcu.h. */
#include "iso_fb_mcu.h"

void iso_fb_mcu_config_default(iso_fb_mcu_config *cfg, uint8_t n_channels)
{
    uint8_t *b = (uint8_t *)cfg;
    for (size_t i = 0; i < sizeof *cfg; i++)
        b[i] = 0;
    cfg->n_channels = n_channels;
    for (unsigned i = 0; i < ISO_FB_MAX_CHANNELS; i++) {
        cfg->ch[i].min = -1000;
        cfg->ch[i].max = 1000;
        cfg->ch[i].max_rate = 2000;
        cfg->ch[i].safe = 0;
    }
    cfg->watchdog_ms = 100;
    cfg->heartbeat_ms = 100;
    cfg->sample_ms = 20;
}

void iso_fb_mcu_config_board(iso_fb_mcu_config *cfg)
{
    iso_fb_mcu_config_default(cfg, 4);
    cfg->ch[1].min = -1500;
    cfg->ch[1].max = 1500;
    cfg->ch[2].max_rate = 500;
    cfg->ch[3].min = 0;
    cfg->ch[3].max = 2000;
    cfg->ch[3].safe = 0;
}

static void send(iso_fb_mcu *m, uint8_t type, const uint8_t *payload, int len)
{
    uint8_t wire[ISO_FB_FRAME_MAX];
    if (len < 0)
        return; /* cannot happen with the fixed layouts; never send a broken frame */
    int n = iso_fb_frame_encode(wire, sizeof wire, type, m->tx_seq, payload, (size_t)len);
    if (n < 0)
        return;
    m->tx_seq++;
    m->write(m->write_ctx, wire, (size_t)n);
}

static void send_hello(iso_fb_mcu *m, uint8_t flags)
{
    iso_fb_hello h;
    h.proto_version = ISO_FB_VERSION;
    h.fw_version = ISO_FB_MCU_FW_VERSION;
    h.flags = flags | ISO_FB_HELLO_CAN_SAFE;
    h.uptime_ms = m->now_ms;
    h.n_channels = m->cfg.n_channels;
    for (unsigned i = 0; i < m->cfg.n_channels; i++)
        h.ch[i] = m->cfg.ch[i];
    uint8_t p[ISO_FB_MAX_PAYLOAD];
    send(m, ISO_FB_HELLO, p, iso_fb_hello_pack(p, sizeof p, &h));
}

static void send_nak(iso_fb_mcu *m, const iso_fb_view *v, uint8_t reason)
{
    iso_fb_nak k = {v->type, v->seq, reason};
    uint8_t p[ISO_FB_MAX_PAYLOAD];
    m->naks++;
    send(m, ISO_FB_NAK, p, iso_fb_nak_pack(p, sizeof p, &k));
}

static void send_fault(iso_fb_mcu *m, uint8_t reason, uint32_t detail)
{
    iso_fb_fault f = {reason, detail, m->now_ms};
    uint8_t p[ISO_FB_MAX_PAYLOAD];
    m->faults++;
    send(m, ISO_FB_FAULT, p, iso_fb_fault_pack(p, sizeof p, &f));
}

/* The safe state brakes: every channel is at its safe position at once, not
 * rate-limited, because the host that would ramp it is gone. */
static void go_safe(iso_fb_mcu *m, uint8_t state)
{
    m->state = state;
    for (unsigned i = 0; i < m->cfg.n_channels; i++)
        m->pos_u[i] = m->target_u[i] = (int32_t)m->cfg.ch[i].safe * 1000;
}

int iso_fb_mcu_init(iso_fb_mcu *m, const iso_fb_mcu_config *cfg, iso_fb_mcu_write_fn write,
                    void *write_ctx, uint32_t now_ms)
{
    if (!m || !cfg || !write || cfg->n_channels == 0 || cfg->n_channels > ISO_FB_MAX_CHANNELS ||
        cfg->watchdog_ms == 0)
        return ISO_FB_EARG;
    for (unsigned i = 0; i < cfg->n_channels; i++)
        if (cfg->ch[i].min > cfg->ch[i].max || cfg->ch[i].safe < cfg->ch[i].min ||
            cfg->ch[i].safe > cfg->ch[i].max)
            return ISO_FB_EARG;
    uint8_t *b = (uint8_t *)m;
    for (size_t i = 0; i < sizeof *m; i++)
        b[i] = 0;
    m->cfg = *cfg;
    iso_fb_parser_init(&m->parser);
    m->write = write;
    m->write_ctx = write_ctx;
    m->now_ms = m->last_heartbeat_ms = m->last_sample_ms = m->last_setpoints_ms = now_ms;
    go_safe(m, ISO_FB_STATE_IDLE);
    send_hello(m, ISO_FB_HELLO_BOOT);
    return 0;
}

static int32_t clamp_i32(int32_t v, int32_t lo, int32_t hi)
{
    return v < lo ? lo : v > hi ? hi : v;
}

static void on_setpoints(iso_fb_mcu *m, const iso_fb_view *v)
{
    iso_fb_setpoints s;
    if (iso_fb_setpoints_unpack(&s, v->payload, v->len) != 0) {
        send_nak(m, v, ISO_FB_NAK_BAD_PAYLOAD);
        return;
    }
    if (m->state != ISO_FB_STATE_ARMED) {
        send_nak(m, v, ISO_FB_NAK_NOT_ARMED);
        return;
    }
    if (s.n != m->cfg.n_channels) {
        send_nak(m, v, ISO_FB_NAK_CHANNELS);
        return;
    }
    for (unsigned i = 0; i < s.n; i++) {
        int32_t t = clamp_i32(s.value[i], m->cfg.ch[i].min, m->cfg.ch[i].max);
        m->clamped += t != s.value[i];
        m->target_u[i] = t * 1000;
    }
    m->last_setpoints_ms = m->now_ms;
    m->setpoints_applied++;
    iso_fb_ack a;
    a.type = v->type;
    a.seq = v->seq;
    a.tick = s.tick;
    a.n = s.n;
    for (unsigned i = 0; i < s.n; i++)
        a.value[i] = s.value[i];
    uint8_t p[ISO_FB_MAX_PAYLOAD];
    send(m, ISO_FB_ACK, p, iso_fb_ack_pack(p, sizeof p, &a));
}

static void on_hello(iso_fb_mcu *m, const iso_fb_view *v)
{
    iso_fb_hello h;
    if (iso_fb_hello_unpack(&h, v->payload, v->len) != 0 || h.proto_version != ISO_FB_VERSION) {
        send_nak(m, v, ISO_FB_NAK_BAD_PAYLOAD);
        return;
    }
    /* Arm holding the current positions, and give the host one watchdog
     * period from now to send its first SETPOINTS. */
    m->state = ISO_FB_STATE_ARMED;
    for (unsigned i = 0; i < m->cfg.n_channels; i++)
        m->target_u[i] = m->pos_u[i];
    m->last_setpoints_ms = m->now_ms;
    send_hello(m, 0);
}

static void on_diag(iso_fb_mcu *m, const iso_fb_view *v)
{
    iso_fb_diag d;
    if (iso_fb_diag_unpack(&d, v->payload, v->len) != 0 || d.magic != ISO_FB_DIAG_HANG_MAGIC) {
        send_nak(m, v, ISO_FB_NAK_BAD_PAYLOAD);
        return;
    }
    /* Never hang with actuators live: only from IDLE or SAFE. */
    if (m->state == ISO_FB_STATE_ARMED) {
        send_nak(m, v, ISO_FB_NAK_REFUSED);
        return;
    }
    iso_fb_ack a = {v->type, v->seq, 0, 0, {0}};
    uint8_t p[ISO_FB_MAX_PAYLOAD];
    send(m, ISO_FB_ACK, p, iso_fb_ack_pack(p, sizeof p, &a));
    m->hang_requested = 1;
}

/* SAFE brakes at once in any state, the same brake as the link watchdog's,
 * and says so with FAULT(REQUESTED) so the host knows when it took effect.
 * An idle MCU is at its safe positions already and stays idle. Motion
 * resumes only after a fresh HELLO exchange. */
static void on_safe(iso_fb_mcu *m, const iso_fb_view *v)
{
    iso_fb_safe q;
    if (iso_fb_safe_unpack(&q, v->payload, v->len) != 0) {
        send_nak(m, v, ISO_FB_NAK_BAD_PAYLOAD);
        return;
    }
    go_safe(m, m->state == ISO_FB_STATE_IDLE ? ISO_FB_STATE_IDLE : ISO_FB_STATE_SAFE);
    send_fault(m, ISO_FB_FAULT_REQUESTED, q.cause);
}

void iso_fb_mcu_rx(iso_fb_mcu *m, const uint8_t *bytes, size_t n)
{
    for (size_t i = 0; i < n; i++) {
        iso_fb_view v;
        if (iso_fb_parser_feed(&m->parser, bytes[i], &v) != ISO_FB_FRAME)
            continue;
        switch (v.type) {
        case ISO_FB_HELLO: on_hello(m, &v); break;
        case ISO_FB_SETPOINTS: on_setpoints(m, &v); break;
        case ISO_FB_DIAG: on_diag(m, &v); break;
        case ISO_FB_SAFE: on_safe(m, &v); break;
        default: send_nak(m, &v, ISO_FB_NAK_REFUSED); break; /* MCU-to-host types */
        }
    }
}

static void move_actuators(iso_fb_mcu *m, uint32_t elapsed_ms)
{
    for (unsigned i = 0; i < m->cfg.n_channels; i++) {
        /* max_rate milli-units/s is exactly max_rate micro-units/ms. */
        int64_t step = (int64_t)m->cfg.ch[i].max_rate * elapsed_ms;
        int64_t d = (int64_t)m->target_u[i] - m->pos_u[i];
        if (d > step)
            d = step;
        if (d < -step)
            d = -step;
        m->pos_u[i] += (int32_t)d;
    }
}

void iso_fb_mcu_tick(iso_fb_mcu *m, uint32_t now_ms)
{
    uint32_t elapsed = now_ms - m->now_ms;
    m->now_ms = now_ms;
    if (m->state == ISO_FB_STATE_ARMED) {
        uint32_t quiet = now_ms - m->last_setpoints_ms;
        if (quiet > m->cfg.watchdog_ms) {
            go_safe(m, ISO_FB_STATE_SAFE);
            send_fault(m, ISO_FB_FAULT_WATCHDOG, quiet);
        } else {
            move_actuators(m, elapsed);
        }
    }
    if (m->cfg.heartbeat_ms && now_ms - m->last_heartbeat_ms >= m->cfg.heartbeat_ms) {
        m->last_heartbeat_ms = now_ms;
        iso_fb_heartbeat h;
        h.uptime_ms = now_ms;
        h.state = m->state;
        h.n = m->cfg.n_channels;
        for (unsigned i = 0; i < h.n; i++)
            h.pos[i] = iso_fb_mcu_position(m, i);
        uint8_t p[ISO_FB_MAX_PAYLOAD];
        send(m, ISO_FB_HEARTBEAT, p, iso_fb_heartbeat_pack(p, sizeof p, &h));
    }
    if (m->cfg.sample_ms && m->state == ISO_FB_STATE_ARMED &&
        now_ms - m->last_sample_ms >= m->cfg.sample_ms) {
        m->last_sample_ms = now_ms;
        iso_fb_sample s;
        iso_fb_mcu_synth_sample(now_ms * 1000u, &s);
        uint8_t p[ISO_FB_MAX_PAYLOAD];
        send(m, ISO_FB_HANDLE_SAMPLE, p, iso_fb_sample_pack(p, sizeof p, &s));
    }
}

int16_t iso_fb_mcu_position(const iso_fb_mcu *m, unsigned ch)
{
    if (ch >= m->cfg.n_channels)
        return 0;
    return (int16_t)(m->pos_u[ch] / 1000);
}

void iso_fb_mcu_synth_sample(uint32_t t_us, iso_fb_sample *out)
{
    /* A slow sawtooth per axis: cheap on a Cortex-M0/M3 (no FPU, no libm)
     * and exactly reproducible on the host. */
    uint32_t ms = t_us / 1000u;
    out->t_us = t_us;
    out->kind = ISO_FB_SAMPLE_POSE;
    out->buttons = (uint16_t)((ms / 500u) & 0x3u);
    for (int i = 0; i < 6; i++)
        out->v[i] = (int32_t)((ms * (uint32_t)(i + 1)) % 20000u) - 10000;
}
