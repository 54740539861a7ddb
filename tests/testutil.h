/* tests/testutil.h -- small helpers shared by the cmocka test programs. */
#ifndef ISO_TESTUTIL_H
#define ISO_TESTUTIL_H

#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>

/* cmocka.h needs the four above first. */
#include <cmocka.h>

/* Exit code CTest reads as "skipped" (SKIP_RETURN_CODE). */
#define ISO_TEST_SKIP 77

/* Writes a path under the test build's tmp folder into buf. */
const char *iso_test_tmp(char *buf, size_t cap, const char *name);
/* Writes `len` bytes (or strlen(text) if len < 0) to path; asserts success. */
void iso_test_write(const char *path, const char *text, long len);
/* Path of a benchmark file (e.g. "03-cactus-bend/cactus.off") into buf;
 * returns 1 if the file exists, else 0. */
int iso_test_benchmark(char *buf, size_t cap, const char *rel);

/* max |a_i - b_i| over n entries. */
double iso_test_max_abs_diff(const double *a, const double *b, size_t n);
/* max |a_i| */
double iso_test_max_abs(const double *a, size_t n);
/* Largest Euclidean norm of a vertex's difference a - b (nv xyz triples). */
double iso_test_vertex_max_diff(const double *a, const double *b, int nv);

/* Every object key in the JSON text is snake_case ([a-z][a-z0-9_]*, the
 * key style of every command's output, common/iso_json.h). Returns 1, or 0
 * with the first key that is not in bad. */
int iso_test_json_keys_snake_case(const char *json, char *bad, size_t cap);
/* The number after the first "key": in the JSON text; fails the test when
 * the key is absent. */
double iso_test_json_num(const char *json, const char *key);

/* Runs `sh -c "<cmd>"` with stdin from /dev/null and stdout and stderr
 * captured into out and err (NUL-terminated, truncated to cap). Returns the
 * exit status, or -1 when it did not exit normally. */
int iso_test_sh(const char *cmd, char *out, size_t out_cap, char *err, size_t err_cap);
/* The isoshape binary: $ISOSHAPE_BIN, else <build>/isoshape next to this
 * test's build folder. Returns 0 if it is there and executable. */
int iso_test_isoshape_bin(char *buf, size_t cap);

/* Seconds on CLOCK_MONOTONIC, and a sleep of ms milliseconds. */
double iso_test_now_s(void);
void iso_test_nap_ms(int ms);

#endif
