/* tests/test_team.c -- the solver's two-thread team (solver/team.c):
 *   (a) both halves of a job run, the second on the helper thread, and the
 *       call returns after both;
 *   (b) the helper runs each job at the scheduling of the thread that hands
 *       it over: SCHED_FIFO at the caller's priority for a real-time caller
 *       (a tick waits for its halves, so they must not run below it), and
 *       back under SCHED_OTHER for a normal caller. (b) skips, saying why,
 *       where this process may not use SCHED_FIFO. */
#include <errno.h>
#include <pthread.h>
#include <sched.h>
#include <stdio.h>
#include <string.h>

#include "../solver/solver_internal.h"
#include "testutil.h"

typedef struct job {
    int ran[2];
    pthread_t who[2];
    int policy[2], priority[2];
} job;

static void record(void *ctx, int half)
{
    job *j = ctx;
    struct sched_param sp;
    j->ran[half]++;
    j->who[half] = pthread_self();
    j->policy[half] = sched_getscheduler(0);
    j->priority[half] = sched_getparam(0, &sp) == 0 ? sp.sched_priority : -1;
}

static void both_halves_run(void **state)
{
    (void)state;
    iso_solver__team *t = iso_solver__team_create();
    assert_non_null(t);
    job j;
    memset(&j, 0, sizeof j);
    for (int k = 0; k < 3; k++)
        iso_solver__team_run(t, record, &j);
    assert_int_equal(j.ran[0], 3);
    assert_int_equal(j.ran[1], 3);
    assert_true(pthread_equal(j.who[0], pthread_self()));
    if (iso_solver__team_threads(t) == 2)
        assert_false(pthread_equal(j.who[1], pthread_self()));
    iso_solver__team_destroy(t);
}

static void the_helper_follows_its_caller(void **state)
{
    (void)state;
    iso_solver__team *t = iso_solver__team_create();
    assert_non_null(t);
    if (iso_solver__team_threads(t) != 2) {
        iso_solver__team_destroy(t);
        print_message("skipped: the team could not start its helper thread\n");
        skip();
    }
    struct sched_param old, rt = {.sched_priority = 10};
    int old_policy = sched_getscheduler(0);
    assert_int_equal(sched_getparam(0, &old), 0);
    if (sched_setscheduler(0, SCHED_FIFO, &rt) != 0) {
        iso_solver__team_destroy(t);
        print_message("skipped: SCHED_FIFO is not permitted here (%s)\n", strerror(errno));
        skip();
    }
    job j;
    memset(&j, 0, sizeof j);
    iso_solver__team_run(t, record, &j);
    int fifo = j.policy[1], fifo_prio = j.priority[1];
    assert_int_equal(sched_setscheduler(0, old_policy, &old), 0);
    iso_solver__team_run(t, record, &j);
    print_message("helper under a SCHED_FIFO %d caller: policy %d priority %d; under a normal "
                  "caller: policy %d priority %d\n",
                  rt.sched_priority, fifo, fifo_prio, j.policy[1], j.priority[1]);
    assert_int_equal(fifo, SCHED_FIFO);
    assert_int_equal(fifo_prio, rt.sched_priority);
    assert_int_equal(j.policy[1], old_policy);
    assert_int_equal(j.priority[1], old.sched_priority);
    iso_solver__team_destroy(t);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(both_halves_run),
        cmocka_unit_test(the_helper_follows_its_caller),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
