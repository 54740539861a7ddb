/* controller/loop_stats.c -- tick statistics of the real-time loop, and the
 * summary it prints and writes as JSON. The storage is fixed before the
 * first tick (loop_internal.h says how): the tick allocates nothing. */
#include "loop_internal.h"

#include <math.h>
#include <stddef.h>
#include <stdlib.h>
#include <string.h>

#include "iso_json.h"

/* The histogram's bins: bin b holds [HIST_LO g^b, HIST_LO g^(b+1)) ms with
 * g = 1.005; the first and last also hold what lies beyond them. */
#define HIST_LO 1e-4
#define HIST_GROWTH 1.005

void iso_loop__stats_init(iso_loop_stats *s)
{
    memset(s, 0, sizeof *s);
}

void iso_loop__stats_deinit(iso_loop_stats *s)
{
    free(s->tick_ms);
    free(s->lat_ms);
    memset(s, 0, sizeof *s);
}

int iso_loop__stats_reserve(iso_loop_stats *s, long n, iso_err *err)
{
    if (n > ISO_LOOP_SAMPLES_MAX)
        n = ISO_LOOP_SAMPLES_MAX;
    if (n <= s->cap)
        return ISO_OK;
    double *a = realloc(s->tick_ms, (size_t)n * sizeof *a);
    if (a)
        s->tick_ms = a;
    double *b = realloc(s->lat_ms, (size_t)n * sizeof *b);
    if (b)
        s->lat_ms = b;
    if (!a || !b)
        return iso_err_set(err, ISO_ENOMEM, -1, "out of memory for %ld tick samples", n);
    s->cap = n;
    return ISO_OK;
}

static int hist_bin(double ms)
{
    if (!(ms > HIST_LO)) /* also NaN */
        return 0;
    double b = floor(log(ms / HIST_LO) / log(HIST_GROWTH));
    return b >= ISO_LOOP_HIST_BINS - 1 ? ISO_LOOP_HIST_BINS - 1 : (int)b;
}

void iso_loop__stats_add(iso_loop_stats *s, double tick_ms, double lat_ms)
{
    if (s->n < s->cap) {
        s->tick_ms[s->n] = tick_ms;
        s->lat_ms[s->n] = lat_ms;
    }
    s->n++;
    s->hist_tick[hist_bin(tick_ms)]++;
    s->hist_lat[hist_bin(lat_ms)]++;
    s->max_tick_ms = s->n == 1 || tick_ms > s->max_tick_ms ? tick_ms : s->max_tick_ms;
    s->max_lat_ms = s->n == 1 || lat_ms > s->max_lat_ms ? lat_ms : s->max_lat_ms;
    s->last_lat_ms = lat_ms;
    s->recent[s->head] = tick_ms;
    s->head = (s->head + 1) % ISO_LOOP_RECENT;
    if (s->n_recent < ISO_LOOP_RECENT)
        s->n_recent++;
}

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

/* nearest rank: the smallest value with at least q of the samples at or below it */
static long rank_of(long n, double q)
{
    long k = (long)ceil(q * (double)n) - 1;
    return k < 0 ? 0 : k >= n ? n - 1 : k;
}

double iso_loop__quantile(const double *v, long n, double q)
{
    if (n <= 0)
        return NAN;
    double *c = malloc((size_t)n * sizeof *c);
    if (!c)
        return NAN;
    memcpy(c, v, (size_t)n * sizeof *c);
    qsort(c, (size_t)n, sizeof *c, cmp_double);
    double r = c[rank_of(n, q)];
    free(c);
    return r;
}

double iso_loop__stats_quantile(const iso_loop_stats *s, int lat, double q)
{
    if (s->n <= 0)
        return NAN;
    if (q >= 1)
        return lat ? s->max_lat_ms : s->max_tick_ms;
    if (s->n <= s->cap)
        return iso_loop__quantile(lat ? s->lat_ms : s->tick_ms, s->n, q);
    const uint32_t *h = lat ? s->hist_lat : s->hist_tick;
    long k = rank_of(s->n, q), seen = 0;
    for (int b = 0; b < ISO_LOOP_HIST_BINS; b++) {
        seen += h[b];
        if (seen > k) /* the bin's geometric middle: within 0.25 % of any value in it */
            return HIST_LO * pow(HIST_GROWTH, b + 0.5);
    }
    return lat ? s->max_lat_ms : s->max_tick_ms;
}

