#!/usr/bin/env bash
# tests/tools/load_figures.sh -- the README's demo scene under background
# load, as the load was first measured: `isoshape run
# config/scenes/replay_cactus.yaml --no-display --speed 0.25 --duration 5`,
# REPS times alone and REPS times beside BUSY busy processes (started and
# killed here), alternating, for each isoshape binary given. One row a run:
# slowest and p99 tick, deadline misses, the worker's wait per evaluation,
# loop stalls (the actuators' watchdog braked). The emulated MCU is the
# native one for every binary (ISO_FB_QEMU=""), so builds with and without
# the firmware ELF compare alike. Timings on a shared machine move with its
# load: the load average is printed with each run. Each binary runs in the
# source tree above its build folder when that has the scene (an older
# build reads its own tree's recordings), else in this one.
#   usage: tests/tools/load_figures.sh [REPS (3)] [BUSY (nproc + 1)] BIN...
set -euo pipefail
cd "$(dirname "$0")/../.."
reps=${1:-3}
busy=${2:-$(($(nproc) + 1))}
shift $(($# < 2 ? $# : 2)) # REPS and BUSY, as many as were given
bins=("$@")
((${#bins[@]})) || bins=(build/isoshape)
tmp=$(mktemp -d)
pids=()
cleanup() { for p in "${pids[@]}"; do kill -9 "$p" 2>/dev/null || true; done; rm -rf "$tmp"; }
trap cleanup EXIT

num() { grep -o "\"$2\": [-0-9.e+]*" "$1" | head -n 1 | awk '{print $2}'; }

printf '%-34s %-6s %5s | %8s %8s %8s | %9s %5s | %8s | %s\n' binary load rep "max ms" \
    "p99 ms" "median" misses lost "wait ms" "loop stalls"
for r in $(seq 1 "$reps"); do
    for b in "${bins[@]}"; do
        for n in 0 "$busy"; do
            pids=()
            for _ in $(seq 1 "$n"); do
                (end=$((SECONDS + 60)); while [ $SECONDS -lt $end ]; do :; done) & # ends by itself
                pids+=($!)
            done
            la=$(cut -d' ' -f1 /proc/loadavg)
            bin=$(cd "$(dirname "$b")" && pwd)/$(basename "$b")
            src=$(dirname "$(dirname "$bin")")
            [ -f "$src/config/scenes/replay_cactus.yaml" ] || src=.
            (cd "$src" && ISO_FB_QEMU="" "$bin" run config/scenes/replay_cactus.yaml --no-display \
                --speed 0.25 --duration 5 --stats-json "$tmp/s.json") >"$tmp/out" 2>&1 || {
                cat "$tmp/out" >&2
                exit 1
            }
            for p in "${pids[@]}"; do kill -9 "$p" 2>/dev/null || true; done
            wait 2>/dev/null || true
            stalls=$(grep -o 'loop stalls [0-9]*' "$tmp/out" | head -n 1 | awk '{print $3}')
            label=alone
            [ "$n" = 0 ] || label="$n busy"
            awk -v b="$b" -v n="$label" -v r="$r" -v la="$la" -v mx="$(num "$tmp/s.json" max)" \
                -v p99="$(num "$tmp/s.json" p99)" -v med="$(num "$tmp/s.json" median)" \
                -v mi="$(num "$tmp/s.json" misses)" -v t="$(num "$tmp/s.json" ticks)" \
                -v sk="$(num "$tmp/s.json" skipped)" \
                -v w="$(num "$tmp/s.json" worker_wait_s)" -v e="$(num "$tmp/s.json" evaluations)" \
                -v st="$stalls" 'BEGIN {
                printf "%-34s %-6s %5d | %8.1f %8.1f %8.1f | %4d/%-4d %5d | %8.2f | %s\n",
                       b, n, r, mx, p99, med, mi, t, sk,
                       (e > 0 ? 1e3 * w / e : 0), st }'
            echo "  (load average before: $la)"
        done
    done
done
echo "max / p99 / median: tick compute time (wake to published); misses: ticks that started after"
echo "a later deadline had passed; lost: deadlines late ticks covered beyond their own (of 300);"
echo "wait: the tick's wait for the factorization worker per evaluation."
