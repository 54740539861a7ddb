/* sinks/foxglove_encode.c -- a session's channels in Foxglove's JSON schemas (see
 * iso_foxglove.h). The schemas below are written from Foxglove's published
 * message definitions, reduced to the fields these messages fill. */
#include "iso_foxglove.h"

#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "iso_snapshot.h"

/* ---- schemas ------------------------------------------------------------ */

#define TIME_SCHEMA                                                                                \
    "{\"type\":\"object\",\"properties\":{\"sec\":{\"type\":\"integer\",\"minimum\":0},"           \
    "\"nsec\":{\"type\":\"integer\",\"minimum\":0,\"maximum\":999999999}}}"
#define VEC3_SCHEMA                                                                                \
    "{\"type\":\"object\",\"properties\":{\"x\":{\"type\":\"number\"},\"y\":{\"type\":\"number\"}" \
    ","                                                                                            \
    "\"z\":{\"type\":\"number\"}}}"
#define QUAT_SCHEMA                                                                                \
    "{\"type\":\"object\",\"properties\":{\"x\":{\"type\":\"number\"},\"y\":{\"type\":\"number\"}" \
    ","                                                                                            \
    "\"z\":{\"type\":\"number\"},\"w\":{\"type\":\"number\"}}}"
#define COLOR_SCHEMA                                                                               \
    "{\"type\":\"object\",\"properties\":{\"r\":{\"type\":\"number\"},\"g\":{\"type\":\"number\"}" \
    ","                                                                                            \
    "\"b\":{\"type\":\"number\"},\"a\":{\"type\":\"number\"}}}"
#define ARRAY_OF(s) "{\"type\":\"array\",\"items\":" s "}"
#define ANY_ARRAY "{\"type\":\"array\"}"

static const char scene_update_schema[] =
    "{\"title\":\"foxglove.SceneUpdate\",\"type\":\"object\",\"properties\":{"
    "\"deletions\":" ANY_ARRAY ",\"entities\":" ARRAY_OF(
        "{\"type\":\"object\",\"properties\":{\"timestamp\":" TIME_SCHEMA
        ",\"frame_id\":{\"type\":\"string\"},\"id\":{\"type\":\"string\"},\"lifetime\":" TIME_SCHEMA
        ",\"frame_locked\":{\"type\":\"boolean\"},\"metadata\":" ANY_ARRAY ",\"arrows\":" ANY_ARRAY
        ",\"cubes\":" ANY_ARRAY ",\"spheres\":" ANY_ARRAY ",\"cylinders\":" ANY_ARRAY
        ",\"lines\":" ANY_ARRAY ",\"triangles\":" ARRAY_OF(
            "{\"title\":\"foxglove.TriangleListPrimitive\",\"type\":\"object\",\"properties\":{"
            "\"pose\":{\"type\":\"object\",\"properties\":{\"position\":" VEC3_SCHEMA
            ",\"orientation\":" QUAT_SCHEMA "}},\"points\":" ARRAY_OF(
                VEC3_SCHEMA) ",\"color\":" COLOR_SCHEMA
                             ",\"colors\":" ARRAY_OF(COLOR_SCHEMA) ",\"indices\":" ARRAY_OF(
                                 "{\"type\":\"integer\",\"minimum\":0}") "}}") ",\"texts\""
                                                                               ":" ANY_ARRAY
                                                                               ",\"models\""
                                                                               ":" ANY_ARRAY
                                                                               "}}") "}}";

static const char frame_transform_schema[] =
    "{\"title\":\"foxglove.FrameTransform\",\"type\":\"object\",\"properties\":{"
    "\"timestamp\":" TIME_SCHEMA ",\"parent_frame_id\":{\"type\":\"string\"},"
    "\"child_frame_id\":{\"type\":\"string\"},\"translation\":" VEC3_SCHEMA
    ",\"rotation\":" QUAT_SCHEMA "}}";

