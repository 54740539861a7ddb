/* controller/loop_writer.c -- the file sinks' writer thread: PLY frames, PNG
 * snapshots, the PC2 point cache and the MCAP file are written here, never
 * on the tick.
 *
 * Between the tick and the thread is a bounded queue of frame slots, made
 * before the first tick (each slot holds a tick's positions and what the
 * MCAP channels say of it), with one producer and one consumer: the tick
 * fills the next free slot and publishes it with a release store and a
 * semaphore post, both non-blocking; it takes no lock and never waits. A
 * queue, not a latest-wins slot, because every frame of a sequence or a
 * cache is wanted. When the disk is slower than the loop and the queue is
 * full, the tick's frame is dropped and counted (the summary says how many;
 * /loop carries the count), and the tick goes on: a dropped tick has no PLY
 * file, no MCAP messages, and repeats the previous frame in the PC2 cache,
 * so the cache's frame k stays tick k. Without deadlines (--fast, an
 * export) nothing is late, so the tick waits for room instead of dropping:
 * the files are then whole and the same on every machine. A write that
 * fails stops the run with an error naming the file, at the next tick. */
#include "loop_internal.h"

#include <errno.h>
#include <pthread.h>
#include <semaphore.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "iso_foxglove.h"
#include "iso_mcap.h"
#include "iso_pc2.h"
#include "iso_thread.h"

/* Queue memory: up to 64 slots, at most ~32 MB of positions, at least 4. */
#define SLOTS_MAX 64
#define SLOTS_BYTES (32u << 20)

enum { WANT_PLY = 1, WANT_PNG = 2, WANT_STREAM = 4 };

typedef struct slot {
    iso_sink_frame f;
    double *x;
    int want;
} slot;

struct iso_loop_writer {
    const iso_scene *sc;
    int nv, n_slots;
    slot *slots;
    _Atomic long head, tail; /* filled by the tick / emptied by the thread, monotonic */
    sem_t wake, room;        /* a slot filled / a slot emptied */
    int wait_for_room;       /* 1 without deadlines: the tick waits instead of dropping */
    atomic_int stop, failed;
    pthread_t th;
    int started;
    iso_err err; /* the thread's first error, read after `failed` */
    long dropped;
    /* the thread's own */
    iso_ply_frames *ply;
    iso_pc2 *pc2;
    iso_mcap *mcap;
    iso_fox_encoder *enc;
    iso_fox_channel ch[ISO_FOX_MAX_CHANNELS];
    uint16_t ch_id[ISO_FOX_MAX_CHANNELS];
    int n_ch;
    double *prev;  /* the PC2's last frame, repeated for dropped ticks */
    long pc2_next; /* the tick the cache's next frame is */
    _Atomic long ply_written, snapshots, pc2_frames, mcap_messages;
};

/* ---- the thread ------------------------------------------------------- */

static int write_snapshot(iso_loop_writer *w, const slot *s, iso_err *err)
{
    const iso_scene_display *d = &w->sc->display;
    char path[ISO_SCENE_PATH_MAX + 32];
    snprintf(path, sizeof path, "%s%stick_%08ld.png", d->snapshot_dir,
             d->snapshot_dir[0] ? "/" : "", s->f.tick);
    int rc = iso_snapshot_png(w->sc->mesh, s->x, &w->sc->regions, path, 960, 720, NULL, err);
    if (rc == ISO_OK)
        atomic_fetch_add(&w->snapshots, 1);
    return rc;
}

static int write_stream(iso_loop_writer *w, const slot *s, iso_err *err)
{
    int rc = ISO_OK;
    size_t bytes = (size_t)w->nv * 3 * sizeof *w->prev;
    for (; w->pc2 && w->pc2_next < s->f.tick && rc == ISO_OK; w->pc2_next++)
        rc = iso_pc2_write(w->pc2, w->pc2_next > 0 ? w->prev : s->x, err);
    if (w->pc2 && rc == ISO_OK) {
        rc = iso_pc2_write(w->pc2, s->x, err);
        memcpy(w->prev, s->x, bytes);
        w->pc2_next = s->f.tick + 1;
        atomic_store(&w->pc2_frames, iso_pc2_frames(w->pc2));
    }
    for (int c = 0; w->mcap && c < w->n_ch && rc == ISO_OK; c++) {
        const char *data;
        size_t len;
        rc = iso_fox_encode(w->enc, &w->ch[c], &s->f, &data, &len, err);
        if (rc == ISO_OK)
            rc = iso_mcap_write(w->mcap, w->ch_id[c], (uint64_t)s->f.t_ns, data, len, err);
    }
    if (w->mcap)
        atomic_store(&w->mcap_messages, (long)iso_mcap_messages(w->mcap));
    return rc;
}

