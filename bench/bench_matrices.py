"""The matrices `sepbrdf bench --matrices DIR` exports, read back for the
Python peers (bench/peers.py, bench/solvers.py): io{n}_{r,g,b}.f64, n x n
float64 in column-major order."""
import os
import sys

import numpy as np


def load(folder, n, who):
    """The three channels as Fortran-ordered n x n arrays; exits naming
    `who` and the file when one has the wrong size."""
    chans = []
    for c in "rgb":
        a = np.fromfile(os.path.join(folder, f"io{n}_{c}.f64"), dtype=np.float64)
        if a.size != n * n:
            sys.exit(f"{who}: io{n}_{c}.f64: {a.size} values, expected {n * n}")
        chans.append(np.asfortranarray(a.reshape((n, n), order="F")))
    return chans
