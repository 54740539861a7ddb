/* mesh/mesh_io_ply.c -- the PLY reader: ascii, binary_little_endian and
 * binary_big_endian.
 *
 * The vertex element must have scalar x, y, z of any numeric type; its other
 * properties are skipped. The face element must have a list property named
 * vertex_indices or vertex_index (any count and index types). Other elements
 * are skipped, which in binary files means walking their lists. Text errors
 * name the line, binary ones the byte offset of the element entry. Counts are
 * checked against the bytes left before anything is read, so a bogus header
 * fails at once instead of allocating or looping for it. */
#include "mesh_io_internal.h"

#include <math.h>
#include <stdint.h>
#include <string.h>

#define PLY_MAX_ELEMS 32
#define PLY_MAX_PROPS 64

enum ply_type { T_I8 = 1, T_U8, T_I16, T_U16, T_I32, T_U32, T_F32, T_F64 };
enum ply_role { R_NONE = 0, R_X, R_Y, R_Z, R_INDICES };
enum ply_kind { K_OTHER = 0, K_VERTEX, K_FACE };
enum ply_format { F_ASCII = 0, F_LE, F_BE };

typedef struct ply_prop {
    int type;       /* value type (item type for a list) */
    int count_type; /* 0 for a scalar */
    int role;
} ply_prop;

typedef struct ply_elem {
    char name[32];
    long count;
    long line; /* header line, for messages */
    int kind;
    int nprop;
    ply_prop prop[PLY_MAX_PROPS];
} ply_elem;

typedef struct ply_header {
    int format;
    int nelem;
    ply_elem elem[PLY_MAX_ELEMS];
} ply_header;

static int type_size(int t)
{
    static const int size[] = {0, 1, 1, 2, 2, 4, 4, 4, 8};
    return size[t];
}

static int parse_type(const char *tok, size_t n)
{
    static const struct {
        const char *name;
        int type;
    } names[] = {{"char", T_I8},   {"int8", T_I8},     {"uchar", T_U8},   {"uint8", T_U8},
                 {"short", T_I16}, {"int16", T_I16},   {"ushort", T_U16}, {"uint16", T_U16},
                 {"int", T_I32},   {"int32", T_I32},   {"uint", T_U32},   {"uint32", T_U32},
                 {"float", T_F32}, {"float32", T_F32}, {"double", T_F64}, {"float64", T_F64}};
    for (size_t i = 0; i < sizeof names / sizeof names[0]; i++)
        if (strlen(names[i].name) == n && memcmp(names[i].name, tok, n) == 0)
            return names[i].type;
    return 0;
}

static int word_is(const char *tok, size_t n, const char *w)
{
    return strlen(w) == n && memcmp(tok, w, n) == 0;
}

/* ==== header ============================================================= */

static int header_error(iso_mesh__builder *b, long line, iso_err *err, const char *what,
                        const char *tok, size_t n)
{
    char loc[320], q[40];
    b->src_is_offset = 0;
    if (tok)
        return iso_err_set(err, ISO_EPARSE, line, "%s: PLY header: %s '%s'",
                           iso_mesh__where(loc, sizeof loc, b, line), what,
                           iso_mesh__quote(q, sizeof q, tok, n));
    return iso_err_set(err, ISO_EPARSE, line, "%s: PLY header: %s",
                       iso_mesh__where(loc, sizeof loc, b, line), what);
}

