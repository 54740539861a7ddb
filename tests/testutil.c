/* tests/testutil.c -- see testutil.h. */
#include "testutil.h"

#include <math.h>
#include <stdio.h>
#include <string.h>
#include <sys/stat.h>

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

const char *iso_test_data(char *buf, size_t cap, const char *rel)
{
    snprintf(buf, cap, "%s/%s", ISO_TEST_DATA, rel);
    return buf;
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
