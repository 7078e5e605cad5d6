#!/bin/sh
# Matrices beyond memory (docs/performance.md, "Streamed factorisation"):
#   bench/stream.sh [R_BIG] [R_MPI]      (defaults 256, 48; 0 skips a part)
# 1. the stream solver (--method stream) against the dense SVD (--method
#    full, topk at R = 64) on the io layout of an anisotropic GGX at
#    R = 16, 32, 64, and against the exact block-circulant SVD (every
#    singular value, the tests hold it to dgesdd) of the isotropic GGX at
#    R = 64, 128: rel_rms of every J' and their largest relative gap;
# 2. the streamed solver over MPI ranks (sepbrdf-mpi factor --method
#    stream, where it is built): the anisotropic GGX at R_MPI, streamed
#    (--memory-limit 64M), on 1, 2 and 3 ranks: wall time and the largest
#    relative gap of rel_rms to the single process;
# 3. `factor --param io -r R_BIG` (the matrix would not fit the memory
#    limit, so it is streamed): peak resident memory (/usr/bin/time -v)
#    and wall time.  R = 256 is 4.3e9 cells a pass, 6 passes (5 for the
#    terms, 1 for the errors).
set -eu
here=$(cd "$(dirname "$0")" && pwd)
root=$(dirname "$here")
build=${BUILD:-$root/build}
big=${1:-256}
rmpi=${2:-48}
src="microfacet:roughness=0.3,anisotropy=0.8"
iso="microfacet:roughness=0.3"
[ -d "$build" ] || cmake -S "$root" -B "$build" >/dev/null
cmake --build "$build" --target sepbrdf_launch -j2 >/dev/null
cmake --build "$build" --target sepbrdf_mpi -j2 >/dev/null 2>&1 || true
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
echo "# $(nproc) cores, $(grep -m1 'model name' /proc/cpuinfo | sed 's/.*: //'); load $(cut -d' ' -f1-3 /proc/loadavg)"
echo "# sources $src and $iso, --param io, J = 8"

# rel_rms (all channels) of every J' from report.json, one per line
rels() { grep -o '"rel_rms": *[0-9.e+-]*' "$1/report.json" | sed 's/.*: *//'; }
# largest and smallest b / a - 1 over the rel_rms of folders $1 (a) and $2
# (b): a stream below its reference (negative) means the reference is not
# the optimum there (Eckart-Young)
gap() {
    rels "$1" >"$work/a.txt"
    rels "$2" >"$work/b.txt"
    paste "$work/a.txt" "$work/b.txt" | awk 'NR == 1 { hi = lo = $2 / $1 - 1 }
        { g = $2 / $1 - 1; if (g > hi) hi = g; if (g < lo) lo = g } END { printf "%+.2e %+.2e", hi, lo }'
}
now() { date +%s.%N; }

echo "source R   reference   rel_stream / rel_ref - 1 over J' = 1..8: max, min   time ref   time stream"
for case in "aniso 16 full" "aniso 32 full" "aniso 64 topk" "iso 64 auto" "iso 128 auto"; do
    set -- $case
    s=$src
    [ "$1" = iso ] && s=$iso
    t0=$(now)
    "$build/sepbrdf" factor "$s" --param io -r "$2" -J 8 --method "$3" -q -o "$work/d"
    t1=$(now)
    "$build/sepbrdf" factor "$s" --param io -r "$2" -J 8 --method stream -q -o "$work/s"
    t2=$(now)
    ref=$(grep -o '"method": *"[a-z]*"' "$work/d/report.json" | sed 's/.*"\([a-z]*\)"$/\1/')
    awk -v s="$1" -v r="$2" -v d="$ref" -v g="$(gap "$work/d" "$work/s")" -v a="$t0" -v b="$t1" -v c="$t2" \
        'BEGIN { printf "%-6s %-3s %-11s %s   %8.2f s  %8.2f s\n", s, r, d, g, b - a, c - b }'
done

if [ "$rmpi" -gt 0 ] && [ -x "$build/sepbrdf-mpi" ] && command -v mpirun >/dev/null; then
    [ "$(id -u)" -eq 0 ] && export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
    opts="--param io -r $rmpi -J 8 --method stream --memory-limit 64M -q"
    echo "ranks  wall (R = $rmpi, streamed)  rel / rel_1 - 1: max, min"
    t0=$(now)
    "$build/sepbrdf" factor "$src" $opts -o "$work/m1"
    t1=$(now)
    awk -v a="$t0" -v b="$t1" 'BEGIN { printf "1 (sepbrdf) %8.2f s\n", b - a }'
    for np in 2 3; do
        t0=$(now)
        mpirun -np "$np" --oversubscribe "$build/sepbrdf-mpi" factor "$src" $opts -o "$work/m$np"
        t1=$(now)
        awk -v n="$np" -v a="$t0" -v b="$t1" -v g="$(gap "$work/m1" "$work/m$np")" \
            'BEGIN { printf "%d (mpirun) %9.2f s   %s\n", n, b - a, g }'
    done
fi

if [ "$big" -gt 0 ]; then
    echo "factor --param io -r $big -J 8 (streamed):"
    /usr/bin/time -v "$build/sepbrdf" factor "$src" --param io -r "$big" -J 8 --method stream -o "$work/big" \
        2>"$work/time.txt" | sed -n '2,11p'
    grep -E 'Maximum resident|Elapsed|User time' "$work/time.txt"
fi
