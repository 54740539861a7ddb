/* controller/cmd_inspect.c -- `isoshape inspect FILE`: a readable dump of a
 * recording: its header, then every record with its raw bytes and what the
 * decoders make of it; damage and a torn end are reported where they are. */
#include "internal.h"

#include <inttypes.h>
#include <stdio.h>
#include <string.h>

#include "iso_dev_decode.h"
#include "iso_dev_rec.h"
#include "iso_dev_view.h"

static const char *type_name(int t)
{
    switch (t) {
    case ISO_DEV_CHUNK_DATA: return "data";
    case ISO_DEV_CHUNK_GONE: return "GONE";
    case ISO_DEV_CHUNK_BACK: return "BACK";
    case ISO_DEV_CHUNK_TICK: return "tick";
    case ISO_DEV_CHUNK_SKIP: return "SKIP";
    default: return "?";
    }
}

static void print_event(const iso_dev_event *e)
{
    switch (e->kind) {
    case ISO_DEV_EV_AXES:
        printf("      axes  t %6d %6d %6d  r %6d %6d %6d\n", e->axes[0], e->axes[1], e->axes[2],
               e->axes[3], e->axes[4], e->axes[5]);
        break;
    case ISO_DEV_EV_BUTTONS: printf("      buttons 0x%08" PRIx32 "\n", e->buttons); break;
    case ISO_DEV_EV_POSE:
    case ISO_DEV_EV_TWIST:
        printf("      %s p %.6g %.6g %.6g  r %.6g %.6g %.6g\n",
               e->kind == ISO_DEV_EV_POSE ? "pose " : "twist", e->v[0], e->v[1], e->v[2], e->v[3],
               e->v[4], e->v[5]);
        break;
    case ISO_DEV_EV_GPIO:
        printf("      %s %s\n", e->line == ISO_DEV_GPIO_ESTOP ? "e-stop" : "clutch",
               e->level ? "active" : "released");
        break;
    case ISO_DEV_EV_TARGET:
        printf("      target handle %u p %.9g %.9g %.9g  r %.9g %.9g %.9g\n", e->line, e->v[0],
               e->v[1], e->v[2], e->v[3], e->v[4], e->v[5]);
        break;
    case ISO_DEV_EV_RELEASE: printf("      control released\n"); break;
    case ISO_DEV_EV_GONE: printf("      device gone\n"); break;
    case ISO_DEV_EV_BACK: printf("      device back\n"); break;
    default: break;
    }
}

/* A view's envelope, as the server wrote it: who, and what (applied or
 * not: the decoded events below say what the loop took). */
static void print_view_chunk(const iso_dev_chunk *c)
{
    static const char *const what[] = {"?", "message", "control granted", "control ended"};
    static const char *const type[] = {"?", "TAKE", "RELEASE", "TARGET", "STOP", "UNSTOP"};
    if (c->len < ISO_DEV_VIEW_ENVELOPE)
        return;
    uint32_t conn = (uint32_t)c->data[1] | (uint32_t)c->data[2] << 8 | (uint32_t)c->data[3] << 16 |
                    (uint32_t)c->data[4] << 24;
    printf("      view: %s, viewer %u", what[c->data[0] <= 3 ? c->data[0] : 0], (unsigned)conn);
    iso_dev_view_msg m;
    if (c->data[0] == ISO_DEV_VIEW_MSG &&
        iso_dev_view_parse(c->data + ISO_DEV_VIEW_ENVELOPE, c->len - ISO_DEV_VIEW_ENVELOPE, &m,
                           NULL, 0) == ISO_OK)
        printf(": %s seq %u, page clock %.3f ms", type[m.type], (unsigned)m.seq, m.page_ms);
    printf("\n");
}

typedef struct inspect_args {
    int raw; /* 1: each data record's bytes */
} inspect_args;

static const iso_cli__opt inspect_options[] = {
    {"no-bytes", ISO_CLI_OPT_FLAG, ISO_CLI_INT_AT(inspect_args, raw), NULL,
     .help = "leave out each record's raw bytes", .flag = 0},
    {0}};