static int parse_property(iso_mesh__builder *b, ply_elem *el, const char *p, const char *e,
                          long line, iso_err *err)
{
    const char *tok;
    size_t n;
    if (el->nprop == PLY_MAX_PROPS)
        return header_error(b, line, err, "too many properties in one element", NULL, 0);
    ply_prop *pr = &el->prop[el->nprop];
    memset(pr, 0, sizeof *pr);
    if (!iso_mesh__token(&p, e, &tok, &n))
        return header_error(b, line, err, "property without a type", NULL, 0);
    if (word_is(tok, n, "list")) {
        if (!iso_mesh__token(&p, e, &tok, &n) || !(pr->count_type = parse_type(tok, n)))
            return header_error(b, line, err, "bad list count type", n ? tok : NULL, n);
        if (pr->count_type == T_F32 || pr->count_type == T_F64)
            return header_error(b, line, err, "list count type must be an integer type", tok, n);
        if (!iso_mesh__token(&p, e, &tok, &n) || !(pr->type = parse_type(tok, n)))
            return header_error(b, line, err, "bad list item type", n ? tok : NULL, n);
    } else if (!(pr->type = parse_type(tok, n))) {
        return header_error(b, line, err, "unknown property type", tok, n);
    }
    if (!iso_mesh__token(&p, e, &tok, &n))
        return header_error(b, line, err, "property without a name", NULL, 0);
    if (el->kind == K_VERTEX && !pr->count_type) {
        if (word_is(tok, n, "x"))
            pr->role = R_X;
        else if (word_is(tok, n, "y"))
            pr->role = R_Y;
        else if (word_is(tok, n, "z"))
            pr->role = R_Z;
    } else if (el->kind == K_FACE && pr->count_type &&
               (word_is(tok, n, "vertex_indices") || word_is(tok, n, "vertex_index"))) {
        pr->role = R_INDICES;
    }
    el->nprop++;
    return ISO_OK;
}

static int parse_element(iso_mesh__builder *b, ply_header *h, const char *p, const char *e,
                         long line, iso_err *err)
{
    const char *tok;
    size_t n;
    if (h->nelem == PLY_MAX_ELEMS)
        return header_error(b, line, err, "too many elements", NULL, 0);
    ply_elem *el = &h->elem[h->nelem];
    memset(el, 0, sizeof *el);
    el->line = line;
    if (!iso_mesh__token(&p, e, &tok, &n))
        return header_error(b, line, err, "element without a name", NULL, 0);
    iso_mesh__quote(el->name, sizeof el->name, tok, n);
    el->kind = word_is(tok, n, "vertex") ? K_VERTEX : word_is(tok, n, "face") ? K_FACE : K_OTHER;
    for (int i = 0; i < h->nelem; i++)
        if (el->kind != K_OTHER && h->elem[i].kind == el->kind)
            return header_error(b, line, err, "repeated element", tok, n);
    if (!iso_mesh__token(&p, e, &tok, &n) || iso_mesh__to_long(tok, n, &el->count) ||
        el->count < 0 || el->count > INT32_MAX)
        return header_error(b, line, err, "bad element count", n ? tok : NULL, n);
    h->nelem++;
    return ISO_OK;
}

static int check_roles(iso_mesh__builder *b, const ply_header *h, iso_err *err)
{
    int have_vertex = 0;
    for (int i = 0; i < h->nelem; i++) {
        const ply_elem *el = &h->elem[i];
        int seen[5] = {0};
        for (int k = 0; k < el->nprop; k++)
            seen[el->prop[k].role] = 1;
        if (el->kind == K_VERTEX) {
            have_vertex = 1;
            if (!seen[R_X] || !seen[R_Y] || !seen[R_Z])
                return header_error(b, el->line, err,
                                    "element vertex lacks a scalar x, y or z property", NULL, 0);
        }
        if (el->kind == K_FACE && !seen[R_INDICES])
            return header_error(b, el->line, err,
                                "element face has no list property vertex_indices or "
                                "vertex_index",
                                NULL, 0);
    }
    if (!have_vertex)
        return header_error(b, -1, err, "no vertex element", NULL, 0);
    return ISO_OK;
}

