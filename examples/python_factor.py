#!/usr/bin/env python3
"""Factor three BRDFs from Python: the default gold microfacet, a measured
table, and a BRDF written as a numpy function; print each one's error and
compare the reconstruction with the BRDF at a few direction pairs.

    python3 examples/python_factor.py [OUT_FOLDER]

(after `cmake --install build`, or with PYTHONPATH=python and
SEPBRDF_LIBRARY=build/libsepbrdf.so in the source tree)."""
import os
import sys

import numpy as np

import sepbrdf

here = os.path.dirname(os.path.abspath(__file__))
out = sys.argv[1] if len(sys.argv) > 1 else "sepbrdf-py-out"


def blinn_phong(wi, wo):
    """A normalised Blinn-Phong lobe over a white diffuse base, in numpy."""
    h = wi + wo
    h /= np.linalg.norm(h, axis=-1, keepdims=True)
    spec = (40 + 8) / (8 * np.pi) * np.maximum(h[:, 2], 0) ** 40
    f = 0.6 / np.pi + 0.4 * spec
    return np.where((wi[:, 2] > 0) & (wo[:, 2] > 0), f, 0.0)[:, None] * np.array([1.0, 0.9, 0.8])


def show(name, fac, source):
    rng = np.random.default_rng(1)
    z = rng.uniform(0.2, 1, (2, 5))
    phi = rng.uniform(0, 2 * np.pi, (2, 5))
    d = np.stack([np.sqrt(1 - z * z) * np.cos(phi), np.sqrt(1 - z * z) * np.sin(phi), z], axis=-1)
    f, _ = source.eval(d[0], d[1])
    layout = fac.param.split(",warp")[0]  # the warp tables make a long spec
    print(f"{name}: {layout}, form {fac.form}, J = {fac.terms}, headline error {fac.headline():.3e}")
    print("  f_r (blue) at 5 pairs:    ", np.array2string(f[:, 2], precision=4))
    print("  reconstruction:           ", np.array2string(fac.eval(d[0], d[1])[:, 2], precision=4))


fac = sepbrdf.factor(terms=4)  # as `sepbrdf factor`
show("default", fac, sepbrdf.Source())
fac.write(out)
print(f"  wrote {', '.join(sorted(os.listdir(out)))} into {out}/")

table = os.path.join(here, "..", "tests", "data", "measured", "cornell_acryl_blue.brdf")
if os.path.exists(table):
    show("measured", sepbrdf.factor(table, param="iso", terms=4), sepbrdf.Source(table))

src = sepbrdf.Source.from_function(blinn_phong, isotropic=True, reciprocal=True)
show("numpy Blinn-Phong", sepbrdf.factor(src, param="iso", res=16, terms=2), src)

try:
    sepbrdf.factor("microfacet:roughness=abc")
except sepbrdf.Error as e:
    print(f"a bad spec: {e.code}: {e}")
