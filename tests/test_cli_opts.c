/* tests/test_cli_opts.c -- the isoshape command's option tables
 * (controller/cli_opts.c). In-process: the parser, the range check and the
 * --help printer on a table of every kind. Through the built binary, for
 * every subcommand in the command table: its --help lists every row of its
 * option table and no other option; every number option refuses a value
 * out of its range and a value of the wrong type, naming the option and the
 * range, the same for --opt=VALUE and --opt VALUE; every enum option lists
 * its names. Links the command's static library (isoshape_cmd), so it
 * reaches controller/internal.h. */
#include "testutil.h"

#include <limits.h>
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
    char bin[PATH_MAX];                  /* the isoshape binary, "" if absent */
    char out[65536], stderr_text[16384]; /* the last command's output */
    char line[1024];                     /* the command line, cut into words */
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
                   "--count '99999999999' is out of range: expected an integer in [1, 99].");
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

/* ---- every subcommand ------------------------------------------------------- */

/* A command's rows, included tables flattened (headings and ends left out). */
typedef struct rows {
    const iso_cli__opt *o[128];
    int n;
} rows;

static void flatten(const iso_cli__opt *t, rows *r)
{
    for (; t->kind != ISO_CLI_OPT_END; t++)
        if (t->kind == ISO_CLI_OPT_TABLE)
            flatten(t->table, r);
        else if (t->kind != ISO_CLI_OPT_HEADING && r->n < 128)
            r->o[r->n++] = t;
}

/* Runs `isoshape ARGS`; returns its exit status, output in g.out and g.stderr_text. */
static int iso(const char *fmt, ...) ISO_PRINTF(1, 2);
static int iso(const char *fmt, ...)
{
    char args[1024], cmd[PATH_MAX + 1100];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(args, sizeof args, fmt, ap);
    va_end(ap);
    /* a value wrongly taken would start the command: bound it */
    snprintf(cmd, sizeof cmd, "timeout 60 '%s' %s </dev/null", g.bin, args);
    return iso_test_sh(cmd, g.out, sizeof g.out, g.stderr_text, sizeof g.stderr_text);
}

static void need_binary(void)
{
    if (!g.bin[0]) {
        printf("skipped: no isoshape binary (set ISOSHAPE_BIN)\n");
        skip();
    }
}

/* The options --help lists: its lines "  --name ..." or "  -c ..." (an
 * option's help continues at column 21, so never at column 2), by the
 * spelling the table uses ("--name" when the row has one). */
static int listed_options(const char *help, char names[][64], const char **lines, int cap)
{
    int n = 0;
    for (const char *l = help; *l; l = strchr(l, '\n') ? strchr(l, '\n') + 1 : l + strlen(l)) {
        if (strncmp(l, "  -", 3) != 0)
            continue;
        const char *o = l + 2;
        size_t len = strcspn(o, " ,\n");
        if (o[len] == ',' && strncmp(o + len, ", --", 4) == 0) { /* "-c, --name" */
            o += len + 2;
            len = strcspn(o, " \n");
        }
        if (n < cap) {
            snprintf(names[n], 64, "%.*s", (int)len, o);
            lines[n] = l;
        }
        n++;
    }
    return n;
}

/* The help block of the option listed at `line`: up to the next line that
 * does not continue it (one not indented to the help column). */
static void option_block(const char *line, char *buf, size_t cap)
{
    const char *end = strchr(line, '\n');
    while (end && strncmp(end + 1, "                     ", 21) == 0)
        end = strchr(end + 1, '\n');
    size_t n = end ? (size_t)(end - line) : strlen(line);
    snprintf(buf, cap, "%.*s", (int)n, line);
}

