/* solver/worker.c -- numeric factorizations on a thread of their own
 * (iso_solver_opts.worker_lag; the policy is in linsolve.c).
 *
 * Why: on the cactus a factorization takes ~25-30 ms, a 60 Hz tick 16.7
 * ms, and the ticks that factored were the ones that missed their
 * deadlines. The worker factors a copy of the matrix an evaluation
 * assembled while the evaluations go on with the old factor; the factor is
 * handed over a fixed number of evaluations later, waiting for the worker
 * if it is not done. Which factor serves which evaluation is therefore
 * fixed by evaluation counts alone, never by a clock, and a run gives the
 * same bits whether the worker was early or late (replays and `run --fast`
 * against real time depend on it).
 *
 * The worker has its own CHOLMOD Common (a Common is not shared between
 * threads) and its own copy of the values of A. It sets OpenMP's
 * max-active-levels on its own thread once (the setting is per thread;
 * made on the evaluating thread it would not reach this one), blocks all
 * signals (they stay with the program's threads) and starts under the
 * default scheduling policy whatever the creator's. A real-time loop, whose
 * tick waits for it at each hand-over, puts it just below the tick's
 * priority (iso_solver_set_worker_priority; controller/iso_loop.h states
 * the rule): under SCHED_OTHER any busy process on the machine could hold
 * up the tick through it. Its lock inherits priority for the same reason. */
#include <pthread.h>
#include <sched.h>
#include <signal.h>
#include <stdlib.h>
#include <string.h>

#include "iso_clock.h"
#include "solver_internal.h"

struct iso_solver__worker {
    pthread_t thread;
    pthread_mutex_t mu;
    pthread_cond_t cv;
    int job;  /* a factorization is asked for */
    int done; /* it has ended (status in ok) */
    int quit;
    int ok;                   /* the ended job's cholmod_factorize result */
    cholmod_common c;         /* the worker's own; only the worker touches it while a job runs */
    cholmod_sparse *A;        /* the values to factor (a copy of the solver's A) */
    cholmod_factor *L;        /* the worker's factor; swapped with the solver's at hand-over */
    iso_solver__frame *frame; /* its frame (rotate.c), likewise; NULL without the solver's */
    void (*omp_set_levels)(int);
    double t_job; /* seconds the ended job took */
    int nv;       /* vertices, for the frame's positions */
};

static void *worker_main(void *arg)
{
    iso_solver__worker *w = arg;
    if (w->omp_set_levels)
        w->omp_set_levels(0);
    pthread_mutex_lock(&w->mu);
    for (;;) {
        while (!w->job && !w->quit)
            pthread_cond_wait(&w->cv, &w->mu);
        if (w->quit)
            break;
        pthread_mutex_unlock(&w->mu);
        double t0 = iso_clock_now();
        int ok = cholmod_factorize(w->A, w->L, &w->c);
        if (w->frame)
            iso_solver__frame_prepare(w->frame);
        double dt = iso_clock_now() - t0;
        pthread_mutex_lock(&w->mu);
        w->ok = ok;
        w->t_job = dt;
        w->job = 0;
        w->done = 1;
        pthread_cond_broadcast(&w->cv);
    }
    pthread_mutex_unlock(&w->mu);
    return NULL;
}

