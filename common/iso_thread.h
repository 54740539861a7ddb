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
#include <semaphore.h>
#include <stdatomic.h>

/* pthread_create's result: 0, or an errno value. */
int iso_thread_start(pthread_t *th, void *(*fn)(void *), void *arg);

/* A thread started so that sleeps until it is posted to (the recording's
 * button, the hub's reopens): its function loops on iso_thread_waker_wait,
 * does what the posts asked for, and returns once
 * iso_thread_waker_quitting says so. A poster never waits: sem_post takes
 * no lock, so a real-time tick may post. */
typedef struct iso_thread_waker {
    pthread_t th;
    sem_t wake;
    _Atomic int quit;
} iso_thread_waker;
/* 0, or an errno value with nothing left to undo. */
int iso_thread_waker_start(iso_thread_waker *w, void *(*fn)(void *), void *arg);
void iso_thread_waker_post(iso_thread_waker *w);
void iso_thread_waker_wait(iso_thread_waker *w); /* until a post (EINTR aside) */
int iso_thread_waker_quitting(iso_thread_waker *w);
/* Asks the thread to quit, wakes it and joins it (what it is doing
 * finishes first). */
void iso_thread_waker_stop(iso_thread_waker *w);

#endif
