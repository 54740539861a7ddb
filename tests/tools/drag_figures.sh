#!/usr/bin/env bash
# tests/tools/drag_figures.sh -- the real-time loop under a person's hand
# (docs/performance.md, "Under a person's hand"): tests/tools/drag_bench in
# real time for each source (the README demo's recorded 3D-mouse session,
# the fast one, a page's drag at a person's speed and at the view's
# limits' scale), on the cactus and the plane, restoration on and off. Each
# row is one run, so run it twice to see the spread; a loaded machine's
# figures say nothing.
#   usage: tests/tools/drag_figures.sh [BUILD_DIR [ISOSHAPE]] (about 3 minutes)
set -euo pipefail
cd "$(dirname "$0")/../.."
build=${1:-build}
bin=${2:-$build/isoshape}
tool="$build/tests/tools/drag_bench"
[ -x "$tool" ] && [ -x "$bin" ] || {
    echo "drag_figures: no $tool or $bin; build first (bash .ci/setup)" >&2
    exit 2
}
rt=rt
[ "${DRAG_FIGURES_NO_RT:-}" = 1 ] && rt=no
printf '%-16s %-6s %-3s | %-19s | %-22s | %-22s | %-10s | %-19s | %s\n' source mesh rst \
    "ticks computed" "tick med/p99/max ms" "input->publish med/p90/p99" "fact tick/wk" \
    "inexact, worst res, guard" "max strain"
for mesh in cactus plane; do
    for src in "$PWD/tests/streams/sm_session.isorec" "$PWD/tests/streams/sm_fast.isorec" \
        view-person view-fast; do
        for restore in on off; do
            "$tool" "$bin" "$src" "$mesh" "$restore" "$rt" ||
                echo "drag_figures: $src $mesh $restore failed" >&2
        done
    done
done
echo "ticks computed: of the periods the run spanned; input->publish: a device tick's input"
echo "due to its frame published; fact tick/wk: factorizations on the tick's thread (besides"
echo "the one before the clock starts) / handed over by the worker; inexact: solves that kept"
echo "their best iterate at the tick's budget, the worst relative residual, and the solves that"
echo "factored because theirs stayed above ISO_SOLVER_BOUNDED_RES."
