#!/bin/sh
# What positivity costs: `factor --method nmf` against the default method
# on the same layout (report.json errors[].nmf_over_svd at every J'), and
# the wall time of each against the default run's.  Usage:
#     bench/positive.sh [build dir] [out dir]      (RES=32 TERMS=4 by default)
# One line per source and layout: the ratios at J' = 1..TERMS, what
# stopped the fit (report.json fit.stopped: tolerance or its sweep cap),
# the times of nmf (with its SVD beside) and of the default run.
# docs/positive.md has our figures.
set -eu
BIN=${1:-build}/sepbrdf
OUT=${2:-/tmp/sepbrdf-positive}
RES=${RES:-32}
TERMS=${TERMS:-4}
MEAS=${MEAS:-$(dirname "$0")/../tests/data}
mkdir -p "$OUT"
ratios() { # report.json -> "r1 r2 ... stopped=..."
    python3 -c '
import json, sys
r = json.load(open(sys.argv[1]))
print(" ".join("%.3f" % e["nmf_over_svd"] for e in r["errors"]), "stopped=%s" % r["fit"]["stopped"])' "$1"
}
secs() { python3 -c 'import json,sys; print("%.2f" % json.load(open(sys.argv[1]))["timings"]["total_s"])' "$1"; }
run() { # source ("default": the embedded gold) param
    tag=$(echo "$1 $2" | tr -c 'A-Za-z0-9.\n' '_')
    src=$1
    [ "$1" = default ] && src=
    # shellcheck disable=SC2086
    $BIN factor $src --param "$2" --res "$RES" --terms "$TERMS" -o "$OUT/$tag.svd" >/dev/null 2>&1 ||
        { echo "$1 $2: svd failed"; return; }
    # shellcheck disable=SC2086
    $BIN factor $src --param "$2" --res "$RES" --terms "$TERMS" --method nmf -o "$OUT/$tag.nmf" >/dev/null 2>&1 ||
        { echo "$1 $2: nmf failed"; return; }
    printf '%-44s %-5s %s  nmf %ss  svd %ss\n' "$1" "$2" "$(ratios "$OUT/$tag.nmf/report.json")" \
        "$(secs "$OUT/$tag.nmf/report.json")" "$(secs "$OUT/$tag.svd/report.json")"
}
run default auto
for g in 0.1 0.3; do
    for p in iso hd io; do run "cook-torrance:d=ggx,roughness=$g" $p; done
done
for f in ${SOURCES:-$MEAS/measured/cornell_acryl_blue.brdf $MEAS/measured/rgl_chm_orange_rgb.bsdf}; do run "$f" auto; done
