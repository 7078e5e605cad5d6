#!/usr/bin/env python3
"""Where the error is (docs/bands.md): band errors of the default and auto
fits of the analytic models (and the measured files given) at J = 1, 4, 8.

    bench/bands.py [--build DIR] [--J 1,4,8] [--extra "ARGS"] [FILE.bsdf ...]

For every source: `sepbrdf factor SOURCE -J J` (auto layout, plus --extra),
then from report.json the kept layout and form, the headline, the band
errors theta_i > 80 and > 89 degrees with their bounds (3x the headline or
1 %; 10x or 5 %), the worst band, p99 and max relative error where
f cos theta_i is above 1 % of its largest, and the most negative value over
the largest.  Prints a Markdown table; a row fails its bound with "NO".
"""
import argparse
import json
import os
import subprocess
import sys
import tempfile

MODELS = [
    ("gold (default)", None),
    ("GGX 0.1", "cook-torrance:roughness=0.1"),
    ("GGX 0.3", "cook-torrance:roughness=0.3"),
    ("Blinn-Phong n=200", "blinn-phong:n=200"),
    ("Phong n=100", "phong:n=100"),
]


def run(build, src, J, extra, out):
    cmd = [os.path.join(build, "sepbrdf"), "-q", "factor"] + ([src] if src else []) + ["-J", str(J), "-o", out]
    cmd += extra.split()
    r = subprocess.run(cmd, capture_output=True, text=True)
    if r.returncode != 0:
        return None
    with open(os.path.join(out, "report.json")) as fp:
        return json.load(fp)


def pct(v):
    return "n/a" if v is None else "%.3g %%" % (100 * v)


def parser(J):
    """The options the bench/ scripts share: --build (default $BUILD or
    the repository's build/) and --J (a comma list)."""
    here = os.path.dirname(os.path.abspath(__file__))
    ap = argparse.ArgumentParser()
    ap.add_argument("--build", default=os.environ.get("BUILD", os.path.join(os.path.dirname(here), "build")))
    ap.add_argument("--J", default=J)
    return ap


def main():
    ap = parser("1,4,8")
    ap.add_argument("--extra", default="")
    ap.add_argument("files", nargs="*")
    a = ap.parse_args()
    sources = MODELS + [(os.path.basename(f), f) for f in a.files]
    print("| source | J | kept | headline | θi>80° | bound | θi>89° | bound | worst band | p99 lit | max lit | most negative |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as tmp:
        for name, src in sources:
            for J in [int(x) for x in a.J.split(",")]:
                rep = run(a.build, src, J, a.extra, os.path.join(tmp, "o"))
                if rep is None:
                    print("| %s | %d | failed |" % (name, J))
                    continue
                e = rep["errors"][rep["terms"] - 1]
                h, b = e["headline"], e["band_rel"]
                ok80 = b["theta_i_80"] <= max(3 * h, 0.01)
                ok89 = b["theta_i_89"] <= max(10 * h, 0.05)
                print("| %s | %d | %s %s | %s | %s | %s | %s | %s | %s | %s | %s | %s |" % (
                    name, rep["terms"], rep["param"], rep["form"], pct(h), pct(b["theta_i_80"]),
                    "ok" if ok80 else "NO", pct(b["theta_i_89"]), "ok" if ok89 else "NO", e["worst_band"],
                    pct(e["p99_rel_lit"]), "%.3g" % e["max_rel_lit"], pct(e["min_rel"])))
                sys.stdout.flush()


if __name__ == "__main__":
    main()