static const char tick_schema[] =
    "{\"title\":\"isoshape.Tick\",\"description\":\"One tick of the isoshape loop\","
    "\"type\":\"object\",\"properties\":{\"timestamp\":" TIME_SCHEMA
    ",\"tick\":{\"type\":\"integer\"},\"dt_s\":{\"type\":\"number\"},"
    "\"substeps\":{\"type\":\"integer\"},\"merged\":{\"type\":\"integer\"},"
    "\"restart\":{\"type\":\"boolean\"},\"active_handle\":{\"type\":\"integer\"},"
    "\"clutch\":{\"type\":\"boolean\"},\"estop\":{\"type\":\"boolean\"},"
    "\"buttons\":{\"type\":\"integer\"},\"evaluations\":{\"type\":\"integer\"},"
    "\"factorizations\":{\"type\":\"integer\"},\"cg_iterations\":{\"type\":\"integer\"},"
    "\"tick_ms\":{\"type\":\"number\"},\"latency_ms\":{\"type\":\"number\"},"
    "\"misses\":{\"type\":\"integer\"},\"frames_dropped\":{\"type\":\"integer\"}}}";

static const char device_schema[] =
    "{\"title\":\"isoshape.DeviceSample\",\"description\":\"A "
    "device's decoded state and "
    "counters\",\"type\":\"object\",\"properties\":{"
    "\"timestamp\":" TIME_SCHEMA ",\"kind\":{\"type\":\"string\"},\"present\":{\"type\":"
    "\"boolean\"},"
    "\"stale\":{\"type\":\"boolean\"},\"axes\":" ARRAY_OF(
        "{\"type"
        "\":"
        "\"intege"
        "r\"}") ",\"buttons\":{\"type\":\"integer\"},"
                "\"pose\":" ARRAY_OF("{\"type\":"
                                     "\"number\"}") ",\"twi"
                                                    "st\""
                                                    ":" ARRAY_OF("{\"type\":"
                                                                 "\"number\""
                                                                 "}") ",\"co"
                                                                      "unter"
                                                                      "s\":{"
                                                                      "\"typ"
                                                                      "e\":"
                                                                      "\"obj"
                                                                      "ect\""
                                                                      ",\"ad"
                                                                      "ditio"
                                                                      "nalPr"
                                                                      "opert"
                                                                      "ies\""
                                                                      ":{"
                                                                      "\"typ"
                                                                      "e\":"
                                                                      "\"int"
                                                                      "eger"
                                                                      "\"}}}"
                                                                      "}";

static const char act_schema[] =
    "{\"title\":\"isoshape.Actuators\",\"description\":\"Setpoints sent and the MCU's "
    "state\",\"type\":\"object\",\"properties\":{\"timestamp\":" TIME_SCHEMA
    ",\"setpoints\":" ARRAY_OF(
        "{\"type\":\"object\",\"properties\":{\"channel\":{\"type\":\"integer\"},"
        "\"value\":{\"type\":\"integer\"}}}") ",\"mcu_state\":{\"type\":\"string\"},"
                                              "\"mcu_positions\":" ARRAY_OF(
                                                  "{\"type\":\"integer\"}") ",\"counters\":{"
                                                                            "\"type\":\"object\","
                                                                            "\"additionalProperties"
                                                                            "\":{\"type\":"
                                                                            "\"number\"}}}}";

int iso_fox_channels(const iso_sink_session *s, iso_fox_channel *out, int cap)
{
    int n = 0;
#define ADD(w, i, name, sch, ...)                                                                  \
    do {                                                                                           \
        if (n < cap) {                                                                             \
            out[n].what = (w);                                                                     \
            out[n].index = (i);                                                                    \
            out[n].schema_name = (name);                                                           \
            out[n].schema = (sch);                                                                 \
            snprintf(out[n].topic, sizeof out[n].topic, __VA_ARGS__);                              \
        }                                                                                          \
        n++;                                                                                       \
    } while (0)
    ADD(ISO_FOX_MESH, 0, "foxglove.SceneUpdate", scene_update_schema, "/mesh");
    for (int h = 0; h < s->n_handles && h < ISO_SINK_MAX_HANDLES; h++) {
        ADD(ISO_FOX_COMMANDED, h, "foxglove.FrameTransform", frame_transform_schema,
            "/handles/%s/commanded", s->handle_name[h]);
        ADD(ISO_FOX_ACHIEVED, h, "foxglove.FrameTransform", frame_transform_schema,
            "/handles/%s/achieved", s->handle_name[h]);
    }
    ADD(ISO_FOX_LOOP, 0, "isoshape.Tick", tick_schema, "/loop");
    for (int d = 0; d < s->n_devices && d < ISO_SINK_MAX_DEVICES; d++)
        ADD(ISO_FOX_DEVICE, d, "isoshape.DeviceSample", device_schema, "/devices/%d", d);
    if (s->n_act > 0)
        ADD(ISO_FOX_ACT, 0, "isoshape.Actuators", act_schema, "/actuators");
#undef ADD
    return n < cap ? n : cap;
}

