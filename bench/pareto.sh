#!/bin/sh
# The Pareto pictures of docs/guide.md ("Performance") and docs/performance.md (issue 36):
#   bench/pareto.sh [OUT]     (default docs/perf)
# `sepbrdf bench --pareto`: CPU seconds of the whole job against the
# headline error, front marked, on the default source (gold GGX: layouts
# auto, io, iso, hd, methods auto, randomized, topk, R = 16, 32, J = 1,
# 2, 4, 8; hd at R = 32, J = 8 alone takes ~70 CPU s) and on a measured
# file (the tests' RGL orange, tests/data/measured: layouts auto, io, iso,
# method auto, the same R and J).  Writes OUT/pareto-default.{csv,png}
# and OUT/pareto-measured.{csv,png}.  CASES="default measured" by default.
set -eu
here=$(cd "$(dirname "$0")" && pwd)
root=$(dirname "$here")
build=${BUILD:-$root/build}
out=${1:-$root/docs/perf}
[ -d "$build" ] || cmake -S "$root" -B "$build" >/dev/null
cmake --build "$build" --target sepbrdf_launch -j2 >/dev/null
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
mkdir -p "$out"
echo "# $(nproc) cores, $(grep -m1 'model name' /proc/cpuinfo | sed 's/.*: //'); load $(cut -d' ' -f1-3 /proc/loadavg)"
measured=${MEASURED:-$root/tests/data/measured/rgl_chm_orange_rgb.bsdf}
for case in ${CASES:-default measured}; do
    src= grid="--layouts auto,io,iso,hd --methods auto,randomized,topk"
    [ "$case" = measured ] && src="--source $measured" grid="--layouts auto,io,iso --methods auto"
    echo "# $case${src:+ ($measured)}"
    # shellcheck disable=SC2086
    "$build/sepbrdf" bench --pareto $src $grid --res 16,32 --terms 1,2,4,8 -o "$work/$case"
    cp "$work/$case/pareto.csv" "$out/pareto-$case.csv"
    cp "$work/$case/pareto.png" "$out/pareto-$case.png"
done
