#!/bin/sh
# Matrices beyond memory (docs/performance.md, "Streamed factorisation"):
#   bench/stream.sh [R_BIG]      (default 256)
# 1. the stream solver (--method stream) against the dense SVD (--method
#    full, topk at R = 64) on the io layout of an anisotropic GGX at
#    R = 16, 32, 64: rel_rms of every J' and their largest relative gap;
# 2. `factor --param io -r R_BIG` (the matrix would not fit the memory
#    limit, so it is streamed): peak resident memory (/usr/bin/time -v)
#    and wall time.  R = 256 is 4.3e9 cells a pass, 6 passes (5 for the
#    terms, 1 for the errors): 3 hours at the 430 ns a cell (wall, both
#    cores) measured on the 2-core VM under a load of 19.
set -eu
here=$(cd "$(dirname "$0")" && pwd)
root=$(dirname "$here")
build=${BUILD:-$root/build}
big=${1:-256}
src="microfacet:roughness=0.3,anisotropy=0.8"
[ -d "$build" ] || cmake -S "$root" -B "$build" >/dev/null
cmake --build "$build" --target sepbrdf_cli -j2 >/dev/null
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
echo "# $(nproc) cores, $(grep -m1 'model name' /proc/cpuinfo | sed 's/.*: //'); source $src, --param io, J = 8"

# rel_rms (all channels) of every J' from report.json, one per line
rels() { grep -o '"rel_rms": *[0-9.e+-]*' "$1/report.json" | sed 's/.*: *//'; }

echo "R   dense   max |rel_stream / rel_dense - 1| over J' = 1..8   time dense  time stream"
for r in 16 32 64; do
    dense=full
    [ "$r" -ge 64 ] && dense=topk
    t0=$(date +%s.%N)
    "$build/sepbrdf" factor "$src" --param io -r "$r" -J 8 --method "$dense" -q -o "$work/d"
    t1=$(date +%s.%N)
    "$build/sepbrdf" factor "$src" --param io -r "$r" -J 8 --method stream -q -o "$work/s"
    t2=$(date +%s.%N)
    rels "$work/d" >"$work/d.txt"
    rels "$work/s" >"$work/s.txt"
    gap=$(paste "$work/d.txt" "$work/s.txt" | awk '{ g = $2 / $1 - 1; if (g < 0) g = -g; if (g > m) m = g } END { printf "%.2e", m }')
    awk -v r="$r" -v d="$dense" -v g="$gap" -v a="$t0" -v b="$t1" -v c="$t2" \
        'BEGIN { printf "%-3s %-7s %s   %8.2f s  %8.2f s\n", r, d, g, b - a, c - b }'
done

echo "factor --param io -r $big -J 4 (streamed):"
/usr/bin/time -v "$build/sepbrdf" factor "$src" --param io -r "$big" -J 4 --method stream -o "$work/big" 2>"$work/time.txt" |
    sed -n '2,7p'
grep -E 'Maximum resident|Elapsed' "$work/time.txt"
