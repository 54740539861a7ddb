/* tests/fuzz/fuzz_http.c -- the live view's HTTP request parsing
 * (view/display_http.c) under arbitrary bytes, as the server hands them
 * over: text without NUL bytes (the server refuses those), cut after the
 * first empty line. Every field the parser returns must lie inside the
 * buffer, and the host checks must answer without reading past a field. */
#include <stdlib.h>
#include <string.h>

#include "display_internal.h"

static void inside(const char *buf, size_t n, const char *p, size_t len)
{
    if (p && (p < buf || p + len > buf + n))
        abort();
}

int LLVMFuzzerTestOneInput(const unsigned char *data, size_t size)
{
    if (size > ISO_DISPLAY_MAX_REQUEST)
        size = ISO_DISPLAY_MAX_REQUEST;
    char *buf = malloc(size + 5);
    if (!buf)
        return 0;
    memcpy(buf, data, size);
    buf[size] = 0;
    size_t n = strlen(buf); /* up to the first NUL, as the server would refuse it */
    char *end = strstr(buf, "\r\n\r\n");
    if (end)
        n = (size_t)(end - buf) + 4;
    else
        memcpy(buf + n, "\r\n\r\n", 4), n += 4;
    buf[n] = 0;
    iso_display__request r;
    if (iso_display__parse_request(buf, &r) == 0) {
        inside(buf, n, r.method, r.method_len);
        inside(buf, n, r.path, r.path_len);
        inside(buf, n, r.host, r.host_len);
        inside(buf, n, r.origin, r.origin_len);
        inside(buf, n, r.upgrade, r.upgrade_len);
        inside(buf, n, r.key, r.key_len);
        inside(buf, n, r.version, r.version_len);
        inside(buf, n, r.query, r.query_len);
        inside(buf, n, r.protocol, r.protocol_len);
        if (!r.method || r.method_len == 0 || !r.path)
            abort();
        const char *names[] = {"localhost", "127.0.0.1", "[::1]", NULL};
        if (r.host)
            (void)iso_display__authority_is(r.host, r.host_len, 8080, 1, names, 4);
        if (r.origin && r.origin_len > 7)
            (void)iso_display__authority_is(r.origin + 7, r.origin_len - 7, 8080, 0, names, 4);
        if (r.upgrade)
            (void)iso_display__contains_ci(r.upgrade, r.upgrade_len, "websocket");
        char accept[29];
        if (r.key)
            (void)iso_display__ws_accept(r.key, r.key_len, accept);
        size_t tl = 0;
        const char *tok = iso_display__query_get(r.query, r.query_len, "token", &tl);
        if (tok)
            inside(buf, n, tok, tl);
    }
    free(buf);
    return 0;
}
