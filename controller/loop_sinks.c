/* controller/loop_sinks.c -- where each tick's vertices go: the live display
 * (copied into its latest-frame slot; its own thread writes to browsers), the
 * file outputs (PNG snapshots at chosen ticks, a PLY frame sequence, a PC2
 * point cache, an MCAP file: handed to the writer thread, loop_writer.c),
 * and the actuators behind the firmware bridge. The tick allocates nothing
 * and waits on no file or socket. A sink that fails to write stops the run
 * with an error naming it: files already written stay whole. */
#include "loop_internal.h"

#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "iso_actuators.h"
#include "iso_clock.h"
#include "iso_foxglove.h"

struct iso_loop_sinks {
    iso_display *display;
    iso_actuators *act;
    char act_line[1000];     /* kept when the actuators close (the counters run ~650) */
    char act_stop[600];      /* how the safe stop went */
    iso_act_stats act_stats; /* the counters, kept when the actuators close */
    int had_act;
    iso_loop_writer *writer; /* the file outputs; NULL without */
    iso_sink_frame frame;    /* this tick's channels, for the writer and the view */
    iso_loop_summary files;  /* the writer's counts, kept when it closes */
    long frames_sent;        /* kept when the display closes */
    /* What handing the frame to the writer costs the tick (the summary's
     * handoff_ms_*), timed on the tick's thread. */
    int64_t handoff_ns_sum, handoff_ns_max;
    long handoff_n;
};

static void display_notice(void *ctx, const char *line)
{
    iso_loop *l = ctx;
    iso_loop_say(l, "live view: %s", line);
}

/* The handles a page may move: the device-driven ones, in the mapping's
 * order (the view device's handle j is the mapping's). */
static int view_handles(const iso_loop *l, iso_display_handle *out)
{
    int n = 0;
    for (int j = 0; j < l->n_dev && n < ISO_DISPLAY_MAX_HANDLES; j++, n++) {
        out[n].name = l->sc->handles[l->dev_handle[j]].name;
        out[n].handle = l->dev_handle[j];
    }
    return n;
}

static int open_display(iso_loop *l, iso_err *err)
{
    const iso_scene_display *d = &l->sc->display;
    int on = l->o.display < 0 ? d->enabled : l->o.display;
    if (!on && l->view_src)
        return iso_err_set(err, ISO_EINVAL, -1,
                           "%s: a view device takes its commands from the live view's page, and "
                           "the view is off (%s)",
                           l->sc->path[0] ? l->sc->path : "the scene",
                           l->o.display == 0 ? "--no-display" : "no sinks.display in the scene");
    if (!on)
        return ISO_OK;
    iso_display_opts o;
    iso_display_handle hs[ISO_DISPLAY_MAX_HANDLES];
    memset(&o, 0, sizeof o);
    o.view_device = l->view_src;
    o.handles = hs;
    o.n_handles = l->view_src ? view_handles(l, hs) : 0;
    o.host = d->host[0] ? d->host : NULL;
    o.port = l->o.port >= 0 ? l->o.port : (d->port ? d->port : 8080);
    o.mesh = l->sc->mesh;
    o.regions = &l->sc->regions;
    o.allow_remote = d->allow_remote;
    o.notice = display_notice;
    o.notice_ctx = l;
    int rc = iso_display_create(&o, &l->sinks->display, err);
    if (rc == ISO_EIO && o.port != 0 && l->o.port < 0) {
        /* the scene's port is taken (another run, another server): any free
         * one serves as well, and the line below says which */
        iso_loop_say(l, "%s; using a free port instead", err->msg);
        iso_err_clear(err);
        o.port = 0;
        rc = iso_display_create(&o, &l->sinks->display, err);
    }
    if (rc != ISO_OK)
        return rc;
    char url[300];
    iso_loop_view_url(l, url, sizeof url);
    const char *tok = iso_display_token(l->sinks->display);
    iso_loop_say(l, "live view on %s", url);
    if (l->view_src)
        iso_loop_say(l,
                     "the page can drive %s: take control there, then drag the gizmo "
                     "(Esc stops)%s",
                     o.n_handles == 1 ? "the handle" : "the handles",
                     tok[0] ? "; commanding needs the token in this URL, watching does not" : "");
    return ISO_OK;
}

