#!/usr/bin/env python3
"""Run a factor folder's HLSL, Metal or WGSL snippet (`factor --shader all`)
on the CPU and read it as an outside evaluator would (docs/measured.md,
"Seventh pass").

The snippet as written is compiled as C++ by clang++ over
tests/data/metal/metal_stdlib's vector types and bench/shader_cpu/runtime.h
(textures filtered by the APIs' own rules); WGSL is first rewritten into
C++ syntax line by line (fn/var/let/const, types, select, texture calls).
Its sb_brdf is evaluated at bench/evaluator.py's pairs and compared with
evaluator.py's numpy transcription of sepbrdf.glsl (largest difference
relative to max(1, |f|)) and, through the same source model (or EVAL_REF's
set, an RGL file), its headline at J with report.json's.

    python3 bench/shader_cpu.py DIR hlsl|msl|wgsl [PAIRS] [SEED]

    SHADER_CPU_DOUBLE=1 ...   # the snippet's text in double precision

Uses no sepbrdf code.  Exits 1 where the transcriptions differ by more than
1e-2 in float (1e-4 in double) or the headline lies outside max(4 combined
standard errors, 2 %).
"""
import os
import re
import subprocess
import sys
import tempfile

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
import evaluator as ev  # noqa: E402

DT = np.float64 if os.environ.get("SHADER_CPU_DOUBLE") else np.float32
EXT = {"hlsl": "hlsl", "msl": "metal", "wgsl": "wgsl"}
WTYPES = {"f32": "float", "i32": "int", "u32": "uint", "bool": "bool"}
for n in (2, 3, 4):
    for s, t in (("f", "float"), ("i", "int"), ("u", "uint")):
        WTYPES[f"vec{n}{s}"] = f"{t}{n}"
        WTYPES[f"vec{n}<{ {'f': 'f32', 'i': 'i32', 'u': 'u32'}[s]}>"] = f"{t}{n}"


def split_top(s):
    """s split at the commas outside <...> and (...)."""
    parts, depth, cur = [], 0, ""
    for ch in s:
        depth += ch in "<("
        depth -= ch in ">)"
        if ch == "," and depth == 0:
            parts.append(cur)
            cur = ""
        else:
            cur += ch
    return parts + [cur]


def wtype(t):
    t = t.strip()
    m = re.fullmatch(r"ptr<\s*\w+\s*,\s*(.+)>", t)
    if m:
        return wtype(m.group(1)) + "*"
    m = re.fullmatch(r"array<\s*([\w<>]+)\s*,\s*(\w+)\s*>", t)
    if m:
        return f"std::array<{wtype(m.group(1))}, {m.group(2)}>"
    if t.startswith("texture_2d_array"):
        return "sb_wtex2a"
    if t.startswith("texture_2d"):
        return "sb_wtex2"
    if t == "sampler":
        return "metal::sampler"
    return WTYPES.get(t, t)


def wgsl_to_cpp(src):
    out = []
    for line in src.split("\n"):
        s = re.sub(r"//.*", "", line)
        s = re.sub(r"@\w+(\([^)]*\))?\s*", "", s)
        s = re.sub(r"array<\s*(\w+)\s*,\s*(\w+)\s*>\s*\(", lambda m: f"{wtype(m.group(0)[:-1])}{{", s)
        # a constructor call opened with { above closes with } at its own ')': done below by balance
        m = re.match(r"(\s*)fn (\w+)\((.*)\)\s*(->\s*([^{]+))?\{(.*)$", s)
        if m:
            args = ", ".join(f"{wtype(a.split(':', 1)[1])} {a.split(':', 1)[0].strip()}"
                             for a in split_top(m.group(3)) if a.strip())
            ret = wtype(m.group(5)) if m.group(5) else "void"
            s = f"{m.group(1)}{ret} {m.group(2)}({args}) {{{m.group(6)}"
        s = re.sub(r"\b(var|let)(<\w+>)?\s+(\w+)\s*:\s*([^=;]+?)\s*([=;])",
                   lambda m: f"{wtype(m.group(4))} {m.group(3)} {m.group(5)}", s)
        s = re.sub(r"\b(var|let)\s+(\w+)\s*=", r"auto \2 =", s)
        s = re.sub(r"^(\s*)const\s+(\w+)\s*:\s*([^=]+?)\s*=", lambda m: f"{m.group(1)}const {wtype(m.group(3))} "
                   f"{m.group(2)} =", s)
        s = re.sub(r"^(\s*)const\s+(\w+)\s*=", r"\1const auto \2 =", s)
        for k in sorted(WTYPES, key=len, reverse=True):
            if "<" in k:
                s = s.replace(k + "(", WTYPES[k] + "(")
            else:
                s = re.sub(r"\b%s\b" % k, WTYPES[k], s)
        out.append(s)
    text = "\n".join(out)
    # std::array<T, N>{a, b, c)  ->  {a, b, c}
    res, i = [], 0
    while True:
        j = text.find("std::array<", i)
        if j < 0:
            res.append(text[i:])
            break
        k = text.find(">", j)
        if k + 1 < len(text) and text[k + 1] == "{":
            depth, p = 1, k + 2
            while depth:
                depth += text[p] == "("
                depth -= text[p] == ")"
                p += 1
            res.append(text[i:k + 2] + text[k + 2:p - 1] + "}")
            i = p
        else:
            res.append(text[i:k + 1])
            i = k + 1
    return "#include <array>\nusing namespace metal;\n" + "".join(res)