/* Heap sort in place: qsort may allocate (glibc's merge sort does for more
 * than 1 KiB), and this runs on the tick. */
static void sift_down(double *a, long i, long n)
{
    for (;;) {
        long c = 2 * i + 1;
        if (c >= n)
            return;
        if (c + 1 < n && a[c + 1] > a[c])
            c++;
        if (!(a[c] > a[i]))
            return;
        double t = a[i];
        a[i] = a[c];
        a[c] = t;
        i = c;
    }
}

static void heap_sort(double *a, long n)
{
    for (long i = n / 2 - 1; i >= 0; i--)
        sift_down(a, i, n);
    for (long e = n - 1; e > 0; e--) {
        double t = a[0];
        a[0] = a[e];
        a[e] = t;
        sift_down(a, 0, e);
    }
}

void iso_loop__stats_recent(iso_loop_stats *s, double *med, double *p99, double *max)
{
    long n = s->n_recent;
    if (n <= 0) {
        *med = *p99 = *max = NAN;
        return;
    }
    memcpy(s->scratch, s->recent, (size_t)n * sizeof *s->scratch);
    heap_sort(s->scratch, n);
    *med = s->scratch[rank_of(n, 0.5)];
    *p99 = s->scratch[rank_of(n, 0.99)];
    *max = s->scratch[n - 1];
}

/* ---- the summary ---------------------------------------------------------- */

/* Prints `text` after a label column, a new line for each "; "-separated
 * part, and a part wrapped at ", " to stay within SUMMARY_WIDTH columns
 * (never inside parentheses). A leading "LABEL: " is the label again and
 * goes. */
enum { SUMMARY_INDENT = 14, SUMMARY_WIDTH = 100 };
static void print_wrapped(FILE *f, const char *label, const char *text)
{
    size_t ll = strlen(label);
    if (strncmp(text, label, ll) == 0 && strncmp(text + ll, ": ", 2) == 0)
        text += ll + 2;
    int col = fprintf(f, "  %-*s", SUMMARY_INDENT - 2, label);
    while (*text) {
        size_t n = 0;
        for (int depth = 0; text[n]; n++) {
            depth += text[n] == '(' ? 1 : text[n] == ')' ? -1 : 0;
            if (depth == 0 && (text[n] == ',' || text[n] == ';') && text[n + 1] == ' ')
                break;
        }
        int len = (int)n + (text[n] == ','); /* a comma stays with its item */
        if (col > SUMMARY_INDENT && col + 1 + len > SUMMARY_WIDTH)
            col = fprintf(f, "\n%*s", SUMMARY_INDENT, "") - 1;
        else if (col > SUMMARY_INDENT)
            col += fprintf(f, " ");
        col += fprintf(f, "%.*s", len, text);
        char sep = text[n];
        text += n + (sep ? 2 : 0);
        if (sep == ';' && *text)
            col = fprintf(f, "\n%*s", SUMMARY_INDENT, "") - 1;
    }
    fputc('\n', f);
}