static void every_command_lists_its_table_and_no_other_option(void **state)
{
    (void)state;
    need_binary();
    for (int c = 0; iso_cli__commands[c]; c++) {
        const iso_cli__cmd *cmd = iso_cli__commands[c];
        rows r = {0};
        flatten(cmd->opts, &r);
        assert_int_equal(iso("%s --help", cmd->name), 0);
        /* the usage and prose first, the prose after last, as written */
        if (strncmp(g.out, cmd->usage, strlen(cmd->usage)) != 0)
            fail_msg("isoshape %s --help does not begin with its usage:\n%s", cmd->name, g.out);
        if (cmd->after && (strlen(g.out) < strlen(cmd->after) ||
                           strcmp(g.out + strlen(g.out) - strlen(cmd->after), cmd->after) != 0))
            fail_msg("isoshape %s --help does not end with its closing prose", cmd->name);
        char names[128][64];
        const char *lines[128];
        int n = listed_options(g.out, names, lines, 128);
        if (n != r.n)
            fail_msg("isoshape %s --help lists %d options; its table has %d:\n%s", cmd->name, n,
                     r.n, g.out);
        for (int i = 0; i < r.n; i++) {
            char want[64], range[96], block[2048];
            iso_cli__opt_spelling(r.o[i], want, sizeof want);
            int found = 0;
            for (int k = 0; k < n; k++)
                if (strcmp(names[k], want) == 0) {
                    found++;
                    option_block(lines[k], block, sizeof block);
                }
            if (found != 1)
                fail_msg("isoshape %s --help lists %s %d times:\n%s", cmd->name, want, found,
                         g.out);
            /* the metavar (an enum's names) beside it, the range in its help */
            const char *meta = r.o[i]->metavar;
            if (r.o[i]->kind == ISO_CLI_OPT_ENUM)
                meta = r.o[i]->names[0];
            if (meta && !strstr(block, meta))
                fail_msg("isoshape %s --help: %s without %s: %s", cmd->name, want, meta, block);
            iso_cli__opt_range(r.o[i], range, sizeof range);
            char flat[2048]; /* the block with its line breaks and indents folded */
            size_t m = 0;
            for (const char *p = block; *p && m + 1 < sizeof flat; p++)
                if (!(*p == ' ' && m && flat[m - 1] == ' '))
                    flat[m++] = *p == '\n' ? ' ' : *p;
            flat[m] = '\0';
            if (range[0] && !strstr(flat, range))
                fail_msg("isoshape %s --help: %s does not show its range %s: %s", cmd->name, want,
                         range, block);
        }
    }
}

/* What the table's rows themselves must hold, for every command: one row
 * per spelling, a help line on each, a setter on each CALL row, names on
 * each ENUM row, and a range placed in the help where a row has one. */
static void every_command_table_is_well_formed(void **state)
{
    (void)state;
    for (int c = 0; iso_cli__commands[c]; c++) {
        const iso_cli__cmd *cmd = iso_cli__commands[c];
        rows r = {0};
        flatten(cmd->opts, &r);
        assert_true(r.n < 128);
        assert_non_null(strstr(cmd->usage, "usage: isoshape "));
        assert_ptr_equal(iso_cli__command(cmd->name), cmd);
        for (int i = 0; i < r.n; i++) {
            const iso_cli__opt *o = r.o[i];
            char a[64], b[64];
            iso_cli__opt_spelling(o, a, sizeof a);
            if (!o->help || !o->help[0])
                fail_msg("isoshape %s: %s has no help line", cmd->name, a);
            if (o->kind == ISO_CLI_OPT_CALL && (!o->set || !o->metavar))
                fail_msg("isoshape %s: %s is CALL without a setter or a metavar", cmd->name, a);
            if (o->kind == ISO_CLI_OPT_ENUM && (!o->names || !o->names[0]))
                fail_msg("isoshape %s: %s is ENUM without names", cmd->name, a);
            iso_range range;
            iso_cli__opt_range_of(o, &range);
            if ((range.lo_end || range.hi_end) && !strstr(o->help, "%R"))
                fail_msg("isoshape %s: %s has a range its help does not place (%%R)", cmd->name, a);
            if (o->solver && (!iso_solver_range(o->solver) || o->lo_end || o->hi_end))
                fail_msg("isoshape %s: %s names the solver's range '%s', which %s", cmd->name, a,
                         o->solver,
                         iso_solver_range(o->solver) ? "it overrides" : "the solver lacks");
            for (int k = 0; k < i; k++)
                if (strcmp(a, iso_cli__opt_spelling(r.o[k], b, sizeof b)) == 0 ||
                    (o->short_name && o->short_name == r.o[k]->short_name))
                    fail_msg("isoshape %s: two rows for %s", cmd->name, a);
        }
    }
}

