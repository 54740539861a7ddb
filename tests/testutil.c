/* tests/testutil.c -- see testutil.h. */
#include "testutil.h"

#include <limits.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

const char *iso_test_tmp(char *buf, size_t cap, const char *name)
{
    mkdir(ISO_TEST_TMP, 0755);
    snprintf(buf, cap, "%s/%s", ISO_TEST_TMP, name);
    return buf;
}

void iso_test_write(const char *path, const char *text, long len)
{
    FILE *f = fopen(path, "wb");
    assert_non_null(f);
    size_t n = len < 0 ? strlen(text) : (size_t)len;
    assert_int_equal(fwrite(text, 1, n, f), n);
    assert_int_equal(fclose(f), 0);
}

int iso_test_benchmark(char *buf, size_t cap, const char *rel)
{
    struct stat st;
    snprintf(buf, cap, "%s/%s", ISO_BENCHMARK_DIR, rel);
    return stat(buf, &st) == 0;
}

double iso_test_max_abs_diff(const double *a, const double *b, size_t n)
{
    double m = 0;
    for (size_t i = 0; i < n; i++)
        m = fmax(m, fabs(a[i] - b[i]));
    return m;
}

double iso_test_max_abs(const double *a, size_t n)
{
    double m = 0;
    for (size_t i = 0; i < n; i++)
        m = fmax(m, fabs(a[i]));
    return m;
}

double iso_test_vertex_max_diff(const double *a, const double *b, int nv)
{
    double m = 0;
    for (int i = 0; i < nv; i++) {
        double d0 = a[3 * i] - b[3 * i], d1 = a[3 * i + 1] - b[3 * i + 1],
               d2 = a[3 * i + 2] - b[3 * i + 2];
        m = fmax(m, sqrt(d0 * d0 + d1 * d1 + d2 * d2));
    }
    return m;
}

/* The end of the JSON string that starts at s (at its opening quote). */
static const char *string_end(const char *s)
{
    for (s++; *s && *s != '"'; s++)
        if (*s == '\\' && s[1])
            s++;
    return s;
}

double iso_test_json_num(const char *json, const char *key)
{
    char k[128];
    snprintf(k, sizeof k, "\"%s\": ", key);
    const char *p = strstr(json, k);
    if (!p)
        fail_msg("no \"%s\" in the JSON", key);
    return strtod(p + strlen(k), NULL);
}

int iso_test_json_keys_snake_case(const char *json, char *bad, size_t cap)
{
    for (const char *p = json; *p; p++) {
        if (*p != '"')
            continue;
        const char *end = string_end(p);
        const char *after = end + (*end != '\0');
        after += strspn(after, " \t\r\n");
        if (*after == ':') {
            int ok = p[1] >= 'a' && p[1] <= 'z';
            for (const char *c = p + 1; c < end; c++)
                ok = ok && ((*c >= 'a' && *c <= 'z') || (*c >= '0' && *c <= '9') || *c == '_');
            if (!ok) {
                snprintf(bad, cap, "%.*s", (int)(end - p - 1), p + 1);
                return 0;
            }
        }
        if (!*end)
            break;
        p = end;
    }
    return 1;
}

static void slurp(const char *path, char *buf, size_t cap)
{
    FILE *f = fopen(path, "rb");
    size_t n = 0;
    if (f) {
        n = fread(buf, 1, cap - 1, f);
        fclose(f);
    }
    buf[n] = '\0';
}

int iso_test_sh(const char *cmd, char *out, size_t out_cap, char *err, size_t err_cap)
{
    char o[PATH_MAX], e[PATH_MAX], name[64];
    snprintf(name, sizeof name, "sh_%ld.stdout", (long)getpid());
    iso_test_tmp(o, sizeof o, name);
    snprintf(name, sizeof name, "sh_%ld.stderr", (long)getpid());
    iso_test_tmp(e, sizeof e, name);
    size_t cap = strlen(cmd) + strlen(o) + strlen(e) + 32;
    char *line = malloc(cap);
    assert_non_null(line);
    snprintf(line, cap, "%s >'%s' 2>'%s' </dev/null", cmd, o, e);
    int st = system(line);
    free(line);
    slurp(o, out, out_cap);
    slurp(e, err, err_cap);
    return st != -1 && WIFEXITED(st) ? WEXITSTATUS(st) : -1;
}

int iso_test_isoshape_bin(char *buf, size_t cap)
{
    const char *env = getenv("ISOSHAPE_BIN");
    if (env && *env) {
        snprintf(buf, cap, "%s", env);
        return access(buf, X_OK);
    }
    char self[PATH_MAX];
    ssize_t n = readlink("/proc/self/exe", self, sizeof self - 1);
    if (n <= 0)
        return -1;
    self[n] = '\0';
    for (int up = 0; up < 2; up++) { /* <build>/tests/test_x -> <build> */
        char *slash = strrchr(self, '/');
        if (!slash)
            return -1;
        *slash = '\0';
    }
    snprintf(buf, cap, "%s/isoshape", self);
    return access(buf, X_OK);
}

double iso_test_now_s(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + ts.tv_nsec * 1e-9;
}

void iso_test_nap_ms(int ms)
{
    struct timespec ts = {ms / 1000, (long)(ms % 1000) * 1000000L};
    nanosleep(&ts, NULL);
}
