#!/bin/sh
# Measured tables, default settings (docs/measured.md, "Per material"):
#   bench/measured.sh [DIR] [J]     (defaults: ../shared/data/measured if
#                                    present, else tests/data/measured; J 8)
# For every RGL .bsdf in DIR: `sepbrdf factor FILE -J J` (auto layout), its
# kept layout and form, the headline at J (f cos theta_i, relative L2) with
# its standard error, the per-channel headlines, and the CPU seconds of the
# whole command (/usr/bin/time: user + sys).
set -eu
here=$(cd "$(dirname "$0")" && pwd)
root=$(dirname "$here")
build=${BUILD:-$root/build}
dir=${1:-}
J=${2:-8}
if [ -z "$dir" ]; then
    if [ -d "$root/../shared/data/measured" ]; then dir="$root/../shared/data/measured"; else dir="$root/tests/data/measured"; fi
fi
[ -x "$build/sepbrdf" ] || { cmake -S "$root" -B "$build" >/dev/null && cmake --build "$build" -j2 >/dev/null; }
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
echo "# $(nproc) cores, $(grep -m1 'model name' /proc/cpuinfo | sed 's/.*: //'); load $(cut -d' ' -f1-3 /proc/loadavg); J = $J"
echo "| material | kept | headline | +- | headline R / G / B | CPU s |"
echo "|---|---|---|---|---|---|"
for f in "$dir"/*.bsdf; do
    [ -e "$f" ] || continue
    name=$(basename "$f" .bsdf)
    /usr/bin/time -f "%U %S" -o "$work/t" "$build/sepbrdf" -q factor "$f" -J "$J" -o "$work/out" 2>/dev/null || {
        echo "| $name | failed | | | | |"
        continue
    }
    cpu=$(awk '{printf "%.1f", $1 + $2}' "$work/t")
    python3 - "$work/out/report.json" "$name" "$cpu" "$J" <<'PY'
import json, sys
r = json.load(open(sys.argv[1]))
J = int(sys.argv[4])
e = [x for x in r["errors"] if x["terms"] == J][0]
ch = " / ".join("%.3g" % v for v in e.get("headline_channel", {}).values())
print("| %s | %s %s | %.3g | %.2g | %s | %s |" % (sys.argv[2], r["param"], r["form"], e["headline"],
      e["headline_se"], ch, sys.argv[3]))
PY
done
