#!/usr/bin/env bash
# tests/tools/realtime_minute.sh -- does a large mesh hold its tick rate in
# real time? One minute of stream time (or SECONDS) of a handle dragged out
# and back (keyframes: the problem's .def translation reached at 4 s, rest
# again at 8 s, and so on), paced in real time at 60 Hz with the scene's
# defaults for everything else (so the reduced model where `auto` picks it),
# no view (HZ=N in the environment for another rate). Prints the loop's deadline misses, the tick's median, p99 and max,
# and the reduced model's line. docs/performance.md has the figures.
# PROXY_SMOOTHNESS=matched in the environment steps the proxy with the
# matched omega (solver.proxy_smoothness). FAST=1 computes every tick as
# fast as it goes (--fast) instead: no tick merged into the next, so the
# solver's counts (factorizations, capped solves) are the same on any
# machine and compare two settings exactly.
#   usage: tests/tools/realtime_minute.sh [BUILD_DIR] [MESH] [SECONDS]
#     MESH: bumpplane (the benchmark's 40k plane, else the built-in one at
#           resolution 201), tentacle128 (163,842 vertices), tentacle317
#           (1,004,892), default bumpplane
set -euo pipefail
cd "$(dirname "$0")/../.."
build=${1:-build}
mesh=${2:-bumpplane}
secs=${3:-60}
bin="$build/isoshape"
[ -x "$bin" ] || { echo "realtime_minute: no $bin; build first (bash .ci/setup)" >&2; exit 2; }
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
case "$mesh" in
bumpplane) src="{benchmark: bumpplane, fallback_shape: bumpplane, resolution: 201}"
           move="[-32.3, 0, 56.7]" ;;   # the benchmark's .def: a lift, no turn
tentacle128) src="{shape: tentacle, resolution: 128}"; move="[0.3, 0, -0.6]" ;;
tentacle317) src="{shape: tentacle, resolution: 317}"; move="[0.3, 0, -0.6]" ;;
*) echo "realtime_minute: unknown mesh $mesh" >&2; exit 2 ;;
esac
{
    echo "name: minute_$mesh"
    echo "mesh: $src"
    echo "regions:"
    echo "  sel: builtin"
    echo "  handles:"
    echo "    - name: top"
    echo "      driver:"
    echo "        keyframes:"
    for ((t = 0; t <= secs; t += 4)); do
        if (((t / 4) % 2)); then echo "          - {t: $t, translate: $move}"
        else echo "          - {t: $t, translate: [0, 0, 0]}"; fi
    done
    echo "integrator: {abm: pec}"
    [ -z "${PROXY_SMOOTHNESS:-}" ] || echo "solver: {proxy_smoothness: $PROXY_SMOOTHNESS}"
    echo "tick_hz: ${HZ:-60}"
} > "$tmp/scene.yaml"
uptime
"$bin" run "$tmp/scene.yaml" --no-display --duration "$secs" ${FAST:+--fast} \
    --stats-json "$tmp/s.json" 2>&1 |
    grep -E "reduced model|real-time|tick time|latency|deadlines|scene minute|solver|CG iter|worker"