/* Parses the header; *body is where the data starts. */
static int parse_header(iso_mesh__builder *b, iso_mesh__text *t, ply_header *h, iso_err *err)
{
    const char *p, *e, *tok;
    size_t n;
    int have_format = 0;
    if (!iso_mesh__text_line(t, 0, &p, &e) || !iso_mesh__token(&p, e, &tok, &n) ||
        !word_is(tok, n, "ply") || t->line != 1)
        return header_error(b, 1, err, "the file does not start with the line 'ply'", NULL, 0);
    for (;;) {
        if (!iso_mesh__text_line(t, 0, &p, &e))
            return header_error(b, t->line, err, "no end_header line (truncated header?)", NULL, 0);
        iso_mesh__token(&p, e, &tok, &n);
        if (word_is(tok, n, "end_header"))
            break;
        if (word_is(tok, n, "comment") || word_is(tok, n, "obj_info"))
            continue;
        int rc = ISO_OK;
        if (word_is(tok, n, "format")) {
            if (!iso_mesh__token(&p, e, &tok, &n))
                return header_error(b, t->line, err, "format line without a format", NULL, 0);
            if (word_is(tok, n, "ascii"))
                h->format = F_ASCII;
            else if (word_is(tok, n, "binary_little_endian"))
                h->format = F_LE;
            else if (word_is(tok, n, "binary_big_endian"))
                h->format = F_BE;
            else
                return header_error(b, t->line, err, "unknown format", tok, n);
            have_format = 1;
        } else if (word_is(tok, n, "element")) {
            rc = parse_element(b, h, p, e, t->line, err);
        } else if (word_is(tok, n, "property")) {
            if (h->nelem == 0)
                return header_error(b, t->line, err, "property before any element", NULL, 0);
            rc = parse_property(b, &h->elem[h->nelem - 1], p, e, t->line, err);
        } else {
            return header_error(b, t->line, err, "unknown keyword", tok, n);
        }
        if (rc != ISO_OK)
            return rc;
    }
    if (!have_format)
        return header_error(b, t->line, err, "no format line", NULL, 0);
    return check_roles(b, h, err);
}

/* ==== binary body ======================================================== */

static double get_value(const unsigned char *p, int type, int big_endian)
{
    int size = type_size(type);
    uint64_t u = 0;
    for (int i = 0; i < size; i++)
        u |= (uint64_t)p[big_endian ? size - 1 - i : i] << (8 * i);
    switch (type) {
    case T_I8: return (double)(int8_t)(uint8_t)u;
    case T_U8: return (double)(uint8_t)u;
    case T_I16: return (double)(int16_t)(uint16_t)u;
    case T_U16: return (double)(uint16_t)u;
    case T_I32: return (double)(int32_t)(uint32_t)u;
    case T_U32: return (double)(uint32_t)u;
    case T_F32: {
        uint32_t w = (uint32_t)u;
        float f;
        memcpy(&f, &w, sizeof f);
        return (double)f;
    }
    default: {
        double d;
        memcpy(&d, &u, sizeof d);
        return d;
    }
    }
}

/* An index or count read as a double must be an integer that fits a long. */
static int as_index(double v, long *out)
{
    if (!(v == floor(v)) || fabs(v) > 9.0e15)
        return -1;
    *out = (long)v;
    return 0;
}

typedef struct bin_cursor {
    const unsigned char *data;
    size_t len, off;
    int be;
} bin_cursor;

static int bin_short(iso_mesh__builder *b, const ply_elem *el, long i, size_t off, iso_err *err)
{
    return iso_err_set(err, ISO_EPARSE, (long)off,
                       "%s, byte offset %zu: file ends inside %s %ld of %ld (truncated?)", b->name,
                       off, el->name, i, el->count);
}

