#!/usr/bin/env python3
"""The peers on the project's own matrices, and the ratios.

    bench/peers.py --matrices DIR --results CSV [--reps N] [--whole S] [-o OUT]

DIR holds the matrices sepbrdf_bench wrote (--matrices: ioN_C.f64, raw
float64 column-major, C = r, g, b); CSV is its results.csv of the same run.
For every size N and number of terms J of the CSV, each peer factors the
three channels (wall time: the best of --reps runs of all three) and its
relative error ||M - M_J||_F / ||M||_F over the channels is formed
explicitly:
    numpy      numpy.linalg.svd (full, LAPACK gesdd)     vs sepbrdf full
    svds       scipy.sparse.linalg.svds (ARPACK, exact)   vs sepbrdf topk
    sklearn-q1 sklearn randomized_svd, n_iter=1           vs sepbrdf randomized:q=1
    sklearn-q2 sklearn randomized_svd, n_iter=2           vs sepbrdf randomized (q = 2)
numpy runs up to N = --full-max (default 2304).  The ratio is peer time /
sepbrdf time (the SVD of the three channels, svd_s; factor_s where the CSV
has no svd_s): above 1, sepbrdf is faster.
--whole S compares the whole `sepbrdf factor --param io -r 64 -J 8`
command (S seconds, from bench/run.sh) with sklearn-q2 alone at N = 4096,
J = 8.  The machine's speed drifts over the minutes between those two
timings, so with --whole-cmd CMD (the command) and --topk-cmd CMD (a
sepbrdf_bench line timing topk at N = 4096, J = 8, writing DIR/results.csv
under the folder it names after -o) the two pairs are also timed in
alternation, three rounds of (ours, the peer), and each round's ratio is
reported with the median.  Writes OUT (default DIR/peers.csv).  Exit status 77 when numpy,
scipy or scikit-learn are missing (scripts/setup-deps.sh --bench)."""
import argparse
import csv
import glob
import os
import re
import subprocess
import sys
import time

import bench_matrices

try:
    import numpy as np
    from scipy.sparse.linalg import svds
    from sklearn.utils.extmath import randomized_svd
except ImportError as e:
    print(f"peers.py: {e.name or e}: not installed (scripts/setup-deps.sh --bench); peers skipped", file=sys.stderr)
    sys.exit(77)

PEERS = [  # name, the sepbrdf method it is compared with, factor(M, J) -> (U, s, Vt)
    ("numpy", "full", lambda M, J: np.linalg.svd(M, full_matrices=False)),
    ("svds", "topk", lambda M, J: svds(M, k=J)),
    ("sklearn-q1", "randomized:q=1", lambda M, J: randomized_svd(M, J, n_iter=1, random_state=0)),
    ("sklearn-q2", "randomized", lambda M, J: randomized_svd(M, J, n_iter=2, random_state=0)),
]


def run_peer(fn, chans, J, reps):
    best, out = float("inf"), None
    for _ in range(reps):
        t0 = time.perf_counter()
        res = [fn(M, J) for M in chans]
        t = time.perf_counter() - t0
        if t < best:
            best, out = t, res
    err2 = norm2 = 0.0
    for M, (U, s, Vt) in zip(chans, out):
        order = np.argsort(s)[::-1][:J]  # svds returns ascending values
        R = M - (U[:, order] * s[order]) @ Vt[order, :]
        err2 += float(np.sum(R * R))
        norm2 += float(np.sum(M * M))
    return best, (err2 / norm2) ** 0.5 if norm2 > 0 else 0.0


def timed(cmd):
    t0 = time.perf_counter()
    subprocess.run(cmd, shell=True, check=True, stdout=subprocess.DEVNULL)
    return time.perf_counter() - t0


