/* solver/team.c -- two halves of a job on two threads (solver_internal.h,
 * iso_solver__team).
 *
 * The C assembly of a large mesh is split in two fixed halves (its plan
 * says where); the evaluating thread runs half 0 and a helper thread of
 * the solver's own runs half 1. What each half computes, and the order in
 * which the halves' sums are put together, are fixed by the plan, never by
 * which thread ran first, so the result is the same bits on one thread or
 * two (a team that could not start its thread runs both halves on the
 * caller, one after the other).
 *
 * The helper is started like the factorization worker (worker.c): all
 * signals blocked (signals stay with the program's threads) and the
 * default scheduling policy whatever the creator's. It waits on a
 * condition variable between jobs. Each job then runs at the scheduling
 * of the thread that hands it over: the helper does half of that
 * thread's work while that thread waits for it, so it must not run below
 * it. A real-time tick's halves run at the tick's priority, above the
 * factorization worker just below it, which would otherwise keep the
 * second core and hold the tick up for the rest of a factorization; and a
 * normal caller's halves run at normal priority. */
#include <pthread.h>
#include <sched.h>
#include <signal.h>
#include <stdlib.h>

#include "solver_internal.h"

struct iso_solver__team {
    pthread_t thread;
    pthread_mutex_t mu;
    pthread_cond_t cv;
    int started; /* the helper runs; else both halves run on the caller */
    int quit;
    unsigned long given, done; /* jobs handed to the helper, and finished by it */
    int policy, priority;      /* the helper's scheduling, as last set */
    void (*fn)(void *ctx, int half);
    void *ctx;
};

static void *team_main(void *arg)
{
    iso_solver__team *t = arg;
    unsigned long seen = 0;
    pthread_mutex_lock(&t->mu);
    for (;;) {
        while (t->given == seen && !t->quit)
            pthread_cond_wait(&t->cv, &t->mu);
        if (t->quit)
            break;
        seen = t->given;
        void (*fn)(void *, int) = t->fn;
        void *ctx = t->ctx;
        pthread_mutex_unlock(&t->mu);
        fn(ctx, 1);
        pthread_mutex_lock(&t->mu);
        t->done = seen;
        pthread_cond_broadcast(&t->cv);
    }
    pthread_mutex_unlock(&t->mu);
    return NULL;
}

int iso_solver__start_thread(pthread_t *th, void *(*fn)(void *), void *arg)
{
    pthread_attr_t attr;
    if (pthread_attr_init(&attr) != 0)
        return -1;
    int rc = pthread_attr_setinheritsched(&attr, PTHREAD_EXPLICIT_SCHED);
    if (rc == 0)
        rc = pthread_attr_setschedpolicy(&attr, SCHED_OTHER);
    sigset_t all, old;
    sigfillset(&all);
    if (rc == 0)
        rc = pthread_sigmask(SIG_SETMASK, &all, &old);
    if (rc == 0) {
        rc = pthread_create(th, &attr, fn, arg);
        pthread_sigmask(SIG_SETMASK, &old, NULL);
    }
    pthread_attr_destroy(&attr);
    return rc == 0 ? 0 : -1;
}

iso_solver__team *iso_solver__team_create(void)
{
    iso_solver__team *t = calloc(1, sizeof *t);
    if (!t)
        return NULL;
    if (pthread_mutex_init(&t->mu, NULL) != 0) {
        free(t);
        return NULL;
    }
    if (pthread_cond_init(&t->cv, NULL) != 0) {
        pthread_mutex_destroy(&t->mu);
        free(t);
        return NULL;
    }
    t->started = iso_solver__start_thread(&t->thread, team_main, t) == 0;
    t->policy = SCHED_OTHER;
    return t;
}

void iso_solver__team_destroy(iso_solver__team *t)
{
    if (!t)
        return;
    if (t->started) {
        pthread_mutex_lock(&t->mu);
        t->quit = 1;
        pthread_cond_broadcast(&t->cv);
        pthread_mutex_unlock(&t->mu);
        pthread_join(t->thread, NULL);
    }
    pthread_cond_destroy(&t->cv);
    pthread_mutex_destroy(&t->mu);
    free(t);
}

int iso_solver__team_threads(const iso_solver__team *t)
{
    return t && t->started ? 2 : 1;
}

/* The helper to the caller's scheduling, when it changed (the calling
 * thread's, read from the kernel: a thread may have changed its own with
 * sched_setscheduler, which pthread's cached view does not see). If the
 * change is refused the helper stays as it was. */
static void follow_caller(iso_solver__team *t)
{
    struct sched_param sp;
    int policy = sched_getscheduler(0);
    if (policy < 0 || sched_getparam(0, &sp) != 0)
        return;
    if (policy == t->policy && sp.sched_priority == t->priority)
        return;
    if (pthread_setschedparam(t->thread, policy, &sp) == 0) {
        t->policy = policy;
        t->priority = sp.sched_priority;
    }
}

void iso_solver__team_run(iso_solver__team *t, void (*fn)(void *ctx, int half), void *ctx)
{
    if (!t || !t->started) {
        fn(ctx, 0);
        fn(ctx, 1);
        return;
    }
    follow_caller(t);
    pthread_mutex_lock(&t->mu);
    t->fn = fn;
    t->ctx = ctx;
    unsigned long job = ++t->given;
    pthread_cond_broadcast(&t->cv);
    pthread_mutex_unlock(&t->mu);
    fn(ctx, 0);
    pthread_mutex_lock(&t->mu);
    while (t->done != job)
        pthread_cond_wait(&t->cv, &t->mu);
    pthread_mutex_unlock(&t->mu);
}

void iso_solver__team_half(int n, int half, int *begin, int *end)
{
    *begin = half == 0 ? 0 : n / 2;
    *end = half == 0 ? n / 2 : n;
}