FLOAT_LIT = re.compile(r"(?<![\w.])(\d+\.\d*(?:[eE][-+]?\d+)?|\.\d+(?:[eE][-+]?\d+)?|\d+[eE][-+]?\d+)(?![\w.])")


def to_cpp(lang, src):
    if lang == "msl":
        return src
    src = FLOAT_LIT.sub(r"\1f", src)  # HLSL's and WGSL's literals are float, C++'s double
    if lang == "hlsl":
        src = re.sub(r"\s*:\s*register\(\w+\)", "", src)
        src = re.sub(r"\b(?:in)?out\s+(\w+)\s+(\w+)", r"\1& \2", src)  # out parameters: references
        return "using namespace metal;\n" + src
    return wgsl_to_cpp(src)


MAIN = r"""
#include <vector>
static std::vector<float> sb_read(const char *path, size_t n) {
    std::vector<float> v(n);
    FILE *f = fopen(path, "rb");
    if (!f || fread(v.data(), sizeof(float), n, f) != n) { fprintf(stderr, "cannot read %%s\n", path); exit(2); }
    fclose(f);
    return v;
}
int main(int argc, char **argv) {
    /* argv: dir n  then per texture: name w h layers wrap_s wrap_t */
    const char *dir = argv[1];
    size_t n = strtoul(argv[2], 0, 10);
    static std::vector<float> data[8];
    %(obj)s
    for (int a = 3, k = 0; a + 5 < argc; a += 6, k++) {
        sb_tex t = {atoi(argv[a + 1]), atoi(argv[a + 2]), atoi(argv[a + 3]), atoi(argv[a + 4]), atoi(argv[a + 5]), 0};
        char path[4096];
        snprintf(path, sizeof path, "%%s/%%s.bin", dir, argv[a]);
        data[k] = sb_read(path, (size_t)t.w * t.h * t.layers * 4);
        t.d = data[k].data();
        const void *p = 0;
        %(lookup)s
        if (!p) { fprintf(stderr, "no texture %%s\n", argv[a]); return 2; }
        sb_texs[p] = t;
    }
    char path[4096];
    snprintf(path, sizeof path, "%%s/pairs.bin", dir);
    std::vector<float> pr = sb_read(path, n * 6);
    snprintf(path, sizeof path, "%%s/out.bin", dir);
    FILE *o = fopen(path, "wb");
    for (size_t i = 0; i < n; i++) {
        float3 L = float3(pr[6 * i], pr[6 * i + 1], pr[6 * i + 2]), V = float3(pr[6 * i + 3], pr[6 * i + 4], pr[6 * i + 5]);
        float3 f = %(call)s(L, V);
        float v[3] = {f.x, f.y, f.z};
        fwrite(v, sizeof v, 1, o);
    }
    fclose(o);
    return 0;
}
"""


def compile_snippet(folder, lang, work):
    src = open(f"{folder}/sepbrdf.{EXT[lang]}").read()
    names = [n for n in ("sb_g", "sb_h", "sb_vndf") if re.search(r"\b%s\b" % n, src)]
    if lang == "msl":
        obj = "static sb_shader sh{};"
        lookup = " ".join(f'if (!strcmp(argv[a], "{n}")) p = &sh.{n};' for n in names)
        call = "sh.sb_brdf"
    else:
        obj = ""
        lookup = " ".join(f'if (!strcmp(argv[a], "{n}")) p = &{n};' for n in names)
        call = "sb_brdf"
    body = to_cpp(lang, src)
    pre = ""
    if os.environ.get("SHADER_CPU_DOUBLE"):  # the same text in double precision: where float32 rounding matters
        pre, body = "#include <cmath>\n#include <cstdio>\n#include <cstdlib>\n#include <map>\n#include <cstring>\n#include <vector>\n#include <array>\n#define float double\n", re.sub(r"(\d)f\b", r"\1", body)
        body = re.sub(r"(?<![\w.:])(sqrt|floor|atan2|atan|abs|min|max|clamp|sin|cos|acos|fract|mix|pow|exp|log|round|"
                      r"saturate|sign|step|ceil|trunc)\(", r"metal::\1(", body)
    cpp = (pre + '#include "runtime.h"\n#include <cstring>\n' + body +
           MAIN % {"obj": obj, "lookup": lookup, "call": call})
    open(f"{work}/snippet.cpp", "w").write(cpp)
    root = os.path.dirname(HERE)
    r = subprocess.run(["clang++", "-std=c++17", "-O1", "-w", "-I", f"{root}/tests/data/metal", "-I",
                        f"{HERE}/shader_cpu", f"{work}/snippet.cpp", "-o", f"{work}/snippet"],
                       capture_output=True, text=True)
    if r.returncode:
        raise SystemExit(f"{lang}: the snippet does not compile as C++:\n{r.stderr[:3000]}")
    return src, names


