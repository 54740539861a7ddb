/* firmware-bridge/fb_host.c -- see iso_fb_host.h. */
#include <inttypes.h>
#include <stdio.h>
#include <string.h>

#include "internal.h"
#include "iso_fb_host.h"
#include "iso_fb_host_drill.h"

static int send_frame(iso_fb_host *h, uint8_t type, const uint8_t *payload, int len, iso_err *err)
{
    if (len < 0)
        return iso_err_set(err, ISO_EINVAL, -1, "fb host: cannot pack message type %u: %s",
                           (unsigned)type, iso_fb_strerror(len));
    uint8_t wire[ISO_FB_FRAME_MAX];
    int n = iso_fb_frame_encode(wire, sizeof wire, type, h->tx_seq, payload, (size_t)len);
    if (n < 0)
        return iso_err_set(err, ISO_EINVAL, -1, "fb host: cannot frame type %u: %s", (unsigned)type,
                           iso_fb_strerror(n));
    int rc = iso_link_write(h->link, wire, (size_t)n, h->opts.write_timeout_ms, err);
    if (rc != ISO_OK)
        return rc;
    h->tx_seq++;
    h->stats.tx_frames++;
    h->stats.tx_bytes += (uint64_t)n;
    return ISO_OK;
}

static void link_down(iso_fb_host *h)
{
    if (h->state != ISO_FB_HOST_DOWN)
        h->stats.link_losses++;
    h->state = ISO_FB_HOST_DOWN;
    h->last_reopen_us = iso_clock_us();
}

static void send_hello(iso_fb_host *h)
{
    iso_fb_hello req;
    memset(&req, 0, sizeof req);
    req.proto_version = ISO_FB_VERSION;
    uint8_t p[ISO_FB_MAX_PAYLOAD];
    iso_err_clear(&h->last_err);
    if (send_frame(h, ISO_FB_HELLO, p, iso_fb_hello_pack(p, sizeof p, &req), &h->last_err) !=
        ISO_OK) {
        link_down(h);
        return;
    }
    h->state = ISO_FB_HOST_HANDSHAKE;
    h->last_hello_us = iso_clock_us();
}

int iso_fb_host_init(iso_fb_host *h, iso_link *link, const iso_fb_host_opts *opts,
                     const iso_fb_host_callbacks *cb, iso_err *err)
{
    if (!h || !link)
        return iso_err_set(err, ISO_EINVAL, -1, "fb host: NULL host or link");
    memset(h, 0, sizeof *h);
    h->link = link;
    h->opts.hello_retry_ms = 200;
    h->opts.link_timeout_ms = 1000;
    h->opts.reopen_ms = 250;
    h->opts.write_timeout_ms = 100;
    if (opts) {
        if (opts->hello_retry_ms > 0)
            h->opts.hello_retry_ms = opts->hello_retry_ms;
        if (opts->link_timeout_ms > 0)
            h->opts.link_timeout_ms = opts->link_timeout_ms;
        if (opts->reopen_ms > 0)
            h->opts.reopen_ms = opts->reopen_ms;
        if (opts->write_timeout_ms > 0)
            h->opts.write_timeout_ms = opts->write_timeout_ms;
    }
    if (cb)
        h->cb = *cb;
    iso_fb_parser_init(&h->parser);
    iso_err_clear(&h->last_err);
    h->stats.rtt_min_us = UINT32_MAX;
    h->last_rx_us = iso_clock_us();
    send_hello(h);
    if (h->state == ISO_FB_HOST_DOWN)
        return iso_err_set(err, ISO_EIO, -1, "fb host: first HELLO failed: %s", h->last_err.msg);
    return ISO_OK;
}

void iso_fb_host_deinit(iso_fb_host *h)
{
    if (h)
        h->link = NULL;
}

void iso_fb_host_rehello(iso_fb_host *h)
{
    if (h->state == ISO_FB_HOST_STREAMING)
        h->state = ISO_FB_HOST_HANDSHAKE;
    h->last_hello_us = 0; /* send at the next step */
}

static void note_rtt(iso_fb_host *h, uint16_t seq)
{
    unsigned slot = seq % ISO_FB_HOST_RTT_SLOTS;
    if (h->sent_seq[slot] != seq || h->sent_us[slot] == 0)
        return;
    uint64_t d = iso_clock_us() - h->sent_us[slot];
    h->sent_us[slot] = 0;
    uint32_t us = d > UINT32_MAX ? UINT32_MAX : (uint32_t)d;
    h->stats.rtt_last_us = us;
    h->stats.rtt_sum_us += us;
    h->stats.rtt_count++;
    if (us < h->stats.rtt_min_us)
        h->stats.rtt_min_us = us;
    if (us > h->stats.rtt_max_us)
        h->stats.rtt_max_us = us;
}

