/* tests/test_late_tick.c -- late ticks keep the mesh whole:
 *   (a) a recorded browser session whose loop stalled (ticks covering 0.5,
 *       28 and 31 s of stream time while the handle was dragged and let
 *       go; tests/scenes/late_drag.yaml) replays to a mesh whose largest
 *       edge strain stays below 30%, with restoration on and without it.
 *       Before the stepper restarted its history for a step far longer than
 *       its last (iso_integrate.h), the replay without restoration ended at
 *       961% strain; before the loop also bounded a sub-step's length under
 *       restoration to its τ (iso_loop.h), the one with it tore the mesh to 1,000%
 *       and failed ("the free-free system is not positive definite");
 *   (b) the same replay twice gives the same bits (the rules are functions
 *       of the recorded tick times alone). */
#include <stdio.h>
#include <string.h>

#include "iso_loop.h"
#include "replay_fast.h"
#include "testutil.h"

#define SCENES ISO_TEST_STREAMS "/../scenes/"

static void late_ticks_keep_the_mesh_whole(void **state)
{
    (void)state;
    static const char *const scenes[] = {SCENES "late_drag.yaml", SCENES "late_drag_off.yaml"};
    for (int k = 0; k < 2; k++) {
        iso_loop_summary a, b;
        replay_fast(scenes[k], scenes[k], &a);
        replay_fast(scenes[k], scenes[k], &b);
        print_message("%s: %ld ticks over %.1f s of stream time, %ld sub-steps beyond one a "
                      "tick, %ld coarse: largest edge strain %.3g%%, rms %.3g%%, metricErr %.3g\n",
                      scenes[k], a.ticks, a.stream_s, a.substeps, a.coarse,
                      100 * a.metrics.max_edge_strain, 100 * a.metrics.rms_edge_strain,
                      a.metrics.metric_err);
        assert_true(a.stream_s > 60); /* the stalls are in the recording */
        assert_true(a.metrics.max_edge_strain < 0.3);
        assert_true(a.checksum == b.checksum);
    }
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(late_ticks_keep_the_mesh_whole),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
