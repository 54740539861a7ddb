/* controller/loop_sinks.c -- where each tick's vertices go: the live display
 * (copied into its latest-frame slot; its own thread writes to browsers), PNG
 * snapshots at chosen ticks, a PLY frame sequence, and the actuators behind
 * the firmware bridge. A sink that fails to write stops the run with an error
 * naming it: files already written stay whole. */
#include "loop_internal.h"

#include <errno.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

struct iso_loop_sinks {
    iso_display *display;
    iso_ply_frames *ply;
    long ply_written, snapshots;
    long frames_sent; /* kept when the display closes */
};

static int open_display(iso_loop *l, iso_err *err)
{
    const iso_scene_display *d = &l->sc->display;
    int on = l->o.display < 0 ? d->enabled : l->o.display;
    if (!on)
        return ISO_OK;
    iso_display_opts o;
    memset(&o, 0, sizeof o);
    o.host = d->host[0] ? d->host : NULL;
    o.port = l->o.port >= 0 ? l->o.port : (d->port ? d->port : 8080);
    o.mesh = l->sc->mesh;
    o.regions = &l->sc->regions;
    int rc = iso_display_create(&o, &l->sinks->display, err);
    if (rc == ISO_EIO && o.port != 0 && l->o.port < 0) {
        /* the scene's port is taken (another run, another server): any free
         * one serves as well, and the line below says which */
        fprintf(l->log, "isoshape run: %s; using a free port instead\n", err->msg);
        iso_err_clear(err);
        o.port = 0;
        rc = iso_display_create(&o, &l->sinks->display, err);
    }
    if (rc == ISO_ENOTSUP) { /* a build without civetweb still runs headless */
        fprintf(l->log, "isoshape run: no live display: %s\n", err->msg);
        iso_err_clear(err);
        return ISO_OK;
    }
    if (rc != ISO_OK)
        return rc;
    fprintf(l->log, "isoshape run: live view on http://%s:%d/\n", o.host ? o.host : "127.0.0.1",
            iso_display_port(l->sinks->display));
    return ISO_OK;
}

int iso_loop__sinks_open(iso_loop *l, iso_err *err)
{
    l->sinks = calloc(1, sizeof *l->sinks);
    if (!l->sinks)
        return iso_err_set(err, ISO_ENOMEM, -1, "out of memory for the sinks");
    int rc = open_display(l, err);
    if (rc == ISO_OK && l->sc->ply.enabled) {
        rc = iso_ply_frames_create(l->sc->ply.dir, l->sc->mesh, l->sc->ply.every, &l->sinks->ply,
                                   err);
        if (rc == ISO_OK)
            fprintf(l->log, "isoshape run: PLY frames every %d ticks into %s\n", l->sc->ply.every,
                    l->sc->ply.dir);
    }
    if (rc == ISO_OK && l->sc->display.n_snapshots > 0) {
        const char *dir = l->sc->display.snapshot_dir;
        if (dir[0] && mkdir(dir, 0777) != 0 && errno != EEXIST)
            rc = iso_err_set(err, ISO_EIO, -1, "sinks.display.snapshot_dir %s: %s", dir,
                             strerror(errno));
    }
    return rc;
}

static int snapshot(iso_loop *l, long tick, iso_err *err)
{
    const iso_scene_display *d = &l->sc->display;
    for (int i = 0; i < d->n_snapshots; i++) {
        if (d->snapshot_ticks[i] != tick)
            continue;
        char path[ISO_SCENE_PATH_MAX + 32];
        snprintf(path, sizeof path, "%s%stick_%08ld.png", d->snapshot_dir,
                 d->snapshot_dir[0] ? "/" : "", tick);
        int rc = iso_snapshot_png(l->sc->mesh, l->x, &l->sc->regions, path, 960, 720, NULL, err);
        if (rc != ISO_OK)
            return rc;
        l->sinks->snapshots++;
    }
    return ISO_OK;
}

int iso_loop__sinks_publish(iso_loop *l, long tick, iso_err *err)
{
    struct iso_loop_sinks *k = l->sinks;
    int rc = ISO_OK;
    if (k->display) {
        iso_display_stats ds;
        iso_loop__stats_recent(&l->stats, &ds.tick_ms_median, &ds.tick_ms_p99, &ds.tick_ms_max);
        long n = l->stats.n;
        ds.latency_ms = n > 0 ? l->stats.lat_ms[n - 1] : 0;
        ds.misses = l->stats.misses;
        rc = iso_display_publish(k->display, tick, l->x, &ds, err);
    }
    if (rc == ISO_OK && k->ply) {
        rc = iso_ply_frames_write(k->ply, tick, l->x, err);
        if (rc > 0) {
            k->ply_written++;
            rc = ISO_OK;
        }
    }
    if (rc == ISO_OK)
        rc = snapshot(l, tick, err);
    return rc;
}

int iso_loop__sinks_close(iso_loop *l, iso_err *err)
{
    (void)err;
    struct iso_loop_sinks *k = l->sinks;
    if (!k)
        return ISO_OK;
    if (k->display)
        k->frames_sent = iso_display_frames_sent(k->display);
    iso_display_destroy(k->display);
    iso_ply_frames_destroy(k->ply);
    k->display = NULL;
    k->ply = NULL;
    return ISO_OK;
}

void iso_loop__sinks_summary(const iso_loop *l, iso_loop_summary *s)
{
    const struct iso_loop_sinks *k = l->sinks;
    if (!k)
        return;
    s->frames_sent = k->display ? iso_display_frames_sent(k->display) : k->frames_sent;
    s->ply_frames = k->ply_written;
    s->snapshots = k->snapshots;
}

void iso_loop__sinks_status(const iso_loop *l, char *buf, size_t cap)
{
    const struct iso_loop_sinks *k = l->sinks;
    buf[0] = 0;
    if (k && k->display)
        snprintf(buf, cap, "browsers %d", iso_display_clients(k->display));
}
