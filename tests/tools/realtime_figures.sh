#!/usr/bin/env bash
# tests/tools/realtime_figures.sh -- the real-time loop's figures on the
# four benchmark scenes (docs/performance.md): each scene's scripted path through
# `isoshape run --fast` (one ABM step per tick, every tick computed, no
# waiting), under both ABM modes in the same run, so the ratio stands beside
# the figures. The scenes read ../shared/data/benchmark when it is there and
# fall back to built-in shapes otherwise (the vertex column says which).
#   usage: tests/tools/realtime_figures.sh [BUILD_DIR] [SCENE...]
#          (default: build; cactus cylinder bar bumpplane)
set -euo pipefail
cd "$(dirname "$0")/../.."
build=${1:-build}
shift || true
scenes=("$@")
((${#scenes[@]})) || scenes=(cactus cylinder bar bumpplane)
bin="$build/isoshape"
[ -x "$bin" ] || { echo "realtime_figures: no $bin; build first (bash .ci/setup)" >&2; exit 2; }
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT

# One JSON number by key (the loop's --stats-json is flat enough for this).
num() { grep -o "\"$2\": [-0-9.e+]*" "$1" | head -n 1 | awk '{print $2}'; }

printf '%-10s %6s %5s %5s | %8s %8s %8s %8s | %6s %6s %6s | %7s %7s %7s | %s\n' \
    scene verts abm ticks "ticks/s" "med ms" "p99 ms" "max ms" "ev/tk" "CG/ev" "facts" \
    "asm ms" "fac ms" "sol ms" "60 Hz (16.7 ms)"
for s in "${scenes[@]}"; do
    file="config/scenes/$s.yaml"
    [ -f "$file" ] || { echo "realtime_figures: no $file" >&2; exit 2; }
    verts=$("$bin" check "$file" | awk '/vertices/ {print $2; exit}' | tr -d ,)
    for abm in pece pec; do
        json="$tmp/$s-$abm.json"
        echo "realtime_figures: $s, $abm ..." >&2
        "$bin" run "$file" --fast --no-display --no-rt --quiet --abm "$abm" --stats-json "$json"
        ticks=$(num "$json" ticks)
        wall=$(num "$json" wall_s)
        evals=$(num "$json" evaluations)
        awk -v s="$s" -v v="$verts" -v a="$abm" -v t="$ticks" -v w="$wall" -v e="$evals" \
            -v med="$(num "$json" median)" -v p99="$(num "$json" p99)" \
            -v mx="$(num "$json" max)" -v cg="$(num "$json" cg_iterations)" \
            -v f="$(num "$json" factorizations)" -v as="$(num "$json" assembly_s)" \
            -v fs="$(num "$json" factor_s)" -v ss="$(num "$json" solve_s)" 'BEGIN {
            verdict = p99 <= 16.667 ? "held (p99)" : (med <= 16.667 ? "median only" : \
                      sprintf("no: %.1fx short at the median", med / 16.667))
            printf "%-10s %6s %5s %5d | %8.1f %8.2f %8.2f %8.2f | %6.2f %6.2f %6d | %7.2f %7.2f %7.2f | %s\n",
                   s, v, a, t, t / w, med, p99, mx, e / t, cg / e, f,
                   1e3 * as / e, 1e3 * fs / e, 1e3 * ss / e, verdict }'
    done
done
echo "median / p99 / max: tick compute time (wake to published); ev/tk: field evaluations per tick;"
echo "CG/ev: conjugate-gradient iterations per evaluation; facts: factorizations;"
echo "asm / fac / sol: milliseconds per evaluation in assembly, factorization, solve."
