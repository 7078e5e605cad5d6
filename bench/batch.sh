#!/bin/sh
# A database in one command (docs/guide.md, "Batches"):
#   bench/batch.sh [R] [J...]           default: 16 16
# Sources: the measured files of MEASURED (default tests/data/measured,
# the tables of ../shared/data/measured) plus 36 analytic ones (the
# microfacet model, 6 base colours x 6 roughnesses): 41, each on every
# layout of LAYOUTS (default "io io-area hd") and every J: one manifest
# (columns source, param, terms), one command.  In one run it
#  1. times `sepbrdf batch` (its default -j) and checks that the summary
#     lists every row;
#  2. times a sequential loop of `sepbrdf factor` over the same rows;
#  3. runs the batch again into a new folder, kills it (SIGKILL, the
#     whole process group) once a third of the rows are published, runs
#     it again to the end, and compares with 1: textures byte for byte,
#     summaries but for time_s;
#  4. where sepbrdf-mpi is built: `mpirun -np 3` over the same manifest,
#     compared with 1 alike.
# Rows that cannot be (iso on a non-reciprocal table) fail alike in all.
set -eu
here=$(cd "$(dirname "$0")" && pwd)
root=$(dirname "$here")
build=${BUILD:-$root/build}
measured=${MEASURED:-$root/tests/data/measured}
layouts=${LAYOUTS:-io io-area hd}
res=${1:-16}
[ $# -ge 1 ] && shift
[ $# -ge 1 ] || set -- 16
[ -d "$build" ] || cmake -S "$root" -B "$build" >/dev/null
cmake --build "$build" --target sepbrdf_launch -j2 >/dev/null
cmake --build "$build" --target sepbrdf_mpi -j2 >/dev/null 2>&1 || true
cli=$build/sepbrdf
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
tab=$(printf '\t')

# the manifest and the same rows for the loop: source, layout, J
echo "source,param,terms" >"$work/manifest.csv"
: >"$work/rows.tsv"
row() {
    echo "\"$1\",$2,$3" >>"$work/manifest.csv"
    printf '%s\t%s\t%s\n' "$1" "$2" "$3" >>"$work/rows.tsv"
}
for layout in $layouts; do
    for terms in "$@"; do
        for f in "$measured"/*; do
            case $f in *.md) continue ;; esac
            row "$f" "$layout" "$terms"
        done
        for base in gold copper silver iron aluminium 0.5; do
            for r in 0.1 0.25 0.4 0.55 0.7 0.9; do
                row "microfacet:base=$base,roughness=$r" "$layout" "$terms"
            done
        done
    done
done
rows=$(wc -l <"$work/rows.tsv")
sources=$((rows / $(echo $layouts | wc -w) / $#))
echo "# $(nproc) cores, $(grep -m1 'model name' /proc/cpuinfo | sed 's/.*: //'); load $(cut -d' ' -f1-3 /proc/loadavg)"
echo "# $sources sources x layouts ($layouts) x J ($*) = $rows rows, -r $res"

now() { date +%s.%N; }
# summary.csv without its time_s column
summary() { sed -E 's/,[0-9.]+,(ok|error),/,\1,/' "$1/summary.csv"; }
# "yes" when folders $1 and $2 hold the same textures, byte for byte
same_textures() {
    (cd "$1" && find . -name '*.exr' | sort) >"$work/exr.txt"
    n=$(wc -l <"$work/exr.txt")
    bad=0
    while read -r f; do cmp -s "$1/$f" "$2/$f" || bad=$((bad + 1)); done <"$work/exr.txt"
    [ "$(cd "$2" && find . -name '*.exr' | wc -l)" -eq "$n" ] || bad=$((bad + 1))
    [ "$bad" -eq 0 ] && echo "yes ($n files)" || echo "NO ($bad of $n differ)"
}
same_summary() { summary "$1" >"$work/s1.txt" && summary "$2" >"$work/s2.txt" && cmp -s "$work/s1.txt" "$work/s2.txt" && echo yes || echo NO; }

t0=$(now)
"$cli" batch "$work/manifest.csv" -r "$res" -q -o "$work/batch" || true
t1=$(now)
mkdir "$work/loop"
n=0
while IFS="$tab" read -r src layout terms; do
    n=$((n + 1))
    "$cli" factor "$src" --param "$layout" -r "$res" -J "$terms" -q -o "$work/loop/$n" 2>/dev/null || true
done <"$work/rows.tsv"
t2=$(now)
listed=$(($(wc -l <"$work/batch/summary.csv") - 1))
ok=$(grep -c ',ok,' "$work/batch/summary.csv" || true)
loop_ok=$(find "$work/loop" -name report.json | wc -l)
awk -v a="$t0" -v b="$t1" -v c="$t2" -v rows="$rows" -v ok="$ok" -v lok="$loop_ok" -v l="$listed" 'BEGIN {
    printf "sepbrdf batch:           %8.1f s  (%d rows in the summary, %d of %d ok)\n", b - a, l, ok, rows
    printf "loop of sepbrdf factor:  %8.1f s  (%d of %d rows ok)\n", c - b, lok, rows
    printf "loop / batch:            %8.2f\n", (c - b) / (b - a)
}'

# interrupted and resumed
setsid "$cli" batch "$work/manifest.csv" -r "$res" -q -o "$work/resumed" >/dev/null 2>&1 &
pid=$!
while kill -0 "$pid" 2>/dev/null &&
    [ "$(find "$work/resumed" -name sepbrdf-set-factor.txt 2>/dev/null | wc -l)" -lt $((rows / 3)) ]; do
    sleep 0.2
done
kill -KILL -"$pid" 2>/dev/null || true
wait "$pid" 2>/dev/null || true
done_then=$(find "$work/resumed" -name sepbrdf-set-factor.txt | wc -l)
t3=$(now)
"$cli" batch "$work/manifest.csv" -r "$res" -q -o "$work/resumed" >/dev/null 2>&1 || true
t4=$(now)
awk -v a="$t3" -v b="$t4" -v d="$done_then" -v rows="$rows" 'BEGIN {
    printf "killed at %d of %d rows, resumed in %.1f s\n", d, rows, b - a }'
echo "  textures as the uninterrupted batch: $(same_textures "$work/batch" "$work/resumed")"
echo "  summary equal but for time_s:        $(same_summary "$work/batch" "$work/resumed")"

if [ -x "$build/sepbrdf-mpi" ] && command -v mpirun >/dev/null; then
    [ "$(id -u)" -eq 0 ] && export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
    t5=$(now)
    mpirun -np 3 --oversubscribe "$build/sepbrdf-mpi" batch "$work/manifest.csv" -r "$res" -q -o "$work/mpi" \
        >/dev/null 2>&1 || true
    t6=$(now)
    awk -v a="$t5" -v b="$t6" 'BEGIN { printf "mpirun -np 3 sepbrdf-mpi batch: %.1f s\n", b - a }'
    echo "  textures as the single-process batch: $(same_textures "$work/batch" "$work/mpi")"
    echo "  summary equal but for time_s:         $(same_summary "$work/batch" "$work/mpi")"
else
    echo "mpirun -np 3: sepbrdf-mpi is not built (CMake found no MPI)"
fi
