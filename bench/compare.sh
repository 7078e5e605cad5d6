#!/bin/sh
# Regressions caught by ratios, not absolute times (issue 36):
#   bench/compare.sh [--quick] [--update] [--rounds N]
# Measures the ratios of bench/floor.sh (the whole `sepbrdf factor`
# against its physical floor, CPU seconds in alternation: io64, io256 and
# the default; --quick: io64 and the default, 3 rounds, about 10-20 s)
# and compares each with bench/baseline.txt (lines `ratio CASE MEDIAN
# MIN MAX`).  A ratio moved when its median differs from the baseline's
# by more than the noise: half the spread (MAX - MIN) of the baseline
# plus half that of this run, and at least 10 % of the baseline.  Prints
# one line a ratio (ok / MOVED, up = slower) and always exits 0: timing
# on a shared machine never fails CI.  --update writes the run as the
# new baseline.
set -eu
here=$(cd "$(dirname "$0")" && pwd)
rounds=5 cases="io64 io256 default" update=0
while [ $# -gt 0 ]; do
    case $1 in
    --quick) rounds=3 cases="io64 default" ;;
    --update) update=1 ;;
    --rounds)
        rounds=$2
        shift
        ;;
    *)
        echo "bench/compare.sh: unknown option $1 (--quick, --update, --rounds N)" >&2
        exit 1
        ;;
    esac
    shift
done
base=$here/baseline.txt
run=$(mktemp)
trap 'rm -f "$run"' EXIT
"$here/floor.sh" "$rounds" "$cases" | tee "$run" | grep '^#' || true
if [ "$update" = 1 ]; then
    {
        echo "# bench/baseline.txt: ratios of bench/floor.sh (bench/compare.sh --update), $(date -u +%Y-%m-%d)"
        grep -m1 '^# [0-9]* cores' "$run" || true
        grep '^ratio ' "$run"
    } >"$base"
    echo "bench/compare.sh: baseline written to $base"
    exit 0
fi
grep '^ratio ' "$run" | while read -r _ name med lo hi; do
    line=$(grep "^ratio $name " "$base" 2>/dev/null || true)
    if [ -z "$line" ]; then
        echo "ratio $name $med ($lo-$hi): no baseline"
        continue
    fi
    echo "$line" | awk -v name="$name" -v med="$med" -v lo="$lo" -v hi="$hi" '{
        bm = $3; bl = $4; bh = $5
        noise = (bh - bl) / 2 + (hi - lo) / 2
        if (noise < 0.1 * bm) noise = 0.1 * bm
        d = med - bm
        verdict = (d > noise) ? "MOVED up (slower)" : ((-d > noise) ? "MOVED down (faster)" : "ok")
        printf "ratio %s %.3f (%.3f-%.3f) against baseline %.3f (%.3f-%.3f), noise %.3f: %s\n", name, med, lo, hi, bm, bl, bh, noise, verdict
    }'
done
exit 0
