/* common/iso_outfile.c -- see iso_outfile.h. */
#define _DEFAULT_SOURCE /* realpath */
#include "iso_outfile.h"

#include <errno.h>
#include <fcntl.h>
#include <limits.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

/* "<stem>.part-<pid><ext>" beside `final`: the extension kept, since some
 * writers choose their format by it. */
static void temp_beside(iso_outfile *o)
{
    const char *p = o->final;
    const char *slash = strrchr(p, '/'), *dot = strrchr(p, '.');
    if (!dot || (slash && dot < slash))
        dot = p + strlen(p);
    snprintf(o->write, sizeof o->write, "%.*s.part-%ld%s", (int)(dot - p), p, (long)getpid(), dot);
}

/* A link's target when the link points to nothing yet: resolved through
 * its folder, which must exist. */
static int dangling_target(iso_outfile *o, const char *what, iso_err *err)
{
    char link[ISO_OUTFILE_PATH_MAX];
    ssize_t n = readlink(o->path, link, sizeof link - 1);
    if (n < 0)
        return iso_err_set(err, ISO_EIO, -1, "%s %s: %s", what, o->path, strerror(errno));
    link[n] = 0;
    int dir = link[0] == '/' || !strchr(o->path, '/') ? 0 : (int)(strrchr(o->path, '/') - o->path);
    int len = dir ? snprintf(o->final, sizeof o->final, "%.*s/", dir, o->path) : 0;
    if ((size_t)len + (size_t)n >= sizeof o->final)
        return iso_err_set(err, ISO_EINVAL, -1, "%s %s: its link's target is too long", what,
                           o->path);
    memcpy(o->final + len, link, (size_t)n + 1);
    return ISO_OK;
}

static int plan_fifo(iso_outfile *o, const char *what, iso_err *err)
{
    /* a FIFO opened for writing without a reader fails at once here
     * (ENXIO) instead of waiting; one with a reader is held, so that the
     * reader sees no end of file before the output's own */
    o->hold_fd = open(o->path, O_WRONLY | O_NONBLOCK | O_CLOEXEC);
    o->held = o->hold_fd >= 0;
    if (o->hold_fd < 0 && errno == ENXIO)
        return iso_err_set(err, ISO_EINVAL, -1,
                           "%s %s: a FIFO that nobody reads: start its reader first", what,
                           o->path);
    if (o->hold_fd < 0)
        return iso_err_set(err, ISO_EIO, -1, "%s %s: %s", what, o->path, strerror(errno));
    return ISO_OK;
}

int iso_outfile_plan(iso_outfile *o, const char *what, const char *path, int how, iso_err *err)
{
    memset(o, 0, sizeof *o);
    if (!path || !path[0] || strlen(path) >= sizeof o->path)
        return iso_err_set(err, ISO_EINVAL, -1, "%s: no path, or one too long", what);
    snprintf(o->path, sizeof o->path, "%s", path);
    snprintf(o->final, sizeof o->final, "%s", path);
    struct stat st, lst;
    if (stat(path, &st) != 0) {
        if (errno != ENOENT)
            return iso_err_set(err, ISO_EIO, -1, "%s %s: %s", what, path, strerror(errno));
        int rc = ISO_OK;
        if (lstat(path, &lst) == 0 && S_ISLNK(lst.st_mode))
            rc = dangling_target(o, what, err);
        if (rc != ISO_OK)
            return rc;
        temp_beside(o);
        return ISO_OK;
    }
    if (S_ISREG(st.st_mode)) {
        char real[PATH_MAX];
        if (lstat(path, &lst) == 0 && S_ISLNK(lst.st_mode) && realpath(path, real))
            snprintf(o->final, sizeof o->final, "%s", real);
        temp_beside(o);
        return ISO_OK;
    }
    const char *kind = S_ISFIFO(st.st_mode)   ? "a FIFO"
                       : S_ISCHR(st.st_mode)  ? "a character device"
                       : S_ISDIR(st.st_mode)  ? "a folder"
                       : S_ISSOCK(st.st_mode) ? "a socket"
                                              : "a block device";
    if (!S_ISFIFO(st.st_mode) && !S_ISCHR(st.st_mode))
        return iso_err_set(err, ISO_EINVAL, -1, "%s %s: is %s, not a file", what, path, kind);
    if (how == ISO_OUTFILE_SEEKS)
        return iso_err_set(err, ISO_EINVAL, -1,
                           "%s %s: is %s; this output rewrites its header at the end and needs a "
                           "regular file",
                           what, path, kind);
    o->through = 1;
    snprintf(o->write, sizeof o->write, "%s", path);
    return S_ISFIFO(st.st_mode) ? plan_fifo(o, what, err) : ISO_OK;
}

static void let_go(iso_outfile *o)
{
    if (o->held)
        close(o->hold_fd);
    o->held = 0;
}

int iso_outfile_commit(iso_outfile *o, const char *what, iso_err *err)
{
    let_go(o);
    int rc = ISO_OK;
    if (!o->through && o->write[0] && rename(o->write, o->final) != 0) {
        rc = iso_err_set(err, ISO_EIO, -1, "%s %s: %s", what, o->path, strerror(errno));
        unlink(o->write);
    }
    o->write[0] = 0; /* done: abort has nothing left to remove */
    return rc;
}

void iso_outfile_abort(iso_outfile *o)
{
    let_go(o);
    if (!o->through && o->write[0])
        unlink(o->write);
    o->write[0] = 0;
}
