/* tests/test_cli_opts.c -- the isoshape command's option tables
 * (controller/cli_opts.c): the parser, the range check and the --help
 * printer on a table of every kind, in-process. Links the command's static
 * library (isoshape_cmd), so it reaches controller/internal.h. */
#include "testutil.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "internal.h"

/* ---- a table of every kind ------------------------------------------------ */

typedef struct inner {
    double weight;
    int mode;
} inner;

typedef struct targs {
    int flag, count, color, calls;
    double x, speed, limit;
    const char *path, *name, *out;
    int pair[2];
    inner in;
} targs;

static const char *const colours[] = {"red", "green", "blue", NULL};

static int set_pair(const iso_cli__opt *o, void *dst, const char *val, char *why, size_t cap)
{
    int *p = dst;
    char tail;
    (void)o;
    if (sscanf(val, "%d,%d%c", &p[0], &p[1], &tail) != 2) {
        snprintf(why, cap, "expected two integers A,B");
        return -1;
    }
    return 0;
}

static int count_call(const iso_cli__opt *o, void *dst, const char *val, char *why, size_t cap)
{
    (void)o, (void)why, (void)cap;
    assert_null(val);
    (*(int *)dst)++;
    return 0;
}

/* Stores twice the value, up to a limit of its own: the row's range is
 * checked first, then this. */
static int set_limit(const iso_cli__opt *o, void *dst, const char *val, char *why, size_t cap)
{
    double v = strtod(val, NULL);
    (void)o;
    if (v > 10) {
        snprintf(why, cap, "above the setter's limit 10");
        return -1;
    }
    *(double *)dst = 2 * v;
    return 0;
}

static const iso_cli__opt inner_opts[] = {{"weight", ISO_CLI_OPT_DOUBLE,
                                           ISO_CLI_DOUBLE_AT(inner, weight), "W",
                                           .help = "a weight %R", ISO_CLI_GT(0), ISO_CLI_LE(1)},
                                          {"mode", ISO_CLI_OPT_ENUM, ISO_CLI_ENUM_AT(inner, mode),
                                           NULL, .help = "the mode", .names = colours},
                                          {0}};

static const iso_cli__opt opts[] = {
    {NULL, ISO_CLI_OPT_HEADING, 0, NULL, .help = "Things:"},
    {"flag", ISO_CLI_OPT_FLAG, ISO_CLI_INT_AT(targs, flag), NULL, .help = "a flag", .flag = 1},
    {"count", ISO_CLI_OPT_INT, ISO_CLI_INT_AT(targs, count), "N", .help = "a count %R, or none",
     ISO_CLI_GE(1), ISO_CLI_LE(99)},
    {"x", ISO_CLI_OPT_DOUBLE, ISO_CLI_DOUBLE_AT(targs, x), "X", .help = "any finite number"},
    {"speed", ISO_CLI_OPT_DOUBLE, ISO_CLI_DOUBLE_AT(targs, speed), "S",
     .help = "a speed whose range the help does not place", ISO_CLI_GT(0)},
    {"limit", ISO_CLI_OPT_DOUBLE, ISO_CLI_DOUBLE_AT(targs, limit), "L",
     .help = "a number the setter stores", ISO_CLI_GE(0), .set = set_limit},
    {"path", ISO_CLI_OPT_STRING, ISO_CLI_STRING_AT(targs, path), "FILE",
     .help = "a path, empty allowed"},
    {"name", ISO_CLI_OPT_STRING, ISO_CLI_STRING_AT(targs, name), "NAME", .help = "a name",
     .nonempty = 1},
    {"color", ISO_CLI_OPT_ENUM, ISO_CLI_ENUM_AT(targs, color), NULL, .help = "a colour",
     .names = colours},
    {"pair", ISO_CLI_OPT_CALL, offsetof(targs, pair), "A,B", .help = "two integers",
     .set = set_pair},
    {"call", ISO_CLI_OPT_FLAG, ISO_CLI_INT_AT(targs, calls), NULL, .help = "counts its calls",
     .set = count_call},
    {NULL, ISO_CLI_OPT_TABLE, ISO_CLI_AT(targs, in, inner), .table = inner_opts},
    {NULL, ISO_CLI_OPT_STRING, ISO_CLI_STRING_AT(targs, out), "FILE", .short_name = 'o',
     .help = "where to write: a long help line that the printer has to wrap at eighty columns, "
             "continuing under the help column rather than at the left margin"},
    {0}};

/* The test program's state (the SQLite manner). */
typedef struct globals {
    char line[1024]; /* the command line, cut into words */
    char *argv[64];
    int argc;
    const char *pos[4];
    int n_pos;
    iso_err err;
} globals;

static globals g;

