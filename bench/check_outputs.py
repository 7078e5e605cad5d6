#!/usr/bin/env python3
"""An outsider's checks of factor folders (docs/measured.md, "Tenth pass").

    SB=build/sepbrdf python3 bench/check_outputs.py DIR...

For each DIR `sepbrdf factor` wrote: its set list (sepbrdf-set-factor.txt)
equals the files there; report.json's terms equal the g_/h_ EXR counts and
its files object names every file of the set; every EXR parses (own header
reader), has report.json's texture_size and pixel type (HALF for storage
half, FLOAT otherwise), and `sepbrdf info` describes it (exit 0); sampler.bin
(own header reader: its size; `sepbrdf info --json`: its checks) holds
report.json's sampler shares (cosine_share, lobe_share, lobe_alpha) and the
snippets sample the GGX lobe (sb_lobe_dir, sb_lobe_pdf) where it has one; the
snippet compiles: GLSL 330 and 300 es (glslangValidator), HLSL to SPIR-V
(glslangValidator -D, then spirv-val), MSL (clang++ -fsyntax-only over
tests/data/metal), WGSL (Tint in headless Chromium, one page for all).
Prints one line per folder ("FAIL ..." for each failure) and exits 1 when
any failed.  A missing tool is said, not counted as a failure.
"""
import glob
import json
import os
import re
import shutil
import struct
import subprocess
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
SB = os.environ.get("SB", os.path.join(HERE, "..", "build", "sepbrdf"))
META = os.path.join(HERE, "..", "tests", "data", "metal")
def sh(cmd, cwd=None):
    p = subprocess.run(cmd, shell=True, cwd=cwd, capture_output=True, text=True)
    return p.returncode, (p.stdout + p.stderr)
def exr_info(path):
    d = open(path, 'rb').read(4096)
    assert d[:4] == b'v/1\x01', 'magic'
    pos, at = 8, {}
    while d[pos] != 0:
        e = d.index(b'\0', pos); e2 = d.index(b'\0', e + 1)
        (n,) = struct.unpack_from('<i', d, e2 + 1)
        at[d[pos:e].decode()] = d[e2 + 5:e2 + 5 + n]; pos = e2 + 5 + n
    c, p, ch = at['channels'], 0, []
    while c[p] != 0:
        e = c.index(b'\0', p); (pt,) = struct.unpack_from('<i', c, e + 1); ch.append((c[p:e].decode(), pt)); p = e + 17
    x0, y0, x1, y1 = struct.unpack('<4i', at['dataWindow'])
    return dict(w=x1 - x0 + 1, h=y1 - y0 + 1, ch=ch, attrs=list(at))
GLSL_MAIN = "in vec3 vL; in vec3 vV; out vec4 o;\nvoid main() { o = vec4(sb_brdf(normalize(vL), normalize(vV)), 1.0);\n#ifdef SB_SAMPLE_CH\n vec3 Ls; float pdf; if (sb_sample(normalize(vV), vL.xy, Ls, pdf)) o.xyz += Ls * pdf + sb_pdf(Ls, vV);\n#endif\n}\n"
HLSL_MAIN = 'float4 main(float3 L : TEXCOORD0, float3 V : TEXCOORD1) : SV_Target {\n    float3 f = sb_brdf(normalize(L), normalize(V));\n#ifdef SB_SAMPLE_CH\n    float3 Ls;\n    float pdf;\n    if (sb_sample(normalize(V), L.xy, Ls, pdf)) f += Ls * pdf + sb_pdf(Ls, V);\n#endif\n    return float4(f, 1.0);\n}\n'
MSL = {'plain': "float4 sb_test(texture2d_array<float> g, sampler gs, texture2d_array<float> h, sampler hs, float3 L, float3 V) {\n    sb_shader s = {g, gs, h, hs};\n    return float4(s.sb_brdf(normalize(L), normalize(V)), 1.0f);\n}\n",
 'sampled': "float4 sb_test(texture2d_array<float> g, sampler gs, texture2d_array<float> h, sampler hs,\n texture2d_array<float> c, sampler cs, float3 L, float3 V) {\n    sb_shader s = {g, gs, h, hs, c, cs};\n    float3 Ls;\n    float pdf;\n    float3 f = s.sb_brdf(normalize(L), normalize(V));\n    if (s.sb_sample(normalize(V), L.xy, Ls, pdf)) f += Ls * pdf + s.sb_pdf(Ls, V);\n    return float4(f, 1.0f);\n}\n",
 'vndf': "float4 sb_test(texture2d_array<float> g, sampler gs, texture2d_array<float> h, sampler hs,\n texture2d<float> v, float3 L, float3 V) {\n    sb_shader s = {g, gs, h, hs, v};\n    return float4(s.sb_brdf(normalize(L), normalize(V)), 1.0f);\n}\n"}
