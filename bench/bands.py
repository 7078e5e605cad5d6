#!/usr/bin/env python3
"""Where the error is (docs/bands.md): band errors of the default and auto
fits of the analytic models (and the measured files given) at J = 1, 4, 8.

    bench/bands.py [--build DIR] [--J 1,4,8] [--models NAMES] [--extra "ARGS"] [--check N [--grow M]] [FILE.bsdf ...]

--models "GGX 0.3,gold": only the models whose names contain one of these
(empty: none, for measured files alone).

For every source: `sepbrdf factor SOURCE -J J` (auto layout, plus --extra),
then from report.json the kept layout and form, the headline, the band
errors theta_i > 80 and > 89 degrees with their bounds (3x the headline or
1 %; 10x or 5 %), the worst band, p99 and max relative error where
f cos theta_i is above 1 % of its largest, and the most negative value over
the largest.  Prints a Markdown table; a row fails its bound with "NO".

--seeds K: with --check, the uniform draw repeated with K sequences
(SB_BANDS_SEED=1..K, N pairs each, as an independent evaluator of N pairs
would read it): the median reading, the pooled value of all K N pairs and
how many of the K readings agree with the report.

--mix: with --check --seeds, the draws of the GGX models take wo from
sepbrdf_bench_bands' mixture (SB_BANDS_MIX) with the model's own alpha
(roughness^2), each pair weighted by the uniform density over the
mixture's: the same band, with the mirror peak that holds it drawn (GGX
0.1, theta_i > 89 degrees: 99 % of f^2 cos^2 theta_i at theta_h < 1
degree, where a uniform pair falls with probability 6e-6; docs/bands.md,
"Ninth pass").

--check N: then, per row, the reported band errors theta_i > 60, 80, 89
degrees against sepbrdf_bench_bands (bench/bands_check.c: N pairs drawn
uniformly in solid angle inside each band, the written EXR files evaluated
as the snippet evaluates them, the source's values; no estimator), and with
--grow M the library's estimator grown to M pairs on the same files; "ok"
where the report is within 10 % or two standard errors (both) of the
uniform draw.  A band whose error sits in a few pairs (GGX 0.3, theta_i >
89 degrees: the grazing mirror peak) leaves the uniform draw's value low
in most runs, with an underestimated standard error (docs/bands.md).
"""
import argparse
import json
import os
import subprocess
import sys
import tempfile

# GGX alpha (roughness^2) of the models that --mix draws about the mirror
ALPHA = {"cook-torrance:roughness=0.1": 0.01, "cook-torrance:roughness=0.3": 0.09}

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


CHECKED = ["theta_i_60", "theta_i_80", "theta_i_89"]


def agrees(v, se, u, use):
    """Within 10 % or two standard errors (both) of the uniform draw."""
    return abs(v - u) <= 0.1 * u or abs(v - u) <= 2 * (se ** 2 + use ** 2) ** 0.5


def draw(build, rep, out, n, band, seed, mix=None):
    """One uniform draw of n pairs inside band (sepbrdf_bench_bands), wo from
    the mixture of GGX alpha mix where given: (error, se, the sums of the
    squared errors and of the squared values)."""
    cmd = [os.path.join(build, "sepbrdf_bench_bands"), rep["source_spec"], out, str(rep["terms"]), str(n)]
    env = dict(os.environ, SB_BANDS_ONLY=band, SB_BANDS_SEED=str(seed), SB_BANDS_SUMS="1")
    if mix:
        env["SB_BANDS_MIX"] = str(mix)
    w = subprocess.run(cmd, capture_output=True, text=True, env=env).stdout.split()
    return float(w[1]), float(w[2]), float(w[3]), float(w[4])