/* ---- the encoder -------------------------------------------------------- */

struct iso_fox_encoder {
    iso_sink_session s;
    int nv, nt;
    char *out;
    size_t n, cap;
    int oom;
    double *rest_len;         /* 3 per triangle: its edges' rest lengths */
    unsigned char *tint;      /* per triangle: 0 none, 1 fixed, 2 handle */
    int *key, *order, *count; /* colour key per triangle; triangles by key; keys' counts */
    int *remap, *stamp;       /* per vertex: its index in the current primitive */
    int decimals;             /* a point coordinate's decimals: 1e-7 of the mesh's size */
    double scale;             /* 10^decimals */
};

enum { N_KEYS = 3 * ISO_FOX_STRAIN_LEVELS };

static void add(iso_fox_encoder *e, const char *fmt, ...) ISO_PRINTF(2, 3);
static void add(iso_fox_encoder *e, const char *fmt, ...)
{
    for (int tries = 0; tries < 2 && !e->oom; tries++) {
        va_list ap;
        va_start(ap, fmt);
        int k = vsnprintf(e->out + e->n, e->cap - e->n, fmt, ap);
        va_end(ap);
        if (k < 0) {
            e->oom = 1;
            return;
        }
        if ((size_t)k < e->cap - e->n) {
            e->n += (size_t)k;
            return;
        }
        size_t cap = e->cap * 2 + (size_t)k + 1;
        char *p = realloc(e->out, cap);
        if (!p) {
            e->oom = 1;
            return;
        }
        e->out = p;
        e->cap = cap;
    }
}

static void add_num(iso_fox_encoder *e, const char *fmt, double v);

/* n bytes as they are. */
static void add_raw(iso_fox_encoder *e, const char *p, size_t n)
{
    if (e->oom)
        return;
    if (e->n + n + 1 > e->cap) {
        size_t cap = e->cap * 2 + n + 1;
        char *q = realloc(e->out, cap);
        if (!q) {
            e->oom = 1;
            return;
        }
        e->out = q;
        e->cap = cap;
    }
    memcpy(e->out + e->n, p, n);
    e->n += n;
    e->out[e->n] = 0;
}

/* v with e->decimals decimals, trailing zeros dropped, without printf: a
 * mesh message is mostly coordinates, and printf's %g costs ten times this
 * (the MCAP writer must keep up with the loop on the cores the solver
 * leaves). Beyond 15 digits, or not finite, printf says it (or null). */
static void add_coord(iso_fox_encoder *e, double v)
{
    double r = nearbyint(v * e->scale);
    if (!(fabs(r) < 1e15)) {
        add_num(e, "%.7g", v);
        return;
    }
    char d[24], out[32];
    long long u = (long long)(r < 0 ? -r : r);
    int m = 0;
    do
        d[m++] = (char)('0' + u % 10);
    while ((u /= 10) != 0);
    while (m <= e->decimals)
        d[m++] = '0'; /* at least one digit before the point */
    int lo = 0;       /* trailing zeros of the fraction are dropped */
    while (lo < e->decimals && d[lo] == '0')
        lo++;
    size_t n = 0;
    if (r < 0)
        out[n++] = '-';
    for (int i = m - 1; i >= e->decimals; i--)
        out[n++] = d[i];
    if (lo < e->decimals) {
        out[n++] = '.';
        for (int i = e->decimals - 1; i >= lo; i--)
            out[n++] = d[i];
    }
    add_raw(e, out, n);
}

