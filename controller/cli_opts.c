/* controller/cli_opts.c -- the isoshape command's options as tables.
 *
 * One row per option (internal.h, iso_cli__opt) says its name, kind, range,
 * metavar, help line and where its value goes; the parser, the range check
 * and the --help printer below all read that row, so what --help says, what
 * is parsed and what is refused cannot drift apart. Every error names the
 * option, the value and what was expected, so a user sees what to fix
 * without reading the help. */
#include "internal.h"

#include <errno.h>
#include <limits.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

void iso_cli__fail(const char *cmd, const char *fmt, ...)
{
    va_list ap;
    fprintf(stderr, "isoshape%s%s: ", cmd ? " " : "", cmd ? cmd : "");
    va_start(ap, fmt);
    vfprintf(stderr, fmt, ap);
    va_end(ap);
    fputc('\n', stderr);
}

/* ------------------------------------------------------------------------ */
/* Names, ranges and what was expected                                        */
/* ------------------------------------------------------------------------ */

const char *iso_cli__opt_spelling(const iso_cli__opt *o, char *buf, size_t cap)
{
    if (o->name)
        snprintf(buf, cap, "--%s", o->name);
    else
        snprintf(buf, cap, "-%c", o->short_name);
    return buf;
}

_Static_assert((int)ISO_CLI_NONE == (int)ISO_RANGE_NONE &&
                   (int)ISO_CLI_OPEN == (int)ISO_RANGE_OPEN &&
                   (int)ISO_CLI_CLOSED == (int)ISO_RANGE_CLOSED,
               "a row's ends are iso_range's");

void iso_cli__opt_range_of(const iso_cli__opt *o, iso_range *r)
{
    const iso_range *solver = o->solver ? iso_solver_range(o->solver) : NULL;
    if (solver) {
        *r = *solver;
    } else {
        memset(r, 0, sizeof *r);
        r->lo = o->lo;
        r->hi = o->hi;
        r->lo_end = (iso_range_end)o->lo_end;
        r->hi_end = (iso_range_end)o->hi_end;
    }
    r->integer = o->kind == ISO_CLI_OPT_INT;
}

const char *iso_cli__opt_range(const iso_cli__opt *o, char *buf, size_t cap)
{
    iso_range r;
    iso_cli__opt_range_of(o, &r);
    return iso_range_text(&r, buf, cap);
}

/* ------------------------------------------------------------------------ */
/* Parsing                                                                    */
/* ------------------------------------------------------------------------ */

/* If arg spells row o ("--name", "--name=V", "-c", "-c=V"), returns 1 and
 * points *val at V (NULL without '='). */
static int spells(const iso_cli__opt *o, const char *arg, const char **val)
{
    const char *rest = NULL;
    if (arg[0] == '-' && arg[1] == '-' && o->name) {
        size_t n = strlen(o->name);
        if (strncmp(arg + 2, o->name, n) == 0)
            rest = arg + 2 + n;
    } else if (arg[0] == '-' && o->short_name && arg[1] == o->short_name) {
        rest = arg + 2;
    }
    if (!rest || (*rest != '\0' && *rest != '='))
        return 0;
    *val = *rest == '=' ? rest + 1 : NULL;
    return 1;
}

/* The row arg spells, searching included tables too; *at is its value's
 * offset in the command's arguments. NULL if none. */
static const iso_cli__opt *find_row(const iso_cli__opt *t, size_t base, const char *arg, size_t *at,
                                    const char **val)
{
    for (; t->kind != ISO_CLI_OPT_END; t++) {
        if (t->kind == ISO_CLI_OPT_TABLE) {
            const iso_cli__opt *o = find_row(t->table, base + t->at, arg, at, val);
            if (o)
                return o;
        } else if (t->kind != ISO_CLI_OPT_HEADING && spells(t, arg, val)) {
            *at = base + t->at;
            return t;
        }
    }
    return NULL;
}

/* Puts a checked value at dst: its bytes, or through the row's setter,
 * which may refuse it still (a range owned elsewhere, as the mapping's). */
static int put(const iso_cli__opt *o, void *dst, const char *val, const void *v, size_t n,
               long index, iso_err *err)
{
    char opt[64], why[192];
    if (!o->set) {
        memcpy(dst, v, n);
        return ISO_OK;
    }
    if (o->set(o, dst, val, why, sizeof why) == 0)
        return ISO_OK;
    iso_cli__opt_spelling(o, opt, sizeof opt);
    if (val)
        return iso_err_set(err, ISO_EINVAL, index, "%s '%s': %s.", opt, val, why);
    return iso_err_set(err, ISO_EINVAL, index, "%s: %s.", opt, why);
}