/* The e-stop inputs the sender reads by itself: the embedder's probe and
 * the devices' e-stop lines (the hub outlives the sinks). */
static int estop_inputs(void *ctx)
{
    const iso_loop *l = ctx;
    if (l->o.estop_probe && l->o.estop_probe(l->o.estop_ctx))
        return 1;
    return l->hub && iso_dev_hub_estop_probe(l->hub); /* 0 without e-stop inputs */
}

/* The scene's actuator channels and link, in the sink's own terms
 * (actuators/ does not read scene files). */

static int open_actuators(iso_loop *l, iso_err *err)
{
    const iso_scene_actuators *a = &l->sc->actuators;
    if (!a->enabled)
        return ISO_OK;
    if (a->n_ch > ISO_ACT_MAX_CHANNELS)
        return iso_err_set(err, ISO_EINVAL, -1,
                           "sinks.actuators: %d channels, a SETPOINTS frame carries at most %d",
                           a->n_ch, ISO_ACT_MAX_CHANNELS);
    iso_act_channel ch[ISO_ACT_MAX_CHANNELS];
    iso_scene_actuator_channels(a, ch);
    iso_act_link_spec link;
    iso_scene_actuator_link(a, &link);
    iso_act_opts o = {0, iso_loop__note, l};
    /* The loop watchdog: no progress for max(250 ms, 5 periods) and the
     * sender stops streaming and sends SAFE. The loop reports progress every
     * tick, every ABM step and inside each field evaluation (iso_loop.h). */
    iso_act_safety_opts so;
    memset(&so, 0, sizeof so);
    so.tick_period_ms = (int)ceil(1000.0 / l->sc->tick_hz);
    so.loop_timeout_ms = a->loop_timeout_ms; /* 0: the default above */
    so.estop_probe = estop_inputs;           /* read on the sender thread, every 2 ms */
    so.estop_ctx = l;
    return iso_actuators_create(ch, a->n_ch, l->nv, &l->sc->regions, &link, &o, &so, &l->sinks->act,
                                err);
}

int iso_loop__sinks_open(iso_loop *l, iso_err *err)
{
    l->sinks = calloc(1, sizeof *l->sinks);
    if (!l->sinks)
        return iso_err_set(err, ISO_ENOMEM, -1, "out of memory for the sinks");
    int rc = open_display(l, err);
    if (rc == ISO_OK)
        rc = open_actuators(l, err);
    if (rc == ISO_OK && l->sc->display.n_snapshots > 0) {
        const char *dir = l->sc->display.snapshot_dir;
        if (dir[0] && mkdir(dir, 0777) != 0 && errno != EEXIST)
            rc = iso_err_set(err, ISO_EIO, -1, "sinks.display.snapshot_dir %s: %s", dir,
                             strerror(errno));
    }
    if (rc == ISO_OK)
        rc = iso_loop__writer_open(l, &l->sinks->writer, err);
    if (rc == ISO_OK && l->sinks->display) { /* Foxglove Studio may connect to the view too */
        iso_sink_session s;
        iso_loop__fox_session(l, &s);
        rc = iso_display_foxglove(l->sinks->display, &s, err);
    }
    return rc;
}

