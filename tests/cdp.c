/* tests/cdp.c -- see cdp.h. */
#include "cdp.h"

#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <poll.h>
#include <signal.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

static const char *const chromium_flags[] = {"--headless",
                                             "--no-sandbox",
                                             "--disable-gpu",
                                             "--use-angle=swiftshader",
                                             "--enable-unsafe-swiftshader",
                                             "--disable-quic",
                                             "--no-first-run",
                                             "--disable-background-networking",
                                             "--disable-component-update",
                                             "--disable-sync",
                                             "--disable-background-timer-throttling",
                                             "--disable-renderer-backgrounding",
                                             "--disable-backgrounding-occluded-windows",
                                             "--mute-audio",
                                             "--window-size=800,600",
                                             "--remote-debugging-pipe"};

static void say(iso_cdp *c, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
static void say(iso_cdp *c, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(c->why, sizeof c->why, fmt, ap);
    va_end(ap);
}

static long long now_ms(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (long long)ts.tv_sec * 1000 + ts.tv_nsec / 1000000;
}

int iso_cdp_start(iso_cdp *c, const char *profile, const char *log)
{
    memset(c, 0, sizeof *c);
    c->to_fd = c->from_fd = -1;
    c->pid = -1;
    if (access(ISO_CDP_CHROMIUM, X_OK) != 0) {
        say(c, "%s is not installed (apt-get install chromium)", ISO_CDP_CHROMIUM);
        return 77;
    }
    snprintf(c->profile, sizeof c->profile, "%s", profile);
    char rm[600];
    snprintf(rm, sizeof rm, "rm -rf '%s'", profile);
    if (system(rm) != 0)
        return say(c, "cannot clear %s", profile), -1;
    int in[2], out[2];
    if (pipe(in) != 0 || pipe(out) != 0)
        return say(c, "pipe: %s", strerror(errno)), -1;
    c->pid = fork();
    if (c->pid < 0)
        return say(c, "fork: %s", strerror(errno)), -1;
    if (c->pid == 0) {
        /* Chromium reads commands on fd 3 and writes on fd 4. */
        int lg = open(log, O_WRONLY | O_CREAT | O_TRUNC, 0644);
        int nul = open("/dev/null", O_RDWR);
        int r = dup(in[0]), w = dup(out[1]); /* above 4 whatever they were */
        while (r <= 4)
            r = dup(r);
        while (w <= 4)
            w = dup(w);
        dup2(nul, 0);
        dup2(lg >= 0 ? lg : nul, 1);
        dup2(lg >= 0 ? lg : nul, 2);
        dup2(r, 3);
        dup2(w, 4);
        for (int fd = 5; fd < 1024; fd++)
            close(fd);
        char dir[600];
        snprintf(dir, sizeof dir, "--user-data-dir=%s", profile);
        const char *argv[32];
        int n = 0;
        argv[n++] = ISO_CDP_CHROMIUM;
        for (size_t i = 0; i < sizeof chromium_flags / sizeof chromium_flags[0]; i++)
            argv[n++] = chromium_flags[i];
        argv[n++] = dir;
        argv[n++] = "about:blank";
        argv[n] = NULL;
        execv(ISO_CDP_CHROMIUM, (char *const *)argv);
        _exit(127);
    }
    close(in[0]);
    close(out[1]);
    c->to_fd = in[1];
    c->from_fd = out[0];
    fcntl(c->from_fd, F_SETFL, fcntl(c->from_fd, F_GETFL) | O_NONBLOCK);
    c->cap = 1 << 16;
    c->buf = malloc(c->cap);
    c->next_id = 1;
    return c->buf ? 0 : (say(c, "out of memory"), -1);
}

/* The next whole message (NUL-terminated, malloc'd), or NULL at the
 * deadline or when Chromium is gone. */
static char *next_message(iso_cdp *c, long long deadline)
{
    for (;;) {
        char *nul = c->len ? memchr(c->buf, 0, c->len) : NULL;
        if (nul) {
            size_t n = (size_t)(nul - c->buf) + 1;
            char *m = malloc(n);
            if (!m)
                return NULL;
            memcpy(m, c->buf, n);
            memmove(c->buf, c->buf + n, c->len - n);
            c->len -= n;
            return m;
        }
        long long left = deadline - now_ms();
        if (left <= 0)
            return say(c, "no answer from Chromium in time"), NULL;
        struct pollfd p = {c->from_fd, POLLIN, 0};
        if (poll(&p, 1, (int)(left > 1000 ? 1000 : left)) < 0 && errno != EINTR)
            return say(c, "poll: %s", strerror(errno)), NULL;
        if (c->len + 65536 > c->cap) {
            char *b = realloc(c->buf, c->cap * 2);
            if (!b)
                return NULL;
            c->buf = b;
            c->cap *= 2;
        }
        ssize_t r = read(c->from_fd, c->buf + c->len, c->cap - c->len);
        if (r == 0)
            return say(c, "Chromium closed its DevTools pipe (did it crash? see its log)"), NULL;
        if (r > 0)
            c->len += (size_t)r;
    }
}

static int write_all(int fd, const char *p, size_t n)
{
    while (n) {
        ssize_t w = write(fd, p, n);
        if (w < 0 && errno == EINTR)
            continue;
        if (w <= 0)
            return -1;
        p += w;
        n -= (size_t)w;
    }
    return 0;
}

char *iso_cdp_call(iso_cdp *c, int on_page, const char *method, const char *params, int timeout_ms)
{
    int id = c->next_id++;
    size_t cap = strlen(params ? params : "{}") + 512;
    char *cmd = malloc(cap);
    if (!cmd)
        return NULL;
    int n = snprintf(cmd, cap, "{\"id\":%d,\"method\":\"%s\",\"params\":%s%s%s%s}", id, method,
                     params ? params : "{}", on_page ? ",\"sessionId\":\"" : "",
                     on_page ? c->session : "", on_page ? "\"" : "");
    int bad = write_all(c->to_fd, cmd, (size_t)n + 1); /* the NUL ends the message */
    free(cmd);
    if (bad)
        return say(c, "%s: cannot write to Chromium", method), NULL;
    char want[32];
    snprintf(want, sizeof want, "{\"id\":%d,", id);
    long long deadline = now_ms() + timeout_ms;
    for (;;) {
        char *m = next_message(c, deadline);
        if (!m) {
            char why[256];
            snprintf(why, sizeof why, "%.255s", c->why);
            say(c, "%s: %s", method, why);
            return NULL;
        }
        if (strncmp(m, want, strlen(want)) != 0) { /* an event, or another answer */
            free(m);
            continue;
        }
        if (strstr(m, "\"error\":{")) {
            say(c, "%s: %.400s", method, m);
            free(m);
            return NULL;
        }
        return m;
    }
}

/* The string value after `key` ("value":"...") unescaped, malloc'd. */
static char *json_string(const char *json, const char *key)
{
    char k[64];
    snprintf(k, sizeof k, "\"%s\":\"", key);
    const char *p = strstr(json, k);
    if (!p)
        return NULL;
    p += strlen(k);
    char *out = malloc(strlen(p) + 1), *o = out;
    if (!out)
        return NULL;
    for (; *p && *p != '"'; p++) {
        if (*p != '\\') {
            *o++ = *p;
            continue;
        }
        p++;
        switch (*p) {
        case 'n': *o++ = '\n'; break;
        case 't': *o++ = '\t'; break;
        case 'r': *o++ = '\r'; break;
        case 'b': *o++ = '\b'; break;
        case 'f': *o++ = '\f'; break;
        case 'u': {
            unsigned v = 0;
            for (int i = 1; i <= 4 && p[i]; i++)
                v = v * 16 + (unsigned)(p[i] <= '9' ? p[i] - '0' : (p[i] | 32) - 'a' + 10);
            *o++ = v < 128 ? (char)v : '?';
            p += 4;
            break;
        }
        case '\0': p--; break;
        default: *o++ = *p; break; /* \" \\ \/ */
        }
    }
    *o = 0;
    return out;
}

int iso_cdp_open(iso_cdp *c, const char *url, int timeout_ms)
{
    char params[1200];
    snprintf(params, sizeof params, "{\"url\":\"%s\"}", url);
    char *r = iso_cdp_call(c, 0, "Target.createTarget", params, timeout_ms);
    char *target = r ? json_string(r, "targetId") : NULL;
    free(r);
    if (!target)
        return -1;
    snprintf(params, sizeof params, "{\"targetId\":\"%s\",\"flatten\":true}", target);
    free(target);
    r = iso_cdp_call(c, 0, "Target.attachToTarget", params, timeout_ms);
    char *session = r ? json_string(r, "sessionId") : NULL;
    free(r);
    if (!session)
        return -1;
    snprintf(c->session, sizeof c->session, "%s", session);
    free(session);
    /* the page gets the whole window, whatever headless keeps for itself */
    r = iso_cdp_call(c, 1, "Emulation.setDeviceMetricsOverride",
                     "{\"width\":800,\"height\":600,\"deviceScaleFactor\":1,\"mobile\":false}",
                     timeout_ms);
    free(r);
    if (!r)
        return -1;
    r = iso_cdp_call(c, 1, "Page.enable", NULL, timeout_ms);
    free(r);
    return r ? 0 : -1;
}

char *iso_cdp_eval(iso_cdp *c, const char *expr, int timeout_ms)
{
    size_t cap = 2 * strlen(expr) + 128;
    char *params = malloc(cap), *o = params;
    if (!params)
        return NULL;
    o += sprintf(o, "{\"expression\":\"");
    for (const char *p = expr; *p; p++) {
        if (*p == '"' || *p == '\\')
            *o++ = '\\';
        *o++ = *p == '\n' ? ' ' : *p;
    }
    sprintf(o, "\",\"returnByValue\":true}");
    char *r = iso_cdp_call(c, 1, "Runtime.evaluate", params, timeout_ms);
    free(params);
    if (!r)
        return NULL;
    char *v = strstr(r, "\"exceptionDetails\"") ? NULL : json_string(r, "value");
    if (!v)
        say(c, "Runtime.evaluate: %.400s", r);
    free(r);
    return v;
}

int iso_cdp_wait(iso_cdp *c, const char *cond, int timeout_ms)
{
    size_t cap = strlen(cond) + 64;
    char *expr = malloc(cap);
    if (!expr)
        return 0;
    snprintf(expr, cap, "String(!!(%s))", cond);
    long long deadline = now_ms() + timeout_ms;
    int ok = 0;
    while (!ok) {
        char *v = iso_cdp_eval(c, expr, 10000);
        ok = v && strcmp(v, "true") == 0;
        free(v);
        if (ok || now_ms() >= deadline)
            break;
        struct timespec ts = {0, 50 * 1000 * 1000};
        nanosleep(&ts, NULL);
    }
    if (!ok)
        say(c, "waited %d ms for %.300s", timeout_ms, cond);
    free(expr);
    return ok;
}

int iso_cdp_mouse(iso_cdp *c, const char *type, double x, double y, int left)
{
    char params[256];
    snprintf(params, sizeof params,
             "{\"type\":\"%s\",\"x\":%.3f,\"y\":%.3f,\"button\":\"%s\",\"buttons\":%d,"
             "\"clickCount\":%d}",
             type, x, y, "left", left && strcmp(type, "mouseReleased") ? 1 : 0,
             strcmp(type, "mouseMoved") ? 1 : 0);
    char *r = iso_cdp_call(c, 1, "Input.dispatchMouseEvent", params, 10000);
    free(r);
    return r ? 0 : -1;
}

int iso_cdp_key(iso_cdp *c, const char *key, const char *code, int keycode, int shift)
{
    const char *types[] = {"keyDown", "keyUp"};
    for (int i = 0; i < 2; i++) {
        char params[256];
        snprintf(params, sizeof params,
                 "{\"type\":\"%s\",\"key\":\"%s\",\"code\":\"%s\",\"windowsVirtualKeyCode\":%d,"
                 "\"modifiers\":%d}",
                 types[i], key, code, keycode, shift ? 8 : 0);
        char *r = iso_cdp_call(c, 1, "Input.dispatchKeyEvent", params, 10000);
        free(r);
        if (!r)
            return -1;
    }
    return 0;
}

static int b64(int ch)
{
    if (ch >= 'A' && ch <= 'Z')
        return ch - 'A';
    if (ch >= 'a' && ch <= 'z')
        return ch - 'a' + 26;
    if (ch >= '0' && ch <= '9')
        return ch - '0' + 52;
    return ch == '+' ? 62 : ch == '/' ? 63 : -1;
}

int iso_cdp_screenshot(iso_cdp *c, const char *path)
{
    char *r = iso_cdp_call(c, 1, "Page.captureScreenshot", "{\"format\":\"png\"}", 30000);
    char *data = r ? json_string(r, "data") : NULL;
    free(r);
    if (!data)
        return -1;
    FILE *f = fopen(path, "wb");
    if (!f) {
        free(data);
        return say(c, "cannot write %s", path), -1;
    }
    unsigned acc = 0;
    int bits = 0;
    for (const char *p = data; *p; p++) {
        int v = b64((unsigned char)*p);
        if (v < 0)
            continue;
        acc = acc << 6 | (unsigned)v;
        bits += 6;
        if (bits >= 8) {
            bits -= 8;
            fputc((int)(acc >> bits & 0xff), f);
        }
    }
    free(data);
    return fclose(f) == 0 ? 0 : -1;
}

void iso_cdp_stop(iso_cdp *c)
{
    if (c->pid > 0) {
        char *r = c->to_fd >= 0 ? iso_cdp_call(c, 0, "Browser.close", NULL, 5000) : NULL;
        free(r);
        int st;
        for (int i = 0; i < 100 && waitpid(c->pid, &st, WNOHANG) == 0; i++) {
            struct timespec ts = {0, 50 * 1000 * 1000};
            nanosleep(&ts, NULL);
            if (i == 60)
                kill(c->pid, SIGKILL); /* 3 s after asking: no more patience */
        }
        waitpid(c->pid, &st, WNOHANG);
        c->pid = -1;
    }
    if (c->to_fd >= 0)
        close(c->to_fd);
    if (c->from_fd >= 0)
        close(c->from_fd);
    c->to_fd = c->from_fd = -1;
    free(c->buf);
    c->buf = NULL;
    if (c->profile[0]) {
        char rm[600];
        snprintf(rm, sizeof rm, "rm -rf '%s'", c->profile);
        if (system(rm) != 0)
            fprintf(stderr, "cdp: could not remove %s\n", c->profile);
    }
}

double iso_cdp_num(const char *json, const char *key)
{
    char k[128];
    snprintf(k, sizeof k, "\"%s\":", key);
    const char *p = json ? strstr(json, k) : NULL;
    if (!p)
        return NAN;
    p += strlen(k);
    if (strncmp(p, "null", 4) == 0)
        return NAN;
    return strtod(p, NULL);
}
