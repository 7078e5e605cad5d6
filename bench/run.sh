#!/bin/sh
# Full benchmark of the factor step (docs/performance.md):
#   bench/run.sh [sepbrdf_bench options]     e.g. --quick, --sizes 1024
# Builds sepbrdf_bench in $BUILD (default ./build), writes bench/results.csv
# and bench/results.png (gnuplot), then times the whole `sepbrdf factor`
# command at R = 32 and 64, J = 8 (best of 3) when the CLI is built.
# OPENBLAS_NUM_THREADS / OPENBLAS_CORETYPE in the environment pass through.
set -eu
here=$(cd "$(dirname "$0")" && pwd)
root=$(dirname "$here")
build=${BUILD:-$root/build}
[ -d "$build" ] || cmake -S "$root" -B "$build" >/dev/null
cmake --build "$build" --target sepbrdf_bench -j2 >/dev/null

echo "# $(nproc) cores, $(grep -m1 'model name' /proc/cpuinfo | sed 's/.*: //')"
echo "# OPENBLAS_NUM_THREADS=${OPENBLAS_NUM_THREADS:-unset} OPENBLAS_CORETYPE=${OPENBLAS_CORETYPE:-unset}"
"$build/sepbrdf_bench" -o "$here" "$@"

# The whole command: sample, plan, factor, write EXR + report + GLSL.
if cmake --build "$build" --target sepbrdf_cli -j2 >/dev/null 2>&1; then
    out=$(mktemp -d)
    for R in 32 64; do
        best=
        for i in 1 2 3; do
            t0=$(date +%s.%N)
            "$build/sepbrdf" factor -r "$R" -J 8 -q -o "$out/r$R"
            t1=$(date +%s.%N)
            best=$(awk -v a="$t0" -v b="$t1" -v best="$best" \
                'BEGIN { t = b - a; if (best == "" || t < best) best = t; printf "%.3f", best }')
        done
        echo "# sepbrdf factor -r $R -J 8 (default method): best of 3 $best s"
    done
    rm -rf "$out"
else
    echo "# sepbrdf CLI not built (src/exr.c missing?): whole-command timing skipped"
fi