/* The devices' state for the writer: decoded samples and counters. */
static void frame_devices(const iso_loop *l, iso_sink_frame *f)
{
    size_t nd = l->hub ? iso_dev_hub_sources(l->hub) : 0;
    for (size_t i = 0; i < nd && i < ISO_SINK_MAX_DEVICES; i++) {
        iso_sink_device *d = &f->dev[i];
        const iso_dev_map_src *m = &l->map.src[i];
        if (iso_dev_hub_source_stats(l->hub, i, &d->stats) != ISO_OK)
            memset(&d->stats, 0, sizeof d->stats);
        d->present = d->stats.present;
        d->stale = d->stats.is_stale;
        memcpy(d->axes, m->axes, sizeof d->axes);
        d->buttons = m->buttons;
        d->has_pose = m->has_pose;
        d->has_twist = m->has_twist;
        memcpy(d->v, m->v, sizeof d->v);
    }
}

/* Fills the writer's frame of this tick: everything but the positions,
 * which the push copies. Plain copies: no allocation, no wait. */
static void fill_frame(iso_loop *l, long tick, iso_sink_frame *f)
{
    f->tick = tick;
    f->t_ns = l->t_now - l->stream0;
    f->dt_ns = l->last_dt_ns;
    for (int h = 0; h < l->nh && h < ISO_SINK_MAX_HANDLES; h++) {
        f->commanded[h] = l->cmd_pose[h];
        f->achieved[h] = *iso_stepper_pose(l->st, h);
    }
    f->substeps = l->last_substeps;
    f->merged = l->last_merged;
    f->restart = l->last_restart;
    f->active = l->last.active;
    f->clutch = l->last.clutch;
    f->estop = l->last.estop;
    f->buttons = l->last.buttons;
    iso_solver_stats ss;
    iso_solver_get_stats(l->solver, &ss);
    iso_integrate_stats is;
    iso_stepper_stats(l->st, &is);
    f->evaluations = is.evaluations;
    f->factorizations = ss.factorizations;
    f->cg_iterations = ss.cg_iterations;
    /* this tick's compute time is not known until it is published: the last one's */
    long n = l->stats.n;
    f->tick_ms =
        n > 0 ? l->stats.recent[(l->stats.head + ISO_LOOP_RECENT - 1) % ISO_LOOP_RECENT] : NAN;
    f->latency_ms = n > 0 ? l->stats.last_lat_ms : NAN;
    f->misses = l->stats.skipped; /* deadlines without a tick of their own */
    f->dropped = iso_loop__writer_dropped(l->sinks->writer);
    frame_devices(l, f);
    f->have_act = 0;
    if (l->sinks->act) {
        uint32_t t;
        f->have_act = iso_actuators_setpoints(l->sinks->act, f->setpoints, &t);
        iso_actuators_stats(l->sinks->act, &f->act);
    }
}

/* What the page shows of the handles and of the view device's commands:
 * each handle's pose, the last command the ticks applied (the page times
 * its commands by it) and the state of the stream. */
static void view_figures(const iso_loop *l, iso_display_stats *ds)
{
    ds->n_handles = l->nh < ISO_DISPLAY_MAX_HANDLES ? l->nh : ISO_DISPLAY_MAX_HANDLES;
    for (int h = 0; h < ds->n_handles; h++)
        ds->handle[h] = *iso_stepper_pose(l->st, h);
    ds->cmd_conn = ds->cmd_seq = 0;
    ds->cmd_page_ms = 0;
    ds->flags = l->last.estop ? ISO_DISPLAY_FLAG_ESTOP : 0;
    size_t n = l->hub ? iso_dev_hub_sources(l->hub) : 0;
    for (size_t i = 0; i < n; i++) {
        const iso_dev_decoder *dec = iso_dev_hub_decoder(l->hub, i);
        if (dec->kind != ISO_DEV_KIND_VIEW)
            continue;
        uint32_t bit = (uint32_t)1 << i;
        ds->cmd_conn = dec->view.applied_conn;
        ds->cmd_seq = dec->view.applied_seq;
        ds->cmd_page_ms = dec->view.applied_ms;
        ds->flags |= (l->last.targeting & bit ? ISO_DISPLAY_FLAG_TARGETING : 0) |
                     (l->last.stale & bit ? ISO_DISPLAY_FLAG_STALE : 0) |
                     (dec->view.holder ? ISO_DISPLAY_FLAG_HOLDER : 0);
        break;
    }
}