def wrap(src, key):
    m = re.search(r"(?:#define %s|const %s =) (\d)" % (key, key), src)
    return int(m.group(1)) if m else 0


def texture_args(folder, src, names, terms, work):
    args = []
    for n in names:
        if n == "sb_vndf":
            ch, _ = ev.read_exr(f"{folder}/vndf.exr")
            a = np.stack([ch[c] for c in "RGB"] + [np.zeros_like(ch["R"])], -1)[None]
            ws = wt = 0
        else:
            side = n[-1]
            t = ev.tex_stack(folder, side, terms)
            a = np.concatenate([t, np.zeros(t.shape[:3] + (1,))], -1)
            ws, wt = wrap(src, f"SB_WRAP_{side.upper()}_S"), wrap(src, f"SB_WRAP_{side.upper()}_T")
        a.astype(DT).tofile(f"{work}/{n}.bin")
        args += [n, str(a.shape[2]), str(a.shape[1]), str(a.shape[0]), str(ws), str(wt)]
    return args


def main():
    folder, lang = sys.argv[1], sys.argv[2]
    pairs = int(sys.argv[3]) if len(sys.argv) > 3 else 100000
    rng = np.random.default_rng(int(sys.argv[4]) if len(sys.argv) > 4 else 1)
    rep = ev.json.load(open(f"{folder}/report.json"))
    terms = rep["terms"]
    ev.REF = os.environ.get("EVAL_REF")
    batches, num, den, worst = 20, [], [], 0.0
    with tempfile.TemporaryDirectory() as work:
        src, names = compile_snippet(folder, lang, work)
        targs = texture_args(folder, src, names, terms, work)
        for _ in range(batches):
            L, V, wgt = ev.draw_pairs(rng, pairs // batches)
            np.concatenate([L, V], 1).astype(DT).tofile(f"{work}/pairs.bin")
            subprocess.run([f"{work}/snippet", work, str(len(L))] + targs, check=True)
            fs = np.fromfile(f"{work}/out.bin", DT).reshape(-1, 3).astype(np.float64)
            fn = ev.reconstruct(folder, L, V, terms)[0][-1]
            d = np.max(np.abs(fs - fn) / np.maximum(1, np.abs(fn)), -1) * (wgt > 0)  # V below: weight 0
            worst = max(worst, float(d.max()))
            if os.environ.get("SHADER_CPU_DEBUG") and d.max() > 1e-4:
                i = int(np.argmax(d))
                print("pair", L[i], V[i], "shader", fs[i], "numpy", fn[i], "share > 1e-4", float((d > 1e-4).mean()))
            if ev.REF:
                refrep = ev.json.load(open(f"{ev.REF}/report.json"))
                f = ev.reconstruct(ev.REF, L, V, refrep["terms"])[0][-1]
            else:
                f = ev.model(rep["source"], L, V)
            q = L[:, 2]**2 * wgt
            if rep["estimate"].get("domain") == "cap":
                tm = float(rep["param_spec"].split("theta_max=")[1].split(",")[0])
                q = q * ((L[:, 2] >= np.cos(np.radians(tm))) & (V[:, 2] >= np.cos(np.radians(tm))))
            num.append((((fs - f)**2).sum(-1) * q).sum())
            den.append(((f**2).sum(-1) * q).sum())
    num, den = np.array(num), np.array(den)
    h = np.sqrt(num.sum() / den.sum())
    jk = np.array([np.sqrt((num.sum() - num[i]) / (den.sum() - den[i])) for i in range(batches)])
    se = np.sqrt((batches - 1) / batches * ((jk - jk.mean())**2).sum())
    e = rep["errors"][terms - 1]
    ok_h = abs(h - e["headline"]) <= max(4 * np.hypot(se, e["headline_se"]), 0.02 * e["headline"])
    ok_t = worst <= (1e-4 if DT == np.float64 else 1e-2)  # float32: vndf's grazing peaks reach 2e-3
    print(f"{folder} {lang}: {rep['param_spec'][:50]} J = {terms}: against the GLSL transcription "
          f"{worst:.2g}{'' if ok_t else ' DIFFERS'}; headline {h:.4g}±{se:.2g} vs {e['headline']:.4g}"
          f"{'' if ok_h else ' DIFFERS'}")
    return 0 if ok_h and ok_t else 1


if __name__ == "__main__":
    sys.exit(main())