WGSL_MAIN = "@fragment fn main(@location(0) L: vec3f, @location(1) V: vec3f) -> @location(0) vec4f {\n    var f = sb_brdf(normalize(L), normalize(V));\n    return vec4f(f, 1.0);\n}\n"
WGSL_MAIN_S = "@fragment fn main(@location(0) L: vec3f, @location(1) V: vec3f) -> @location(0) vec4f {\n    var f = sb_brdf(normalize(L), normalize(V));\n    var Ls: vec3f;\n    var pdf: f32;\n    if (sb_sample(normalize(V), L.xy, &Ls, &pdf)) { f += Ls * pdf + sb_pdf(Ls, V); }\n    return vec4f(f, 1.0);\n}\n"
wgsl_mods = []
def have(tool):
    return shutil.which(tool) is not None


def set_files(d, rep, bad):
    """The set list against the folder, and report.json's files against the list."""
    # factor's list, and any other command's beside it (view's index.html:
    # sepbrdf-set-view.txt); the folder is their union
    setf = f"{d}/sepbrdf-set-factor.txt"
    if not os.path.exists(setf):
        return bad("no set list")
    lists = sorted(glob.glob(f"{d}/sepbrdf-set-*.txt"))
    read = lambda f: {ln.strip() for ln in open(f) if ln.strip() and not ln.startswith("#")}
    listed = read(setf)
    every = set().union(*[read(f) for f in lists])
    here = set(os.listdir(d)) - {os.path.basename(f) for f in lists}
    if every != here:
        bad(f"set lists and folder differ: {sorted(every ^ here)}")
    fo = rep.get("files", {})
    named = set(fo.get("g", []) + fo.get("h", []) + fo.get("shaders", []))
    named |= {fo[k] for k in ("glsl", "sampler", "vndf") if fo.get(k)}
    own = {"report.json", "batch.txt"}  # batch.txt: batch's record of a material's folder, not the factor set's
    if named != listed - own:
        bad(f"report.json files and the set differ: {sorted(named ^ (listed - own))}")


def textures(d, rep, bad):
    """Counts, sizes and pixel types against report.json; info on each."""
    J = rep["terms"]
    ts = rep["texture_size"]
    want = 1 if rep["storage"] == "half" else 2  # EXR pixel types: 1 HALF, 2 FLOAT
    for side in "gh":
        names = sorted(os.path.basename(p) for p in glob.glob(f"{d}/{side}_*.exr"))
        if len(names) != J:
            bad(f"{len(names)} {side} textures, terms {J}")
        for f in names:
            e = exr_info(f"{d}/{f}")
            if [e["w"], e["h"]] != ts[side]:
                bad(f"{f} {e['w']}x{e['h']}, texture_size {ts[side]}")
            if {p for _, p in e["ch"]} != {want}:
                bad(f"{f} pixel types {e['ch']}, storage {rep['storage']}")
    for p in sorted(glob.glob(f"{d}/*.exr")):
        rc, t = sh(f"{SB} info {p}")
        if rc:
            bad(f"info {os.path.basename(p)} exit {rc}: {t.strip()[-200:]}")


def sampler(d, rep, bad):
    """sampler.bin: its size from its header, info's checks, the shares of report.json."""
    p, sm = f"{d}/sampler.bin", rep.get("sampler") or {}
    if not os.path.exists(p):
        return
    b = open(p, 'rb').read()
    W1, H1, L, C = struct.unpack_from('<4I', b, 8) if len(b) >= 24 else (0, 0, 0, 0)
    if b[:8] != b'sbsampl1' or len(b) != 24 + 4 * W1 * H1 * L:
        return bad(f"sampler.bin: {len(b)} bytes, header {W1} x {H1} x {L}")
    rc, t = sh(f"{SB} info {p} --json")
    if rc:
        return bad(f"info sampler.bin exit {rc}: {t.strip()[-200:]}")
    got = json.loads(t)
    for k in ("cosine_share", "lobe_share", "lobe_alpha"):
        if abs(got[k] - sm.get(k, float('nan'))) > 1e-7 or sm.get(k) is None:
            bad(f"sampler.bin {k} {got[k]}, report.json {sm.get(k)}")
    for f in glob.glob(f"{d}/sepbrdf.*"):
        src = open(f).read()
        if got["lobe_share"] > 0 and "sb_sample" in src and not ("sb_lobe_dir" in src and "sb_lobe_pdf" in src):
            bad(f"{os.path.basename(f)}: samples without the GGX lobe (sb_lobe_dir, sb_lobe_pdf)")