/* "a,b,c" after prefix, without printf: the indices are most of a mesh
 * message's numbers. */
static void add_ints(iso_fox_encoder *e, const char *prefix, int a, int b, int c)
{
    char tmp[48];
    size_t n = 0;
    int v[3] = {a, b, c};
    for (const char *p = prefix; *p; p++)
        tmp[n++] = *p;
    for (int k = 0; k < 3; k++) {
        char d[12];
        int m = 0;
        unsigned u = (unsigned)v[k];
        do
            d[m++] = (char)('0' + u % 10);
        while ((u /= 10) != 0);
        if (k)
            tmp[n++] = ',';
        while (m)
            tmp[n++] = d[--m];
    }
    add_raw(e, tmp, n);
}

/* A number JSON can hold: a non-finite value is written as null. */
static void add_num(iso_fox_encoder *e, const char *fmt, double v)
{
    if (isfinite(v))
        add(e, fmt, v);
    else
        add(e, "null");
}

static void add_time(iso_fox_encoder *e, const char *key, int64_t t)
{
    if (t < 0)
        t = 0;
    add(e, "\"%s\":{\"sec\":%lld,\"nsec\":%lld}", key, (long long)(t / 1000000000),
        (long long)(t % 1000000000));
}

static double edge(const double *x, int i, int j)
{
    double d0 = x[3 * i] - x[3 * j], d1 = x[3 * i + 1] - x[3 * j + 1],
           d2 = x[3 * i + 2] - x[3 * j + 2];
    return sqrt(d0 * d0 + d1 * d1 + d2 * d2);
}

int iso_fox_encoder_create(const iso_sink_session *s, iso_fox_encoder **out, iso_err *err)
{
    *out = NULL;
    if (!s || !s->mesh)
        return iso_err_set(err, ISO_EINVAL, -1, "Foxglove channels: no mesh");
    iso_fox_encoder *e = calloc(1, sizeof *e);
    if (!e)
        return iso_err_set(err, ISO_ENOMEM, -1, "Foxglove channels: out of memory");
    e->s = *s;
    for (int h = 0; h < ISO_SINK_MAX_HANDLES; h++) /* names go into JSON strings unescaped */
        for (char *c = e->s.handle_name[h]; *c; c++)
            if (*c == '"' || *c == '\\' || (unsigned char)*c < 0x20)
                *c = '_';
    e->nv = iso_mesh_vertex_count(s->mesh);
    e->nt = iso_mesh_triangle_count(s->mesh);
    size_t nt = (size_t)e->nt, nv = (size_t)e->nv;
    e->rest_len = malloc(3 * nt * sizeof *e->rest_len);
    e->tint = malloc(nt ? nt : 1);
    e->key = malloc(nt * sizeof *e->key + 1);
    e->order = malloc(nt * sizeof *e->order + 1);
    e->count = calloc(N_KEYS + 1, sizeof *e->count);
    e->remap = malloc(nv * sizeof *e->remap + 1);
    e->stamp = malloc(nv * sizeof *e->stamp + 1);
    e->cap = 1 << 16;
    e->out = malloc(e->cap);
    if (!e->rest_len || !e->tint || !e->key || !e->order || !e->count || !e->remap || !e->stamp ||
        !e->out) {
        iso_fox_encoder_destroy(e);
        return iso_err_set(err, ISO_ENOMEM, -1, "Foxglove channels: out of memory");
    }
    const double *X = iso_mesh_positions(s->mesh);
    const int *T = iso_mesh_triangles(s->mesh);
    for (size_t t = 0; t < nt; t++) {
        int h = 0, f = 0;
        for (int k = 0; k < 3; k++) {
            e->rest_len[3 * t + k] = edge(X, T[3 * t + k], T[3 * t + (k + 1) % 3]);
            if (s->regions) {
                h |= s->regions->kind[T[3 * t + k]] == ISO_HANDLE;
                f |= s->regions->kind[T[3 * t + k]] == ISO_FIXED;
            }
        }
        e->tint[t] = (unsigned char)(h ? 2 : f ? 1 : 0);
    }
    for (size_t v = 0; v < nv; v++)
        e->stamp[v] = -1;
    /* coordinates to 1e-7 of the mesh's size: far below what a view shows
     * (float32 holds 6e-8), and the same digits on every machine */
    double diag = iso_mesh_bbox_diagonal(s->mesh);
    int dec = diag > 0 ? 7 - (int)ceil(log10(diag)) : 7;
    e->decimals = dec < 0 ? 0 : dec > 12 ? 12 : dec;
    e->scale = pow(10.0, e->decimals);
    *out = e;
    return ISO_OK;
}