void iso_loop_print_summary(const iso_loop_summary *s, const iso_scene *sc, FILE *f)
{
    fprintf(f, "scene %s: %ld ticks, %.3f s of stream time in %.3f s wall (%.1f ticks/s)\n",
            sc->name, s->ticks, s->stream_s, s->wall_s,
            s->wall_s > 0 ? (double)s->ticks / s->wall_s : 0.0);
    fprintf(f, "  tick time   median %.2f ms, p99 %.2f ms, max %.2f ms (period %.2f ms)\n",
            s->tick_median, s->tick_p99, s->tick_max, s->period_ms);
    fprintf(f,
            "  latency     median %.2f ms, p90 %.2f ms, p99 %.2f ms, max %.2f ms (input due to "
            "published)\n",
            s->latency_median, s->latency_p90, s->latency_p99, s->latency_max);
    long periods = s->ticks + s->skipped;
    fprintf(f,
            "  deadlines   %ld of %ld passed without a tick of their own (%.2f%%)\n"
            "              caught up by %ld late ticks; longest wait between ticks %.2f ms\n",
            s->skipped, periods, periods ? 100.0 * (double)s->skipped / (double)periods : 0.0,
            s->misses, s->gap_max_ms);
    fprintf(f,
            "  integrator  %d steps (%d low-order, %ld restarts, ABM3 %s), %ld field evaluations, "
            "at most %d a step\n",
            s->integ.steps, s->integ.low_order_steps, s->restarts,
            iso_abm_mode_name((iso_abm_mode)sc->abm_mode), s->integ.evaluations,
            s->integ.max_step_evaluations);
    double ev = s->solver.evaluations > 0 ? (double)s->solver.evaluations : NAN;
    fprintf(
        f,
        "  solver      per evaluation: assembly %.2f ms, factor %.2f ms, solve %.2f ms\n"
        "              %ld factorizations, %ld CG iterations (at most %ld a step, %ld capped)\n",
        1e3 * s->solver.t_assembly / ev, 1e3 * s->solver.t_factor / ev,
        1e3 * s->solver.t_solve / ev, s->solver.factorizations, s->solver.cg_iterations,
        s->integ.max_step_cg_iterations, s->solver.cg_capped);
    if (s->proxy_vertices > 0)
        fprintf(f,
                "              reduced model: the method on a proxy of %d vertices (built in "
                "%.2f s), the %d of the mesh following it; its fit %.1f CG iterations a "
                "tick, at most %ld%s\n",
                s->proxy_vertices, s->proxy_build_s, iso_mesh_vertex_count(sc->mesh),
                s->proxy.prolongations ? (double)s->proxy.fit_iterations / s->proxy.prolongations
                                       : 0.0,
                s->proxy.fit_max_iterations,
                s->proxy.fit_failures ? ", FAILED (the prolongation stood) in some" : "");
    if (sc->solver.worker_lag > 0)
        fprintf(f,
                "              worker lag %d: %ld factors handed over, %.1f s factoring, "
                "waits %.2f ms/evaluation\n",
                sc->solver.worker_lag, s->solver.handovers, s->solver.t_worker,
                1e3 * s->solver.t_wait / ev);
    if (sc->solver.worker_lag > 0) /* bounded solves (iso_solver_set_bounded) */
        fprintf(f,
                "              %ld solves ended inexact at the tick's budget (worst relative "
                "residual %.1e), %ld factorizations on the tick (a residual above %g)\n",
                s->solver.inexact, s->solver.inexact_res_max, s->solver.refactors,
                ISO_SOLVER_BOUNDED_RES);
    fprintf(f, "  distortion  of the mesh against its rest pose (e' and e: an edge now and at "
               "rest)\n");
    iso_metrics_print(f, "    ", &s->metrics);
    for (int h = 0; h < s->n_handles; h++)
        fprintf(f, "  handle %d    '%s' at %.6g %.6g %.6g\n", h, sc->handles[h].name,
                s->handle_p[h][0], s->handle_p[h][1], s->handle_p[h][2]);
    for (int i = 0; i < s->n_devices; i++) {
        const iso_dev_source_stats *d = &s->device[i];
        fprintf(f,
                "  device %d    %s\n"
                "              %u events, %u bad frames, %u garbage bytes, %u resyncs, gone %u, "
                "back %u, stale %u\n",
                i, s->device_desc[i], d->events, d->dec.bad_frames, d->dec.garbage, d->dec.resyncs,
                d->gone, d->back, d->stale);
        if (d->dec.unrecorded)
            fprintf(f, "              %u noise bytes left out of the recording (its cap)\n",
                    d->dec.unrecorded);
    }
    if (sc->display.enabled || s->frames_sent)
        fprintf(f, "  display     %ld frames sent\n", s->frames_sent);
    if (s->view_device)
        fprintf(f,
                "  view        %u commands taken, %u refused, %u malformed, %u dropped; control "
                "taken %u times, %u stops\n",
                s->view_accepted, s->view_refused, s->view_malformed, s->view_dropped,
                s->view_grants, s->view_stops);
    if (s->ply_frames || s->snapshots)
        fprintf(f, "  files       %ld PLY frames, %ld PNG snapshots\n", s->ply_frames,
                s->snapshots);
    if (s->pc2_frames || s->mcap_messages)
        fprintf(f, "  streams     %ld PC2 frames, %ld MCAP messages\n", s->pc2_frames,
                s->mcap_messages);
    if (s->handoff_ms_max > 0)
        fprintf(f,
                "  writer      the tick's hand-off of its frame: mean %.3f ms, max %.3f ms (the "
                "writer thread encodes and writes)\n",
                s->handoff_ms_mean, s->handoff_ms_max);
    if (s->frames_dropped)
        fprintf(f,
                "  dropped     %ld ticks not written to files (the disk was slower than the "
                "loop)\n",
                s->frames_dropped);
    if (s->act_line[0])
        print_wrapped(f, "actuators", s->act_line);
    fprintf(f, "  realtime    %s\n",
            s->rt_active ? "SCHED_FIFO" : (s->rt_note[0] ? s->rt_note : "off (--fast or --no-rt)"));
    fprintf(f, "  vertices checksum %016llx\n", (unsigned long long)s->checksum);
}

