/* common/iso_thread.h -- the one way the library starts a thread of its own
 * that no deadline depends on (a writer, an encoder, a reader that hands
 * bytes on): at normal priority whoever starts it (a real-time caller's
 * policy is not inherited), with every signal blocked, so that a signal the
 * program waits for (SIGINT, SIGTERM) goes to the program's threads, and a
 * SIGPIPE from a write to a reader that left stays with the thread as
 * EPIPE instead of ending the process. The caller's own signal mask is left
 * as it was. Internal to the library (CMakeLists.txt, iso_add_part
 * INTERNAL). */
#ifndef ISO_THREAD_H
#define ISO_THREAD_H

#include <pthread.h>

/* pthread_create's result: 0, or an errno value. */
int iso_thread_start(pthread_t *th, void *(*fn)(void *), void *arg);

#endif
