/* tests/test_outfile.c -- whole-or-nothing outputs replace only regular
 * files (common/iso_outfile.h):
 *   - a regular file (or none) is written under a temporary name beside it
 *     and renamed onto it; nothing is left beside it after a commit or an
 *     abort;
 *   - a symbolic link stays a link and its target is replaced, also when
 *     the target does not exist yet;
 *   - a FIFO with a reader and a character device are written through and
 *     stay what they are; a FIFO nobody reads, a folder, and a FIFO or a
 *     device for an output that seeks are refused when planned;
 *   - end to end: `isoshape run --stats-json FIFO` writes the summary into
 *     the FIFO's reader and leaves the FIFO a FIFO; `--pc2 FIFO` and
 *     `--out x.glb` are refused before the run starts (no run, exit 1).
 * Skips the end-to-end part (77) without the isoshape binary. */
#include "testutil.h"

#include <errno.h>
#include <fcntl.h>
#include <poll.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include "iso_outfile.h"

static void path_in_tmp(char *buf, size_t cap, const char *name)
{
    iso_test_tmp(buf, cap, name);
    unlink(buf);
}

static void write_text(const char *path, const char *text)
{
    FILE *f = fopen(path, "w");
    assert_non_null(f);
    fputs(text, f);
    assert_int_equal(fclose(f), 0);
}

static void read_text(const char *path, char *buf, size_t cap)
{
    FILE *f = fopen(path, "r");
    assert_non_null(f);
    size_t n = fread(buf, 1, cap - 1, f);
    buf[n] = 0;
    fclose(f);
}

static void a_regular_file_is_replaced_whole(void **state)
{
    (void)state;
    char path[4096], got[64];
    path_in_tmp(path, sizeof path, "outfile_regular.json");
    write_text(path, "old");
    iso_outfile o;
    iso_err e;
    iso_err_clear(&e);
    assert_int_equal(iso_outfile_plan(&o, "--stats-json", path, ISO_OUTFILE_SEEKS, &e), ISO_OK);
    assert_int_equal(o.through, 0);
    assert_string_not_equal(o.write, path);
    assert_non_null(strstr(o.write, ".part-"));
    assert_non_null(strstr(o.write, ".json")); /* the extension kept */
    write_text(o.write, "new");
    read_text(path, got, sizeof got);
    assert_string_equal(got, "old"); /* untouched until the commit */
    char tmp[sizeof o.write];
    snprintf(tmp, sizeof tmp, "%s", o.write);
    assert_int_equal(iso_outfile_commit(&o, "--stats-json", &e), ISO_OK);
    read_text(path, got, sizeof got);
    assert_string_equal(got, "new");
    assert_int_equal(access(tmp, F_OK), -1);
    /* an aborted one leaves nothing beside it, and the old file stands */
    assert_int_equal(iso_outfile_plan(&o, "--stats-json", path, ISO_OUTFILE_SEEKS, &e), ISO_OK);
    write_text(o.write, "torn");
    snprintf(tmp, sizeof tmp, "%s", o.write);
    iso_outfile_abort(&o);
    assert_int_equal(access(tmp, F_OK), -1);
    read_text(path, got, sizeof got);
    assert_string_equal(got, "new");
    unlink(path);
}

static void a_link_stays_a_link(void **state)
{
    (void)state;
    char target[4096], link[4096], got[64];
    path_in_tmp(target, sizeof target, "outfile_target.ply");
    path_in_tmp(link, sizeof link, "outfile_link.ply");
    write_text(target, "old");
    assert_int_equal(symlink("outfile_target.ply", link), 0); /* relative, as people make them */
    iso_outfile o;
    iso_err e;
    iso_err_clear(&e);
    for (int pass = 0; pass < 2; pass++) { /* the target there, then not yet */
        assert_int_equal(iso_outfile_plan(&o, "--out", link, ISO_OUTFILE_SEQUENTIAL, &e), ISO_OK);
        write_text(o.write, pass ? "second" : "first");
        assert_int_equal(iso_outfile_commit(&o, "--out", &e), ISO_OK);
        struct stat st;
        assert_int_equal(lstat(link, &st), 0);
        assert_true(S_ISLNK(st.st_mode));
        read_text(target, got, sizeof got);
        assert_string_equal(got, pass ? "second" : "first");
        unlink(target);
    }
    unlink(link);
}

typedef struct fifo_reader {
    char path[4096];
    int fd;
    char got[1 << 16];
    size_t n;
    pthread_t th;
} fifo_reader;

/* Reads until the last writer has come and gone (POLLHUP with nothing
 * left), as `cat FIFO` does. */
static void *read_fifo(void *arg)
{
    fifo_reader *r = arg;
    for (;;) {
        struct pollfd p = {r->fd, POLLIN, 0};
        if (poll(&p, 1, 20000) <= 0)
            break;
        ssize_t k = read(r->fd, r->got + r->n, sizeof r->got - 1 - r->n);
        if (k > 0)
            r->n += (size_t)k;
        else if (k == 0 || (errno != EAGAIN && errno != EINTR))
            break;
    }
    r->got[r->n] = 0;
    close(r->fd);
    return NULL;
}

/* A new FIFO with a reader on it (opened here, so it is there at once). */
static void fifo_with_reader(fifo_reader *r, const char *name)
{
    memset(r, 0, sizeof *r);
    path_in_tmp(r->path, sizeof r->path, name);
    assert_int_equal(mkfifo(r->path, 0600), 0);
    r->fd = open(r->path, O_RDONLY | O_NONBLOCK);
    assert_true(r->fd >= 0);
    assert_int_equal(pthread_create(&r->th, NULL, read_fifo, r), 0);
}