static void handle_frame(iso_fb_host *h, const iso_fb_view *v)
{
    h->stats.rx_frames++;
    int bad = 0;
    switch (v->type) {
    case ISO_FB_HELLO: {
        iso_fb_hello m;
        if ((bad = iso_fb_hello_unpack(&m, v->payload, v->len) != 0 ||
                   m.proto_version != ISO_FB_VERSION))
            break;
        h->stats.hellos++;
        if (m.flags & ISO_FB_HELLO_BOOT) {
            /* The MCU (re)booted: whatever we had is gone; ask again now. */
            if (h->state == ISO_FB_HOST_STREAMING)
                h->state = ISO_FB_HOST_HANDSHAKE;
            h->last_hello_us = 0;
        } else if (h->state == ISO_FB_HOST_HANDSHAKE) {
            h->device = m;
            h->state = ISO_FB_HOST_STREAMING;
            h->stats.handshakes++;
        }
        if (h->cb.on_hello)
            h->cb.on_hello(h->cb.ctx, &m);
        break;
    }
    case ISO_FB_HANDLE_SAMPLE: {
        iso_fb_sample m;
        if ((bad = iso_fb_sample_unpack(&m, v->payload, v->len) != 0))
            break;
        h->stats.samples++;
        if (h->cb.on_sample)
            h->cb.on_sample(h->cb.ctx, &m);
        break;
    }
    case ISO_FB_HEARTBEAT: {
        iso_fb_heartbeat m;
        if ((bad = iso_fb_heartbeat_unpack(&m, v->payload, v->len) != 0))
            break;
        h->stats.heartbeats++;
        if (h->cb.on_heartbeat)
            h->cb.on_heartbeat(h->cb.ctx, &m);
        /* A heartbeat that says "not armed" while we stream means our HELLO
         * answer or a FAULT was lost on the wire: shake hands again. */
        if (h->state == ISO_FB_HOST_STREAMING && m.state != ISO_FB_STATE_ARMED)
            iso_fb_host_rehello(h);
        break;
    }
    case ISO_FB_ACK: {
        iso_fb_ack m;
        if ((bad = iso_fb_ack_unpack(&m, v->payload, v->len) != 0))
            break;
        h->stats.acks++;
        if (m.type == ISO_FB_SETPOINTS)
            note_rtt(h, m.seq);
        if (h->cb.on_ack)
            h->cb.on_ack(h->cb.ctx, &m);
        break;
    }
    case ISO_FB_NAK: {
        iso_fb_nak m;
        if ((bad = iso_fb_nak_unpack(&m, v->payload, v->len) != 0))
            break;
        h->stats.naks++;
        if (m.reason == ISO_FB_NAK_NOT_ARMED && h->state == ISO_FB_HOST_STREAMING)
            iso_fb_host_rehello(h);
        break;
    }
    case ISO_FB_FAULT: {
        iso_fb_fault m;
        if ((bad = iso_fb_fault_unpack(&m, v->payload, v->len) != 0))
            break;
        h->stats.faults++;
        /* Motion resumes only after a fresh HELLO exchange. */
        if (h->state == ISO_FB_HOST_STREAMING)
            h->state = ISO_FB_HOST_HANDSHAKE;
        h->last_hello_us = 0;
        if (h->cb.on_fault)
            h->cb.on_fault(h->cb.ctx, &m);
        break;
    }
    default:
        bad = 1; /* host-to-MCU types have no business here */
        break;
    }
    h->stats.bad_payloads += bad != 0;
}

int iso_fb_host_poll(iso_fb_host *h, int timeout_ms)
{
    if (!h || h->state == ISO_FB_HOST_DOWN)
        return 0;
    uint8_t buf[512];
    int frames = 0;
    int wait = timeout_ms;
    for (;;) {
        iso_err_clear(&h->last_err);
        int n = iso_link_read(h->link, buf, sizeof buf, wait, &h->last_err);
        if (n < 0) {
            link_down(h);
            break;
        }
        if (n == 0)
            break;
        wait = 0; /* drain what is there, then return */
        h->stats.rx_bytes += (uint64_t)n;
        for (int i = 0; i < n; i++) {
            iso_fb_view v;
            if (iso_fb_parser_feed(&h->parser, buf[i], &v) == ISO_FB_FRAME) {
                h->last_rx_us = iso_clock_us();
                handle_frame(h, &v);
                frames++;
            }
        }
        h->stats.rx = h->parser.n;
    }
    if (h->state != ISO_FB_HOST_DOWN &&
        iso_clock_us() - h->last_rx_us > (uint64_t)h->opts.link_timeout_ms * 1000u) {
        iso_err_clear(&h->last_err);
        iso_err_set(&h->last_err, ISO_EIO, -1, "fb host: no valid frame for %d ms",
                    h->opts.link_timeout_ms);
        link_down(h);
    }
    return frames;
}

/* Brings the link up: reopen when DOWN (rate-limited), HELLO when not
 * answered within hello_retry_ms. */
static void service(iso_fb_host *h)
{
    uint64_t now = iso_clock_us();
    if (h->state == ISO_FB_HOST_DOWN) {
        if (now - h->last_reopen_us < (uint64_t)h->opts.reopen_ms * 1000u)
            return;
        h->last_reopen_us = now;
        iso_err_clear(&h->last_err);
        if (iso_link_reopen(h->link, &h->last_err) != ISO_OK)
            return;
        h->stats.reopens++;
        iso_fb_parser_init(&h->parser);
        h->last_rx_us = now;
        send_hello(h);
        return;
    }
    if (h->state == ISO_FB_HOST_HANDSHAKE &&
        (h->last_hello_us == 0 ||
         now - h->last_hello_us >= (uint64_t)h->opts.hello_retry_ms * 1000u))
        send_hello(h);
}

