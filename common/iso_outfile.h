/* common/iso_outfile.h -- where a whole-or-nothing output is written, one
 * rule for every part that writes one (the run's --out, --png and
 * --stats-json, the PC2 cache and its rest mesh, the MCAP file).
 *
 * Such an output is written under a temporary name beside its path and
 * renamed onto it when it is complete, so a failure never leaves a torn
 * file. That is right only when the path names a regular file or nothing:
 *   - a regular file, or no file yet: the temporary name beside it, renamed
 *     onto it;
 *   - a symbolic link to a regular file (or to nothing yet in an existing
 *     folder): the same beside the link's target, so the link stays and
 *     its target is replaced;
 *   - a FIFO or a character device (/dev/stdout, a terminal, /dev/null):
 *     written through, nothing is renamed or created beside it. An output
 *     that must seek (PC2 rewrites its header) refuses them, and a FIFO
 *     that has no reader when the output is planned is refused too (the
 *     write would wait for one at the end of the run); one that has a
 *     reader is held open until the output is done, so the reader is not
 *     told the end of the file before it comes;
 *   - anything else (a folder, a socket, a block device) is refused.
 * Refusals come when the output is planned, so a command can say them
 * before its run starts. */
#ifndef ISO_OUTFILE_H
#define ISO_OUTFILE_H

#include "iso_err.h"

#define ISO_OUTFILE_PATH_MAX 4096

typedef struct iso_outfile {
    char path[ISO_OUTFILE_PATH_MAX];       /* what was asked for, for messages */
    char final[ISO_OUTFILE_PATH_MAX];      /* what is replaced: path, or a link's target */
    char write[ISO_OUTFILE_PATH_MAX + 64]; /* where the bytes go: a temporary name, or path */
    int through;                           /* 1: a FIFO or character device, written directly */
    int held, hold_fd; /* a FIFO's writer held open until done (a zeroed struct holds none) */
} iso_outfile;

enum { ISO_OUTFILE_SEQUENTIAL = 0, ISO_OUTFILE_SEEKS = 1 };

/* Plans the output at `path` by the rules above; `what` names it in
 * messages ("--stats-json", "PC2"). ISO_EINVAL "WHAT PATH: ..." for what
 * cannot be honoured (a folder; a FIFO without a reader; a FIFO or device
 * for an output that seeks), ISO_EIO for a path that cannot be examined. */
ISO_API ISO_NODISCARD int iso_outfile_plan(iso_outfile *o, const char *what, const char *path,
                                           int how, iso_err *err);

/* The output is complete in o->write: renames it onto o->final (nothing to
 * rename when written through) and lets go of a held FIFO. ISO_EIO naming
 * the path; the temporary file is removed then. */
ISO_API ISO_NODISCARD int iso_outfile_commit(iso_outfile *o, const char *what, iso_err *err);

/* The output failed or is not wanted: removes the temporary file (nothing
 * when written through) and lets go of a held FIFO. After a commit, or on
 * a zeroed struct, it does nothing. */
ISO_API void iso_outfile_abort(iso_outfile *o);

#endif