int iso_loop__sinks_publish(iso_loop *l, long tick, iso_err *err)
{
    struct iso_loop_sinks *k = l->sinks;
    int rc = ISO_OK;
    if (k->display) {
        iso_display_stats ds;
        iso_loop__stats_recent(&l->stats, &ds.tick_ms_median, &ds.tick_ms_p99, &ds.tick_ms_max);
        ds.latency_ms = l->stats.last_lat_ms;
        ds.misses = l->stats.misses;
        view_figures(l, &ds);
        rc = iso_display_publish(k->display, tick, l->x, &ds, err);
        if (rc == ISO_OK) {
            fill_frame(l, tick, &k->frame);
            rc = iso_display_publish_frame(k->display, &k->frame, err);
        }
    }
    if (rc == ISO_OK && k->act) {
        /* 1: streaming, 0: link down or handshaking (the sink recovers by itself) */
        int r = iso_actuators_publish(k->act, (uint32_t)tick, l->x, err);
        rc = r < 0 ? r : ISO_OK;
    }
    if (rc == ISO_OK && k->writer) {
        int64_t t0 = iso_clock_ns();
        rc = iso_loop__writer_check(k->writer, err);
        int want;
        iso_sink_frame *f = rc == ISO_OK ? iso_loop__writer_slot(k->writer, tick, &want) : NULL;
        if (f) {
            if (k->display) { /* filled for the view above */
                const double *slot_x = f->x;
                *f = k->frame;
                f->x = slot_x;
            } else
                fill_frame(l, tick, f);
            iso_loop__writer_push(k->writer, l->x);
        }
        int64_t dt = iso_clock_ns() - t0;
        k->handoff_ns_sum += dt;
        k->handoff_n++;
        if (dt > k->handoff_ns_max)
            k->handoff_ns_max = dt;
    }
    return rc;
}

/* A clean stop: no more setpoints and SAFE, then wait for the MCU's own
 * report of its safe state (one round trip; without SAFE, firmware 1.0, the
 * link watchdog: 100 ms plus a frame). */
#define ISO_LOOP_SAFE_STOP_MS 400

static int close_actuators(struct iso_loop_sinks *k, iso_err *err)
{
    if (!k->act)
        return ISO_OK;
    double safe_ms = 0;
    int rc = iso_actuators_safe_stop(k->act, ISO_LOOP_SAFE_STOP_MS, &safe_ms, err);
    if (rc == ISO_OK)
        snprintf(k->act_stop, sizeof k->act_stop,
                 "safe state reported %.0f ms after the last setpoints", safe_ms);
    else
        snprintf(k->act_stop, sizeof k->act_stop, "safe state NOT confirmed: %s", err->msg);
    iso_actuators_format_stats(k->act, k->act_line, sizeof k->act_line);
    iso_actuators_stats(k->act, &k->act_stats);
    k->had_act = 1;
    iso_actuators_destroy(k->act);
    k->act = NULL;
    return rc;
}

int iso_loop__sinks_close(iso_loop *l, iso_err *err)
{
    struct iso_loop_sinks *k = l->sinks;
    if (!k)
        return ISO_OK;
    int rc = close_actuators(k, err);
    if (k->act_stop[0])
        iso_loop_say(l, "actuators: %s", k->act_stop);
    /* The view stays up with its last frame until the loop is destroyed
     * (iso_loop_view_end), but takes no more commands. */
    iso_display_end(k->display, NULL);
    int r2 = iso_loop__writer_close(k->writer, 1, &k->files, err);
    k->writer = NULL;
    return rc == ISO_OK ? r2 : rc;
}

void iso_loop__sinks_free(iso_loop *l)
{
    struct iso_loop_sinks *k = l->sinks;
    if (!k)
        return;
    iso_display_destroy(k->display);
    k->display = NULL;
}