/* Runs `isoshape CMD OPT=V` and `isoshape CMD OPT V`: both must exit 2
 * with the same one line, which names the option and the value and holds
 * each of `needles`. */
static void assert_both_forms_refuse(const char *cmd, const char *opt, const char *v,
                                     const char *const *needles)
{
    char first[16384];
    assert_int_equal(iso("%s %s='%s'", cmd, opt, v), 2);
    snprintf(first, sizeof first, "%s", g.stderr_text);
    assert_int_equal(iso("%s %s '%s'", cmd, opt, v), 2);
    if (strcmp(first, g.stderr_text) != 0)
        fail_msg("isoshape %s: %s=%s and %s %s say different things:\n%s%s", cmd, opt, v, opt, v,
                 first, g.stderr_text);
    char quoted[128];
    snprintf(quoted, sizeof quoted, "%s '%s'", opt, v);
    if (!strstr(g.stderr_text, quoted))
        fail_msg("isoshape %s %s %s: the message does not name %s: %s", cmd, opt, v, quoted,
                 g.stderr_text);
    for (int k = 0; needles[k]; k++)
        if (!strstr(g.stderr_text, needles[k]))
            fail_msg("isoshape %s %s %s: the message lacks '%s': %s", cmd, opt, v, needles[k],
                     g.stderr_text);
    assert_non_null(strchr(g.stderr_text, '\n'));
    assert_string_equal(strchr(g.stderr_text, '\n'), "\n"); /* one line */
}

static void every_number_option_refuses_out_of_range_and_wrong_type(void **state)
{
    (void)state;
    need_binary();
    int checked = 0;
    for (int c = 0; iso_cli__commands[c]; c++) {
        const iso_cli__cmd *cmd = iso_cli__commands[c];
        rows r = {0};
        flatten(cmd->opts, &r);
        for (int i = 0; i < r.n; i++) {
            const iso_cli__opt *o = r.o[i];
            if (o->kind != ISO_CLI_OPT_INT && o->kind != ISO_CLI_OPT_DOUBLE)
                continue;
            char opt[64], range[96], v[64];
            iso_range e; /* the row's ends, its own or the solver's */
            iso_cli__opt_range_of(o, &e);
            iso_cli__opt_spelling(o, opt, sizeof opt);
            iso_cli__opt_range(o, range, sizeof range);
            const char *type = o->kind == ISO_CLI_OPT_INT ? "is not an integer: expected an integer"
                                                          : "is not a number: expected a";
            const char *wrong_type[] = {type, range, NULL};
            assert_both_forms_refuse(cmd->name, opt, "x1", wrong_type);
            if (o->kind == ISO_CLI_OPT_INT)
                assert_both_forms_refuse(cmd->name, opt, "2.5", wrong_type);
            const char *out_of_range[] = {"is out of range: expected", range, NULL};
            if (e.lo_end) { /* the end itself when open, just below it when closed */
                snprintf(v, sizeof v, "%.17g", e.lo_end == ISO_RANGE_OPEN ? e.lo : e.lo - 1);
                assert_both_forms_refuse(cmd->name, opt, v, out_of_range);
                checked++;
            }
            if (e.hi_end) {
                snprintf(v, sizeof v, "%.17g", e.hi_end == ISO_RANGE_OPEN ? e.hi : e.hi + 1);
                assert_both_forms_refuse(cmd->name, opt, v, out_of_range);
                checked++;
            }
        }
    }
    printf("%d range ends refused, each in both forms\n", checked);
    assert_true(checked >= 20); /* every command with numbers has ranges */
}

