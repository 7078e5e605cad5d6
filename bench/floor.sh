#!/bin/bash
# The whole `sepbrdf factor` against its physical floor (issue 36):
#   bench/floor.sh [ROUNDS] [CASES]     (defaults 5, "io64 io256 default")
# For every case, ROUNDS rounds in alternation of the floor program
# (bench/floor.c: one pass over the R^3 distinct values of the same BRDF,
# three channels, the textures' bytes written raw) and the whole command
# (sample, factor, estimate, write EXR + report + GLSL), each its own
# process; CPU seconds (user + system of the child, from bash's `times`),
# the ratio command / floor of every round, and their median, min and
# max.  CPU, not wall: on a shared machine wall times carry the load.
# Prints lines `ratio CASE MEDIAN MIN MAX` that bench/compare.sh reads.
# Cases:
#   io64     factor --param io -r 64 -J 8     floor R = 64, J = 8, 64x64
#   io256    factor --param io -r 256 -J 8    floor R = 256, J = 8, 256x256
#   default  factor (auto, R = 32, J = 4)     floor R = 32, J = 4, its texture sizes
set -eu
here=$(cd "$(dirname "$0")" && pwd)
root=$(dirname "$here")
build=${BUILD:-$root/build}
rounds=${1:-5}
cases=${2:-io64 io256 default}
[ -d "$build" ] || cmake -S "$root" -B "$build" >/dev/null
cmake --build "$build" --target sepbrdf_launch sepbrdf_bench_floor -j2 >/dev/null
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
mkdir -p "$work/floor"

# CPU seconds (children's user + system) of running "$@"
cpu() {
    local a b
    times >"$work/t0" # no pipe or $( ): a forked shell has no children yet
    "$@" >/dev/null 2>&1
    times >"$work/t1"
    a=$(tail -1 "$work/t0")
    b=$(tail -1 "$work/t1")
    awk -v a="$a" -v b="$b" 'function s(x){ sub("s$","",x); split(x,p,"m"); return p[1]*60+p[2] }
        BEGIN { split(a,x," "); split(b,y," "); printf "%.4f", s(y[1])+s(y[2])-s(x[1])-s(x[2]) }'
}

# median, min, max of the numbers on stdin
stats() { sort -g | awk '{ v[NR] = $1 } END { m = NR % 2 ? v[(NR+1)/2] : (v[NR/2]+v[NR/2+1])/2; printf "%.3f %.3f %.3f", m, v[1], v[NR] }'; }

echo "# $(nproc) cores, $(grep -m1 'model name' /proc/cpuinfo | sed 's/.*: //'); load $(cut -d' ' -f1-3 /proc/loadavg)"
echo "# case: CPU s of the floor and of the whole command, median (min-max) over $rounds rounds in alternation"
for c in $cases; do
    case $c in
    io64) fl="-r 64 -J 8" cmd="--param io -r 64 -J 8" ;;
    io256) fl="-r 256 -J 8" cmd="--param io -r 256 -J 8" ;;
    default) fl="-r 32 -J 4 --size 64x1 --hsize 62x16" cmd="" ;;
    *)
        echo "bench/floor.sh: unknown case $c (io64, io256, default)" >&2
        exit 1
        ;;
    esac
    : >"$work/f" && : >"$work/w" && : >"$work/r"
    for i in $(seq "$rounds"); do
        # shellcheck disable=SC2086
        f=$(cpu "$build/sepbrdf_bench_floor" $fl -o "$work/floor")
        # shellcheck disable=SC2086
        w=$(cpu "$build/sepbrdf" factor $cmd -q -o "$work/out")
        echo "$f" >>"$work/f"
        echo "$w" >>"$work/w"
        awk -v f="$f" -v w="$w" 'BEGIN { printf "%.3f\n", w / (f > 0 ? f : 0.001) }' >>"$work/r"
    done
    echo "# $c: floor $(stats <"$work/f") s, command $(stats <"$work/w") s"
    echo "ratio $c $(stats <"$work/r")"
done