int iso_loop_view_url(const iso_loop *l, char *url, size_t cap)
{
    iso_display *d = l && l->sinks ? l->sinks->display : NULL;
    if (cap)
        url[0] = 0;
    if (!d)
        return 0;
    const char *host = l->sc->display.host[0] ? l->sc->display.host : "127.0.0.1";
    int v6 = strchr(host, ':') != NULL && host[0] != '[';
    const char *tok = iso_display_token(d);
    snprintf(url, cap, "http://%s%s%s:%d/%s%s", v6 ? "[" : "", host, v6 ? "]" : "",
             iso_display_port(d), tok[0] ? "?token=" : "", tok);
    return 1;
}

int iso_loop_view_end(iso_loop *l, const char *text, char *url, size_t cap)
{
    iso_display *d = l && l->sinks ? l->sinks->display : NULL;
    if (d)
        iso_display_end(d, text);
    if (url && cap)
        return iso_loop_view_url(l, url, cap);
    return d != NULL;
}

void iso_loop__sinks_summary(const iso_loop *l, iso_loop_summary *s)
{
    const struct iso_loop_sinks *k = l->sinks;
    if (!k)
        return;
    s->frames_sent = k->display ? iso_display_frames_sent(k->display) : k->frames_sent;
    if (k->display) {
        iso_display_command_stats cs;
        iso_display_command_stats_get(k->display, &cs);
        s->view_accepted = cs.accepted;
        s->view_refused = cs.refused;
        s->view_malformed = cs.malformed;
        s->view_dropped = cs.dropped;
        s->view_grants = cs.grants;
        s->view_stops = cs.stops;
        s->view_device = l->view_src != NULL;
    }
    if (k->handoff_n) {
        s->handoff_ms_mean = (double)k->handoff_ns_sum * 1e-6 / (double)k->handoff_n;
        s->handoff_ms_max = (double)k->handoff_ns_max * 1e-6;
    }
    if (k->writer)
        iso_loop__writer_counts(k->writer, s);
    else {
        s->ply_frames = k->files.ply_frames;
        s->snapshots = k->files.snapshots;
        s->pc2_frames = k->files.pc2_frames;
        s->mcap_messages = k->files.mcap_messages;
        s->frames_dropped = k->files.frames_dropped;
    }
    if (k->act)
        iso_actuators_format_stats(k->act, s->act_line, sizeof s->act_line);
    else if (k->act_line[0])
        snprintf(s->act_line, sizeof s->act_line, "%s; %s", k->act_line, k->act_stop);
    s->has_act = k->act || k->had_act;
    if (k->act)
        iso_actuators_stats(k->act, &s->act);
    else if (k->had_act)
        s->act = k->act_stats;
}

void iso_loop__sinks_alive(iso_loop *l)
{
    if (l->sinks && l->sinks->act)
        iso_actuators_alive(l->sinks->act);
}

void iso_loop__sinks_estop(iso_loop *l, int on)
{
    if (l->sinks && l->sinks->act)
        iso_actuators_estop(l->sinks->act, on);
}

void iso_loop__sinks_status(const iso_loop *l, char *buf, size_t cap)
{
    const struct iso_loop_sinks *k = l->sinks;
    buf[0] = 0;
    if (k && k->display) {
        uint32_t holder = iso_display_holder(k->display);
        if (holder)
            snprintf(buf, cap, "browsers %d (viewer %u in control)",
                     iso_display_clients(k->display), (unsigned)holder);
        else
            snprintf(buf, cap, "browsers %d", iso_display_clients(k->display));
    }
    if (k && k->act) {
        iso_act_stats st;
        iso_actuators_stats(k->act, &st);
        size_t n = strlen(buf);
        snprintf(buf + n, cap - n, "%sactuators %s, %llu acks", n ? "  " : "",
                 iso_actuators_link_state(k->act), (unsigned long long)st.acks);
    }
}

struct iso_actuators *iso_loop_actuators(const iso_loop *l)
{
    return l && l->sinks ? l->sinks->act : NULL;
}
