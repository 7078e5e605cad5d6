#!/bin/sh
# sepbrdf's topk and randomized against scipy svds and sklearn
# randomized_svd on the same matrices, in alternation (issue 36):
#   bench/solvers.sh [ROUNDS] [N] [J]     (defaults 5, 4096, 8)
# Exports the gold GGX io matrices (sepbrdf_bench --matrices), then runs
# bench/solvers.py with OPENBLAS_NUM_THREADS=1 and =2 for both sides (one
# process pair each).  Needs Python with numpy, scipy and scikit-learn
# (Debian: python3-numpy python3-scipy python3-sklearn; $PYTHON picks the
# interpreter); skipped with a message otherwise.  Bench only: no test
# or CI step depends on it.  MATRICES=DIR reuses matrices exported before.
set -eu
here=$(cd "$(dirname "$0")" && pwd)
root=$(dirname "$here")
build=${BUILD:-$root/build}
rounds=${1:-5}
n=${2:-4096}
J=${3:-8}
py=$("$here/python.sh" || true)
if [ -z "$py" ]; then
    echo "# solvers skipped: no Python with numpy, scipy and scikit-learn"
    exit 0
fi
[ -d "$build" ] || cmake -S "$root" -B "$build" >/dev/null
cmake --build "$build" --target sepbrdf_bench sepbrdf_bench_svd -j2 >/dev/null
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
echo "# $(nproc) cores, $(grep -m1 'model name' /proc/cpuinfo | sed 's/.*: //'); OPENBLAS_CORETYPE=${OPENBLAS_CORETYPE:-unset}"
echo "# $("$py" -c 'import numpy, scipy, sklearn; print("numpy", numpy.__version__, "scipy", scipy.__version__, "sklearn", sklearn.__version__)')"
m=${MATRICES:-$work/m}
[ -n "${MATRICES:-}" ] || "$build/sepbrdf_bench" --sizes "$n" --terms "$J" --methods topk --no-baseline --no-write \
    --min-time 0 -q -o "$work/run" --matrices "$m" >/dev/null
for t in 1 2; do
    OPENBLAS_NUM_THREADS=$t "$py" "$here/solvers.py" --server "$build/sepbrdf_bench_svd" --matrices "$m" \
        --n "$n" --terms "$J" --rounds "$rounds"
done
