#!/usr/bin/env python3
"""Scene fits outside the scene (docs/bands.md): for each source, layout,
scene and J, the unweighted fit's whole-domain headline, then the scene
fit's headline inside the scene and over the whole domain, with the
default floor and with floor=0 (cells the scene never touches left out).

    bench/scene_floor.py [--build DIR] [--res R] [--J 2,4]

Prints a Markdown table; "ratio" is whole domain / unweighted (the issue's
bound: at most 2)."""
import json
import os
import subprocess
import sys
import tempfile

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import bands  # noqa: E402  (the shared options)

CASES = [
    ("GGX 0.3", "cook-torrance:roughness=0.3", "io", "view=0..40;light=0..60"),
    ("GGX 0.3", "cook-torrance:roughness=0.3", "io-area", "view=0..40;light=0..60"),
    ("gold", None, "io", "view=0..40;light=0..60"),
    ("GGX 0.3", "cook-torrance:roughness=0.3", "iso", "view=0..40;light=0..60"),
    ("gold", None, "io", "lights=45,45/30,150/60,270"),
    ("GGX 0.3", "cook-torrance:roughness=0.3", "io", "lights=45,45/30,150/60,270"),
    ("GGX 0.1", "cook-torrance:roughness=0.1", "io", "lights=45,45/30,150/60,270"),
]


def run(build, src, args, out):
    cmd = [os.path.join(build, "sepbrdf"), "-q", "factor"] + ([src] if src else []) + args + ["-o", out]
    if subprocess.run(cmd, capture_output=True, text=True).returncode != 0:
        return None
    with open(os.path.join(out, "report.json")) as fp:
        return json.load(fp)


def main():
    ap = bands.parser("2,4")
    ap.add_argument("--res", default="16")
    a = ap.parse_args()
    print("| source | layout | scene | J | unweighted (whole) | inside | whole | ratio | floor=0 inside | floor=0 whole | ratio |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as tmp:
        out = os.path.join(tmp, "o")
        for name, src, param, scene in CASES:
            for J in [int(x) for x in a.J.split(",")]:
                base = ["--param", param, "-r", a.res, "-J", str(J)]
                plain = run(a.build, src, base, out)
                row = ["%.3g %%" % (100 * plain["errors"][J - 1]["headline"])] if plain else ["failed"]
                for sc in (scene, scene + ";floor=0"):
                    rep = run(a.build, src, base + ["--scene", sc], out)
                    if not rep or not plain:
                        row += ["failed"] * 3
                        continue
                    s, whole0 = rep["scene"], plain["errors"][J - 1]["headline"]
                    whole = s["domain_headline"][J - 1]
                    row += ["%.3g %%" % (100 * s["headline"][J - 1]), "%.3g %%" % (100 * whole), "%.2f" % (whole / whole0)]
                print("| %s | %s | `%s` | %d | %s |" % (name, param, scene, J, " | ".join(row)), flush=True)


if __name__ == "__main__":
    main()
