#!/usr/bin/env python3
"""sepbrdf's dense solvers against their Python peers, in alternation.

    bench/solvers.py --server BIN --matrices DIR [--n 4096] [--terms 8] [--rounds 5]

One process pair on the same matrices (DIR/ioN_{r,g,b}.f64, written by
`sepbrdf_bench --matrices DIR`): this Python process runs the peers and
BIN (sepbrdf_bench_svd, bench/svd_serve.c) runs sepbrdf's solvers, kept
alive and asked for one method at a time, so every round times
    topk        (sepbrdf, exact)       against scipy svds (ARPACK, tol 0)
    randomized  (sepbrdf, q = 2, mixed precision: the default)
                                       against sklearn randomized_svd(n_iter=2)
    randomized:q=1 (sepbrdf, q = 1)    against the same sklearn call
    randomized:f32 (sepbrdf, q = 2 in single precision)   against it too
    randomized:double (sepbrdf, q = 2, every step in double)   too
back to back, the order swapped every round.  Each side factors the three
channels; wall and CPU seconds (the whole process, every BLAS thread), and
the relative error sqrt(sum ||A - A_J||^2 / sum ||A||^2) from ||A||^2 -
sum s_j^2 (exact for orthonormal factors of a projection).  The optimum is
sepbrdf topk's (certified to 2^-40 s_1).  Prints every round and the
median (min-max) of the ratios peer / sepbrdf (above 1: sepbrdf faster).
Set OPENBLAS_NUM_THREADS for both sides before starting (bench/solvers.sh
runs 1 and 2).  Exit status 77 when numpy, scipy or scikit-learn are
missing."""
import argparse
import os
import statistics
import subprocess
import sys
import time

import bench_matrices

try:
    import numpy as np
    from scipy.sparse.linalg import svds
    from sklearn.utils.extmath import randomized_svd
except ImportError as e:
    print(f"solvers.py: {e.name or e}: not installed; peers skipped", file=sys.stderr)
    sys.exit(77)

SVDS = ("scipy svds", lambda M, J: svds(M, k=J, return_singular_vectors=True)[1])
SK2 = ("sklearn n_iter=2", lambda M, J: randomized_svd(M, J, n_iter=2, random_state=0)[1])
PEERS = {  # sepbrdf method -> (peer name, factor(M, J) -> singular values)
    "topk": SVDS,
    "randomized": SK2,
    "randomized:q=1": SK2,  # one power step less: faster, its error above sklearn's
    "randomized:f32": SK2,  # q = 2 in single precision: its error still below sklearn's
    "randomized:double": SK2,  # q = 2, every step in double (before the default became mixed)
}


def peer(method, mats, J, norms):
    f = PEERS[method][1]
    w0, c0 = time.perf_counter(), time.process_time()
    resid = 0.0
    for M, n2 in zip(mats, norms):
        s = f(M, J)
        resid += max(n2 - float(np.sum(np.asarray(s) ** 2)), 0.0)
    return time.perf_counter() - w0, time.process_time() - c0, (resid / sum(norms)) ** 0.5


def ours(server, method):
    server.stdin.write(method + "\n")
    server.stdin.flush()
    name, wall, cpu, rel = server.stdout.readline().split()
    assert name == method
    return float(wall), float(cpu), float(rel)


def summary(xs):
    return f"{statistics.median(xs):.2f} ({min(xs):.2f}-{max(xs):.2f})"


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--server", required=True)
    ap.add_argument("--matrices", required=True)
    ap.add_argument("--n", type=int, default=4096)
    ap.add_argument("--terms", type=int, default=8)
    ap.add_argument("--rounds", type=int, default=5)
    a = ap.parse_args()
    mats = bench_matrices.load(a.matrices, a.n, "solvers.py")
    norms = [float(np.sum(M * M)) for M in mats]
    threads = os.environ.get("OPENBLAS_NUM_THREADS", "unset")
    server = subprocess.Popen([a.server, a.matrices, str(a.n), str(a.terms)], stdin=subprocess.PIPE,
                              stdout=subprocess.PIPE, text=True)
    print(f"# N = {a.n}, J = {a.terms}, three channels, OPENBLAS_NUM_THREADS={threads}; "
          f"load {open('/proc/loadavg').read().split()[0]}")
    res = {m: {"wall": [], "cpu": [], "rel": [], "prel": []} for m in PEERS}
    for r in range(a.rounds):
        for method in PEERS:
            first_ours = r % 2 == 0
            o = ours(server, method) if first_ours else None
            p = peer(method, mats, a.terms, norms)
            if not first_ours:
                o = ours(server, method)
            d = res[method]
            d["wall"].append(p[0] / o[0])
            d["cpu"].append(p[1] / o[1])
            d["rel"].append(o[2])
            d["prel"].append(p[2])
            print(f"round {r + 1} {method:14s} sepbrdf {o[0]:.3f} s wall {o[1]:.3f} s CPU rel {o[2]:.6f} | "
                  f"{PEERS[method][0]} {p[0]:.3f} s wall {p[1]:.3f} s CPU rel {p[2]:.6f} | "
                  f"peer/sepbrdf wall {p[0] / o[0]:.2f} CPU {p[1] / o[1]:.2f}", flush=True)
    server.stdin.write("quit\n")
    server.stdin.close()
    server.wait()
    opt = min(res["topk"]["rel"])
    for method, d in res.items():
        print(f"ratio {method}/{PEERS[method][0].replace(' ', '_')} threads={threads}: wall {summary(d['wall'])}, "
              f"CPU {summary(d['cpu'])}; excess over the optimum: sepbrdf {max(d['rel']) - opt:.2e}, "
              f"peer {max(d['prel']) - opt:.2e}")


if __name__ == "__main__":
    main()