void iso_fox_encoder_destroy(iso_fox_encoder *e)
{
    if (!e)
        return;
    free(e->rest_len);
    free(e->tint);
    free(e->key);
    free(e->order);
    free(e->count);
    free(e->remap);
    free(e->stamp);
    free(e->out);
    free(e);
}

/* Each triangle's colour key: tint * LEVELS + quantized strain; the
 * triangles sorted by key (a counting sort, stable). */
static void colour_keys(iso_fox_encoder *e, const double *x)
{
    const int *T = iso_mesh_triangles(e->s.mesh);
    memset(e->count, 0, (N_KEYS + 1) * sizeof *e->count);
    for (int t = 0; t < e->nt; t++) {
        double worst = 0;
        for (int k = 0; k < 3; k++) {
            double l0 = e->rest_len[3 * t + k];
            double l = edge(x, T[3 * t + k], T[3 * t + (k + 1) % 3]);
            double s = l0 > 0 ? fabs(l - l0) / l0 : 0;
            if (s > worst || !(s == s))
                worst = s == s ? s : ISO_SNAPSHOT_STRAIN_FULL;
        }
        double u = worst / ISO_SNAPSHOT_STRAIN_FULL;
        int q = (int)floor((u < 1 ? u : 1) * (ISO_FOX_STRAIN_LEVELS - 1) + 0.5);
        e->key[t] = e->tint[t] * ISO_FOX_STRAIN_LEVELS + q;
        e->count[e->key[t] + 1]++;
    }
    for (int k = 0; k < N_KEYS; k++)
        e->count[k + 1] += e->count[k];
    for (int t = 0; t < e->nt; t++)
        e->order[e->count[e->key[t]]++] = t;
    /* count[k] is now the end of key k's run; the start is count[k-1] */
}

static void primitive(iso_fox_encoder *e, const double *x, int key, int from, int to, int first)
{
    const int *T = iso_mesh_triangles(e->s.mesh);
    double rgb[3];
    iso_snapshot_strain_color((double)(key % ISO_FOX_STRAIN_LEVELS) / (ISO_FOX_STRAIN_LEVELS - 1) *
                                  ISO_SNAPSHOT_STRAIN_FULL,
                              rgb);
    iso_snapshot_tint_color(key / ISO_FOX_STRAIN_LEVELS == 2, key / ISO_FOX_STRAIN_LEVELS == 1,
                            rgb);
    add(e,
        "%s{\"pose\":{\"position\":{\"x\":0,\"y\":0,\"z\":0},\"orientation\":{\"x\":0,"
        "\"y\":0,\"z\":0,\"w\":1}},\"points\":[",
        first ? "" : ",");
    int np = 0;
    for (int i = from; i < to; i++)
        for (int k = 0; k < 3; k++) {
            int v = T[3 * e->order[i] + k];
            if (e->stamp[v] == key)
                continue;
            e->stamp[v] = key;
            e->remap[v] = np++;
            const double *p = x + 3 * v;
            add_raw(e, np > 1 ? ",{\"x\":" : "{\"x\":", np > 1 ? 6 : 5);
            add_coord(e, p[0]);
            add_raw(e, ",\"y\":", 5);
            add_coord(e, p[1]);
            add_raw(e, ",\"z\":", 5);
            add_coord(e, p[2]);
            add_raw(e, "}", 1);
        }
    add(e, "],\"color\":{\"r\":%.4f,\"g\":%.4f,\"b\":%.4f,\"a\":1},\"colors\":[],\"indices\":[",
        rgb[0], rgb[1], rgb[2]);
    for (int i = from; i < to; i++)
        add_ints(e, i == from ? "" : ",", e->remap[T[3 * e->order[i]]],
                 e->remap[T[3 * e->order[i] + 1]], e->remap[T[3 * e->order[i] + 2]]);
    add(e, "]}");
}