static int write_slot(iso_loop_writer *w, const slot *s, iso_err *err)
{
    int rc = ISO_OK;
    if ((s->want & WANT_PLY) && (rc = iso_ply_frames_write(w->ply, s->f.tick, s->x, err)) > 0) {
        atomic_fetch_add(&w->ply_written, 1);
        rc = ISO_OK;
    }
    if (rc == ISO_OK && (s->want & WANT_PNG))
        rc = write_snapshot(w, s, err);
    if (rc == ISO_OK && (s->want & WANT_STREAM))
        rc = write_stream(w, s, err);
    return rc;
}

static void *writer_main(void *arg)
{
    iso_loop_writer *w = arg;
    for (;;) {
        long tail = atomic_load_explicit(&w->tail, memory_order_relaxed);
        long head = atomic_load_explicit(&w->head, memory_order_acquire);
        if (tail == head) {
            if (atomic_load(&w->stop))
                return NULL;
            while (sem_wait(&w->wake) != 0 && errno == EINTR)
                ;
            continue;
        }
        slot *s = &w->slots[tail % w->n_slots];
        if (!atomic_load(&w->failed)) {
            iso_err e;
            iso_err_clear(&e);
            if (write_slot(w, s, &e) != ISO_OK) {
                w->err = e;
                atomic_store(&w->failed, 1);
            }
        }
        atomic_store_explicit(&w->tail, tail + 1, memory_order_release);
        sem_post(&w->room);
    }
}

/* ---- open and close ---------------------------------------------------- */

/* The rest mesh beside the cache, and a line saying where both go. */
static int save_rest(iso_loop *l, const char *pc2, iso_err *err)
{
    char path[ISO_SCENE_PATH_MAX + 16];
    int rc = iso_pc2_save_rest(l->sc->mesh, pc2, path, sizeof path, err);
    if (rc == ISO_OK)
        iso_loop_say(l, "PC2 point cache into %s (whole when the run ends), rest mesh %s", pc2,
                     path);
    return rc;
}

void iso_loop__fox_session(iso_loop *l, iso_sink_session *s)
{
    memset(s, 0, sizeof *s);
    s->mesh = l->sc->mesh;
    s->regions = &l->sc->regions;
    s->n_handles = l->nh < ISO_SINK_MAX_HANDLES ? l->nh : ISO_SINK_MAX_HANDLES;
    for (int h = 0; h < s->n_handles; h++) {
        snprintf(s->handle_name[h], sizeof s->handle_name[h], "%s", l->sc->handles[h].name);
        memcpy(s->handle_centre[h], l->centroid[h], sizeof s->handle_centre[h]);
    }
    size_t nd = l->hub ? iso_dev_hub_sources(l->hub) : 0;
    s->n_devices = (int)(nd < ISO_SINK_MAX_DEVICES ? nd : ISO_SINK_MAX_DEVICES);
    for (int d = 0; d < s->n_devices; d++)
        s->device_kind[d] = iso_dev_hub_decoder(l->hub, (size_t)d)->kind;
    const iso_scene_actuators *a = &l->sc->actuators;
    if (iso_loop_actuators(l)) {
        s->n_act = a->n_ch < ISO_ACT_MAX_CHANNELS ? a->n_ch : ISO_ACT_MAX_CHANNELS;
        for (int i = 0; i < s->n_act; i++)
            s->act_channel[i] = a->ch[i].channel;
    }
    s->wall_times = !l->o.fast;
}

