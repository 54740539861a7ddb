/* mesh/mesh_io_obj.c -- the Wavefront OBJ reader (geometry only).
 *
 * Read: "v x y z [w | r g b]" and "f" with corners i, i/j, i/j/k or i//k;
 * indices are 1-based, negative ones count back from the last vertex read.
 * A face may name a vertex defined later in the file (the range check runs
 * once all is read). Ignored: vn vt vp o g s usemtl mtllib l p. Any other
 * statement is an error, so a misnamed or binary file is not silently read as
 * an empty mesh. */
#include "mesh_io_internal.h"

#include <string.h>

static int is_word(const char *tok, size_t n, const char *w)
{
    return strlen(w) == n && memcmp(tok, w, n) == 0;
}

static int is_ignored(const char *tok, size_t n)
{
    static const char *const words[] = {"vn", "vt",     "vp",     "o", "g",
                                        "s",  "usemtl", "mtllib", "l", "p"};
    for (size_t i = 0; i < sizeof words / sizeof words[0]; i++)
        if (is_word(tok, n, words[i]))
            return 1;
    return 0;
}

static int read_vertex(iso_mesh__builder *b, const char *p, const char *e, long line, iso_err *err)
{
    const char *tok;
    size_t n;
    char loc[320], q[40];
    double v[3];
    for (int c = 0; c < 3; c++) {
        if (!iso_mesh__token(&p, e, &tok, &n))
            return iso_err_set(err, ISO_EPARSE, line,
                               "%s: vertex %zu has %d coordinate(s), "
                               "expected 3",
                               iso_mesh__where(loc, sizeof loc, b, line), b->nv, c);
        if (iso_mesh__to_double(tok, n, &v[c]))
            return iso_err_set(err, ISO_EPARSE, line, "%s: vertex %zu: '%s' is not a number",
                               iso_mesh__where(loc, sizeof loc, b, line), b->nv,
                               iso_mesh__quote(q, sizeof q, tok, n));
    }
    return iso_mesh__add_vertex(b, v, line, err);
}

/* One corner "i", "i/j", "i/j/k" or "i//k": the vertex index is the part
 * before the first '/'; the others must be integers or empty. Returns the
 * 0-based vertex index in *out, or -1 on a malformed corner. */
static int parse_corner(const char *tok, size_t n, size_t nv, long *out, const char **why)
{
    const char *slash = memchr(tok, '/', n);
    size_t head = slash ? (size_t)(slash - tok) : n;
    long i;
    if (iso_mesh__to_long(tok, head, &i)) {
        *why = "is not a vertex index";
        return -1;
    }
    int parts = 1;
    for (const char *s = slash; s; parts++) {
        const char *r = s + 1, *end = tok + n;
        const char *next = memchr(r, '/', (size_t)(end - r));
        size_t len = (size_t)((next ? next : end) - r);
        long dummy;
        if (len && iso_mesh__to_long(r, len, &dummy)) {
            *why = "has a texture or normal index that is not an integer";
            return -1;
        }
        s = next;
        if (parts == 3) {
            *why = "has more than three '/'-separated parts";
            return -1;
        }
    }
    if (i == 0) {
        *why = "uses index 0 (OBJ indices start at 1)";
        return -1;
    }
    if (i < 0) {
        if ((size_t)(-(i + 1)) >= nv) { /* -(i+1) avoids overflow at LONG_MIN */
            *why = "is a relative index reaching before the first vertex";
            return -1;
        }
        *out = (long)nv + i;
    } else {
        *out = i - 1;
    }
    return 0;
}

static int read_face(iso_mesh__builder *b, const char *p, const char *e, long line, iso_err *err)
{
    const char *tok, *why = "";
    size_t n;
    char loc[320], q[40];
    int rc = iso_mesh__face_begin(b, line, err);
    if (rc != ISO_OK)
        return rc;
    while (iso_mesh__token(&p, e, &tok, &n)) {
        long i;
        if (parse_corner(tok, n, b->nv, &i, &why))
            return iso_err_set(err, ISO_EPARSE, line, "%s: face %zu: corner '%s' %s",
                               iso_mesh__where(loc, sizeof loc, b, line), b->nface,
                               iso_mesh__quote(q, sizeof q, tok, n), why);
        if ((rc = iso_mesh__face_index(b, i, err)) != ISO_OK)
            return rc;
    }
    return iso_mesh__face_end(b, err);
}

int iso_mesh__read_obj(iso_mesh__builder *b, const char *data, size_t len, iso_err *err)
{
    iso_mesh__text t;
    const char *p, *e, *tok;
    size_t n;
    char loc[320], q[40];
    iso_mesh__text_init(&t, data, len);
    while (iso_mesh__text_line(&t, 1, &p, &e)) {
        int rc = ISO_OK;
        iso_mesh__token(&p, e, &tok, &n);
        if (is_word(tok, n, "v"))
            rc = read_vertex(b, p, e, t.line, err);
        else if (is_word(tok, n, "f"))
            rc = read_face(b, p, e, t.line, err);
        else if (!is_ignored(tok, n))
            rc = iso_err_set(err, ISO_EPARSE, t.line, "%s: unknown OBJ statement '%s'",
                             iso_mesh__where(loc, sizeof loc, b, t.line),
                             iso_mesh__quote(q, sizeof q, tok, n));
        if (rc != ISO_OK)
            return rc;
    }
    return ISO_OK;
}