/* The devices' counters, each under its field's name. */
#define DEC(f) ISO_JSON_FIELD(iso_dev_counters, f, ISO_JSON_U32)
#define DROP(f) ISO_JSON_FIELD(iso_dev_frame_drops, f, ISO_JSON_U32)
#define SRC(f) ISO_JSON_FIELD(iso_dev_source_stats, f, ISO_JSON_U32)
static const iso_json_field dec_counters[] = {
    {DEC(reports)},     {DEC(bad_frames)},   {DEC(garbage)}, {DEC(short_reports)},
    {DEC(unknown_ids)}, {DEC(bad_payloads)}, {DEC(resyncs)}, {DEC(unrecorded)},
    {DEC(refused)},     {DEC(out_of_order)}, {DEC(grants)},  {DEC(releases)}};
static const iso_json_field drop_counters[] = {
    {DROP(too_long)},     {DROP(bad_cobs)},   {DROP(too_short)},    {DROP(bad_crc)},
    {DROP(bad_version)},  {DROP(bad_length)}, {DROP(unknown_type)}, {DROP(duplicate)},
    {DROP(out_of_order)}, {DROP(seq_gaps)}};
static const iso_json_field src_counters[] = {{SRC(gone)}, {SRC(back)}, {SRC(stale)}};

/* The actuator sink's counters (iso_act_stats), one number each, under
 * their field's names: the summary line says the same for people. */
#define ACT(f, t) ISO_JSON_FIELD(iso_act_stats, f, ISO_JSON_##t)
static const iso_json_field act_counters[] = {{ACT(ticks, U64)},
                                              {ACT(setpoints_sent, U64)},
                                              {ACT(acks, U64)},
                                              {ACT(echo_mismatches, U64)},
                                              {ACT(echo_unknown, U64)},
                                              {ACT(clamps, U64)},
                                              {ACT(link_losses, U32)},
                                              {ACT(reopens, U32)},
                                              {ACT(emu_restarts, U32)},
                                              {ACT(faults, U32)},
                                              {ACT(last_fault_reason, U32)},
                                              {ACT(last_fault_detail_ms, U32)},
                                              {ACT(naks, U32)},
                                              {ACT(handshakes, U32)},
                                              {ACT(heartbeats, U32)},
                                              {ACT(loop_stalls, U32)},
                                              {ACT(estops, U32)},
                                              {ACT(silences, U32)},
                                              {ACT(safe_requests, U32)},
                                              {ACT(safe_confirms, U32)},
                                              {ACT(last_safe_ms, DOUBLE)},
                                              {ACT(last_safe_cause, INT)},
                                              {ACT(rtt_count, U32)},
                                              {ACT(rtt_avg_ms, DOUBLE)},
                                              {ACT(rtt_min_ms, DOUBLE)},
                                              {ACT(rtt_max_ms, DOUBLE)},
                                              {ACT(rtt_last_ms, DOUBLE)},
                                              {ACT(publish_max_ms, DOUBLE)},
                                              {ACT(publish_over_1ms, U64)},
                                              {ACT(alive_calls, U64)},
                                              {ACT(mcu_channels, INT)},
                                              {ACT(mcu_state, INT)},
                                              {ACT(mcu_uptime_ms, U32)}};
