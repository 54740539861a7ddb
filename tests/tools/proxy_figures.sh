#!/usr/bin/env bash
# tests/tools/proxy_figures.sh -- the reduced model's accuracy: a built-in
# problem deformed on the whole mesh, then through proxies of several
# budgets along the same path, each compared with the whole-mesh result
# (the Table 1 measures and the edge strains, each over the whole-mesh
# value, and every vertex's distance to it as a share of the bounding-box
# diagonal), beside a converged ARAP of the same problem. Prints which
# budgets meet metricErr within 1.5x of the whole mesh's and below ARAP's.
# The whole mesh's integral is the reference, so it is integrated at a much
# finer step than the default (REF_TOL, default 1e-6 of the diagonal; the
# default 1e-4 leaves the 40k plane's metricErr 10% low and its vertices 2%
# of the diagonal off); the proxies run at the default step, as a scene's.
#
#   proxy_figures.sh BUILD_DIR SHAPE RESOLUTION "BUDGET ..." [RESTORE [REF_TOL]]
#
# e.g. proxy_figures.sh build bumpplane 201 "2000 4000 8000 16000" off
# RESTORE is deform's --restore (default off: the paper's method).
# SMOOTHNESS in the environment lists --proxy-smoothness values, each a row
# per budget (default "mesh"; "mesh matched" compares the two). Slow:
# the whole-mesh deformation of a 160k mesh takes tens of minutes and
# gigabytes at REF_TOL 1e-6.
set -euo pipefail
build=${1:?usage: proxy_figures.sh BUILD_DIR SHAPE RESOLUTION "BUDGET ..." [RESTORE]}
shape=${2:?shape}
res=${3:?resolution}
budgets=${4:?budgets}
restore=${5:-off}
ref_tol=${6:-1e-6}
smooth=${SMOOTHNESS:-mesh}
iso="$build/isoshape"
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT

# The value of "key" in a one-line JSON object.
field() { grep -o "\"$1\": [^,}]*" | head -1 | awk '{ print $2 }'; }
ratio() { awk -v a="$1" -v b="$2" 'BEGIN { if (b > 0) printf "%.3g", a / b; else print "-" }'; }

"$build/tests/tools/write_shape" "$shape" "$res" "$tmp/p.off" "$tmp/p.sel" "$tmp/p.def" >/dev/null
full=$("$iso" deform --shape "$shape" --resolution "$res" --restore "$restore" \
    --refactor adaptive --worker-lag 0 --tol "$ref_tol" --json --out "$tmp/full.ply" 2>/dev/null)
arap=$("$build/tests/tools/arap_reference" "$tmp/p" 2000 | awk '/^metricErr/ { print $2 }')
keys="metric_err area_err angle_err max_edge_strain rms_edge_strain"
declare -A ref
for k in $keys; do ref[$k]=$(echo "$full" | field "$k"); done
echo "# $shape $res: $(echo "$full" | field evaluations) evaluations at --tol $ref_tol, restore $restore;" \
    "whole mesh: metricErr ${ref[metric_err]}, areaErr ${ref[area_err]}," \
    "angleErr ${ref[angle_err]}, max strain ${ref[max_edge_strain]}," \
    "rms strain ${ref[rms_edge_strain]}, $(echo "$full" | field seconds) s;" \
    "converged ARAP (2000 iterations at most): metricErr $arap"
printf '%7s %8s %6s %8s %9s %8s %8s %8s %8s %8s %10s %10s %8s\n' budget omega proxy seconds \
    metricErr "/whole" "area/" "angle/" "max/" "rms/" "dist max" "dist rms" "meets"
for b in $budgets; do for sm in $smooth; do
    out=$("$iso" deform --shape "$shape" --resolution "$res" --restore "$restore" \
        --refactor adaptive --worker-lag 0 --json --proxy "$b" --proxy-smoothness "$sm" \
        --against "$tmp/full.ply" 2>/dev/null)
    m=$(echo "$out" | field metric_err)
    meets=$(awk -v m="$m" -v w="${ref[metric_err]}" -v a="$arap" \
        'BEGIN { print (m <= 1.5 * w && m < a) ? "yes" : "no" }')
    printf '%7s %8.4g %6s %8.2f %9.4g %8s %8s %8s %8s %8s %10.3g %10.3g %8s\n' "$b" \
        "$(echo "$out" | field proxy_omega)" "$(echo "$out" | field proxy_vertices)" "$(echo "$out" | field seconds)" "$m" \
        "$(ratio "$m" "${ref[metric_err]}")" \
        "$(ratio "$(echo "$out" | field area_err)" "${ref[area_err]}")" \
        "$(ratio "$(echo "$out" | field angle_err)" "${ref[angle_err]}")" \
        "$(ratio "$(echo "$out" | field max_edge_strain)" "${ref[max_edge_strain]}")" \
        "$(ratio "$(echo "$out" | field rms_edge_strain)" "${ref[rms_edge_strain]}")" \
        "$(echo "$out" | field against_max_distance)" \
        "$(echo "$out" | field against_rms_distance)" "$meets"
done; done