static int open_mcap(iso_loop *l, iso_loop_writer *w, iso_err *err)
{
    iso_sink_session s;
    iso_loop__fox_session(l, &s);
    int rc = iso_fox_encoder_create(&s, &w->enc, err);
    if (rc == ISO_OK)
        rc = iso_mcap_create(l->o.mcap, "", "isoshape", &w->mcap, err);
    if (rc == ISO_OK)
        rc = iso_mcap_set_compression(w->mcap, l->o.mcap_compression, err);
    w->n_ch = iso_fox_channels(&s, w->ch, ISO_FOX_MAX_CHANNELS);
    uint16_t schema[ISO_FOX_MAX_CHANNELS];
    for (int c = 0; c < w->n_ch && rc == ISO_OK; c++) {
        schema[c] = 0;
        for (int k = 0; k < c; k++) /* one schema record per schema name */
            if (strcmp(w->ch[k].schema_name, w->ch[c].schema_name) == 0)
                schema[c] = schema[k];
        if (!schema[c])
            rc = iso_mcap_add_schema(w->mcap, w->ch[c].schema_name, "jsonschema", w->ch[c].schema,
                                     &schema[c], err);
        if (rc == ISO_OK)
            rc =
                iso_mcap_add_channel(w->mcap, schema[c], w->ch[c].topic, "json", &w->ch_id[c], err);
    }
    if (rc == ISO_OK)
        iso_loop_say(l, "MCAP into %s (whole when the run ends), %d channels, chunks %s", l->o.mcap,
                     w->n_ch, l->o.mcap_compression == ISO_MCAP_NONE ? "uncompressed" : "in zstd");
    return rc;
}

static int open_files(iso_loop *l, iso_loop_writer *w, iso_err *err)
{
    int rc = ISO_OK;
    if (l->sc->ply.enabled) {
        rc = iso_ply_frames_create(l->sc->ply.dir, l->sc->mesh, l->sc->ply.every, &w->ply, err);
        if (rc == ISO_OK)
            iso_loop_say(l, "PLY frames every %d ticks into %s", l->sc->ply.every, l->sc->ply.dir);
    }
    if (rc == ISO_OK && l->o.pc2 && l->o.pc2[0]) {
        rc = iso_pc2_create(l->o.pc2, l->nv, &w->pc2, err); /* what it refuses, before the rest */
        if (rc == ISO_OK)
            rc = save_rest(l, l->o.pc2, err);
        w->prev = rc == ISO_OK ? calloc((size_t)l->nv * 3, sizeof *w->prev) : NULL;
        if (rc == ISO_OK && !w->prev)
            rc = iso_err_set(err, ISO_ENOMEM, -1, "out of memory for the PC2 writer");
    }
    if (rc == ISO_OK && l->o.mcap && l->o.mcap[0])
        rc = open_mcap(l, w, err);
    return rc;
}

int iso_loop__writer_open(iso_loop *l, iso_loop_writer **out, iso_err *err)
{
    *out = NULL;
    int streams = (l->o.pc2 && l->o.pc2[0]) || (l->o.mcap && l->o.mcap[0]);
    if (!l->sc->ply.enabled && l->sc->display.n_snapshots == 0 && !streams)
        return ISO_OK;
    iso_loop_writer *w = calloc(1, sizeof *w);
    if (!w)
        return iso_err_set(err, ISO_ENOMEM, -1, "out of memory for the file writer");
    w->sc = l->sc;
    w->nv = l->nv;
    size_t frame = (size_t)l->nv * 3 * sizeof(double) + sizeof(slot);
    size_t n = SLOTS_BYTES / frame;
    w->n_slots = n > SLOTS_MAX ? SLOTS_MAX : n < 4 ? 4 : (int)n;
    w->slots = calloc((size_t)w->n_slots, sizeof *w->slots);
    int rc = w->slots ? ISO_OK : ISO_ENOMEM;
    for (int i = 0; i < w->n_slots && rc == ISO_OK; i++)
        if (!(w->slots[i].x = malloc((size_t)l->nv * 3 * sizeof(double))))
            rc = ISO_ENOMEM;
    if (rc != ISO_OK) {
        (void)!iso_loop__writer_close(w, 0, NULL, NULL);
        return iso_err_set(err, ISO_ENOMEM, -1, "out of memory for %d frame slots", w->n_slots);
    }
    rc = open_files(l, w, err);
    w->wait_for_room = l->o.fast;
    if (rc == ISO_OK && (sem_init(&w->wake, 0, 0) != 0 || sem_init(&w->room, 0, 0) != 0))
        rc = iso_err_set(err, ISO_EIO, -1, "file writer: sem_init: %s", strerror(errno));
    if (rc == ISO_OK && iso_thread_start(&w->th, writer_main, w) != 0)
        rc = iso_err_set(err, ISO_EIO, -1, "file writer: cannot start its thread");
    w->started = rc == ISO_OK;
    if (rc != ISO_OK) {
        (void)!iso_loop__writer_close(w, 0, NULL, NULL);
        return rc;
    }
    *out = w;
    return ISO_OK;
}