int iso_solver__worker_create(const iso_solver *s, iso_solver__worker **out, iso_err *err)
{
    *out = NULL;
    iso_solver__worker *w = calloc(1, sizeof *w);
    if (!w)
        return iso_err_set(err, ISO_ENOMEM, -1, "out of memory for the factorization worker");
    cholmod_start(&w->c);
    w->c.final_ll = s->c.final_ll;
    w->c.supernodal = s->c.supernodal;
    w->omp_set_levels = s->omp_set_levels;
    w->nv = s->nv;
    w->A = cholmod_copy_sparse(s->A, &w->c);
    w->L = w->A ? cholmod_copy_factor(s->L, &w->c) : NULL;
    if (s->frame)
        w->frame = iso_solver__frame_create(s->rings, s->nv);
    pthread_mutexattr_t ma;
    pthread_mutexattr_init(&ma);
    pthread_mutexattr_setprotocol(&ma, PTHREAD_PRIO_INHERIT);
    int ok = w->A && w->L && (!s->frame || w->frame) && pthread_mutex_init(&w->mu, &ma) == 0;
    pthread_mutexattr_destroy(&ma);
    if (ok && pthread_cond_init(&w->cv, NULL) != 0) {
        pthread_mutex_destroy(&w->mu);
        ok = 0;
    }
    if (ok && iso_solver__start_thread(&w->thread, worker_main, w) != 0) {
        pthread_cond_destroy(&w->cv);
        pthread_mutex_destroy(&w->mu);
        ok = 0;
    }
    if (!ok) {
        iso_solver__frame_destroy(w->frame);
        cholmod_free_sparse(&w->A, &w->c);
        cholmod_free_factor(&w->L, &w->c);
        cholmod_finish(&w->c);
        free(w);
        return iso_err_set(err, ISO_ENOMEM, -1,
                           "could not start the factorization worker (memory or threads)");
    }
    *out = w;
    return ISO_OK;
}

void iso_solver__worker_destroy(iso_solver__worker *w)
{
    if (!w)
        return;
    pthread_mutex_lock(&w->mu);
    w->quit = 1;
    pthread_cond_broadcast(&w->cv);
    pthread_mutex_unlock(&w->mu);
    pthread_join(w->thread, NULL);
    pthread_cond_destroy(&w->cv);
    pthread_mutex_destroy(&w->mu);
    iso_solver__frame_destroy(w->frame);
    cholmod_free_sparse(&w->A, &w->c);
    cholmod_free_factor(&w->L, &w->c);
    cholmod_finish(&w->c);
    free(w);
}

void iso_solver__worker_start(iso_solver__worker *w, const cholmod_sparse *A, const double *x)
{
    pthread_mutex_lock(&w->mu);
    /* The worker is idle (no job, or its result was taken): its A and frame
     * are ours. */
    memcpy(w->A->x, A->x, (size_t)((const int *)A->p)[A->ncol] * sizeof(double));
    if (w->frame)
        memcpy(iso_solver__frame_positions(w->frame), x, (size_t)w->nv * 3 * sizeof(double));
    w->job = 1;
    w->done = 0;
    pthread_cond_broadcast(&w->cv);
    pthread_mutex_unlock(&w->mu);
}

int iso_solver__worker_finish(iso_solver__worker *w, cholmod_factor **L, iso_solver__frame **frame,
                              int *status, long *minor, double *seconds)
{
    pthread_mutex_lock(&w->mu);
    while (!w->done)
        pthread_cond_wait(&w->cv, &w->mu);
    w->done = 0;
    int ok = w->ok;
    *seconds = w->t_job;
    pthread_mutex_unlock(&w->mu);
    *status = w->c.status;
    *minor = (long)w->L->minor;
    if (L) {
        cholmod_factor *t = *L;
        *L = w->L;
        w->L = t;
    }
    if (L && frame && w->frame) {
        iso_solver__frame *t = *frame;
        *frame = w->frame;
        w->frame = t;
    }
    return ok;
}

int iso_solver_set_worker_priority(iso_solver *s, int priority, iso_err *err)
{
    if (!s || priority < 0)
        return iso_err_set(err, ISO_EINVAL, -1, "worker priority %d: expected 0 or more", priority);
    if (!s->w)
        return ISO_OK;
    struct sched_param sp;
    memset(&sp, 0, sizeof sp);
    sp.sched_priority = priority;
    int rc = pthread_setschedparam(s->w->thread, priority > 0 ? SCHED_FIFO : SCHED_OTHER, &sp);
    if (rc != 0)
        return iso_err_set(err, ISO_EIO, -1, "factorization worker: SCHED_FIFO %d: %s", priority,
                           strerror(rc));
    return ISO_OK;
}
