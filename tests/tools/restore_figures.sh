#!/usr/bin/env bash
# tests/tools/restore_figures.sh -- prints the figures of isometry
# restoration (docs/method.md): the four benchmark problems under the paper's method, with
# restoration and under converged ARAP, and a mu x tau table.
#
#   restore_figures.sh BUILD_DIR [BENCHMARK_DIR] [problems|table|all]
#
# BUILD_DIR holds tests/tools/restore_run and tests/tools/arap_reference.
# BENCHMARK_DIR defaults to ../shared/data/benchmark next to the source tree.
# Slow on a small machine: "problems" runs each problem six times (the
# bumpplane takes minutes each), "table" 54 cactus and cylinder runs.
# Environment: MU, TAU (restoration settings, default 1 and 0.05, the
# `isoshape deform` default), KAPPA0 (non-empty: also 10 steps with tau as
# given, which may blow up), TABLE_PROBLEMS (default cactus and cylinder), ARAP_TIGHT (iterations of the tight ARAP
# solve, stopped at a relative energy change of 1e-12; default 30000).
set -euo pipefail
build=${1:?usage: restore_figures.sh BUILD_DIR [BENCHMARK_DIR] [problems|table|all]}
bench=${2:-$(cd "$(dirname "$0")/../../.." && pwd)/shared/data/benchmark}
what=${3:-all}
run="$build/tests/tools/restore_run"
arap="$build/tests/tools/arap_reference"
mu=${MU:-1}
tau=${TAU:-0.05}
tight=${ARAP_TIGHT:-30000}
export OPENBLAS_NUM_THREADS=${OPENBLAS_NUM_THREADS:-1}

# "metric area angle" of one restore_run, or "failed".
ours() { { "$run" "$@" || true; } | awk '/^failed/ { print "failed"; exit } { print $1, $2, $3, $4 }'; }
# "metric area angle iterations" of one ARAP solve.
arap_of() {
    "$arap" "$1" "$2" | awk '/^iterations/ { it = $2 } /^metricErr/ { m = $2 }
        /^areaErr/ { a = $2 } /^angleErr/ { g = $2 } END { print m, a, g, it }'
}

if [ "$what" = problems ] || [ "$what" = all ]; then
    echo "# metricErr / areaErr / angleErr; restored: mu $mu, tau $tau"
    printf '%-9s %-13s %-30s %s\n' problem method "metric area angle" "steps|iterations"
    for p in 00-plane-lift/knubbel 01-cylinder-bend/cylinder 02-bar-twist/bar \
             03-cactus-bend/cactus; do
        name=${p%%/*}
        name=${name#*-}
        printf '%-9s %-13s %s\n' "$name" "paper-10" "$(ours "$bench/$p" 0 0 10)"
        printf '%-9s %-13s %s\n' "$name" "restored-10" "$(ours "$bench/$p" "$mu" "$tau" 10)"
        printf '%-9s %-13s %s\n' "$name" "paper-adapt" "$(ours "$bench/$p" 0 0 0)"
        printf '%-9s %-13s %s\n' "$name" "restored-adapt" "$(ours "$bench/$p" "$mu" "$tau" 0)"
        printf '%-9s %-13s %s\n' "$name" "ARAP-1000" "$(arap_of "$bench/$p" 1000)"
        printf '%-9s %-13s %s\n' "$name" "ARAP-tight" "$(arap_of "$bench/$p" "$tight")"
    done
fi

if [ "$what" = table ] || [ "$what" = all ]; then
    echo "# mu x tau: metricErr angleErr; 10 fixed steps (kappa 1, and with KAPPA0=1 set"
    echo "# kappa 0 = tau as given), adaptive (kappa 1; metricErr angleErr steps)"
    for p in ${TABLE_PROBLEMS:-03-cactus-bend/cactus 01-cylinder-bend/cylinder}; do
        for m in 0.3 1 3; do
            for t in 0.02 0.05 0.2; do
                f1=$(ours "$bench/$p" "$m" "$t" 10 1 | cut -d' ' -f1,3)
                fa=$(ours "$bench/$p" "$m" "$t" 0 1 | cut -d' ' -f1,3,4)
                f0=skipped
                if [ -n "${KAPPA0:-}" ]; then
                    f0=$(ours "$bench/$p" "$m" "$t" 10 0 | cut -d' ' -f1,3)
                fi
                printf '%-8s mu %-4s tau %-5s | 10 k1: %-20s | 10 k0: %-20s | adapt: %s\n' \
                    "${p##*/}" "$m" "$t" "$f1" "$f0" "$fa"
            done
        done
    done
fi