/* Checks val, the value of row o, and puts it at dst; returns ISO_OK or
 * ISO_EINVAL with the sentence in err. */
static int store(const char *cmd, const iso_cli__opt *o, void *dst, const char *val, long index,
                 iso_err *err)
{
    char opt[64], want[128];
    iso_cli__opt_spelling(o, opt, sizeof opt);
    switch (o->kind) {
    case ISO_CLI_OPT_FLAG: return put(o, dst, NULL, &o->flag, sizeof o->flag, index, err);
    case ISO_CLI_OPT_INT:
    case ISO_CLI_OPT_DOUBLE: {
        /* iso_range_parse's words, the ones scene files use: an int row
         * also holds the value to an int's own range */
        iso_range r;
        char why[192];
        double v;
        iso_cli__opt_range_of(o, &r);
        if (iso_range_parse(&r, val, &v, why, sizeof why) != 0)
            return iso_err_set(err, ISO_EINVAL, index, "%s %s.", opt, why);
        if (o->kind == ISO_CLI_OPT_DOUBLE)
            return put(o, dst, val, &v, sizeof v, index, err);
        if (v < INT_MIN || v > INT_MAX)
            return iso_err_set(err, ISO_EINVAL, index,
                               "%s '%s' is out of range: expected %s, within [%d, %d].", opt, val,
                               iso_range_expected(&r, want, sizeof want), INT_MIN, INT_MAX);
        int i = (int)v;
        return put(o, dst, val, &i, sizeof i, index, err);
    }
    case ISO_CLI_OPT_STRING:
        if (o->nonempty && !*val)
            return iso_err_set(err, ISO_EINVAL, index,
                               "%s is empty: expected %s (see isoshape %s --help).", opt,
                               o->metavar ? o->metavar : "a value", cmd);
        return put(o, dst, val, &val, sizeof val, index, err);
    case ISO_CLI_OPT_ENUM: {
        int v = iso_names_find(o->names, val);
        if (v < 0)
            return iso_err_set(err, ISO_EINVAL, index, "%s '%s' is unknown: use %s.", opt, val,
                               iso_names_list(o->names, " or ", want, sizeof want));
        return put(o, dst, val, &v, sizeof v, index, err);
    }
    case ISO_CLI_OPT_CALL: return put(o, dst, val, NULL, 0, index, err);
    default: return iso_err_set(err, ISO_EINVAL, index, "%s: a row of unknown kind.", opt);
    }
}

static int is_help(const char *arg)
{
    return strcmp(arg, "--help") == 0 || strcmp(arg, "-h") == 0;
}

/* One option at argv[*i]; *i moves past its value. */
static int parse_option(const char *cmd, const iso_cli__opt *opts, int argc, char **argv, int *i,
                        void *args, iso_err *err)
{
    const char *arg = argv[*i], *val = NULL;
    long index = *i; /* errors point at the option, not at its value */
    size_t at = 0;
    char opt[64];
    const iso_cli__opt *o = find_row(opts, 0, arg, &at, &val);
    if (!o)
        return iso_err_set(err, ISO_EINVAL, *i, "unknown option '%s' (see isoshape %s --help).",
                           arg, cmd);
    iso_cli__opt_spelling(o, opt, sizeof opt);
    if (o->kind == ISO_CLI_OPT_FLAG && val)
        return iso_err_set(err, ISO_EINVAL, *i, "option %s takes no value, but was given '%s'.",
                           opt, val);
    if (o->kind != ISO_CLI_OPT_FLAG && !val) {
        if (*i + 1 >= argc)
            return iso_err_set(err, ISO_EINVAL, *i,
                               "option %s needs a value (see isoshape %s --help).", opt, cmd);
        val = argv[++*i];
    }
    return store(cmd, o, (char *)args + at, val, index, err);
}

int iso_cli__opts_parse(const char *cmd, const iso_cli__opt *opts, int argc, char **argv,
                        void *args, const char **pos, int max_pos, int *n_pos, iso_err *err)
{
    *n_pos = 0;
    for (int i = 1; i < argc; i++) {
        const char *arg = argv[i];
        if (is_help(arg))
            return ISO_CLI_HELP;
        if (arg[0] == '-') {
            int rc = parse_option(cmd, opts, argc, argv, &i, args, err);
            if (rc != ISO_OK)
                return rc;
        } else if (*n_pos < max_pos) {
            pos[(*n_pos)++] = arg;
        } else {
            return iso_err_set(err, ISO_EINVAL, i,
                               "unexpected argument '%s' (see isoshape %s --help).", arg, cmd);
        }
    }
    return ISO_OK;
}

