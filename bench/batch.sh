#!/bin/sh
# A database in one command against a shell loop (README "Batches"):
#   bench/batch.sh [R] [J] [LAYOUT...]       default: 16 8 io io-area hd
# Sources: the measured files of tests/data/measured plus 36 analytic
# ones (the microfacet model, 6 base colours x 6 roughnesses): 41, each on
# every LAYOUT.  Times `sepbrdf batch` over one manifest (its default -j)
# against a sequential loop of `sepbrdf factor` over the same rows and
# prints both times, the rows each finished and the ratio.  Rows that
# cannot be (iso on a non-reciprocal table) fail alike in both.
set -eu
here=$(cd "$(dirname "$0")" && pwd)
root=$(dirname "$here")
build=${BUILD:-$root/build}
res=${1:-16}
terms=${2:-8}
[ $# -ge 2 ] && shift 2 || set --
[ $# -ge 1 ] || set -- io io-area hd
[ -d "$build" ] || cmake -S "$root" -B "$build" >/dev/null
cmake --build "$build" --target sepbrdf_cli -j2 >/dev/null
cli=$build/sepbrdf
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

# the manifest: one row per source and layout
{
    echo "source,param"
    for layout in "$@"; do
        for f in "$root"/tests/data/measured/*; do
            case $f in *.md) continue ;; esac
            echo "$f,$layout"
        done
        for base in gold copper silver iron aluminium 0.5; do
            for r in 0.1 0.25 0.4 0.55 0.7 0.9; do
                echo "\"microfacet:base=$base,roughness=$r\",$layout"
            done
        done
    done
} >"$work/manifest.csv"
rows=$(($(wc -l <"$work/manifest.csv") - 1))
echo "# $(nproc) cores, $(grep -m1 'model name' /proc/cpuinfo | sed 's/.*: //'); load $(cut -d' ' -f1-3 /proc/loadavg)"
echo "# $rows rows ($# layouts: $*), -r $res -J $terms"

t0=$(date +%s.%N)
"$cli" batch "$work/manifest.csv" -r "$res" -J "$terms" -q -o "$work/batch" || true
t1=$(date +%s.%N)
mkdir "$work/loop"
tail -n +2 "$work/manifest.csv" | sed 's/^"\(.*\)",\([^,]*\)$/\1\t\2/; t; s/^\([^"\t][^,]*\),\([^,]*\)$/\1\t\2/' >"$work/rows.tsv"
n=0
while IFS="$(printf '\t')" read -r src layout; do
    n=$((n + 1))
    "$cli" factor "$src" --param "$layout" -r "$res" -J "$terms" -q -o "$work/loop/$n" 2>/dev/null || true
done <"$work/rows.tsv"
t2=$(date +%s.%N)

ok=$(grep -c ',ok,' "$work/batch/summary.csv" || true)
loop_ok=$(find "$work/loop" -name report.json | wc -l)
awk -v a="$t0" -v b="$t1" -v c="$t2" -v rows="$rows" -v ok="$ok" -v lok="$loop_ok" 'BEGIN {
    printf "sepbrdf batch:           %8.1f s  (%d of %d rows ok)\n", b - a, ok, rows
    printf "loop of sepbrdf factor:  %8.1f s  (%d of %d rows ok)\n", c - b, lok, rows
    printf "loop / batch:            %8.2f\n", (c - b) / (b - a)
}'