#define N_OF(a) (sizeof(a) / sizeof(a)[0])

/* The actuators' counters and the line that says them, or null without
 * actuators. */
static void json_actuators(iso_json *j, const iso_loop_summary *s)
{
    if (!s->has_act) {
        iso_json_string(j, "actuators", NULL);
        return;
    }
    iso_json_object(j, "actuators");
    iso_json_fields(j, &s->act, act_counters, N_OF(act_counters));
    iso_json_array(j, "clamps_by_channel");
    for (int c = 0; c < ISO_ACT_MAX_CHANNELS; c++)
        iso_json_int(j, NULL, (long long)s->act.clamps_ch[c]);
    iso_json_close(j);
    iso_json_array(j, "mcu_positions");
    for (int c = 0; c < ISO_ACT_MAX_CHANNELS; c++)
        iso_json_int(j, NULL, s->act.mcu_pos[c]);
    iso_json_close(j);
    iso_json_string(j, "line", s->act_line);
    iso_json_close(j);
}

static void json_device(iso_json *j, const char *desc, const iso_dev_source_stats *d)
{
    iso_json_object(j, NULL);
    iso_json_string(j, "device", desc);
    iso_json_int(j, "events", d->events);
    iso_json_fields(j, &d->dec, dec_counters, N_OF(dec_counters));
    iso_json_object(j, "drops");
    iso_json_fields(j, &d->drops, drop_counters, N_OF(drop_counters));
    iso_json_close(j);
    iso_json_fields(j, d, src_counters, N_OF(src_counters));
    iso_json_close(j);
}

/* median, p90 (where given: not NaN), p99 and max of one distribution, in
 * an object of its own */
static void json_spread(iso_json *j, const char *key, double med, double p90, double p99,
                        double max)
{
    iso_json_object(j, key);
    iso_json_number(j, "median", med);
    if (!isnan(p90))
        iso_json_number(j, "p90", p90);
    iso_json_number(j, "p99", p99);
    iso_json_number(j, "max", max);
    iso_json_close(j);
}

/* n counters, keys[i] holding v[i], in that order. */
static void json_counts(iso_json *j, const char *const *keys, const long long *v, size_t n)
{
    for (size_t i = 0; i < n; i++)
        iso_json_int(j, keys[i], v[i]);
}

