#!/usr/bin/env python3
"""Issue 32's check of sparse tables (docs/measured.md, "Random splits
against the reported figure"): for each table, 10 % of its rows held out
at random, the rest factored with the defaults at J and the reconstruction
compared with the rows held out (bench/holdout.c: the whole pipeline,
f cos theta_i, relative L2); counted: the splits whose error is within
1.5x, both ways, of the cross-validated figure (`errors[].cv_headline`)
that `factor` reports on the whole table.

    bench/cv_splits.py [--build DIR] [--J 4] [--splits 10] [--keep DIR] [NAME|FILE ...]

Tables (NAME, or the path of a scattered table FILE of your own; all
NAMEs by default), made in a temporary folder (or --keep DIR):
  acrylic      ../shared/data/measured/cornell_acryl_blue.brdf (1439 rows)
  acrylic-7    the acrylic, every 7th row dropped, angles moved by up to
               0.002 rad, azimuths turned by 0.3 rad, values x (1 + 2 % z)
  acrylic-5    every 5th row dropped, azimuths turned by -0.7 rad, 5 % noise
  ggx-0.1      `sepbrdf sample microfacet:roughness=0.316` (GGX alpha 0.1)
  ggx-0.3      `sepbrdf sample microfacet:roughness=0.548` (GGX alpha 0.3)
  gold         `sepbrdf sample microfacet:base=gold,roughness=0.4` (GGX alpha
               0.16, the default source made glossier)
  new-blue     `microfacet:base=0.1/0.2/0.6,roughness=0.45` at the acrylic's
               1439 direction pairs, 3 % noise (sepbrdf_bench_at_directions)
  new-red      `microfacet:base=0.7/0.15/0.1,roughness=0.35` there, 3 % noise
  new-rgl      RGL chm_light_blue (../shared/data/measured) there
  new-drop     the acrylic with each row dropped with probability 0.2
The three analytic tables are Cornell-like: `--gonio 8,1,8,24` (1536 rows,
a Cornell paint's count), without noise (with 2 % noise every split
errs by the noise); the variants' noise has fixed seeds.  Prints one row
per table (the figure, each split's error / figure, the count within
1.5x), a comment line with the errors and the count for every figure the
whole table's report.json gives (cv_headline, cv_fold_median where the
build has it, cv_pooled, cv_fold_max), and the totals.  About 10 s CPU per
split (20 minutes wall for the six first tables on the loaded 2-core VM).
"""
import argparse
import json
import os
import random
import re
import shutil
import subprocess
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
ACRYLIC = os.path.join(ROOT, "..", "shared", "data", "measured", "cornell_acryl_blue.brdf")
GONIO = "8,1,8,24"
NOISE = "0"
ANALYTIC = {
    "ggx-0.1": "microfacet:roughness=0.316",
    "ggx-0.3": "microfacet:roughness=0.548",
    "gold": "microfacet:base=gold,roughness=0.4",
}
MEASURED = os.path.join(ROOT, "..", "shared", "data", "measured")
AT = {  # NAME: (source, noise, seed, drop) at the acrylic's direction pairs
    "new-blue": ("microfacet:base=0.1/0.2/0.6,roughness=0.45", 0.03, 11, 0),
    "new-red": ("microfacet:base=0.7/0.15/0.1,roughness=0.35", 0.03, 12, 0),
    "new-rgl": (os.path.join(MEASURED, "rgl_chm_light_blue_rgb.bsdf"), 0, 13, 0),
    "new-drop": ("=", 0, 14, 0.2),
}
TABLES = ["acrylic", "acrylic-7", "acrylic-5"] + list(ANALYTIC) + list(AT)
STATS = ["cv_headline", "cv_fold_median", "cv_pooled", "cv_fold_max"]
WITHIN = 1.5


def is_row(line, most):
    """A Cornell data row: the line with the most numbers (the wavelengths have fewer)."""
    try:
        return len([float(x) for x in line.split()]) == most
    except ValueError:
        return False


def variant(src, dst, every, jitter, turn, noise, seed):
    """The acrylic with every `every`-th row dropped, angles moved by up to
    `jitter` rad, azimuths turned by `turn` rad and values x (1 + noise z)."""
    rng = random.Random(seed)
    lines = open(src).read().splitlines()
    most = max(len(ln.split()) for ln in lines)
    out, k = [], 0
    for ln in lines:
        if not is_row(ln, most):
            out.append(ln)
            continue
        k += 1
        if k % every == 0:
            continue
        v = [float(x) for x in ln.split()]
        for a in range(4):
            v[a] += rng.uniform(-jitter, jitter)
        v[0] = min(max(v[0], 0.0), 1.5707)
        v[2] = min(max(v[2], 0.0), 1.5707)
        v[1] += turn
        v[3] += turn
        v[4:] = [max(0.0, x * (1 + noise * rng.gauss(0, 1))) for x in v[4:]]
        out.append(" ".join("%.6f" % x for x in v))
    with open(dst, "w") as f:
        f.write("\n".join(out) + "\n")


