#!/bin/sh
# The issue-38 table: `factor SRC [--param P] -J TERMS --method nmf` on the
# default gold, GGX alpha 0.1 and 0.3 (iso, hd, io), the Cornell acrylic and
# the RGL files; per run the pooled errors[].nmf_over_svd at J' = 1..TERMS,
# the worst channel's errors[].nmf_over_svd_channel at each J', the layout
# kept, and the worst of all (one line each, the worst marked with *).
#     bench/positive_table.sh [build dir] [out dir]   (TERMS=4; RGL=dir)
set -eu
BIN=${1:-build}/sepbrdf
OUT=${2:-/tmp/sepbrdf-positive-table}
TERMS=${TERMS:-4}
RGL=${RGL:-$(dirname "$0")/../../shared/data/measured}
DATA=$(dirname "$0")/../tests/data/measured
mkdir -p "$OUT"
show() { # tag report.json
    python3 -c '
import json, sys
r = json.load(open(sys.argv[2]))
e = r["errors"]
p = [x["nmf_over_svd"] for x in e]
c = [max((x.get("nmf_over_svd_channel") or {"-": 0}).values()) for x in e]
w = max(p + c)
lay = r["param"] if isinstance(r["param"], str) else r["param"].get("name", "?")
print("%-34s %-5s pooled %s | chan %s | worst %.2f%s" % (sys.argv[1], lay,
      " ".join("%.2f" % v for v in p), " ".join("%.2f" % v for v in c), w,
      " *" if w > 1.5 else ""))' "$1" "$2"
}
run() { # tag source param
    d="$OUT/$1"
    src=$2
    [ "$src" = default ] && src=
    # shellcheck disable=SC2086
    $BIN factor $src $3 -J "$TERMS" --method nmf -q -o "$d" >/dev/null 2>&1 || { echo "$1: failed"; return; }
    show "$1" "$d/report.json"
}
run gold default ""
for g in 0.316:0.1 0.548:0.3; do
    for p in iso hd io; do
        run "ggx${g#*:}_$p" "microfacet:roughness=${g%:*}" "--param $p"
    done
done
run cornell "$DATA/cornell_acryl_blue.brdf" ""
for f in aurora_white cc_green_malachite chm_light_blue chm_orange paper_white vch_silk_blue; do
    run "$f" "$RGL/rgl_${f}_rgb.bsdf" ""
done