def topk_svd_s(cmd):
    """Run the sepbrdf_bench line; its svd_s (the three channels' SVD) from results.csv."""
    subprocess.run(cmd, shell=True, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    out = cmd.split(" -o ")[1].split()[0]
    rows = list(csv.DictReader(open(os.path.join(out, "results.csv"))))
    return float(rows[-1]["svd_s"])


def interleaved(a, chans, w):
    """Ours and the peer in alternation, three rounds (the ratio of each)."""
    pairs = []
    if a.whole_cmd:
        pairs.append(("whole factor --param io -r 64 -J 8", "sklearn-q2",
                      lambda: min(timed(a.whole_cmd) for _ in range(5)),
                      lambda: run_peer(PEERS[3][2], chans, 8, 3)[0]))
    if a.topk_cmd:
        pairs.append(("topk svd", "svds", lambda: topk_svd_s(a.topk_cmd), lambda: run_peer(PEERS[1][2], chans, 8, 3)[0]))
    for ours_name, peer, ours, theirs in pairs:
        ratios = []
        for rnd in range(3):
            t_ours, t_peer = ours(), theirs()
            ratios.append(t_peer / t_ours)
            w.writerow([4096, 8, peer, f"{t_peer:.6f}", "", f"{ours_name}, alternating round {rnd + 1}",
                        f"{t_ours:.6f}", "interleaved", f"{ratios[-1]:.3f}"])
            print(f"# alternating round {rnd + 1}: {ours_name} {t_ours:.3f} s, {peer} {t_peer:.3f} s: ratio {ratios[-1]:.2f}",
                  flush=True)
        print(f"# {ours_name} against {peer}, alternating: median ratio {sorted(ratios)[1]:.2f}")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--matrices", required=True)
    ap.add_argument("--results", required=True)
    ap.add_argument("--reps", type=int, default=3)
    ap.add_argument("--whole", type=float, default=None)
    ap.add_argument("--full-max", type=int, default=2304, help="largest N for numpy's full SVD (minutes at 4096)")
    ap.add_argument("--whole-cmd", default=None, help="the whole command, timed in alternation with sklearn-q2")
    ap.add_argument("--topk-cmd", default=None, help="sepbrdf_bench timing topk at N = 4096, J = 8 (-o DIR)")
    ap.add_argument("-o", "--out", default=None)
    a = ap.parse_args()
    rows = list(csv.DictReader(open(a.results)))
    ours = {}
    for r in rows:
        t = float(r["svd_s"]) if float(r["svd_s"]) >= 0 else float(r["factor_s"])
        ours[(int(r["n"]), int(r["terms"]), r["method"])] = (t, "svd" if float(r["svd_s"]) >= 0 else "factor")
    sizes = sorted({int(re.search(r"io(\d+)_r", f).group(1)) for f in glob.glob(os.path.join(a.matrices, "io*_r.f64"))})
    terms = sorted({int(r["terms"]) for r in rows})
    out_path = a.out or os.path.join(a.matrices, "peers.csv")
    with open(out_path, "w", newline="") as fp:
        w = csv.writer(fp)
        w.writerow(["n", "terms", "peer", "peer_s", "peer_rel_err", "sepbrdf_method", "sepbrdf_s", "sepbrdf_stage", "ratio"])
        print(f"{'N':>6} {'J':>3} {'peer':<11} {'peer s':>9} {'rel_err':>11} {'sepbrdf':<15} {'s':>9} {'ratio':>7}")
        q2_4096_8 = None
        for n in sizes:
            chans = bench_matrices.load(a.matrices, n, "peers.py")
            for J in terms:
                for name, method, fn in PEERS:
                    if name == "numpy" and n > a.full_max:
                        continue
                    if name == "numpy" and J != terms[-1]:
                        continue  # the full SVD does not depend on J: once
                    t, err = run_peer(fn, chans, J, a.reps)
                    mine, stage = ours.get((n, J, method), (float("nan"), "-"))
                    ratio = t / mine if mine == mine and mine > 0 else float("nan")
                    if name == "sklearn-q2" and n == 4096 and J == 8:
                        q2_4096_8 = t
                    w.writerow([n, J, name, f"{t:.6f}", f"{err:.10e}", method, f"{mine:.6f}", stage, f"{ratio:.3f}"])
                    print(f"{n:>6} {J:>3} {name:<11} {t:>9.4f} {err:>11.4e} {method:<15} {mine:>9.4f} {ratio:>7.2f}", flush=True)
        if a.whole is not None and q2_4096_8 is not None:
            w.writerow([4096, 8, "sklearn-q2", f"{q2_4096_8:.6f}", "", "whole factor --param io -r 64 -J 8", f"{a.whole:.6f}", "command", f"{q2_4096_8 / a.whole:.3f}"])
            print(f"# whole `sepbrdf factor --param io -r 64 -J 8` {a.whole:.3f} s; sklearn randomized_svd n_iter=2 alone "
                  f"on its three matrices {q2_4096_8:.3f} s: ratio {q2_4096_8 / a.whole:.2f}")
        if 4096 in sizes:
            interleaved(a, bench_matrices.load(a.matrices, 4096, "peers.py"), w)
    print(f"# wrote {out_path}")


if __name__ == "__main__":
    main()