static int read_bin_entry(iso_mesh__builder *b, bin_cursor *c, const ply_elem *el, long i,
                          iso_err *err)
{
    size_t start = c->off;
    double v[3] = {0, 0, 0};
    int rc;
    if (el->kind == K_FACE && (rc = iso_mesh__face_begin(b, (long)start, err)) != ISO_OK)
        return rc;
    for (int k = 0; k < el->nprop; k++) {
        const ply_prop *pr = &el->prop[k];
        size_t vs = (size_t)type_size(pr->type);
        if (!pr->count_type) {
            if (c->len - c->off < vs)
                return bin_short(b, el, i, c->off, err);
            if (pr->role >= R_X && pr->role <= R_Z)
                v[pr->role - R_X] = get_value(c->data + c->off, pr->type, c->be);
            c->off += vs;
            continue;
        }
        size_t cs = (size_t)type_size(pr->count_type);
        long cnt;
        if (c->len - c->off < cs)
            return bin_short(b, el, i, c->off, err);
        if (as_index(get_value(c->data + c->off, pr->count_type, c->be), &cnt) || cnt < 0)
            return iso_err_set(err, ISO_EPARSE, (long)c->off,
                               "%s, byte offset %zu: %s %ld has a negative list count", b->name,
                               c->off, el->name, i);
        c->off += cs;
        if ((size_t)cnt > (c->len - c->off) / vs)
            return iso_err_set(err, ISO_EPARSE, (long)c->off,
                               "%s, byte offset %zu: %s %ld lists %ld values but the file ends "
                               "first (truncated or wrong count)",
                               b->name, c->off, el->name, i, cnt);
        if (pr->role == R_INDICES) {
            for (long q = 0; q < cnt; q++) {
                long idx;
                size_t at = c->off + (size_t)q * vs;
                if (as_index(get_value(c->data + at, pr->type, c->be), &idx))
                    return iso_err_set(err, ISO_EPARSE, (long)at,
                                       "%s, byte offset %zu: face %ld has a vertex index that "
                                       "is not an integer",
                                       b->name, at, i);
                if ((rc = iso_mesh__face_index(b, idx, err)) != ISO_OK)
                    return rc;
            }
        }
        c->off += (size_t)cnt * vs;
    }
    if (el->kind == K_VERTEX)
        return iso_mesh__add_vertex(b, v, (long)start, err);
    if (el->kind == K_FACE)
        return iso_mesh__face_end(b, err);
    return ISO_OK;
}

static int read_binary(iso_mesh__builder *b, const ply_header *h, bin_cursor *c, iso_err *err)
{
    b->src_is_offset = 1;
    for (int e = 0; e < h->nelem; e++) {
        const ply_elem *el = &h->elem[e];
        size_t min = 0;
        for (int k = 0; k < el->nprop; k++)
            min += (size_t)type_size(el->prop[k].count_type ? el->prop[k].count_type
                                                            : el->prop[k].type);
        if (min == 0)
            continue; /* no properties: nothing stored, nothing to read */
        if ((size_t)el->count > (c->len - c->off) / min)
            return iso_err_set(err, ISO_EPARSE, (long)c->off,
                               "%s, byte offset %zu: the header announces %ld %s entries of at "
                               "least %zu bytes, but only %zu bytes are left (truncated or "
                               "wrong count)",
                               b->name, c->off, el->count, el->name, min, c->len - c->off);
        for (long i = 0; i < el->count; i++) {
            int rc = read_bin_entry(b, c, el, i, err);
            if (rc != ISO_OK)
                return rc;
        }
    }
    if (c->off != c->len)
        return iso_err_set(err, ISO_EPARSE, (long)c->off,
                           "%s, byte offset %zu: %zu unexpected bytes after the last element "
                           "(wrong counts?)",
                           b->name, c->off, c->len - c->off);
    return ISO_OK;
}

/* ==== ascii body ========================================================= */

static int ascii_value(iso_mesh__builder *b, iso_mesh__text *t, const char **p, const char *e,
                       const ply_elem *el, long i, double *v, iso_err *err)
{
    const char *tok;
    size_t n;
    char loc[320], q[40];
    if (!iso_mesh__token(p, e, &tok, &n))
        return iso_err_set(err, ISO_EPARSE, t->line, "%s: %s %ld has too few values",
                           iso_mesh__where(loc, sizeof loc, b, t->line), el->name, i);
    if (iso_mesh__to_double(tok, n, v))
        return iso_err_set(err, ISO_EPARSE, t->line, "%s: %s %ld: '%s' is not a number",
                           iso_mesh__where(loc, sizeof loc, b, t->line), el->name, i,
                           iso_mesh__quote(q, sizeof q, tok, n));
    return ISO_OK;
}

