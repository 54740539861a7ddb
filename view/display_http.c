/* view/display_http.c -- see display_internal.h: the view's HTTP request
 * parsing and host names, apart from the server so that a fuzz target can
 * build them alone (tests/fuzz/fuzz_http.c). */
#include "display_internal.h"

#include <string.h>
#include <strings.h>

int iso_display__token_eq(const char *p, size_t n, const char *s)
{
    return strlen(s) == n && strncasecmp(p, s, n) == 0;
}

int iso_display__list_has(const char *p, size_t n, const char *s)
{
    const char *e = p + n;
    while (p < e) {
        const char *comma = memchr(p, ',', (size_t)(e - p));
        const char *te = comma ? comma : e;
        const char *b = p;
        while (b < te && (*b == ' ' || *b == '\t'))
            b++;
        const char *t = te;
        while (t > b && (t[-1] == ' ' || t[-1] == '\t'))
            t--;
        if ((size_t)(t - b) == strlen(s) && memcmp(b, s, (size_t)(t - b)) == 0)
            return 1;
        p = comma ? comma + 1 : e;
    }
    return 0;
}

int iso_display__contains_ci(const char *p, size_t n, const char *s)
{
    size_t k = strlen(s);
    for (size_t i = 0; i + k <= n; i++)
        if (strncasecmp(p + i, s, k) == 0)
            return 1;
    return 0;
}

/* One header line [line, end): the fields the view reads, first wins for
 * Host and Origin (a second one is a smuggling attempt, not an update). */
static void take_header(char *line, char *end, iso_display__request *r)
{
    char *colon = memchr(line, ':', (size_t)(end - line));
    if (!colon)
        return;
    const char *v = colon + 1;
    while (v < end && (*v == ' ' || *v == '\t'))
        v++;
    const char *ve = end;
    while (ve > v && (ve[-1] == ' ' || ve[-1] == '\t'))
        ve--;
    size_t nl = (size_t)(colon - line), vl = (size_t)(ve - v);
    if (iso_display__token_eq(line, nl, "host") && !r->host)
        r->host = v, r->host_len = vl;
    else if (iso_display__token_eq(line, nl, "origin") && !r->origin)
        r->origin = v, r->origin_len = vl;
    else if (iso_display__token_eq(line, nl, "upgrade"))
        r->upgrade = v, r->upgrade_len = vl;
    else if (iso_display__token_eq(line, nl, "sec-websocket-key"))
        r->key = v, r->key_len = vl;
    else if (iso_display__token_eq(line, nl, "sec-websocket-version"))
        r->version = v, r->version_len = vl;
    else if (iso_display__token_eq(line, nl, "sec-websocket-protocol"))
        r->protocol = v, r->protocol_len = vl;
}

int iso_display__parse_request(char *buf, iso_display__request *r)
{
    memset(r, 0, sizeof *r);
    char *eol = strstr(buf, "\r\n");
    if (!eol)
        return -1;
    char *sp1 = memchr(buf, ' ', (size_t)(eol - buf));
    if (!sp1)
        return -1;
    char *sp2 = memchr(sp1 + 1, ' ', (size_t)(eol - sp1 - 1));
    if (!sp2 || sp1 == buf || sp2 == sp1 + 1 || (size_t)(eol - sp2 - 1) < 7 ||
        strncmp(sp2 + 1, "HTTP/1.", 7) != 0)
        return -1;
    r->method = buf;
    r->method_len = (size_t)(sp1 - buf);
    r->path = sp1 + 1;
    r->path_len = (size_t)(sp2 - sp1 - 1);
    const char *q = memchr(r->path, '?', r->path_len);
    if (q) {
        r->query = q + 1;
        r->query_len = r->path_len - (size_t)(q + 1 - r->path);
        r->path_len = (size_t)(q - r->path);
    }
    for (char *line = eol + 2; *line && !(line[0] == '\r' && line[1] == '\n');) {
        char *end = strstr(line, "\r\n");
        if (!end) /* the headers must end in an empty line */
            return -1;
        take_header(line, end, r);
        line = end + 2;
    }
    return 0;
}

const char *iso_display__query_get(const char *q, size_t n, const char *key, size_t *len)
{
    size_t kl = strlen(key);
    for (size_t i = 0; q && i < n;) {
        const char *amp = memchr(q + i, '&', n - i);
        size_t end = amp ? (size_t)(amp - q) : n;
        if (end - i > kl && q[i + kl] == '=' && memcmp(q + i, key, kl) == 0) {
            *len = end - i - kl - 1;
            return q + i + kl + 1;
        }
        i = end + 1;
    }
    *len = 0;
    return NULL;
}

int iso_display__authority_is(const char *a, size_t n, int port, int port_optional,
                              const char *const *names, size_t n_names)
{
    size_t hn = n;
    if (n && a[0] == '[') {
        const char *rb = memchr(a, ']', n);
        if (!rb)
            return 0;
        hn = (size_t)(rb - a) + 1;
    } else {
        const char *colon = memchr(a, ':', n);
        hn = colon ? (size_t)(colon - a) : n;
    }
    if (hn < n) {
        if (a[hn] != ':' || hn + 1 == n || n - hn - 1 > 5)
            return 0;
        int p = 0;
        for (const char *s = a + hn + 1; s < a + n; s++) {
            if (*s < '0' || *s > '9')
                return 0;
            p = 10 * p + (*s - '0');
        }
        if (p != port)
            return 0;
    } else if (!port_optional && port != 80) {
        return 0;
    }
    if (hn == 0)
        return 0;
    for (size_t i = 0; i < n_names; i++)
        if (names[i] && iso_display__token_eq(a, hn, names[i]))
            return 1;
    return 0;
}