int iso_fb_host_step(iso_fb_host *h, uint32_t tick, const int16_t *values, unsigned n)
{
    if (!h || (!values && n) || n > ISO_FB_MAX_CHANNELS)
        return ISO_EINVAL;
    service(h);
    int sent = 0;
    if (h->state == ISO_FB_HOST_STREAMING) {
        iso_fb_setpoints s;
        s.tick = tick;
        s.n = (uint8_t)n;
        for (unsigned i = 0; i < n; i++)
            s.value[i] = values[i];
        uint8_t p[ISO_FB_MAX_PAYLOAD];
        uint16_t seq = h->tx_seq;
        iso_err_clear(&h->last_err);
        if (send_frame(h, ISO_FB_SETPOINTS, p, iso_fb_setpoints_pack(p, sizeof p, &s),
                       &h->last_err) == ISO_OK) {
            unsigned slot = seq % ISO_FB_HOST_RTT_SLOTS;
            h->sent_seq[slot] = seq;
            h->sent_us[slot] = iso_clock_us();
            sent = 1;
        } else {
            link_down(h);
        }
    }
    iso_fb_host_poll(h, 0);
    return sent;
}

int iso_fb_host_send_diag_hang(iso_fb_host *h, iso_err *err)
{
    if (!h || h->state == ISO_FB_HOST_DOWN)
        return iso_err_set(err, ISO_EIO, -1, "fb host: link is down");
    iso_fb_diag d = {ISO_FB_DIAG_HANG_MAGIC};
    uint8_t p[ISO_FB_MAX_PAYLOAD];
    return send_frame(h, ISO_FB_DIAG, p, iso_fb_diag_pack(p, sizeof p, &d), err);
}

int iso_fb_host_send_safe(iso_fb_host *h, uint8_t cause, iso_err *err)
{
    if (!h || h->state == ISO_FB_HOST_DOWN)
        return iso_err_set(err, ISO_EIO, -1, "fb host: link is down");
    if (!iso_fb_host_can_safe(h))
        return iso_err_set(err, ISO_ENOTSUP, -1,
                           "fb host: the MCU (firmware %u.%u) does not offer SAFE; only its link "
                           "watchdog brakes it",
                           (unsigned)(h->device.fw_version >> 8),
                           (unsigned)(h->device.fw_version & 0xffu));
    iso_fb_safe q = {cause};
    uint8_t p[ISO_FB_MAX_PAYLOAD];
    iso_err e;
    iso_err_clear(&e);
    int rc = send_frame(h, ISO_FB_SAFE, p, iso_fb_safe_pack(p, sizeof p, &q), &e);
    if (rc != ISO_OK && rc != ISO_EINVAL) { /* the transport failed: the link is lost */
        h->last_err = e;
        link_down(h);
    }
    if (rc != ISO_OK && err)
        *err = e;
    return rc;
}

int iso_fb_host_can_safe(const iso_fb_host *h)
{
    return h && (h->device.flags & ISO_FB_HELLO_CAN_SAFE) != 0;
}

int iso_fb_host_format_stats(const iso_fb_host *h, char *buf, size_t cap)
{
    return iso_fb_host_format_stats_copy(&h->stats, buf, cap);
}

int iso_fb_host_format_stats_copy(const iso_fb_host_stats *s, char *buf, size_t cap)
{
    double avg = s->rtt_count ? (double)s->rtt_sum_us / s->rtt_count / 1000.0 : 0.0;
    double mn = s->rtt_count ? s->rtt_min_us / 1000.0 : 0.0;
    return snprintf(buf, cap,
                    "fb link: sent %" PRIu64 " frames (%" PRIu64 " B), received %" PRIu64
                    " (%" PRIu64 " B); dropped %" PRIu32 " (crc %" PRIu32 ", cobs %" PRIu32
                    ", too long %" PRIu32 ", short %" PRIu32 ", seq dup %" PRIu32
                    ", seq order %" PRIu32 "), %" PRIu32 " lost in gaps; acks %" PRIu32
                    ", naks %" PRIu32 ", MCU safe states %" PRIu32 ", samples %" PRIu32
                    "; link losses %" PRIu32 ", reopens %" PRIu32 ", armed %" PRIu32 " times"
                    "; rtt avg %.2f ms (min %.2f, max %.2f)",
                    s->tx_frames, s->tx_bytes, s->rx_frames, s->rx_bytes, s->rx.resyncs,
                    s->rx.bad_crc, s->rx.bad_cobs, s->rx.too_long, s->rx.too_short, s->rx.duplicate,
                    s->rx.out_of_order, s->rx.seq_gaps, s->acks, s->naks, s->faults, s->samples,
                    s->link_losses, s->reopens, s->handshakes, avg, mn, s->rtt_max_us / 1000.0);
}