/* ------------------------------------------------------------------------ */
/* --help                                                                     */
/* ------------------------------------------------------------------------ */

enum { HELP_COL = 21, HELP_WIDTH = 80 };

/* The help line with "%R" replaced by the range; a row with a range whose
 * help does not place it gets it at the end, so the range --help shows is
 * always the one the parser checks. */
static void expand_help(const iso_cli__opt *o, char *out, size_t cap)
{
    char range[96];
    const char *h = o->help ? o->help : "";
    const char *mark = strstr(h, "%R");
    iso_cli__opt_range(o, range, sizeof range);
    if (mark)
        snprintf(out, cap, "%.*s%s%s", (int)(mark - h), h, range, mark + 2);
    else if (range[0])
        snprintf(out, cap, "%s (%s)", h, range);
    else
        snprintf(out, cap, "%s", h);
}

/* Writes text from column col, wrapped at HELP_WIDTH with continuation
 * lines at HELP_COL; '\n' in text breaks the line there. */
static void write_wrapped(FILE *f, const char *text, int col)
{
    int first = 1; /* the first word on its line goes there whatever its length */
    for (const char *p = text; *p;) {
        if (*p == '\n' || *p == ' ') {
            if (*p == '\n') {
                fprintf(f, "\n%*s", HELP_COL, "");
                col = HELP_COL;
                first = 1;
            }
            p++;
            continue;
        }
        int n = (int)strcspn(p, " \n");
        if (!first && col + 1 + n > HELP_WIDTH) {
            fprintf(f, "\n%*s", HELP_COL, "");
            col = HELP_COL;
            first = 1;
        }
        if (!first) {
            fputc(' ', f);
            col++;
        }
        fwrite(p, 1, (size_t)n, f);
        col += n;
        first = 0;
        p += n;
    }
    fputc('\n', f);
}

static void print_row(const iso_cli__opt *o, FILE *f)
{
    char left[160], names[128], text[1024];
    const char *meta = o->metavar;
    if (o->kind == ISO_CLI_OPT_ENUM)
        meta = iso_names_join(o->names, "|", "|", names, sizeof names);
    char spelling[64];
    iso_cli__opt_spelling(o, spelling, sizeof spelling);
    int n;
    if (o->name && o->short_name)
        n = snprintf(left, sizeof left, "  -%c, %s%s%s", o->short_name, spelling, meta ? " " : "",
                     meta ? meta : "");
    else
        n = snprintf(left, sizeof left, "  %s%s%s", spelling, meta ? " " : "", meta ? meta : "");
    expand_help(o, text, sizeof text);
    fputs(left, f);
    if (n <= HELP_COL - 2) {
        fprintf(f, "%*s", HELP_COL - n, "");
        n = HELP_COL;
    } else {
        fputs("  ", f);
        n += 2;
    }
    write_wrapped(f, text, n);
}

void iso_cli__opts_print(const iso_cli__opt *opts, FILE *f)
{
    for (const iso_cli__opt *o = opts; o->kind != ISO_CLI_OPT_END; o++) {
        if (o->kind == ISO_CLI_OPT_TABLE)
            iso_cli__opts_print(o->table, f);
        else if (o->kind == ISO_CLI_OPT_HEADING)
            fprintf(f, "%s\n", o->help);
        else
            print_row(o, f);
    }
}

static void print_help(const iso_cli__cmd *c, FILE *f)
{
    fputs(c->usage, f);
    iso_cli__opts_print(c->opts, f);
    if (c->after)
        fputs(c->after, f);
}

int iso_cli__parse(const iso_cli__cmd *c, int argc, char **argv, void *args, const char **pos,
                   int max_pos, int *n_pos)
{
    iso_err err;
    int n = 0;
    iso_err_clear(&err);
    int rc = iso_cli__opts_parse(c->name, c->opts, argc, argv, args, pos, pos ? max_pos : 0,
                                 n_pos ? n_pos : &n, &err);
    if (rc == ISO_CLI_HELP) {
        print_help(c, stdout);
        return 0;
    }
    if (rc != ISO_OK) {
        iso_cli__fail(c->name, "%s", err.msg);
        return 2;
    }
    return -1;
}
