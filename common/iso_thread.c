/* common/iso_thread.c -- see iso_thread.h. */
#include "iso_thread.h"

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