static int inspect_main(int argc, char **argv)
{
    const char *path = NULL;
    inspect_args a = {1};
    int status = iso_cli__parse(&iso_cli__inspect_cmd, argc, argv, &a, &path, 1, NULL);
    if (status >= 0)
        return status;
    if (!path) {
        iso_cli__fail("inspect", "no recording given (isoshape inspect FILE).");
        return 2;
    }
    iso_dev_rec_reader r;
    iso_err err;
    iso_err_clear(&err);
    if (iso_dev_rec_reader_load(&r, path, &err) != ISO_OK) {
        iso_cli__fail("inspect", "%s", err.msg);
        return 1;
    }
    char cut[400];
    int is_cut = iso_dev_rec_reader_cut(&r, cut, sizeof cut, NULL);
    if (is_cut)
        fprintf(stderr, "isoshape inspect: %s: %s\n", path, cut);
    printf("%s: format %u, %zu source(s)\n", path, r.version, r.n_sources);
    static iso_dev_decoder dec[ISO_DEV_MAX_SOURCES];
    int can[ISO_DEV_MAX_SOURCES] = {0};
    for (size_t i = 0; i < r.n_sources; i++) {
        const iso_dev_info *f = &r.infos[i];
        printf("  source %zu: %s \"%s\"", i, iso_dev_kind_name(f->kind), f->name);
        if (f->vid || f->pid)
            printf(" %04x:%04x", f->vid, f->pid);
        if (f->baud)
            printf(" %u %u%c%u", f->baud, f->data_bits, f->parity ? f->parity : '?', f->stop_bits);
        if (f->kind == ISO_DEV_KIND_GPIO)
            printf(" debounce %u us", f->debounce_us);
        if (f->desc_len)
            printf(" report descriptor %u bytes", f->desc_len);
        iso_err e2;
        iso_err_clear(&e2);
        can[i] = iso_dev_decoder_init(&dec[i], f, (uint8_t)i, &e2) == ISO_OK;
        printf("%s%s\n", can[i] ? "" : " -- cannot decode: ", can[i] ? "" : e2.msg);
    }
    iso_dev_chunk c;
    int dmg;
    int64_t t0 = INT64_MIN;
    static iso_dev_event ev[ISO_DEV_EVENTS_PER_CHUNK];
    long ticks = 0;
    while (iso_dev_rec_next(&r, &c, &dmg) == 1) {
        if (dmg)
            printf("! %s\n", r.note);
        if (t0 == INT64_MIN)
            t0 = c.t_ns;
        printf("%10.6f %s", (double)(c.t_ns - t0) * 1e-9, type_name(c.type));
        if (c.type == ISO_DEV_CHUNK_TICK) {
            printf(" %ld\n", ++ticks);
            continue;
        }
        printf(" src %u", c.source);
        if (c.type == ISO_DEV_CHUNK_SKIP && c.len >= 8)
            printf(" noise left out: %u bytes in %u chunks",
                   (unsigned)(c.data[0] | c.data[1] << 8 | c.data[2] << 16 |
                              (unsigned)c.data[3] << 24),
                   (unsigned)(c.data[4] | c.data[5] << 8 | c.data[6] << 16 |
                              (unsigned)c.data[7] << 24));
        if (c.type == ISO_DEV_CHUNK_DATA) {
            printf(" %3u bytes", c.len);
            if (a.raw)
                for (unsigned k = 0; k < c.len; k++)
                    printf("%s%02x", k % 32 == 0 && k ? "\n                          " : " ",
                           c.data[k]);
        }
        printf("\n");
        if (c.type == ISO_DEV_CHUNK_DATA && c.source < r.n_sources &&
            r.infos[c.source].kind == ISO_DEV_KIND_VIEW)
            print_view_chunk(&c);
        if (c.source < r.n_sources && can[c.source]) {
            size_t n = iso_dev_decode(&dec[c.source], &c, ev, ISO_DEV_EVENTS_PER_CHUNK);
            for (size_t k = 0; k < n; k++)
                print_event(&ev[k]);
        }
    }
    if (r.ended)
        printf("end of the recording (its writer closed it)\n");
    printf("%ld records, %ld ticks, %ld damaged\n", r.records, ticks, r.damaged);
    if (is_cut)
        printf("! %s\n", cut);
    else if (r.ended && r.damaged && r.last_damage_at == r.end_at)
        printf("! %s\n", r.note);
    for (size_t i = 0; i < r.n_sources; i++)
        if (can[i]) {
            const iso_dev_counters *n = &dec[i].n;
            printf("  source %zu: %u reports, %u short, %u unknown IDs, %u bad frames, %u "
                   "garbage, %u bounces, %u resyncs, %u bytes not recorded\n",
                   i, n->reports, n->short_reports, n->unknown_ids, n->bad_frames, n->garbage,
                   n->bounces, n->resyncs, n->unrecorded);
        }
    iso_dev_rec_reader_deinit(&r);
    return 0;
}

const iso_cli__cmd iso_cli__inspect_cmd = {
    .name = "inspect",
    .summary = "print a device recording, record by record, decoded",
    .usage = "usage: isoshape inspect FILE [--no-bytes]\n"
             "\n"
             "Prints a recording (devices/RECORDING.md): the header's sources, then\n"
             "every record with its time, source, raw bytes and decoded events.\n"
             "Damaged records are reported with their byte offsets, and a recording cut\n"
             "off (it ends inside a record, or without its END record) says where.\n",
    .opts = inspect_options,
    .main = inspect_main};
