#!/bin/sh
# Regenerate the seed corpora in fuzz/corpus/ (committed; run this only to
# refresh them).  Usage: fuzz/make-seeds.sh BUILD_DIR   (a normal build with
# the sepbrdf binary).  Seeds are small: libFuzzer mutates them.
set -eu
cd "$(dirname "$0")/.."
build=${1:-build}
cli=$build/sepbrdf
c=fuzz/corpus
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
mkdir -p $c/spec $c/exr $c/measured

# spec: valid, boundary and malformed model specs
i=0
for s in "lambert" "lambert:albedo=0.8" "lambert:albedo=0.9/0.5/0.1" \
         "microfacet:base=gold,roughness=0.5" "microfacet:roughness=0.001" \
         "microfacet:base=0.9/0.6/0.3,metallic=0.5,reflectance=0.3,roughness=1" \
         "microfacet:base=glass,reflectance=0,metallic=1" "phong:exponent=10000" \
         "lambert:albedo=1e-300" "microfacet:roughness=4.9e-324" "lambert:albedo=0x1p-3" \
         "microfacet:base=1/2" "lambert:=" "lambert:albedo" ":" ""; do
    printf '%s' "$s" > $c/spec/seed-$i
    i=$((i + 1))
done

# exr: "SBX2" + little-endian length of g_00.exr + g_00.exr + h_00.exr
pair() { # name, factor args...
    name=$1
    shift
    rm -rf "$tmp/o"
    "$cli" factor "$@" -q -o "$tmp/o"
    g=$(wc -c < "$tmp/o/g_00.exr")
    {
        printf 'SBX2'
        printf "$(printf '\\%03o\\%03o\\%03o\\%03o' $((g & 255)) $((g >> 8 & 255)) $((g >> 16 & 255)) $((g >> 24 & 255)))"
        cat "$tmp/o/g_00.exr" "$tmp/o/h_00.exr"
    } > "$c/exr/$name"
}
pair lambert-float lambert:albedo=0.5/0.6/0.7 --res 2 -J 1 --param io
pair ggx-half microfacet:roughness=0.2 --res 4 -J 1 --param io --half
pair ggx-float microfacet:base=gold,roughness=0.05 --res 3 -J 1 --param io --form cos2

# measured: first byte picks the extension (0 .binary, 1 .brdf, 2 .dat,
# 3 .alta, 4 .csv, 5 .bsdf), the rest is the file
m=../shared/data/measured
ext() { printf "$(printf '\\%03o' "$1")"; }
# MERL: int32 90 90 180 then doubles (truncated), and a tiny 1 x 1 x 2 table
{ ext 0; printf '\132\000\000\000\132\000\000\000\264\000\000\000'; head -c 64 /dev/zero; } > $c/measured/merl-truncated
{ ext 0; printf '\001\000\000\000\001\000\000\000\002\000\000\000'
  printf '\000\000\000\000\000\000\360\077%.0s' 1 2 3 4 5 6; } > $c/measured/merl-tiny
{ ext 0; printf '\377\377\377\177\001\000\000\000\001\000\000\000'; } > $c/measured/merl-2g-dim
if [ -d $m ]; then
    { ext 1; head -n 12 $m/cornell_acryl_blue.brdf; } > $c/measured/cornell-head
    { ext 2; head -n 14 $m/alta_retro-3M-jaune.dat; } > $c/measured/alta-dat-head
    { ext 3; head -n 12 $m/alta_merl_pink-felt-1d.alta; } > $c/measured/alta-1d-head
    { ext 5; head -c 1024 $m/rgl_paper_white_rgb.bsdf; } > $c/measured/rgl-head
fi
{ ext 4; printf 'theta_i,phi_i,theta_o,phi_o,r,g,b\n0.1,0,0.2,3.14159,0.5,0.4,0.3\n0.5,1,0.7,0,0.2,0.2,0.2\n'; } > $c/measured/csv-small
{ ext 4; printf 'theta_i,phi_i,theta_o,phi_o,r,g,b\n0.1,0,0.2,3.14,nan,inf,-1\n1e999,0,0,0,1,1,1\n'; } > $c/measured/csv-hostile
{ ext 3; printf '#DIM 3 1\n#PARAM_IN ISOTROPIC_TL_TV_PROJ_DPHI\n#PARAM_OUT INV_STERADIAN_COSINE_FACTOR\n0.2 0.1 0.05 0.4\nnan 0 0 1\n'; } > $c/measured/alta-tiny
echo "seeds: $(ls $c/spec | wc -l) spec, $(ls $c/exr | wc -l) exr, $(ls $c/measured | wc -l) measured"
# RGL: a complete tiny tensor_file (2 theta_i slices, 2 x 2 tables)
if command -v python3 > /dev/null; then
    python3 - "$c/measured/rgl-tiny" <<'PY'
import struct, sys
def field(name, dt, shape, data):
    return (name, dt, shape, data)
f = [field("theta_i", 10, [2], [0.0, 1.5]), field("phi_i", 10, [1], [0.0]),
     field("ndf", 10, [2, 2], [1, 2, 3, 4]), field("sigma", 10, [2, 2], [1, 1, 1, 1]),
     field("vndf", 10, [1, 2, 2, 2], [1, 2, 1, 2, 3, 1, 1, 1]),
     field("rgb", 10, [1, 2, 3, 2, 2], [0.1 * k for k in range(24)]),
     field("jacobian", 1, [1], [1]), field("description", 1, [4], list(b"tiny"))]
head = 18 + sum(2 + len(n) + 3 + 8 + 8 * len(s) for n, _, s, _ in f)
out, data, off = bytearray(b"\x05tensor_file\0\x01\x00" + struct.pack("<I", len(f))), bytearray(), head
for n, dt, s, d in f:
    blob = struct.pack("<%d%s" % (len(d), "f" if dt == 10 else "B"), *d)
    out += struct.pack("<H", len(n)) + n.encode() + struct.pack("<HBQ", len(s), dt, off + len(data))
    out += b"".join(struct.pack("<Q", x) for x in s)
    data += blob
open(sys.argv[1], "wb").write(out + data)
PY
fi