def shaders(d, bad):
    gl = open(f"{d}/sepbrdf.glsl").read()
    if have("glslangValidator"):
        for ver in ("#version 330", "#version 300 es\nprecision highp float;"):
            open(f"{d}/_chk.frag", "w").write(ver + "\n" + gl + GLSL_MAIN)
            rc, t = sh(f"glslangValidator {d}/_chk.frag")
            if rc:
                bad(f"glsl {ver[:16]}: {t[-300:]}")
    if os.path.exists(f"{d}/sepbrdf.hlsl") and have("glslangValidator"):
        open(f"{d}/_chk.hlsl", "w").write('#include "sepbrdf.hlsl"\n' + HLSL_MAIN)
        rc, t = sh(f"glslangValidator -D -V -S frag -e main -o {d}/_chk.spv {d}/_chk.hlsl")
        if rc:
            bad(f"hlsl: {t[-300:]}")
        elif have("spirv-val"):
            rc, t = sh(f"spirv-val {d}/_chk.spv")
            if rc:
                bad(f"spirv-val: {t[-300:]}")
    if os.path.exists(f"{d}/sepbrdf.metal") and have("clang++"):
        m = open(f"{d}/sepbrdf.metal").read()
        kind = "sampled" if "sb_sample" in m else "vndf" if "texture2d<float> sb_vndf;" in m else "plain"
        open(f"{d}/_chk.metal", "w").write(m + MSL[kind])
        rc, t = sh(f"clang++ -std=c++14 -fsyntax-only -I {META} -x c++ {d}/_chk.metal")
        if rc:
            bad(f"msl ({kind}): {t[-300:]}")
    if os.path.exists(f"{d}/sepbrdf.wgsl"):
        w = open(f"{d}/sepbrdf.wgsl").read()
        wgsl_mods.append((d, w + (WGSL_MAIN_S if "fn sb_sample" in w else WGSL_MAIN)))
    for f in glob.glob(f"{d}/_chk*"):
        os.remove(f)


def check(d):
    out = []

    def bad(m):
        out.append("FAIL " + m)

    rep = json.load(open(f"{d}/report.json"), parse_constant=lambda c: bad("json " + c))
    set_files(d, rep, bad)
    textures(d, rep, bad)
    sampler(d, rep, bad)
    shaders(d, bad)
    return out


def js(s): return json.dumps(s).replace('<', '\\x3c')
def main():
    failed = 0
    missing = [t for t in ("glslangValidator", "spirv-val", "clang++", "chromium") if not have(t)]
    if missing:
        print("not checked (missing): " + ", ".join(missing))
    for d in sys.argv[1:]:
        try:
            r = check(d)
        except Exception as ex:  # a folder the checks cannot read is a failure too
            r = [f"FAIL {ex!r}"]
        failed += bool(r)
        print(d, "|", "; ".join(r) if r else "ok")
    return 1 if wgsl(failed) else 0


def wgsl(failed):
    if not wgsl_mods or not have("chromium"):
        return failed
    if wgsl_mods:
        import tempfile; wd = tempfile.mkdtemp(prefix='sb-wgsl-')
        page = "<html><body><script>\nconst mods = [" + ",\n".join(js(m) for _, m in wgsl_mods) + "];\n(async () => {\n  const a = navigator.gpu && await navigator.gpu.requestAdapter();\n  if (!a) { console.log('SB-WGSL-NOADAPTER'); return; }\n  const d = await a.requestDevice();\n  for (let i = 0; i < mods.length; i++) {\n    const info = await d.createShaderModule({code: mods[i]}).getCompilationInfo();\n    const e = info.messages.filter(m => m.type == 'error');\n    console.log('SB-WGSL ' + i + ' ' + e.length + ' ' + e.map(m => m.lineNum + ':' + m.linePos + ' ' + m.message).join(' | '));\n  }\n  console.log('SB-WGSL-DONE');\n})();\n</script></body></html>\n"
        open(f'{wd}/wgsl.html', 'w').write(page)
        cmd = (f"cd {wd} && rm -f log; {{ timeout 300 chromium --headless=new --no-sandbox --no-first-run --disable-gpu-sandbox "
               f"--enable-unsafe-webgpu --enable-unsafe-swiftshader --use-webgpu-adapter=swiftshader "
               f"--user-data-dir={wd}/profile --enable-logging=stderr --v=0 file://{wd}/wgsl.html 2> log & pid=$!; "
               "for i in $(seq 1 600); do grep -q 'SB-WGSL-DONE\\|SB-WGSL-NOADAPTER' log && break; sleep 0.5; done; "
               "kill $pid; wait $pid; grep -o 'SB-WGSL[^\"]*' log; }")
        rc, t = sh(cmd)
        for line in t.splitlines():
            m = re.match(r'SB-WGSL (\d+) (\d+)(.*)', line)
            if m:
                print("wgsl", wgsl_mods[int(m.group(1))][0], "errors", m.group(2), m.group(3)[:300])
                failed += m.group(2) != "0"
            elif "SB-WGSL" in line:
                print(line)
        if "SB-WGSL-DONE" not in t:
            print("wgsl: the page did not finish (no WebGPU adapter?)")
    return failed


if __name__ == "__main__":
    sys.exit(main())
