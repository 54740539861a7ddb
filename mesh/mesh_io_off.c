/* mesh/mesh_io_off.c -- the OFF reader.
 *
 * Accepted: an "OFF" keyword (with the optional C/N/ST prefixes, whose extra
 * per-vertex values are ignored), the counts "nv nf [ne]" on the same or the
 * next line, nv vertex lines of at least 3 numbers, nf face lines
 * "k i0 .. ik-1" optionally followed by colour values. '#' starts a comment
 * anywhere; blank lines and extra spaces are fine. Anything after the
 * announced faces is an error: it means the counts are wrong. */
#include "mesh_io_internal.h"

#include <string.h>

/* "OFF", "COFF", "NOFF", "CNOFF", "STOFF", "STCNOFF"...: letters from S, T,
 * C, N and then OFF. "4OFF"/"nOFF" (other dimensions) are not accepted. */
static int is_off_keyword(const char *t, size_t n)
{
    if (n < 3 || memcmp(t + n - 3, "OFF", 3) != 0)
        return 0;
    for (size_t i = 0; i + 3 < n; i++)
        if (!strchr("STCN", t[i]) || t[i] == '\0')
            return 0;
    return 1;
}

/* Reads "nv nf [ne]" from [p, e). Returns the number of integers read (up to
 * 3), or -1 at a token that is not a non-negative integer. */
static int read_counts(const char *p, const char *e, long c[3], const char **bad, size_t *badn)
{
    const char *tok;
    size_t n;
    int k = 0;
    while (iso_mesh__token(&p, e, &tok, &n)) {
        if (k == 3 || iso_mesh__to_long(tok, n, &c[k]) || c[k] < 0) {
            *bad = tok;
            *badn = n;
            return -1;
        }
        k++;
    }
    return k;
}

static int read_header(iso_mesh__builder *b, iso_mesh__text *t, long *nv, long *nf, iso_err *err)
{
    const char *p, *e, *tok;
    size_t n;
    char loc[320], q[40];
    if (!iso_mesh__text_line(t, 1, &p, &e))
        return iso_err_set(err, ISO_EPARSE, -1, "%s: empty file (no OFF header)", b->name);
    iso_mesh__token(&p, e, &tok, &n);
    if (!is_off_keyword(tok, n))
        return iso_err_set(err, ISO_EPARSE, t->line, "%s: expected the OFF header, found '%s'",
                           iso_mesh__where(loc, sizeof loc, b, t->line),
                           iso_mesh__quote(q, sizeof q, tok, n));
    long c[3];
    const char *badt = NULL;
    size_t badn = 0;
    int k = read_counts(p, e, c, &badt, &badn);
    if (k == 0) {
        if (!iso_mesh__text_line(t, 1, &p, &e))
            return iso_err_set(err, ISO_EPARSE, t->line,
                               "%s: file ends after the OFF keyword (no counts line)",
                               iso_mesh__where(loc, sizeof loc, b, t->line));
        k = read_counts(p, e, c, &badt, &badn);
    }
    if (k < 0)
        return iso_err_set(err, ISO_EPARSE, t->line,
                           "%s: bad counts line: '%s' is not a non-negative integer (expected "
                           "\"vertices faces [edges]\")",
                           iso_mesh__where(loc, sizeof loc, b, t->line),
                           iso_mesh__quote(q, sizeof q, badt, badn));
    if (k < 2)
        return iso_err_set(err, ISO_EPARSE, t->line,
                           "%s: bad counts line: expected \"vertices faces [edges]\", found %d "
                           "number(s)",
                           iso_mesh__where(loc, sizeof loc, b, t->line), k);
    /* Every vertex line needs at least 6 bytes ("0 0 0\n"), every face line 8
     * ("3 0 1 2\n"): a header that promises more than the file holds is
     * refused before anything is read or allocated. */
    size_t left = (size_t)(t->end - t->p) + 1;
    if ((size_t)c[0] > left || (size_t)c[1] > left ||
        6 * (size_t)c[0] + 8 * (size_t)c[1] > left + 2)
        return iso_err_set(err, ISO_EPARSE, t->line,
                           "%s: the header announces %ld vertices and %ld faces, but only %zu "
                           "bytes follow: the counts are wrong or the file is truncated",
                           iso_mesh__where(loc, sizeof loc, b, t->line), c[0], c[1], left - 1);
    *nv = c[0];
    *nf = c[1];
    return ISO_OK;
}