def make(name, folder, build):
    """The table NAME in folder (made once); a FILE as it is."""
    if name not in TABLES:
        return name
    ext = ".brdf" if name.startswith("acrylic") else ".csv"
    path = os.path.join(folder, name + ext)
    if os.path.exists(path):
        return path
    if name == "acrylic":
        shutil.copy(ACRYLIC, path)
    elif name == "acrylic-7":
        variant(ACRYLIC, path, 7, 0.002, 0.3, 0.02, 7)
    elif name == "acrylic-5":
        variant(ACRYLIC, path, 5, 0.0, -0.7, 0.05, 5)
    elif name in AT:
        src, noise, seed, drop = AT[name]
        with open(path, "w") as f:
            subprocess.run([os.path.join(build, "sepbrdf_bench_at_directions"), ACRYLIC, src, str(noise), str(seed),
                            str(drop)], stdout=f, check=True)
    else:
        subprocess.run([os.path.join(build, "sepbrdf"), "-q", "sample", ANALYTIC[name], "--gonio", GONIO,
                        "--noise", NOISE, "-o", path], check=True)
    return path


def splits(build, path, J, n):
    """(figure, figure's se, [split errors]) from sepbrdf_bench_holdout."""
    r = subprocess.run([os.path.join(build, "sepbrdf_bench_holdout"), path, "0.1", str(n), str(J)],
                       capture_output=True, text=True, check=True)
    m = re.search(r"cv_headline of the whole table (\S+) \+- (\S+)", r.stdout)
    errs = [float(ln.split("|")[3]) for ln in r.stdout.splitlines() if re.match(r"\| \d+ \|", ln)]
    return float(m.group(1)), float(m.group(2)), errs


def figures(build, path, J, folder):
    """The whole table's figures at J from `sepbrdf factor` (report.json):
    cv_headline and, where the build has them, the others a split could be
    compared with."""
    out = os.path.join(folder, "out")
    subprocess.run([os.path.join(build, "sepbrdf"), "-q", "factor", path, "-J", str(J), "-o", out], check=True)
    e = json.load(open(os.path.join(out, "report.json")))["errors"][J - 1]
    return {k: e[k] for k in STATS if isinstance(e.get(k), (int, float))}


def within(fig, errs):
    return sum(1 for e in errs if fig > 0 and 1 / WITHIN <= e / fig <= WITHIN)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--build", default=os.path.join(ROOT, "build"))
    ap.add_argument("--J", type=int, default=4)
    ap.add_argument("--splits", type=int, default=10)
    ap.add_argument("--keep", help="make (or reuse) the tables in this folder")
    ap.add_argument("names", nargs="*", default=TABLES)
    a = ap.parse_args()
    for n in a.names:
        if n not in TABLES and not os.path.isfile(n):
            sys.exit("cv_splits.py: unknown table %s (known: %s, or a file)" % (n, ", ".join(TABLES)))
    folder = a.keep or tempfile.mkdtemp(prefix="sb_cv_splits")
    os.makedirs(folder, exist_ok=True)
    total, hits = 0, {}
    print("| table | cv_headline J = %d | %d splits: error / cv_headline | within %gx |" % (a.J, a.splits, WITHIN))
    print("|---|---|---|---|")
    try:
        for n in a.names:
            cv, se, errs = splits(a.build, make(n, folder, a.build), a.J, a.splits)
            ratios = [e / cv for e in errs]
            total += len(ratios)
            figs = figures(a.build, make(n, folder, a.build), a.J, folder)
            for k, v in figs.items():
                hits[k] = hits.get(k, 0) + within(v, errs)
            print("| %s | %.4g ± %.2g | %s | %d of %d |" % (os.path.basename(n), cv, se, " ".join("%.2f" % q for q in ratios),
                                                           within(cv, errs), len(ratios)))
            print("# %s: errors %s; %s" % (os.path.basename(n), " ".join("%.4g" % e for e in errs), ", ".join(
                "%s %.4g (%d within)" % (k, v, within(v, errs)) for k, v in figs.items())), flush=True)
    finally:
        if not a.keep:
            shutil.rmtree(folder)
    for k, v in hits.items():
        print("# all tables: %d of %d splits within %gx of %s" % (v, total, WITHIN, k))


if __name__ == "__main__":
    main()