int iso_loop__writer_close(iso_loop_writer *w, int commit, iso_loop_summary *counts, iso_err *err)
{
    if (!w)
        return ISO_OK;
    if (w->started) {
        atomic_store(&w->stop, 1);
        sem_post(&w->wake);
        pthread_join(w->th, NULL);
        sem_destroy(&w->wake);
        sem_destroy(&w->room);
        w->started = 0;
    }
    int rc = ISO_OK;
    if (atomic_load(&w->failed)) {
        rc = iso_err_set(err, w->err.code, w->err.offset, "%s", w->err.msg);
        commit = 0; /* the files hold what was written; the error says where it stopped */
    }
    if (w->pc2 && commit) {
        int r = iso_pc2_commit(w->pc2, err);
        rc = rc == ISO_OK ? r : rc;
    } else {
        iso_pc2_destroy(w->pc2);
    }
    w->pc2 = NULL;
    if (w->mcap && commit) {
        int r = iso_mcap_finish(w->mcap, err);
        rc = rc == ISO_OK ? r : rc;
    } else {
        iso_mcap_destroy(w->mcap);
    }
    w->mcap = NULL;
    iso_fox_encoder_destroy(w->enc);
    w->enc = NULL;
    iso_ply_frames_destroy(w->ply);
    w->ply = NULL;
    for (int i = 0; w->slots && i < w->n_slots; i++)
        free(w->slots[i].x);
    free(w->slots);
    w->slots = NULL;
    free(w->prev);
    if (counts)
        iso_loop__writer_counts(w, counts);
    free(w);
    return rc;
}

/* ---- the tick's side ----------------------------------------------------- */

/* What the writer wants of tick `tick`: 0 for nothing. */
static int wanted(const iso_loop_writer *w, long tick)
{
    int want = 0;
    if (w->ply && tick % w->sc->ply.every == 0)
        want |= WANT_PLY;
    for (int i = 0; i < w->sc->display.n_snapshots; i++)
        if (w->sc->display.snapshot_ticks[i] == tick)
            want |= WANT_PNG;
    if (w->pc2 || w->mcap)
        want |= WANT_STREAM;
    return want;
}

iso_sink_frame *iso_loop__writer_slot(iso_loop_writer *w, long tick, int *want)
{
    *want = wanted(w, tick);
    if (!*want)
        return NULL;
    long head = atomic_load_explicit(&w->head, memory_order_relaxed);
    long tail = atomic_load_explicit(&w->tail, memory_order_acquire);
    while (w->wait_for_room && head - tail >= w->n_slots && !atomic_load(&w->failed)) {
        sem_wait(&w->room); /* EINTR or a stale post: look again */
        tail = atomic_load_explicit(&w->tail, memory_order_acquire);
    }
    if (head - tail >= w->n_slots) {
        w->dropped++;
        return NULL;
    }
    slot *s = &w->slots[head % w->n_slots];
    s->want = *want;
    s->f.x = s->x;
    return &s->f;
}

void iso_loop__writer_push(iso_loop_writer *w, const double *x)
{
    long head = atomic_load_explicit(&w->head, memory_order_relaxed);
    slot *s = &w->slots[head % w->n_slots];
    memcpy(s->x, x, (size_t)w->nv * 3 * sizeof *s->x);
    atomic_store_explicit(&w->head, head + 1, memory_order_release);
    sem_post(&w->wake);
}

int iso_loop__writer_check(iso_loop_writer *w, iso_err *err)
{
    if (!w || !atomic_load(&w->failed))
        return ISO_OK;
    return iso_err_set(err, w->err.code, w->err.offset, "%s", w->err.msg);
}

void iso_loop__writer_counts(const iso_loop_writer *w, iso_loop_summary *s)
{
    if (!w)
        return;
    s->ply_frames = atomic_load(&((iso_loop_writer *)w)->ply_written);
    s->snapshots = atomic_load(&((iso_loop_writer *)w)->snapshots);
    s->frames_dropped = w->dropped;
    s->pc2_frames = atomic_load(&((iso_loop_writer *)w)->pc2_frames);
    s->mcap_messages = atomic_load(&((iso_loop_writer *)w)->mcap_messages);
}

long iso_loop__writer_dropped(const iso_loop_writer *w)
{
    return w ? w->dropped : 0;
}
