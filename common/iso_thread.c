/* common/iso_thread.c -- see iso_thread.h. */
#include "iso_thread.h"

#include <errno.h>
#include <sched.h>
#include <signal.h>
#include <string.h>

int iso_thread_start(pthread_t *th, void *(*fn)(void *), void *arg)
{
    pthread_attr_t at;
    pthread_attr_init(&at);
    pthread_attr_setinheritsched(&at, PTHREAD_EXPLICIT_SCHED);
    pthread_attr_setschedpolicy(&at, SCHED_OTHER);
    struct sched_param sp;
    memset(&sp, 0, sizeof sp);
    pthread_attr_setschedparam(&at, &sp);
    sigset_t all, old;
    sigfillset(&all);
    pthread_sigmask(SIG_SETMASK, &all, &old);
    int rc = pthread_create(th, &at, fn, arg);
    pthread_sigmask(SIG_SETMASK, &old, NULL);
    pthread_attr_destroy(&at);
    return rc;
}

int iso_thread_waker_start(iso_thread_waker *w, void *(*fn)(void *), void *arg)
{
    atomic_init(&w->quit, 0);
    if (sem_init(&w->wake, 0, 0) != 0)
        return errno;
    int e = iso_thread_start(&w->th, fn, arg);
    if (e != 0)
        sem_destroy(&w->wake);
    return e;
}

void iso_thread_waker_post(iso_thread_waker *w)
{
    sem_post(&w->wake);
}

void iso_thread_waker_wait(iso_thread_waker *w)
{
    while (sem_wait(&w->wake) != 0 && errno == EINTR)
        ;
}

int iso_thread_waker_quitting(iso_thread_waker *w)
{
    return atomic_load(&w->quit);
}

void iso_thread_waker_stop(iso_thread_waker *w)
{
    atomic_store(&w->quit, 1);
    sem_post(&w->wake);
    pthread_join(w->th, NULL);
    sem_destroy(&w->wake);
}