static int read_ascii_entry(iso_mesh__builder *b, iso_mesh__text *t, const ply_elem *el, long i,
                            iso_err *err)
{
    const char *p, *e, *tok;
    size_t n;
    char loc[320];
    double v[3] = {0, 0, 0}, d;
    int rc;
    if (!iso_mesh__text_line(t, 0, &p, &e))
        return iso_err_set(err, ISO_EPARSE, t->line,
                           "%s: file ends before %s %ld of %ld (truncated?)",
                           iso_mesh__where(loc, sizeof loc, b, t->line), el->name, i, el->count);
    if (el->kind == K_FACE && (rc = iso_mesh__face_begin(b, t->line, err)) != ISO_OK)
        return rc;
    for (int k = 0; k < el->nprop; k++) {
        const ply_prop *pr = &el->prop[k];
        if ((rc = ascii_value(b, t, &p, e, el, i, &d, err)) != ISO_OK)
            return rc;
        if (!pr->count_type) {
            if (pr->role >= R_X && pr->role <= R_Z)
                v[pr->role - R_X] = d;
            continue;
        }
        long cnt;
        if (as_index(d, &cnt) || cnt < 0)
            return iso_err_set(err, ISO_EPARSE, t->line, "%s: %s %ld has a bad list count",
                               iso_mesh__where(loc, sizeof loc, b, t->line), el->name, i);
        for (long q = 0; q < cnt; q++) {
            long idx;
            if ((rc = ascii_value(b, t, &p, e, el, i, &d, err)) != ISO_OK)
                return rc;
            if (pr->role != R_INDICES)
                continue;
            if (as_index(d, &idx))
                return iso_err_set(err, ISO_EPARSE, t->line,
                                   "%s: face %ld has a vertex index that is not an integer",
                                   iso_mesh__where(loc, sizeof loc, b, t->line), i);
            if ((rc = iso_mesh__face_index(b, idx, err)) != ISO_OK)
                return rc;
        }
    }
    if (iso_mesh__token(&p, e, &tok, &n))
        return iso_err_set(err, ISO_EPARSE, t->line,
                           "%s: %s %ld has more values than the header declares",
                           iso_mesh__where(loc, sizeof loc, b, t->line), el->name, i);
    if (el->kind == K_VERTEX)
        return iso_mesh__add_vertex(b, v, t->line, err);
    if (el->kind == K_FACE)
        return iso_mesh__face_end(b, err);
    return ISO_OK;
}

static int read_ascii(iso_mesh__builder *b, const ply_header *h, iso_mesh__text *t, iso_err *err)
{
    char loc[320];
    for (int e = 0; e < h->nelem; e++) {
        const ply_elem *el = &h->elem[e];
        if (el->nprop == 0)
            continue;
        /* each entry is a line of at least "0\n" */
        if ((size_t)el->count > (size_t)(t->end - t->p) / 2 + 1)
            return iso_err_set(err, ISO_EPARSE, el->line,
                               "%s: the header announces %ld %s entries but only %zu bytes "
                               "follow it (truncated or wrong count)",
                               iso_mesh__where(loc, sizeof loc, b, el->line), el->count, el->name,
                               (size_t)(t->end - t->p));
        for (long i = 0; i < el->count; i++) {
            int rc = read_ascii_entry(b, t, el, i, err);
            if (rc != ISO_OK)
                return rc;
        }
    }
    const char *p, *e;
    if (iso_mesh__text_line(t, 0, &p, &e))
        return iso_err_set(err, ISO_EPARSE, t->line,
                           "%s: unexpected content after the last element (wrong counts?)",
                           iso_mesh__where(loc, sizeof loc, b, t->line));
    return ISO_OK;
}

int iso_mesh__read_ply(iso_mesh__builder *b, const unsigned char *data, size_t len, iso_err *err)
{
    iso_mesh__text t;
    ply_header h;
    int rc;
    memset(&h, 0, sizeof h);
    iso_mesh__text_init(&t, (const char *)data, len);
    b->src_is_offset = 0;
    if ((rc = parse_header(b, &t, &h, err)) != ISO_OK)
        return rc;
    if (h.format == F_ASCII)
        return read_ascii(b, &h, &t, err);
    bin_cursor c = {data, len, (size_t)(t.p - (const char *)data), h.format == F_BE};
    return read_binary(b, &h, &c, err);
}