static void encode_mesh(iso_fox_encoder *e, const iso_sink_frame *f)
{
    colour_keys(e, f->x);
    for (int v = 0; v < e->nv; v++)
        e->stamp[v] = -1;
    add(e, "{\"deletions\":[],\"entities\":[{");
    add_time(e, "timestamp", f->t_ns);
    add(e, ",\"frame_id\":\"world\",\"id\":\"mesh\",\"lifetime\":{\"sec\":0,\"nsec\":0},"
           "\"frame_locked\":false,\"metadata\":[],\"arrows\":[],\"cubes\":[],\"spheres\":[],"
           "\"cylinders\":[],\"lines\":[],\"triangles\":[");
    int first = 1;
    for (int k = 0; k < N_KEYS; k++) {
        int from = k > 0 ? e->count[k - 1] : 0, to = e->count[k];
        if (to > from) {
            primitive(e, f->x, k, from, to, first);
            first = 0;
        }
    }
    add(e, "],\"texts\":[],\"models\":[]}]}");
}

static void encode_transform(iso_fox_encoder *e, const iso_sink_frame *f, int h, int achieved)
{
    const iso_pose *P = achieved ? &f->achieved[h] : &f->commanded[h];
    double c[3], q[4]; /* q: w, x, y, z */
    iso_pose_apply(P, e->s.handle_centre[h], c);
    iso_rotation_quaternion(P->R, q);
    add(e, "{");
    add_time(e, "timestamp", f->t_ns);
    add(e, ",\"parent_frame_id\":\"world\",\"child_frame_id\":\"%s/%s\",", e->s.handle_name[h],
        achieved ? "achieved" : "commanded");
    add(e, "\"translation\":{\"x\":%.17g,\"y\":%.17g,\"z\":%.17g},", c[0], c[1], c[2]);
    add(e, "\"rotation\":{\"x\":%.17g,\"y\":%.17g,\"z\":%.17g,\"w\":%.17g}}", q[1], q[2], q[3],
        q[0]);
}

static void encode_loop(iso_fox_encoder *e, const iso_sink_frame *f)
{
    add(e, "{");
    add_time(e, "timestamp", f->t_ns);
    add(e,
        ",\"tick\":%ld,\"dt_s\":%.17g,\"substeps\":%d,\"merged\":%d,\"restart\":%s,"
        "\"active_handle\":%d,\"clutch\":%s,\"estop\":%s,\"buttons\":%u,\"evaluations\":%ld,"
        "\"factorizations\":%ld,\"cg_iterations\":%ld",
        f->tick, (double)f->dt_ns * 1e-9, f->substeps, f->merged, f->restart ? "true" : "false",
        f->active, f->clutch ? "true" : "false", f->estop ? "true" : "false", (unsigned)f->buttons,
        f->evaluations, f->factorizations, f->cg_iterations);
    if (e->s.wall_times) {
        add(e, ",\"tick_ms\":");
        add_num(e, "%.6g", f->tick_ms);
        add(e, ",\"latency_ms\":");
        add_num(e, "%.6g", f->latency_ms);
        add(e, ",\"misses\":%ld,\"frames_dropped\":%ld", f->misses, f->dropped);
    }
    add(e, "}");
}

