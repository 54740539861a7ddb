/* controller/loop_stats.c -- tick statistics of the real-time loop, and the
 * summary it prints and writes as JSON. Samples are kept whole rather than
 * in a histogram: quantiles are exact, and a long run costs 16 bytes a tick. */
#include "loop_internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

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
    fprintf(f,
            "  solver      per evaluation: assembly %.2f ms, factor %.2f ms, solve %.2f ms\n"
            "              %ld factorizations, %ld CG iterations (at most %ld a step, %ld capped)\n",
            1e3 * s->solver.t_assembly / ev, 1e3 * s->solver.t_factor / ev,
            1e3 * s->solver.t_solve / ev, s->solver.factorizations, s->solver.cg_iterations,
            s->integ.max_step_cg_iterations, s->solver.cg_capped);
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

/* JSON numbers: non-finite values become null (JSON has no NaN). */
static void num(FILE *f, const char *key, double v, int comma)
{
    if (isfinite(v))
        fprintf(f, "\"%s\": %.17g%s", key, v, comma ? ", " : "");
    else
        fprintf(f, "\"%s\": null%s", key, comma ? ", " : "");
}

static void json_string(FILE *f, const char *s)
{
    fputc('"', f);
    for (; *s; s++) {
        unsigned char c = (unsigned char)*s;
        if (c == '"' || c == '\\')
            fprintf(f, "\\%c", c);
        else if (c < 0x20)
            fprintf(f, "\\u%04x", c);
        else
            fputc(c, f);
    }
    fputc('"', f);
}

int iso_loop_write_json(const iso_loop_summary *s, const iso_scene *sc, const char *path,
                        iso_err *err)
{
    FILE *f = fopen(path, "w");
    if (!f)
        return iso_err_set(err, ISO_EIO, -1, "--stats-json %s: cannot write it", path);
    fprintf(f, "{\"scene\": ");
    json_string(f, sc->name);
    fprintf(f, ", \"ticks\": %ld, ", s->ticks);
    num(f, "stream_s", s->stream_s, 1);
    num(f, "wall_s", s->wall_s, 1);
    num(f, "period_ms", s->period_ms, 1);
    fprintf(f, "\n \"tick_ms\": {");
    num(f, "median", s->tick_median, 1);
    num(f, "p99", s->tick_p99, 1);
    num(f, "max", s->tick_max, 0);
    fprintf(f, "},\n \"latency_ms\": {");
    num(f, "median", s->latency_median, 1);
    num(f, "p99", s->latency_p99, 1);
    num(f, "max", s->latency_max, 0);
    fprintf(f, "},\n \"misses\": %ld, \"skipped\": %ld, \"restarts\": %ld, ", s->misses, s->skipped,
            s->restarts);
    fprintf(f, "\"steps\": %d, \"rk4_steps\": %d, \"abm\": \"%s\", \"evaluations\": %ld,\n",
            s->integ.steps, s->integ.rk4_steps, iso_abm_mode_name((iso_abm_mode)sc->abm_mode),
            s->integ.evaluations);
    fprintf(f, " \"low_order_steps\": %d, \"max_step_evaluations\": %d, ", s->integ.low_order_steps,
            s->integ.max_step_evaluations);
    fprintf(f, "\"max_step_cg_iterations\": %ld,\n", s->integ.max_step_cg_iterations);
    fprintf(f, " \"solver\": {\"factorizations\": %ld, \"cg_iterations\": %ld, ",
            s->solver.factorizations, s->solver.cg_iterations);
    fprintf(f, "\"cg_capped\": %ld, ", s->solver.cg_capped);
    num(f, "assembly_s", s->solver.t_assembly, 1);
    num(f, "factor_s", s->solver.t_factor, 1);
    num(f, "solve_s", s->solver.t_solve, 0);
    fprintf(f, "},\n \"metrics\": {");
    num(f, "metric_err", s->metrics.metric_err, 1);
    num(f, "area_err", s->metrics.area_err, 1);
    num(f, "angle_err", s->metrics.angle_err, 1);
    num(f, "max_edge_strain", s->metrics.max_edge_strain, 1);
    num(f, "rms_edge_strain", s->metrics.rms_edge_strain, 0);
    fprintf(f, "},\n \"handles\": [");
    for (int h = 0; h < s->n_handles; h++) {
        fprintf(f, "%s{\"name\": ", h ? ", " : "");
        json_string(f, sc->handles[h].name);
        fprintf(f, ", \"p\": [%.17g, %.17g, %.17g]}", s->handle_p[h][0], s->handle_p[h][1],
                s->handle_p[h][2]);
    }
    fprintf(f, "],\n \"devices\": [");
    for (int i = 0; i < s->n_devices; i++) {
        const iso_dev_source_stats *d = &s->device[i];
        const iso_dev_frame_drops *x = &d->drops;
        fprintf(f, "%s{\"device\": ", i ? ", " : "");
        json_string(f, s->device_desc[i]);
        fprintf(f,
                ", \"events\": %u, \"reports\": %u, \"bad_frames\": %u, \"garbage\": %u, "
                "\"short_reports\": %u, \"unknown_ids\": %u, \"bad_payloads\": %u, "
                "\"drops\": {\"too_long\": %u, \"bad_cobs\": %u, \"too_short\": %u, "
                "\"bad_crc\": %u, \"bad_version\": %u, \"bad_length\": %u, "
                "\"unknown_type\": %u, \"duplicate\": %u, \"out_of_order\": %u, "
                "\"seq_gaps\": %u}, \"gone\": %u, \"back\": %u, \"stale\": %u}",
                d->events, d->dec.reports, d->dec.bad_frames, d->dec.garbage, d->dec.short_reports,
                d->dec.unknown_ids, d->dec.bad_payloads, x->too_long, x->bad_cobs, x->too_short,
                x->bad_crc, x->bad_version, x->bad_length, x->unknown_type, x->duplicate,
                x->out_of_order, x->seq_gaps, d->gone, d->back, d->stale);
    }
    fprintf(f, "],\n \"late_ticks\": {\"substeps\": %ld, \"coarse\": %ld}, ", s->substeps,
            s->coarse);
    fprintf(f, "\"frames_sent\": %ld, \"ply_frames\": %ld, \"snapshots\": %ld, ", s->frames_sent,
            s->ply_frames, s->snapshots);
    fprintf(f, "\"realtime\": %s, \"memory_locked\": %s, ", s->rt_active ? "true" : "false",
            s->mem_locked ? "true" : "false");
    fprintf(f, "\"actuators\": ");
    json_string(f, s->act_line);
    fprintf(f, ",\n \"checksum\": \"%016llx\"}\n", (unsigned long long)s->checksum);
    if (fclose(f) != 0)
        return iso_err_set(err, ISO_EIO, -1, "--stats-json %s: write failed", path);
    return ISO_OK;
}
