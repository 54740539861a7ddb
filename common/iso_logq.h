/* common/iso_logq.h -- lines from real-time threads to a stream that may
 * block, without ever blocking them.
 *
 * A thread that keeps a deadline (the tick, the actuators' sender, the
 * devices' reader, the view's server, which carries a page's STOP) must
 * never write to a descriptor or take a stdio lock: a stderr nobody drains
 * (a pipe nobody reads, `| less` at its page end, Ctrl-S on a terminal)
 * would hold it in write(2) for as long as it pleases. Such a thread puts
 * its line into a bounded lock-free queue made at creation (no allocation,
 * no system call), and a thread of the queue's own, at normal priority,
 * writes it out:
 *
 *   - a full queue drops the line and counts it; the count is written as a
 *     line of its own once the stream takes lines again;
 *   - a line that was written less than ISO_LOGQ_REPEAT_S ago is not
 *     written again but counted, and the count follows as one line
 *     ("... [N more times in 2 s]") when the window ends, so a flapping
 *     pair of notices costs two lines every two seconds, not a flood;
 *   - the writer waits for the stream with poll() before each write of at
 *     most a pipe's atomic size, so even its own thread is never stuck in
 *     write(2), and closing ends within a stated time whatever the
 *     stream does (lines it could not write by then are counted as
 *     dropped).
 *
 * A status line (a terminal's live line, redrawn a few times a second)
 * goes through the same queue; only the newest of a batch is drawn, and a
 * notice clears it first.
 *
 * Internal to the library (CMakeLists.txt, iso_add_part INTERNAL). */
#ifndef ISO_LOGQ_H
#define ISO_LOGQ_H

#include <stdio.h>

#include "iso_err.h"

#define ISO_LOGQ_LINE_MAX 640 /* bytes of one line, the newline included */
#define ISO_LOGQ_SLOTS 128    /* lines in flight before the queue drops */
#define ISO_LOGQ_REPEAT_S 2.0 /* a repeated line is counted, not written, this long */
#define ISO_LOGQ_CLOSE_MS 300 /* what closing waits for a stream that takes nothing */

typedef struct iso_logq iso_logq; /* opaque */

typedef struct iso_logq_stats {
    long written;   /* lines that reached the stream */
    long dropped;   /* lines lost: the queue full, or the stream still full at close */
    long collapsed; /* repeats counted instead of written */
} iso_logq_stats;

/* Starts a queue and its writer thread onto `f` (not owned; it must stay
 * open until destroy). Its descriptor, when it has one, is written with
 * write(2) after fflush(f); a FILE without one (a memory stream) with
 * fputs. `status_clear`: a notice first erases a status line ("\r\033[K"),
 * for a terminal. ISO_ENOMEM or ISO_EIO (the thread) naming what failed. */
ISO_NODISCARD int iso_logq_create(FILE *f, int status_clear, iso_logq **out, iso_err *err);

/* Writes what is queued, waiting at most ISO_LOGQ_CLOSE_MS for a stream
 * that takes nothing, then stops the thread and frees the queue. NULL is
 * a no-op. */
void iso_logq_destroy(iso_logq *q);

/* Queues one line (no newline needed; a longer one is cut). Lock-free and
 * wait-free for any number of threads: no allocation, no system call, no
 * lock. Returns 0, or -1 when the queue was full and the line was dropped
 * (counted). q NULL: the line goes nowhere (-1). */
int iso_logq_say(iso_logq *q, const char *line);
int iso_logq_sayf(iso_logq *q, const char *fmt, ...) ISO_PRINTF(2, 3);

/* Queues the status line, drawn without a newline in place of the last. */
int iso_logq_status(iso_logq *q, const char *line);

/* Blocks until everything queued so far was written or dropped (for a
 * caller that reads the stream next, such as a test). Not for a real-time
 * thread. 0, or -1 when it gave up after timeout_ms. */
int iso_logq_flush(iso_logq *q, int timeout_ms);

/* The counters so far (any thread). */
void iso_logq_get_stats(const iso_logq *q, iso_logq_stats *out);

#endif
