#!/usr/bin/python3
"""The chi2 p-values that build/sepbrdf_bench_sampler_variance prints (the
last column of its table), pooled: how many below 0.05 and 0.01, and the
Kolmogorov-Smirnov test against uniform (scipy; Debian's /usr/bin/python3).

    build/sepbrdf_bench_sampler_variance > out.txt; bench/pvalues_ks.py out.txt
"""
import sys

from scipy import stats


def pvalues(path):
    ps = []
    for line in open(path):
        if line.startswith("| ") and not line.startswith("| source") and "failed" not in line:
            ps += [float(x) for x in line.strip().strip("|").split("|")[-1].split()]
    return ps


def main():
    if len(sys.argv) < 2:
        sys.exit(__doc__)
    ps = [p for path in sys.argv[1:] for p in pvalues(path)]
    if not ps:
        sys.exit("no p-values in " + " ".join(sys.argv[1:]))
    n = len(ps)
    ks = stats.kstest(ps, "uniform")
    print(f"{n} p-values: {sum(p < 0.05 for p in ps)} below 0.05 ({0.05 * n:.1f} expected), "
          f"{sum(p < 0.01 for p in ps)} below 0.01 ({0.01 * n:.1f}); lowest {min(ps)}")
    print(f"Kolmogorov-Smirnov against uniform: D = {ks.statistic:.3f}, p = {ks.pvalue:.3g}")


if __name__ == "__main__":
    main()
