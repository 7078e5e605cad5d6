#!/usr/bin/env python3
"""RGL tensor_file variants of the measured files, for an outside pass
(docs/measured.md, "Fourteenth pass"): other resolutions, spectral layouts
as RGL's `_spec` files have them (spectra [phi_i, theta_i, n, S, S] and
wavelengths, no rgb), one wavelength, anisotropic phi_i, zeros and NaN in
a slice, tiny and huge values, missing fields.  Reads and writes the
Mitsuba container itself (a copy written back is byte-identical).

    python3 bench/rgl_variants.py DATA_DIR OUT_DIR
"""
import os
import struct
import sys

import numpy as np

DT = {1: np.uint8, 2: np.int8, 3: np.uint16, 4: np.int16, 5: np.uint32, 6: np.int32, 7: np.uint64,
      8: np.int64, 9: np.float16, 10: np.float32, 11: np.float64}
RDT = {np.dtype(v): k for k, v in DT.items()}


def read(path):
    b = open(path, "rb").read()
    assert b[:12] == b"tensor_file\0", path
    n, p, out = struct.unpack_from("<I", b, 14)[0], 18, {}
    for _ in range(n):
        ln = struct.unpack_from("<H", b, p)[0]
        name = b[p + 2:p + 2 + ln].decode()
        p += 2 + ln
        nd, dt, off = struct.unpack_from("<HBQ", b, p)
        p += 11
        shape = struct.unpack_from("<%dQ" % nd, b, p)
        p += 8 * nd
        out[name] = np.frombuffer(b, DT[dt], int(np.prod(shape)) if nd else 1, off).reshape(shape).copy()
    return out


def write(path, fields):
    names = list(fields)
    off = 18 + sum(2 + len(k) + 2 + 1 + 8 + 8 * fields[k].ndim for k in names)
    offs = []
    for k in names:
        off = (off + 7) // 8 * 8
        offs.append(off)
        off += fields[k].nbytes
    buf = bytearray(off)
    buf[:14] = b"tensor_file\0\1\0"
    struct.pack_into("<I", buf, 14, len(names))
    p = 18
    for k, o in zip(names, offs):
        a, kb = np.ascontiguousarray(fields[k]), k.encode()
        struct.pack_into("<H", buf, p, len(kb))
        buf[p + 2:p + 2 + len(kb)] = kb
        p += 2 + len(kb)
        struct.pack_into("<HBQ", buf, p, a.ndim, RDT[a.dtype], o)
        p += 11
        for s in a.shape:
            struct.pack_into("<Q", buf, p, s)
            p += 8
        buf[o:o + a.nbytes] = a.tobytes()
    open(path, "wb").write(bytes(buf))


def spec(f, wl):
    """rgb replaced by spectra over wavelengths wl (B below 500 nm, G about 540, R above 560)."""
    g = {k: v for k, v in f.items() if k != "rgb"}
    w = np.stack([np.clip((wl - 560) / 60, 0, 1), np.exp(-((wl - 540) / 50) ** 2), np.clip((500 - wl) / 60, 0, 1)], 1)
    g["spectra"] = np.einsum("abcij,nc->abnij", f["rgb"], w).astype(np.float32)
    g["wavelengths"] = wl.astype(np.float32)
    return g


def decim(f, rs, vs, th=None):
    g = dict(f)
    g["rgb"], g["luminance"] = f["rgb"][..., ::rs, ::rs].copy(), f["luminance"][..., ::rs, ::rs].copy()
    g["vndf"], g["ndf"], g["sigma"] = f["vndf"][..., ::vs, ::vs].copy(), f["ndf"][:, ::vs].copy(), f["sigma"][:, ::vs].copy()
    if th is not None:
        g["theta_i"] = f["theta_i"][th].copy()
        for k in ("rgb", "luminance", "vndf"):
            g[k] = g[k][:, th].copy()
    g.pop("valid", None)
    return g


def aniso(f, phis):
    g = dict(f)
    g["phi_i"] = np.array(phis, np.float32)
    for k in ("rgb", "luminance", "vndf"):
        g[k] = np.repeat(f[k], len(phis), 0).copy()
    return g


def edit(f, key, fn):
    g = dict(f)
    g[key] = f[key].astype(np.float64).copy()
    fn(g[key])
    g[key] = g[key].astype(np.float32)
    return g


def main():
    data, out = sys.argv[1], sys.argv[2]
    os.makedirs(out, exist_ok=True)
    p, o, m = (read(f"{data}/rgl_{n}_rgb.bsdf") for n in ("paper_white", "chm_orange", "cc_green_malachite"))
    up = dict(m)
    up["rgb"] = np.repeat(np.repeat(m["rgb"], 2, 3), 2, 4).copy()
    up["luminance"] = np.repeat(np.repeat(m["luminance"], 2, 2), 2, 3).copy()
    up.pop("valid", None)
    sets = {
        "paper_rt": dict(p),
        "orange_spec": spec(o, np.linspace(360, 1000, 129)),
        "paper_spec": spec(p, np.linspace(360, 1000, 33)),
        "malachite_spec1": spec(m, np.array([550.0])),
        "orange_r16": decim(o, 2, 2),
        "paper_th5": decim(p, 1, 1, [0, 2, 4, 6, 7]),
        "malachite_r64": up,
        "paper_aniso5": aniso(p, np.linspace(-np.pi, np.pi, 5)),
        "orange_aniso_red4": aniso(o, np.linspace(0, np.pi / 2, 3)),
        "orange_zero_slice": edit(o, "rgb", lambda a: a.__setitem__((0, 3), 0)),
        "orange_nan1": edit(o, "rgb", lambda a: a.__setitem__((0, 3, 1, 10, 10), np.nan)),
        "orange_nan_slice": edit(o, "rgb", lambda a: a.__setitem__((0, 5), np.nan)),
        "orange_vndf_zero_slice": edit(o, "vndf", lambda a: a.__setitem__((0, 2), 0)),
        "orange_blue_zero": edit(o, "rgb", lambda a: a.__setitem__((0, slice(None), 2), 0)),
        "orange_blue_neg": edit(o, "rgb", lambda a: a.__setitem__((0, slice(None), 2), -a[0, :, 2])),
        "paper_tiny30": edit(p, "rgb", lambda a: a.__imul__(1e-30)),
        "paper_subnormal": edit(p, "rgb", lambda a: a.__imul__(1e-39)),
        "paper_huge30": edit(p, "rgb", lambda a: a.__imul__(1e30)),
        "paper_minimal": {k: v for k, v in p.items() if k not in ("description", "luminance", "valid", "jacobian", "version")},
        "orange_nojac": {k: v for k, v in o.items() if k != "jacobian"},
        "orange_jac0": dict(o, jacobian=np.array([0], np.uint8)),
    }
    for name, f in sets.items():
        write(f"{out}/{name}.bsdf", f)
    print(f"{len(sets)} variants in {out}/")


if __name__ == "__main__":
    main()
