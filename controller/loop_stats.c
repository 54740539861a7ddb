/* controller/loop_stats.c -- tick statistics of the real-time loop, and the
 * summary it prints and writes as JSON. Samples are kept whole rather than
 * in a histogram: quantiles are exact, and a long run costs 16 bytes a tick. */
#include "loop_internal.h"

#include <math.h>
#include <stddef.h>
#include <stdlib.h>
#include <string.h>

#include "iso_json.h"

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

/* Grows the sample arrays to hold at least n ticks. */
static int stats_grow(iso_loop_stats *s, long n, iso_err *err)
{
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

int iso_loop__stats_reserve(iso_loop_stats *s, long n, iso_err *err)
{
    return stats_grow(s, n, err);
}

int iso_loop__stats_add(iso_loop_stats *s, double tick_ms, double lat_ms, iso_err *err)
{
    if (s->n == s->cap) {
        int rc = stats_grow(s, s->cap ? 2 * s->cap : 4096, err);
        if (rc != ISO_OK)
            return rc;
    }
    s->tick_ms[s->n] = tick_ms;
    s->lat_ms[s->n] = lat_ms;
    s->n++;
    s->recent[s->head] = tick_ms;
    s->head = (s->head + 1) % (int)(sizeof s->recent / sizeof s->recent[0]);
    if (s->n_recent < (int)(sizeof s->recent / sizeof s->recent[0]))
        s->n_recent++;
    return ISO_OK;
}

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
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
    /* nearest rank: the smallest value with at least q of the samples at or below it */
    long k = (long)ceil(q * (double)n) - 1;
    if (k < 0)
        k = 0;
    if (k >= n)
        k = n - 1;
    double r = c[k];
    free(c);
    return r;
}

void iso_loop__stats_recent(const iso_loop_stats *s, double *med, double *p99, double *max)
{
    *med = iso_loop__quantile(s->recent, s->n_recent, 0.5);
    *p99 = iso_loop__quantile(s->recent, s->n_recent, 0.99);
    *max = iso_loop__quantile(s->recent, s->n_recent, 1.0);
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
    fprintf(f, "  latency     median %.2f ms, p99 %.2f ms, max %.2f ms (input due to published)\n",
            s->latency_median, s->latency_p99, s->latency_max);
    fprintf(f, "  deadlines   %ld missed of %ld (%.2f%%), %ld skipped to catch up\n", s->misses,
            s->ticks, s->ticks ? 100.0 * (double)s->misses / (double)s->ticks : 0.0, s->skipped);
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
                "%.2f s), the %d of the mesh following it\n",
                s->proxy_vertices, s->proxy_build_s, iso_mesh_vertex_count(sc->mesh));
    if (sc->solver.worker_lag > 0)
        fprintf(f,
                "              worker lag %d: %ld factors handed over, %.1f s factoring, "
                "waits %.2f ms/evaluation\n",
                sc->solver.worker_lag, s->solver.handovers, s->solver.t_worker,
                1e3 * s->solver.t_wait / ev);
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
                "              %u events, %u bad frames, %u garbage bytes, gone %u, back %u, "
                "stale %u\n",
                i, s->device_desc[i], d->events, d->dec.bad_frames, d->dec.garbage, d->gone,
                d->back, d->stale);
    }
    if (sc->display.enabled || s->frames_sent)
        fprintf(f, "  display     %ld frames sent\n", s->frames_sent);
    if (s->ply_frames || s->snapshots)
        fprintf(f, "  files       %ld PLY frames, %ld PNG snapshots\n", s->ply_frames,
                s->snapshots);
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
static const iso_json_field dec_counters[] = {{DEC(reports)},     {DEC(bad_frames)},
                                              {DEC(garbage)},     {DEC(short_reports)},
                                              {DEC(unknown_ids)}, {DEC(bad_payloads)}};
static const iso_json_field drop_counters[] = {
    {DROP(too_long)},     {DROP(bad_cobs)},   {DROP(too_short)},    {DROP(bad_crc)},
    {DROP(bad_version)},  {DROP(bad_length)}, {DROP(unknown_type)}, {DROP(duplicate)},
    {DROP(out_of_order)}, {DROP(seq_gaps)}};
static const iso_json_field src_counters[] = {{SRC(gone)}, {SRC(back)}, {SRC(stale)}};
#define N_OF(a) (sizeof(a) / sizeof(a)[0])

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

/* median, p99 and max of one distribution, in an object of its own */
static void json_spread(iso_json *j, const char *key, double med, double p99, double max)
{
    iso_json_object(j, key);
    iso_json_number(j, "median", med);
    iso_json_number(j, "p99", p99);
    iso_json_number(j, "max", max);
    iso_json_close(j);
}

static void json_summary(iso_json *j, const iso_loop_summary *s, const iso_scene *sc)
{
    iso_json_string(j, "scene", sc->name);
    iso_json_int(j, "ticks", s->ticks);
    iso_json_number(j, "stream_s", s->stream_s);
    iso_json_number(j, "wall_s", s->wall_s);
    iso_json_number(j, "period_ms", s->period_ms);
    json_spread(j, "tick_ms", s->tick_median, s->tick_p99, s->tick_max);
    json_spread(j, "latency_ms", s->latency_median, s->latency_p99, s->latency_max);
    iso_json_int(j, "misses", s->misses);
    iso_json_int(j, "skipped", s->skipped);
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
    iso_json_int(j, "cg_capped", s->solver.cg_capped);
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
    iso_json_int(j, "ply_frames", s->ply_frames);
    iso_json_int(j, "snapshots", s->snapshots);
    iso_json_bool(j, "realtime", s->rt_active);
    iso_json_bool(j, "memory_locked", s->mem_locked);
    iso_json_string(j, "actuators", s->act_line);
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
