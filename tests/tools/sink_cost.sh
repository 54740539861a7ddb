#!/usr/bin/env bash
# tests/tools/sink_cost.sh -- what writing a PC2 cache and an MCAP file live
# costs the tick: the README's demo scene (config/scenes/replay_cactus.yaml:
# the recorded session bending the cactus at 60 Hz, in real time) run
# without and with `--pc2 --mcap`, alternately, ROUNDS times each, so that
# both see the same machine. Prints each run's tick median and p99, then the
# median of the medians of each and their ratio (the target: at most 1.05).
# The live view is off in both (its cost is not the question here). The
# last line is what the tick itself spends on the outputs (filling its frame
# and copying it to the writer's queue) as a share of its median: on a
# machine whose cores the solver keeps busy, the ratio of medians also
# carries the writer thread's encoding competing for them.
# SPEED (default 1) paces the replay slower than real time: a machine that
# cannot keep the scene at 60 Hz merges late ticks, and then the two runs
# compute different ticks; at SPEED 0.25 every tick is computed, each the
# same 60 Hz step of stream time as in real time.
#   usage: tests/tools/sink_cost.sh [BUILD_DIR] [ROUNDS] [SPEED]   (default: build 3 1)
set -euo pipefail
cd "$(dirname "$0")/../.."
build=${1:-build}
rounds=${2:-3}
speed=${3:-1}
bin="$build/isoshape"
[ -x "$bin" ] || { echo "sink_cost: no $bin; build first (bash .ci/setup)" >&2; exit 2; }
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
scene=config/scenes/replay_cactus.yaml

# A field of one of a --stats-json file's objects: field FILE OBJECT KEY
# (tick_ms median, writer_handoff_ms max, ...).
field() { tr -d '\n ' <"$1" | grep -o "\"$2\":{[^}]*}" | grep -o "\"$3\":[-0-9.e+]*" | cut -d: -f2; }
median() { sort -g | awk '{v[NR] = $1} END {print (NR % 2) ? v[(NR + 1) / 2] : (v[NR / 2] + v[NR / 2 + 1]) / 2}'; }

echo "machine: $(nproc) cores, load $(cut -d' ' -f1-3 /proc/loadavg), speed $speed"
printf '%-8s %5s %10s %10s %8s %8s %12s %10s\n' run round "median ms" "p99 ms" ticks dropped "hand-off ms" "max ms"
: >"$tmp/without" && : >"$tmp/with"
for r in $(seq 1 "$rounds"); do
    for mode in without with; do
        extra=()
        [ "$mode" = with ] && extra=(--pc2 "$tmp/run.pc2" --mcap "$tmp/run.mcap")
        "$bin" run "$scene" --no-display --quiet --speed "$speed" --stats-json "$tmp/s.json" "${extra[@]}" \
            2>"$tmp/err" || { cat "$tmp/err" >&2; exit 1; }
        med=$(field "$tmp/s.json" tick_ms median)
        p99=$(field "$tmp/s.json" tick_ms p99)
        ticks=$(tr -d '\n ' <"$tmp/s.json" | grep -o '"ticks":[0-9]*' | head -n 1 | cut -d: -f2)
        dropped=$(tr -d '\n ' <"$tmp/s.json" | grep -o '"frames_dropped":[0-9]*' | cut -d: -f2)
        hand=$(field "$tmp/s.json" writer_handoff_ms mean)
        hmax=$(field "$tmp/s.json" writer_handoff_ms max)
        printf '%-8s %5s %10.3f %10.3f %8s %8s %12.4f %10.4f\n' "$mode" "$r" "$med" "$p99" "$ticks" "$dropped" "$hand" "$hmax"
        echo "$med" >>"$tmp/$mode"
        if [ "$mode" = with ]; then echo "$hand $med" >>"$tmp/hand"; fi
    done
done
a=$(median <"$tmp/without")
b=$(median <"$tmp/with")
awk -v a="$a" -v b="$b" 'BEGIN {printf "median of medians: without %.3f ms, with PC2+MCAP %.3f ms, ratio %.3f (target <= 1.05)\n", a, b, b / a}'
awk '{s += $1 / $2; n++} END {printf "the tick'"'"'s hand-off to the writer: %.3f %% of the tick median (mean over the runs with the outputs)\n", 100 * s / n}' "$tmp/hand"
