/* tests/test_version.c -- the library's version (common/iso_version.h):
 *   (a) iso_version() is "MAJOR.MINOR.PATCH" of the header's three numbers,
 *       and iso_version_number() their MAJOR * 10000 + MINOR * 100 + PATCH;
 *   (b) both equal the version CMake read from the header for the project
 *       (the shared library's file name, isoshape.pc), passed to this test
 *       as ISO_TEST_PROJECT_VERSION: a parse that went wrong fails here;
 *   (c) `isoshape --version` names the library it runs with.
 * The test links the shared library, so it also needs iso_version exported. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "iso_version.h"
#include "testutil.h"

#ifndef ISO_TEST_PROJECT_VERSION
#error "tests/CMakeLists.txt passes the project's version as ISO_TEST_PROJECT_VERSION"
#endif

static void string_and_number_follow_the_header(void **state)
{
    (void)state;
    char want[64];
    snprintf(want, sizeof want, "%d.%d.%d", ISO_VERSION_MAJOR, ISO_VERSION_MINOR,
             ISO_VERSION_PATCH);
    assert_string_equal(iso_version(), want);
    assert_string_equal(iso_version(), ISO_VERSION_STRING);
    assert_int_equal(iso_version_number(), ISO_VERSION_NUMBER);
    assert_int_equal(iso_version_number(),
                     ISO_VERSION_MAJOR * 10000 + ISO_VERSION_MINOR * 100 + ISO_VERSION_PATCH);
    assert_true(iso_version() == iso_version()); /* static storage */
}

static void the_build_reads_the_same_version(void **state)
{
    (void)state;
    assert_string_equal(iso_version(), ISO_TEST_PROJECT_VERSION);
    int major = -1, minor = -1, patch = -1;
    assert_int_equal(sscanf(ISO_TEST_PROJECT_VERSION, "%d.%d.%d", &major, &minor, &patch), 3);
    assert_int_equal(iso_version_number(), major * 10000 + minor * 100 + patch);
}

static void the_command_names_the_library_version(void **state)
{
    (void)state;
    char bin[4096], cmd[4200], out[8192], err[4096];
    if (iso_test_isoshape_bin(bin, sizeof bin) != 0)
        skip(); /* test_cli covers the command; here it is only a cross-check */
    snprintf(cmd, sizeof cmd, "'%s' --version", bin);
    assert_int_equal(iso_test_sh(cmd, out, sizeof out, err, sizeof err), 0);
    char want[128];
    snprintf(want, sizeof want, "isoshape %s\n", iso_version());
    assert_true(strncmp(out, want, strlen(want)) == 0);
}

int main(void)
{
    const struct CMUnitTest t[] = {
        cmocka_unit_test(string_and_number_follow_the_header),
        cmocka_unit_test(the_build_reads_the_same_version),
        cmocka_unit_test(the_command_names_the_library_version),
    };
    return cmocka_run_group_tests_name("version", t, NULL, NULL);
}