def check_seeds(build, rep, out, n, k, mix=None):
    """The rows of the --check --seeds table: per band the report, the
    median of k readings of n pairs, the pooled value of the k n pairs
    (the ratio of the summed squared errors to the summed squared values,
    as one draw of k n pairs reads it) and how many readings agree with
    the report."""
    e = rep["errors"][rep["terms"] - 1]
    rows = []
    for b in CHECKED:
        v, se = e["band_rel"][b], e["band_rel_se"][b]
        got = [draw(build, rep, out, n, b, s, mix) for s in range(1, k + 1)]
        med = sorted(g[0] for g in got)[k // 2]
        sd = sum(g[3] for g in got)
        pooled = (sum(g[2] for g in got) / sd) ** 0.5 if sd > 0 else float("nan")
        ok = sum(agrees(v, se, g[0], g[1]) for g in got)
        rows.append((b, "%s ± %s" % (pct(v), pct(se)), pct(med), pct(pooled), "%d/%d" % (ok, k),
                     "%.2f" % (v / med)))
    return rows


def check(build, rep, out, n, grow):
    """The rows of the --check table for one written fit (see the docstring)."""
    J = rep["terms"]
    cmd = [os.path.join(build, "sepbrdf_bench_bands"), rep["source_spec"], out, str(J), str(n)]
    cmd += [str(grow)] if grow else []
    r = subprocess.run(cmd, capture_output=True, text=True)
    got, est = {}, {}
    for line in r.stdout.splitlines():
        w = line.split()
        if w[0] == "estimator":
            est[w[1]] = (float(w[2]), float(w[3]))
        elif len(w) == 3:
            got[w[0]] = (float(w[1]), float(w[2]))
    e = rep["errors"][J - 1]
    rows = []
    for b in ["all"] + CHECKED:
        v, se = (e["headline"], e["headline_se"]) if b == "all" else (e["band_rel"][b], e["band_rel_se"][b])
        if b not in got:
            continue
        u, use = got[b]
        ok = agrees(v, se, u, use)
        g = "%s ± %s" % (pct(est[b][0]), pct(est[b][1])) if b in est else "—"
        rows.append((b, "%s ± %s" % (pct(v), pct(se)), "%s ± %s" % (pct(u), pct(use)), g, "ok" if ok else "NO"))
    return rows


def main():
    ap = parser("1,4,8")
    ap.add_argument("--extra", default="")
    ap.add_argument("--check", type=int, default=0, help="pairs per band of the uniform draw (0: none)")
    ap.add_argument("--grow", type=int, default=0, help="with --check: the estimator grown to this many pairs too")
    ap.add_argument("--seeds", type=int, default=0, help="with --check: repeat the uniform draw with this many sequences")
    ap.add_argument("--mix", action="store_true", help="with --check --seeds: GGX models drawn about the mirror")
    ap.add_argument("--models", default=None, help="only the models whose names contain one of these (comma list)")
    ap.add_argument("files", nargs="*")
    a = ap.parse_args()
    models = [m for m in MODELS if a.models is None or any(w and w in m[0] for w in a.models.split(","))]
    sources = models + [(os.path.basename(f), f) for f in a.files]
    checked = []
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
                if a.check and a.seeds:
                    mix = ALPHA.get(src) if a.mix else None
                    checked += [(name, J) + row for row in check_seeds(a.build, rep, os.path.join(tmp, "o"), a.check,
                                                                          a.seeds, mix)]
                elif a.check:
                    checked += [(name, J) + row for row in check(a.build, rep, os.path.join(tmp, "o"), a.check, a.grow)]
    if checked and a.seeds:
        print("\n| source | J | band | report | median of %d draws of %d%s | pooled | agree | report / median |"
              % (a.seeds, a.check, " (GGX: mixture)" if a.mix else ""))
        print("|---|---|---|---|---|---|---|---|")
        for row in checked:
            print("| %s | %d | %s | %s | %s | %s | %s | %s |" % row)
    elif checked:
        print("\n| source | J | band | report | uniform in the band | estimator grown | agree |")
        print("|---|---|---|---|---|---|---|")
        for row in checked:
            print("| %s | %d | %s | %s | %s | %s | %s |" % row)


if __name__ == "__main__":
    main()
