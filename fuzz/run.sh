#!/bin/sh
# Run every libFuzzer harness for a bounded time.
#   CC=clang cmake -S . -B build-fuzz -DSEPBRDF_FUZZ=ON && cmake --build build-fuzz -j2
#   fuzz/run.sh [BUILD_DIR [SECONDS [NAME...]]]      (defaults: build-fuzz 60 all)
# Each harness starts from its seeds in fuzz/corpus/<name>/ plus what
# earlier runs found (kept in BUILD_DIR/fuzz-corpus/<name>/, outside the
# source tree).  A crash leaves its input in BUILD_DIR/fuzz-artifacts/ and
# makes this script fail: copy the input to tests/data/fuzz/<name>/ so that
# test_fuzz_regress replays it in every normal test run, then fix the bug.
set -eu
cd "$(dirname "$0")/.."
build=${1:-build-fuzz}
secs=${2:-60}
[ $# -gt 2 ] && shift 2 && names="$*" || names="spec exr measured"
art=$build/fuzz-artifacts
mkdir -p "$art"
status=0
for n in $names; do
    bin=$build/fuzz/fuzz_$n
    [ -x "$bin" ] || { echo "fuzz/run.sh: $bin missing (build with -DSEPBRDF_FUZZ=ON)" >&2; exit 2; }
    work=$build/fuzz-corpus/$n
    mkdir -p "$work"
    dict=""
    [ -f fuzz/$n.dict ] && dict="-dict=fuzz/$n.dict"
    echo "fuzz/run.sh: $n for ${secs}s" >&2
    # -rss_limit_mb above the library's own 256 MiB limit (fuzz_util.c):
    # forged sizes must be refused by sepbrdf, not by libFuzzer.
    if ! "$bin" -max_total_time="$secs" -timeout=20 -rss_limit_mb=2048 -malloc_limit_mb=1024 \
        -print_final_stats=1 -artifact_prefix="$art/$n-" $dict "$work" fuzz/corpus/$n \
        > "$build/fuzz-$n.log" 2>&1; then
        status=1
        echo "fuzz/run.sh: $n FAILED, see $build/fuzz-$n.log; inputs:" >&2
        ls "$art" | grep "^$n-" >&2 || true
        tail -n 40 "$build/fuzz-$n.log" >&2
    else
        grep -E "stat::number_of_executed_units|stat::new_units_added|stat::peak_rss_mb" "$build/fuzz-$n.log" | tr '\n' ' ' >&2
        echo "corpus $(ls "$work" | wc -l)" >&2
    fi
done
exit $status