/* Where each solver setting is written in a scene, "%s" standing for its
 * value: every command-line row that takes a solver range (.solver) must
 * have its place here, so that the two refusals are compared. */
static const struct {
    const char *setting, *key, *yaml;
} scene_places[] = {
    {"omega", "solver.omega", "solver: {omega: '%s'}"},
    {"cg_tol", "solver.cg_tol", "solver: {cg_tol: '%s'}"},
    {"worker_lag", "solver.worker_lag", "solver: {worker_lag: '%s'}"},
    {"steps_per_tick", "integrator.steps_per_tick", "integrator: {steps_per_tick: '%s'}"},
};

/* What follows "'V' " in a refusal line: the words iso_range_parse chose. */
static const char *after_value(const char *line, const char *v, char *buf, size_t cap)
{
    char quoted[96];
    snprintf(quoted, sizeof quoted, "'%s' ", v);
    const char *p = strstr(line, quoted);
    if (!p)
        return NULL;
    snprintf(buf, cap, "%s", p + strlen(quoted));
    buf[strcspn(buf, "\n")] = '\0';
    size_t n = strlen(buf);
    if (n && buf[n - 1] == '.') /* the command line ends its sentences */
        buf[n - 1] = '\0';
    return buf;
}

/* `isoshape check` on a scene holding `yaml` (with v) and `isoshape CMD OPT
 * ARG` must refuse v in the same words after the value; the scene's line
 * names its file:line:column and key. */
static void assert_refused_alike(const char *cmd, const char *opt, const char *arg, const char *key,
                                 const char *yaml, const char *v)
{
    char path[512], text[1024], line[256], cli[512], scene[512];
    iso_test_tmp(path, sizeof path, "agree.yaml");
    snprintf(line, sizeof line, yaml, v);
    snprintf(text, sizeof text,
             "mesh: {shape: bar, resolution: 4}\nregions: {sel: builtin, handles: [{driver: "
             "none}]}\n%s\n",
             line);
    iso_test_write(path, text, -1);
    assert_int_equal(iso("%s %s '%s'", cmd, opt, arg), 2);
    if (!after_value(g.stderr_text, v, cli, sizeof cli))
        fail_msg("isoshape %s %s %s: %s", cmd, opt, arg, g.stderr_text);
    assert_int_equal(iso("check '%s'", path), 1);
    char where[600];
    snprintf(where, sizeof where, "agree.yaml:3:");
    if (!strstr(g.stderr_text, where) || !strstr(g.stderr_text, key) ||
        !after_value(g.stderr_text, v, scene, sizeof scene))
        fail_msg("scene %s: '%s': %s", key, v, g.stderr_text);
    if (strcmp(cli, scene) != 0)
        fail_msg("%s '%s' and scene key %s disagree:\n  command line: %s\n  scene:        %s", opt,
                 arg, key, cli, scene);
}

static void assert_scene_and_option_agree(const char *cmd, const char *opt, const char *key,
                                          const char *yaml, const char *v)
{
    assert_refused_alike(cmd, opt, v, key, yaml, v);
}

/* One table for solver ranges: each command-line row that takes one is
 * refused out of range and with the wrong type in the very words the scene
 * key of the same setting is, and both hold the table's ends. */