static void encode_device(iso_fox_encoder *e, const iso_sink_frame *f, int d)
{
    const iso_sink_device *v = &f->dev[d];
    const iso_dev_source_stats *s = &v->stats;
    add(e, "{");
    add_time(e, "timestamp", f->t_ns);
    add(e,
        ",\"kind\":\"%s\",\"present\":%s,\"stale\":%s,\"axes\":[%d,%d,%d,%d,%d,%d],"
        "\"buttons\":%u",
        iso_dev_kind_name(e->s.device_kind[d]), v->present ? "true" : "false",
        v->stale ? "true" : "false", v->axes[0], v->axes[1], v->axes[2], v->axes[3], v->axes[4],
        v->axes[5], (unsigned)v->buttons);
    if (v->has_pose || v->has_twist) {
        add(e, ",\"%s\":[", v->has_pose ? "pose" : "twist");
        for (int k = 0; k < 6; k++) {
            add(e, "%s", k ? "," : "");
            add_num(e, "%.17g", v->v[k]);
        }
        add(e, "]");
    }
    add(e,
        ",\"counters\":{\"events\":%u,\"chunks\":%u,\"reports\":%u,\"bad_frames\":%u,"
        "\"garbage\":%u,\"short_reports\":%u,\"unknown_ids\":%u,\"gone\":%u,\"back\":%u,"
        "\"stale\":%u}}",
        s->events, s->dec.chunks, s->dec.reports, s->dec.bad_frames, s->dec.garbage,
        s->dec.short_reports, s->dec.unknown_ids, s->gone, s->back, s->stale);
}

static void encode_act(iso_fox_encoder *e, const iso_sink_frame *f)
{
    const iso_act_stats *a = &f->act;
    add(e, "{");
    add_time(e, "timestamp", f->t_ns);
    add(e, ",\"setpoints\":[");
    for (int i = 0; f->have_act && i < e->s.n_act; i++) {
        int c = e->s.act_channel[i];
        add(e, "%s{\"channel\":%d,\"value\":%d}", i ? "," : "", c,
            c >= 0 && c < ISO_ACT_MAX_CHANNELS ? f->setpoints[c] : 0);
    }
    static const char *const states[] = {"idle", "armed", "safe"};
    add(e, "],\"mcu_state\":\"%s\",\"mcu_positions\":[",
        a->mcu_state >= 0 && a->mcu_state <= 2 ? states[a->mcu_state] : "unknown");
    for (int i = 0; i < a->mcu_channels && i < ISO_ACT_MAX_CHANNELS; i++)
        add(e, "%s%d", i ? "," : "", a->mcu_pos[i]);
    add(e,
        "],\"counters\":{\"setpoints_sent\":%llu,\"acks\":%llu,\"clamps\":%llu,"
        "\"link_losses\":%u,\"faults\":%u,\"naks\":%u,\"heartbeats\":%u,\"mcu_uptime_ms\":%u,"
        "\"estops\":%u,\"loop_stalls\":%u,\"rtt_last_ms\":",
        (unsigned long long)a->setpoints_sent, (unsigned long long)a->acks,
        (unsigned long long)a->clamps, a->link_losses, a->faults, a->naks, a->heartbeats,
        a->mcu_uptime_ms, a->estops, a->loop_stalls);
    add_num(e, "%.6g", a->rtt_count ? a->rtt_last_ms : NAN);
    add(e, "}}");
}

int iso_fox_encode(iso_fox_encoder *e, const iso_fox_channel *c, const iso_sink_frame *f,
                   const char **data, size_t *len, iso_err *err)
{
    e->n = 0;
    e->oom = 0;
    e->out[0] = 0;
    switch (c->what) {
    case ISO_FOX_MESH: encode_mesh(e, f); break;
    case ISO_FOX_COMMANDED:
    case ISO_FOX_ACHIEVED: encode_transform(e, f, c->index, c->what == ISO_FOX_ACHIEVED); break;
    case ISO_FOX_LOOP: encode_loop(e, f); break;
    case ISO_FOX_DEVICE: encode_device(e, f, c->index); break;
    default: encode_act(e, f); break;
    }
    if (e->oom)
        return iso_err_set(err, ISO_ENOMEM, -1, "Foxglove channel %s: out of memory", c->topic);
    *data = e->out;
    *len = e->n;
    return ISO_OK;
}