static int read_vertices(iso_mesh__builder *b, iso_mesh__text *t, long nv, iso_err *err)
{
    const char *p, *e, *tok;
    size_t n;
    char loc[320], q[40];
    for (long i = 0; i < nv; i++) {
        if (!iso_mesh__text_line(t, 1, &p, &e))
            return iso_err_set(err, ISO_EPARSE, t->line,
                               "%s: file ends after %ld of %ld vertices (truncated?)",
                               iso_mesh__where(loc, sizeof loc, b, t->line), i, nv);
        double v[3];
        for (int c = 0; c < 3; c++) {
            if (!iso_mesh__token(&p, e, &tok, &n))
                return iso_err_set(err, ISO_EPARSE, t->line,
                                   "%s: vertex %ld has %d coordinate(s), expected 3",
                                   iso_mesh__where(loc, sizeof loc, b, t->line), i, c);
            if (iso_mesh__to_double(tok, n, &v[c]))
                return iso_err_set(err, ISO_EPARSE, t->line, "%s: vertex %ld: '%s' is not a number",
                                   iso_mesh__where(loc, sizeof loc, b, t->line), i,
                                   iso_mesh__quote(q, sizeof q, tok, n));
        }
        int rc = iso_mesh__add_vertex(b, v, t->line, err);
        if (rc != ISO_OK)
            return rc;
    }
    return ISO_OK;
}

static int read_faces(iso_mesh__builder *b, iso_mesh__text *t, long nf, iso_err *err)
{
    const char *p, *e, *tok;
    size_t n;
    char loc[320], q[40];
    for (long f = 0; f < nf; f++) {
        if (!iso_mesh__text_line(t, 1, &p, &e))
            return iso_err_set(err, ISO_EPARSE, t->line,
                               "%s: file ends after %ld of %ld faces (truncated?)",
                               iso_mesh__where(loc, sizeof loc, b, t->line), f, nf);
        long k;
        iso_mesh__token(&p, e, &tok, &n);
        if (iso_mesh__to_long(tok, n, &k))
            return iso_err_set(err, ISO_EPARSE, t->line,
                               "%s: face %ld: vertex count '%s' is not an integer",
                               iso_mesh__where(loc, sizeof loc, b, t->line), f,
                               iso_mesh__quote(q, sizeof q, tok, n));
        if (k < 3)
            return iso_err_set(err, ISO_EPARSE, t->line,
                               "%s: face %ld has %ld vertices; a face needs at least 3",
                               iso_mesh__where(loc, sizeof loc, b, t->line), f, k);
        int rc = iso_mesh__face_begin(b, t->line, err);
        if (rc != ISO_OK)
            return rc;
        for (long c = 0; c < k; c++) {
            long idx;
            if (!iso_mesh__token(&p, e, &tok, &n))
                return iso_err_set(err, ISO_EPARSE, t->line,
                                   "%s: face %ld announces %ld vertices but lists %ld",
                                   iso_mesh__where(loc, sizeof loc, b, t->line), f, k, c);
            if (iso_mesh__to_long(tok, n, &idx))
                return iso_err_set(err, ISO_EPARSE, t->line,
                                   "%s: face %ld: vertex index '%s' is not an integer",
                                   iso_mesh__where(loc, sizeof loc, b, t->line), f,
                                   iso_mesh__quote(q, sizeof q, tok, n));
            if ((rc = iso_mesh__face_index(b, idx, err)) != ISO_OK)
                return rc;
        }
        /* The rest of the line may be a colour; it is not ours to check. */
        if ((rc = iso_mesh__face_end(b, err)) != ISO_OK)
            return rc;
    }
    return ISO_OK;
}

int iso_mesh__read_off(iso_mesh__builder *b, const char *data, size_t len, iso_err *err)
{
    iso_mesh__text t;
    long nv = 0, nf = 0;
    int rc;
    iso_mesh__text_init(&t, data, len);
    if ((rc = read_header(b, &t, &nv, &nf, err)) != ISO_OK ||
        (rc = read_vertices(b, &t, nv, err)) != ISO_OK ||
        (rc = read_faces(b, &t, nf, err)) != ISO_OK)
        return rc;
    const char *p, *e;
    if (iso_mesh__text_line(&t, 1, &p, &e)) {
        char loc[320];
        return iso_err_set(err, ISO_EPARSE, t.line,
                           "%s: unexpected content after the %ld faces the header announced "
                           "(wrong counts?)",
                           iso_mesh__where(loc, sizeof loc, b, t.line), nf);
    }
    return ISO_OK;
}