static void fifos_and_devices_are_written_through(void **state)
{
    (void)state;
    iso_outfile o;
    iso_err e;
    iso_err_clear(&e);
    /* a FIFO nobody reads: refused, and nothing created beside it */
    char lonely[4096];
    path_in_tmp(lonely, sizeof lonely, "outfile_lonely.fifo");
    assert_int_equal(mkfifo(lonely, 0600), 0);
    assert_int_equal(iso_outfile_plan(&o, "--mcap", lonely, ISO_OUTFILE_SEQUENTIAL, &e),
                     ISO_EINVAL);
    print_message("%s\n", e.msg);
    assert_non_null(strstr(e.msg, "a FIFO that nobody reads"));
    unlink(lonely);
    /* the character device: through, and it stays one */
    iso_err_clear(&e);
    assert_int_equal(iso_outfile_plan(&o, "--stats-json", "/dev/null", ISO_OUTFILE_SEQUENTIAL, &e),
                     ISO_OK);
    assert_int_equal(o.through, 1);
    assert_string_equal(o.write, "/dev/null");
    assert_int_equal(iso_outfile_commit(&o, "--stats-json", &e), ISO_OK);
    struct stat st;
    assert_int_equal(stat("/dev/null", &st), 0);
    assert_true(S_ISCHR(st.st_mode));
    /* an output that seeks cannot go to either; a folder to nothing */
    assert_int_equal(iso_outfile_plan(&o, "PC2", "/dev/null", ISO_OUTFILE_SEEKS, &e), ISO_EINVAL);
    iso_err_clear(&e);
    assert_int_equal(iso_outfile_plan(&o, "--out", "/tmp", ISO_OUTFILE_SEQUENTIAL, &e), ISO_EINVAL);
    assert_non_null(strstr(e.msg, "is a folder"));
}

static void a_fifo_with_a_reader_gets_the_output(void **state)
{
    (void)state;
    fifo_reader r;
    fifo_with_reader(&r, "outfile_read.fifo");
    iso_outfile o;
    iso_err e;
    iso_err_clear(&e);
    assert_int_equal(iso_outfile_plan(&o, "--stats-json", r.path, ISO_OUTFILE_SEQUENTIAL, &e),
                     ISO_OK);
    assert_int_equal(o.through, 1);
    write_text(o.write, "through the FIFO");
    assert_int_equal(iso_outfile_commit(&o, "--stats-json", &e), ISO_OK);
    pthread_join(r.th, NULL);
    assert_string_equal(r.got, "through the FIFO");
    struct stat st;
    assert_int_equal(lstat(r.path, &st), 0);
    assert_true(S_ISFIFO(st.st_mode));
    unlink(r.path);
}

static int run(const char *cmd, char *out, size_t cap)
{
    FILE *p = popen(cmd, "r");
    assert_non_null(p);
    size_t n = fread(out, 1, cap - 1, p);
    out[n] = 0;
    int st = pclose(p);
    return WIFEXITED(st) ? WEXITSTATUS(st) : -1;
}

static void the_run_honours_fifos_and_refuses_up_front(void **state)
{
    (void)state;
    const char *bin = getenv("ISOSHAPE_BIN");
    if (!bin || access(bin, X_OK) != 0)
        skip();
    char cmd[9000], out[8192];
    fifo_reader r;
    fifo_with_reader(&r, "outfile_run.fifo");
    snprintf(cmd, sizeof cmd,
             "%s run %s/../config/scenes/cylinder.yaml --no-rt --no-display --fast --ticks 3 "
             "--stats-json %s 2>&1",
             bin, ISO_TEST_STREAMS "/..", r.path);
    int rc = run(cmd, out, sizeof out);
    pthread_join(r.th, NULL);
    print_message("--stats-json FIFO: exit %d, the reader got %zu bytes\n", rc, r.n);
    assert_int_equal(rc, 0);
    assert_true(r.n > 100 && r.got[0] == '{');
    struct stat st;
    assert_int_equal(lstat(r.path, &st), 0);
    assert_true(S_ISFIFO(st.st_mode));
    /* refused before the run: nothing runs, nothing is made */
    snprintf(cmd, sizeof cmd,
             "%s run %s/../config/scenes/cylinder.yaml --no-rt --no-display --fast --pc2 %s 2>&1",
             bin, ISO_TEST_STREAMS "/..", r.path);
    assert_int_equal(run(cmd, out, sizeof out), 1);
    print_message("--pc2 FIFO: %s", out);
    assert_non_null(strstr(out, "needs a regular file"));
    assert_null(strstr(out, "ticks"));
    char glb[4096];
    path_in_tmp(glb, sizeof glb, "outfile_run.glb");
    snprintf(cmd, sizeof cmd,
             "%s run %s/../config/scenes/cylinder.yaml --no-rt --no-display --fast --out %s 2>&1",
             bin, ISO_TEST_STREAMS "/..", glb);
    assert_int_equal(run(cmd, out, sizeof out), 1);
    print_message("--out x.glb: %s", out);
    assert_non_null(strstr(out, "must end in .off, .obj or .ply"));
    assert_int_equal(access(glb, F_OK), -1);
    unlink(r.path);
}

int main(void)
{
    const struct CMUnitTest t[] = {
        cmocka_unit_test(a_regular_file_is_replaced_whole),
        cmocka_unit_test(a_link_stays_a_link),
        cmocka_unit_test(fifos_and_devices_are_written_through),
        cmocka_unit_test(a_fifo_with_a_reader_gets_the_output),
        cmocka_unit_test(the_run_honours_fifos_and_refuses_up_front),
    };
    return cmocka_run_group_tests_name("outfile", t, NULL, NULL);
}