static void solver_options_and_scene_keys_refuse_alike(void **state)
{
    (void)state;
    need_binary();
    int compared = 0;
    for (int c = 0; iso_cli__commands[c]; c++) {
        const iso_cli__cmd *cmd = iso_cli__commands[c];
        rows r = {0};
        flatten(cmd->opts, &r);
        for (int i = 0; i < r.n; i++) {
            const iso_cli__opt *o = r.o[i];
            if (!o->solver)
                continue;
            size_t j = 0;
            while (j < sizeof scene_places / sizeof scene_places[0] &&
                   strcmp(scene_places[j].setting, o->solver) != 0)
                j++;
            if (j == sizeof scene_places / sizeof scene_places[0])
                fail_msg("isoshape %s: no scene place for the solver setting '%s'", cmd->name,
                         o->solver);
            const iso_range *e = iso_solver_range(o->solver);
            char opt[64], v[64];
            iso_cli__opt_spelling(o, opt, sizeof opt);
            assert_scene_and_option_agree(cmd->name, opt, scene_places[j].key, scene_places[j].yaml,
                                          "x1");
            if (e->lo_end) {
                snprintf(v, sizeof v, "%.17g", e->lo_end == ISO_RANGE_OPEN ? e->lo : e->lo - 1);
                assert_scene_and_option_agree(cmd->name, opt, scene_places[j].key,
                                              scene_places[j].yaml, v);
            }
            if (e->hi_end) {
                snprintf(v, sizeof v, "%.17g", e->hi_end == ISO_RANGE_OPEN ? e->hi : e->hi + 1);
                assert_scene_and_option_agree(cmd->name, opt, scene_places[j].key,
                                              scene_places[j].yaml, v);
            }
            compared++;
        }
    }
    /* --restore MU,TAU is one value of two numbers: each is the scene's
     * solver.restore.mu or .tau, in the same words after its name */
    assert_refused_alike("deform --shape bar", "--restore", "-1,1", "solver.restore.mu",
                         "solver: {restore: {mu: '%s', tau: 1}}", "-1");
    assert_refused_alike("deform --shape bar", "--restore", "1,0", "solver.restore.tau",
                         "solver: {restore: {mu: 1, tau: '%s'}}", "0");
    assert_refused_alike("deform --shape bar", "--restore", "1,soon", "solver.restore.tau",
                         "solver: {restore: {mu: 1, tau: '%s'}}", "soon");
    printf("%d solver options refuse as their scene keys do\n", compared);
    assert_true(compared >= 5); /* omega, cg-tol, worker-lag twice, steps */
}

static void every_enum_option_lists_its_names(void **state)
{
    (void)state;
    need_binary();
    int checked = 0;
    for (int c = 0; iso_cli__commands[c]; c++) {
        const iso_cli__cmd *cmd = iso_cli__commands[c];
        rows r = {0};
        flatten(cmd->opts, &r);
        for (int i = 0; i < r.n; i++) {
            if (r.o[i]->kind != ISO_CLI_OPT_ENUM)
                continue;
            char opt[64];
            iso_cli__opt_spelling(r.o[i], opt, sizeof opt);
            const char *needles[] = {"is unknown: use", NULL};
            assert_both_forms_refuse(cmd->name, opt, "bogus", needles);
            for (int k = 0; r.o[i]->names[k]; k++)
                if (!strstr(g.stderr_text, r.o[i]->names[k]))
                    fail_msg("isoshape %s %s bogus: '%s' is not listed: %s", cmd->name, opt,
                             r.o[i]->names[k], g.stderr_text);
            checked++;
        }
    }
    printf("%d enum options list their names\n", checked);
    assert_true(checked >= 8);
}

int main(void)
{
    if (iso_test_isoshape_bin(g.bin, sizeof g.bin) != 0)
        g.bin[0] = '\0';
    const struct CMUnitTest t[] = {
        cmocka_unit_test(equals_and_space_forms_parse_the_same),
        cmocka_unit_test(out_of_range_is_refused_naming_option_and_range),
        cmocka_unit_test(wrong_type_is_refused_naming_option_and_range),
        cmocka_unit_test(a_setter_stores_after_the_rows_own_checks),
        cmocka_unit_test(an_enum_lists_its_names_on_error),
        cmocka_unit_test(usage_errors_name_the_argument),
        cmocka_unit_test(help_prints_every_row_once_with_its_range),
        cmocka_unit_test(every_command_table_is_well_formed),
        cmocka_unit_test(every_command_lists_its_table_and_no_other_option),
        cmocka_unit_test(every_number_option_refuses_out_of_range_and_wrong_type),
        cmocka_unit_test(every_enum_option_lists_its_names),
        cmocka_unit_test(solver_options_and_scene_keys_refuse_alike),
    };
    return cmocka_run_group_tests_name("cli_opts", t, NULL, NULL);
}
