#!/bin/bash
# Whether a change kept every output of `sepbrdf factor` (issue 36: the
# estimator made cheaper, the same bits):
#   bench/same_outputs.sh OLD_SEPBRDF NEW_SEPBRDF [all]
# runs both programs on the configurations below, each into its own
# folder, and compares the folders: the same files, every EXR and
# sepbrdf.glsl byte for byte, report.json as JSON with every key ending in
# _s (times) and the timings object left out.  Prints SAME or DIFFERENT per
# configuration; exit 1 when any differs.  `all` adds the paths a
# per-pair vector changes (one channel, plain sums, cos2, a layout with a
# gain, hd on another RGL file); `nmf` runs instead `-J 4 --method nmf`
# on the six RGL files of ../shared/data/measured (RGL=dir: elsewhere).
set -u
OLD=$1
NEW=$2
DATA=$(cd "$(dirname "$0")/../tests/data/measured" && pwd)
OUT=$(mktemp -d "${TMPDIR:-/tmp}/same_outputs.XXXXXX")
CFG=("io64|--param io -r 64 -J 8" "default|" "hd|--param hd" "rgl|$DATA/rgl_chm_orange_rgb.bsdf"
    "cornell|$DATA/cornell_acryl_blue.brdf" "scene|--scene view=0..40;light=0..60")
if [ "${3:-}" = all ]; then
    CFG+=("lambert|lambert --param io -r 32" "plain|lambert --param io -r 32 --plain-terms"
        "cos2|--param io -r 32 --form cos2" "vndf|$DATA/rgl_chm_orange_rgb.bsdf --param vndf -r 32"
        "ct_plain|microfacet:roughness=0.1 --param io -r 32 --plain-terms -J 6"
        "paper_hd|$DATA/rgl_paper_white_rgb.bsdf --param hd -r 24")
fi
if [ "${3:-}" = nmf ]; then
    RGL=${RGL:-$(cd "$(dirname "$0")/../../shared/data/measured" && pwd)}
    CFG=()
    for f in aurora_white cc_green_malachite chm_light_blue chm_orange paper_white vch_silk_blue; do
        CFG+=("nmf_$f|$RGL/rgl_${f}_rgb.bsdf -J 4 --method nmf")
    done
fi
fail=0
for c in "${CFG[@]}"; do
    name=${c%%|*}
    read -r -a A <<<"${c#*|}"
    for side in old new; do
        bin=$OLD
        [ $side = new ] && bin=$NEW
        "$bin" factor "${A[@]}" -q -o "$OUT/$name.$side" >"$OUT/$name.$side.log" 2>&1 || echo "$name: $side exit $?"
    done
    python3 - "$OUT/$name.old" "$OUT/$name.new" "$name" <<'PY' || fail=1
import filecmp, json, os, sys
a, b, name = sys.argv[1:4]
def strip(x):
    if isinstance(x, dict):
        return {k: strip(v) for k, v in x.items() if not k.endswith('_s') and k != 'timings'}
    return [strip(v) for v in x] if isinstance(x, list) else x
fa = sorted(os.listdir(a)) if os.path.isdir(a) else []
ok = bool(fa) and fa == (sorted(os.listdir(b)) if os.path.isdir(b) else [])
for f in fa if ok else []:
    pa, pb = os.path.join(a, f), os.path.join(b, f)
    if f == 'report.json':
        same = json.dumps(strip(json.load(open(pa))), sort_keys=True) == json.dumps(strip(json.load(open(pb))), sort_keys=True)
    else:
        same = filecmp.cmp(pa, pb, shallow=False)
    if not same:
        ok = False
        print(name, f, 'differs')
print(name, 'SAME' if ok else 'DIFFERENT', len(fa), 'files')
sys.exit(0 if ok else 1)
PY
done
rm -rf "$OUT"
exit $fail