/* Parses `line` (words split at spaces; "cmd" is argv[0]) into *a, which
 * starts zeroed. */
static int parse(targs *a, const char *line)
{
    memset(a, 0, sizeof *a);
    snprintf(g.line, sizeof g.line, "test %s", line);
    g.argc = 0;
    for (char *w = strtok(g.line, " "); w && g.argc < 63; w = strtok(NULL, " "))
        g.argv[g.argc++] = w;
    g.argv[g.argc] = NULL;
    iso_err_clear(&g.err);
    return iso_cli__opts_parse("test", opts, g.argc, g.argv, a, g.pos, 2, &g.n_pos, &g.err);
}

static void assert_refused(const char *line, const char *msg)
{
    targs a;
    int rc = parse(&a, line);
    if (rc != ISO_EINVAL)
        fail_msg("'%s' was not refused (%d)", line, rc);
    if (strcmp(g.err.msg, msg) != 0)
        fail_msg("'%s': said \"%s\", expected \"%s\"", line, g.err.msg, msg);
}

/* ---- parsing -------------------------------------------------------------- */

static void equals_and_space_forms_parse_the_same(void **state)
{
    (void)state;
    targs a, b;
    assert_int_equal(parse(&a, "--flag --count 7 --x -2.5e3 --speed 3 --path p.off --name n "
                               "--color blue --pair 4,-5 --call --weight 0.25 --mode green "
                               "-o out.ply --call"),
                     ISO_OK);
    assert_int_equal(parse(&b, "--flag --count=7 --x=-2.5e3 --speed=3 --path=p.off --name=n "
                               "--color=blue --pair=4,-5 --call --weight=0.25 --mode=green "
                               "-o=out.ply --call"),
                     ISO_OK);
    assert_int_equal(a.flag, 1);
    assert_int_equal(a.count, 7);
    assert_true(a.x == -2500.0 && a.speed == 3.0);
    assert_string_equal(a.path, "p.off");
    assert_string_equal(a.name, "n");
    assert_int_equal(a.color, 2);
    assert_int_equal(a.pair[0], 4);
    assert_int_equal(a.pair[1], -5);
    assert_int_equal(a.calls, 2);
    assert_true(a.in.weight == 0.25);
    assert_int_equal(a.in.mode, 1);
    assert_string_equal(a.out, "out.ply");
    /* b holds the same values (its strings point elsewhere in argv) */
    assert_int_equal(b.flag, a.flag);
    assert_int_equal(b.count, a.count);
    assert_true(b.x == a.x && b.speed == a.speed && b.in.weight == a.in.weight);
    assert_string_equal(b.path, a.path);
    assert_string_equal(b.name, a.name);
    assert_string_equal(b.out, a.out);
    assert_int_equal(b.color, a.color);
    assert_int_equal(b.in.mode, a.in.mode);
    assert_memory_equal(b.pair, a.pair, sizeof a.pair);
    assert_int_equal(b.calls, a.calls);
    /* an empty value, where the row allows one */
    assert_int_equal(parse(&a, "--path="), ISO_OK);
    assert_non_null(a.path);
    assert_string_equal(a.path, "");
    /* positionals, up to the command's count */
    assert_int_equal(parse(&a, "one --flag two"), ISO_OK);
    assert_int_equal(g.n_pos, 2);
    assert_string_equal(g.pos[0], "one");
    assert_string_equal(g.pos[1], "two");
}

static void out_of_range_is_refused_naming_option_and_range(void **state)
{
    (void)state;
    targs a;
    /* the ends: closed ones are in, open ones out */
    assert_int_equal(parse(&a, "--count 1 --count 99 --weight 1"), ISO_OK);
    assert_int_equal(a.count, 99);
    assert_refused("--count 0", "--count '0' is out of range: expected an integer in [1, 99].");
    assert_refused("--count=100", "--count '100' is out of range: expected an integer in [1, 99].");
    assert_refused("--weight 0", "--weight '0' is out of range: expected a value in (0, 1].");
    assert_refused("--weight 1.000001",
                   "--weight '1.000001' is out of range: expected a value in (0, 1].");
    assert_refused("--speed -1", "--speed '-1' is out of range: expected a value > 0.");
    assert_int_equal(g.err.offset, 1); /* the argument's index */
    assert_refused("--flag --speed 0", "--speed '0' is out of range: expected a value > 0.");
    assert_int_equal(g.err.offset, 2); /* the option's, not its value's */
}