static void json_summary(iso_json *j, const iso_loop_summary *s, const iso_scene *sc)
{
    iso_json_string(j, "scene", sc->name);
    iso_json_int(j, "ticks", s->ticks);
    iso_json_number(j, "stream_s", s->stream_s);
    iso_json_number(j, "wall_s", s->wall_s);
    iso_json_number(j, "period_ms", s->period_ms);
    json_spread(j, "tick_ms", s->tick_median, NAN, s->tick_p99, s->tick_max);
    json_spread(j, "latency_ms", s->latency_median, s->latency_p90, s->latency_p99, s->latency_max);
    iso_json_int(j, "misses", s->misses);
    iso_json_int(j, "skipped", s->skipped);
    iso_json_number(j, "gap_max_ms", s->gap_max_ms);
    iso_json_int(j, "restarts", s->restarts);
    iso_json_int(j, "steps", s->integ.steps);
    iso_json_int(j, "rk4_steps", s->integ.rk4_steps);
    iso_json_string(j, "abm", iso_abm_mode_name((iso_abm_mode)sc->abm_mode));
    iso_json_int(j, "evaluations", s->integ.evaluations);
    iso_json_int(j, "low_order_steps", s->integ.low_order_steps);
    iso_json_int(j, "max_step_evaluations", s->integ.max_step_evaluations);
    iso_json_int(j, "max_step_cg_iterations", s->integ.max_step_cg_iterations);
    iso_json_object(j, "solver");
    iso_json_int(j, "factorizations", s->solver.factorizations);
    iso_json_int(j, "cg_iterations", s->solver.cg_iterations);
    iso_json_int(j, "factor_solves", s->solver.factor_solves);
    iso_json_int(j, "proxy_vertices", s->proxy_vertices);
    iso_json_number(j, "proxy_build_s", s->proxy_build_s);
    iso_json_int(j, "proxy_fit_iterations", s->proxy.fit_iterations);
    iso_json_int(j, "proxy_fit_max_iterations", s->proxy.fit_max_iterations);
    iso_json_int(j, "proxy_fit_failures", s->proxy.fit_failures);
    iso_json_int(j, "cg_capped", s->solver.cg_capped);
    iso_json_int(j, "refactors", s->solver.refactors);
    iso_json_int(j, "inexact", s->solver.inexact);
    iso_json_number(j, "inexact_res_max", s->solver.inexact_res_max);
    iso_json_number(j, "assembly_s", s->solver.t_assembly);
    iso_json_number(j, "factor_s", s->solver.t_factor);
    iso_json_number(j, "solve_s", s->solver.t_solve);
    iso_json_int(j, "worker_handovers", s->solver.handovers);
    iso_json_number(j, "worker_s", s->solver.t_worker);
    iso_json_number(j, "worker_wait_s", s->solver.t_wait);
    iso_json_close(j);
    iso_json_object(j, "metrics");
    size_t n;
    const iso_metrics_measure *k = iso_metrics_measures(&n);
    for (size_t i = 0; i < n; i++)
        iso_json_number(j, k[i].key, iso_metrics_value(&s->metrics, &k[i]));
    iso_json_close(j);
    iso_json_array(j, "handles");
    for (int h = 0; h < s->n_handles; h++) {
        iso_json_object(j, NULL);
        iso_json_string(j, "name", sc->handles[h].name);
        iso_json_array(j, "p");
        for (int c = 0; c < 3; c++)
            iso_json_number(j, NULL, s->handle_p[h][c]);
        iso_json_close(j);
        iso_json_close(j);
    }
    iso_json_close(j);
    iso_json_array(j, "devices");
    for (int i = 0; i < s->n_devices; i++)
        json_device(j, s->device_desc[i], &s->device[i]);
    iso_json_close(j);
    iso_json_object(j, "late_ticks");
    iso_json_int(j, "substeps", s->substeps);
    iso_json_int(j, "coarse", s->coarse);
    iso_json_close(j);
    iso_json_int(j, "frames_sent", s->frames_sent);
    if (s->view_device) { /* the page's commands, as the view's server took them */
        static const char *const keys[] = {"accepted", "refused", "malformed",
                                           "dropped",  "grants",  "stops"};
        const long long v[] = {s->view_accepted, s->view_refused, s->view_malformed,
                               s->view_dropped,  s->view_grants,  s->view_stops};
        iso_json_object(j, "view");
        json_counts(j, keys, v, 6);
        iso_json_close(j);
    }
    static const char *const files[] = {"ply_frames", "snapshots", "pc2_frames", "mcap_messages",
                                        "frames_dropped"};
    const long long nf[] = {s->ply_frames, s->snapshots, s->pc2_frames, s->mcap_messages,
                            s->frames_dropped};
    json_counts(j, files, nf, 5);
    iso_json_object(j, "writer_handoff_ms");
    iso_json_number(j, "mean", s->handoff_ms_mean);
    iso_json_number(j, "max", s->handoff_ms_max);
    iso_json_close(j);
    iso_json_bool(j, "realtime", s->rt_active);
    iso_json_bool(j, "memory_locked", s->mem_locked);
    json_actuators(j, s);
    char sum[17];
    snprintf(sum, sizeof sum, "%016llx", (unsigned long long)s->checksum);
    iso_json_string(j, "checksum", sum);
}

int iso_loop_write_json(const iso_loop_summary *s, const iso_scene *sc, const char *path,
                        iso_err *err)
{
    FILE *f = fopen(path, "w");
    if (!f)
        return iso_err_set(err, ISO_EIO, -1, "--stats-json %s: cannot write it", path);
    iso_json j;
    iso_json_begin(&j, f);
    json_summary(&j, s, sc);
    int bad = iso_json_end(&j);
    if (fclose(f) != 0 || bad)
        return iso_err_set(err, ISO_EIO, -1, "--stats-json %s: write failed", path);
    return ISO_OK;
}