static void wrong_type_is_refused_naming_option_and_range(void **state)
{
    (void)state;
    assert_refused("--count 2.5",
                   "--count '2.5' is not an integer: expected an integer in [1, 99].");
    assert_refused("--count 7x", "--count '7x' is not an integer: expected an integer in [1, 99].");
    assert_refused("--count 99999999999",
                   "--count '99999999999' is not an integer: expected an integer in [1, 99].");
    assert_refused("--weight abc", "--weight 'abc' is not a number: expected a value in (0, 1].");
    assert_refused("--weight nan", "--weight 'nan' is not a number: expected a value in (0, 1].");
    assert_refused("--x inf", "--x 'inf' is not a number: expected a finite number.");
    assert_refused("--x 1e999", "--x '1e999' is not a number: expected a finite number.");
    assert_refused("--x=", "--x '' is not a number: expected a finite number.");
    assert_refused("--name=", "--name is empty: expected NAME (see isoshape test --help).");
    assert_refused("--pair 1", "--pair '1': expected two integers A,B.");
}

static void a_setter_stores_after_the_rows_own_checks(void **state)
{
    (void)state;
    targs a;
    assert_int_equal(parse(&a, "--limit 3"), ISO_OK);
    assert_true(a.limit == 6.0);
    assert_refused("--limit -1", "--limit '-1' is out of range: expected a value >= 0.");
    assert_refused("--limit one", "--limit 'one' is not a number: expected a value >= 0.");
    assert_refused("--limit=11", "--limit '11': above the setter's limit 10.");
}

static void an_enum_lists_its_names_on_error(void **state)
{
    (void)state;
    assert_refused("--color mauve", "--color 'mauve' is unknown: use red, green or blue.");
    assert_refused("--mode=RED", "--mode 'RED' is unknown: use red, green or blue.");
}

static void usage_errors_name_the_argument(void **state)
{
    (void)state;
    targs a;
    assert_refused("--count", "option --count needs a value (see isoshape test --help).");
    assert_refused("--flag=1", "option --flag takes no value, but was given '1'.");
    assert_refused("--cou 3", "unknown option '--cou' (see isoshape test --help).");
    assert_refused("--countx 3", "unknown option '--countx' (see isoshape test --help).");
    assert_refused("-x 3", "unknown option '-x' (see isoshape test --help).");
    assert_refused("-", "unknown option '-' (see isoshape test --help).");
    assert_refused("a b c", "unexpected argument 'c' (see isoshape test --help).");
    /* --help anywhere asks for the help, unless an error came first */
    assert_int_equal(parse(&a, "--count 3 -h --count 0"), ISO_CLI_HELP);
    assert_int_equal(parse(&a, "--help --bogus"), ISO_CLI_HELP);
    assert_refused("--count 0 --help",
                   "--count '0' is out of range: expected an integer in [1, 99].");
    /* a value is taken as it is, even one that looks like an option */
    assert_int_equal(parse(&a, "--path --flag"), ISO_OK);
    assert_string_equal(a.path, "--flag");
    assert_int_equal(a.flag, 0);
}

/* ---- --help ---------------------------------------------------------------- */

static void help_prints_every_row_once_with_its_range(void **state)
{
    (void)state;
    char *text = NULL;
    size_t len = 0;
    FILE *f = open_memstream(&text, &len);
    assert_non_null(f);
    iso_cli__opts_print(opts, f);
    fclose(f);
    static const char *const lines[] = {
        "Things:\n",
        "  --flag             a flag\n",
        "  --count N          a count in [1, 99], or none\n",
        "  --speed S          a speed whose range the help does not place (> 0)\n",
        "  --color red|green|blue  a colour\n",
        "  --pair A,B         two integers\n",
        "  --weight W         a weight in (0, 1]\n",
        "  --mode red|green|blue  the mode\n",
        "  -o FILE            where to write: a long help line that the printer has to\n"
        "                     wrap at eighty columns, continuing under the help column\n"
        "                     rather than at the left margin\n",
    };
    for (size_t i = 0; i < sizeof lines / sizeof lines[0]; i++) {
        const char *at = strstr(text, lines[i]);
        if (!at || strstr(at + 1, lines[i]))
            fail_msg("--help has not exactly one \"%s\" in:\n%s", lines[i], text);
    }
    for (const char *l = text; *l; l = strchr(l, '\n') + 1)
        assert_true(strcspn(l, "\n") <= 80);
    free(text);
}

int main(void)
{
    const struct CMUnitTest t[] = {
        cmocka_unit_test(equals_and_space_forms_parse_the_same),
        cmocka_unit_test(out_of_range_is_refused_naming_option_and_range),
        cmocka_unit_test(wrong_type_is_refused_naming_option_and_range),
        cmocka_unit_test(a_setter_stores_after_the_rows_own_checks),
        cmocka_unit_test(an_enum_lists_its_names_on_error),
        cmocka_unit_test(usage_errors_name_the_argument),
        cmocka_unit_test(help_prints_every_row_once_with_its_range),
    };
    return cmocka_run_group_tests_name("cli_opts", t, NULL, NULL);
}
