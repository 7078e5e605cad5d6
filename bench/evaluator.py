#!/usr/bin/env python3
"""An outside evaluator's reading of a factor folder (docs/measured.md,
"Sixth pass").

Reads g_*.exr / h_*.exr with its own EXR parser (scanline, NO/ZIPS/ZIP
compression, HALF or FLOAT), transcribes the emitted sepbrdf.glsl into numpy
(sb_coords of the layout, GL_LINEAR with the SB_WRAP_* wraps and texel
centres at (x + 0.5)/W, SB_EDGE_H_S, sb_scale, SB_CLAMP, the form's
division), evaluates the source model from the README's formulas (lambert,
phong, cook-torrance with GGX / Smith-Schlick / Schlick) and compares the
headline, theta_i/theta_o > 60 degree and specular bands with report.json.
A scene fit's headline is compared with scene.domain_headline (its bands are
the scene's: left out); a measured table's set needs EVAL_REF (exit 2 without).
Where report.json's estimate.domain is "cap" (--theta-max below 90), only
the pairs with both directions within the cap count (a band beyond: 0).

    python3 bench/evaluator.py DIR [PAIRS] [SEED]
    EVAL_REF=DIR8 python3 bench/evaluator.py DIR   # an RGL file: DIR8 its vndf
                                                   # set at J = slices (the file)

Uses no sepbrdf code.  Prints one line per J' and exits 1 where a figure
lies outside 4 combined standard errors (and 2 % relative) of report.json's.
"""
import json
import re
import struct
import sys
import zlib

import numpy as np

REF = None  # EVAL_REF=DIR: the reference is that factor set at its full J


def read_exr(path):
    """(channels dict name -> (h, w) float64, attributes dict)."""
    d = open(path, "rb").read()
    if d[:4] != b"v/1\x01":
        raise ValueError(f"{path}: not an EXR file")
    pos, attrs = 8, {}
    while d[pos] != 0:
        e = d.index(b"\0", pos)
        name = d[pos:e].decode()
        e2 = d.index(b"\0", e + 1)
        typ = d[e + 1:e2].decode()
        (size,) = struct.unpack_from("<i", d, e2 + 1)
        attrs[name] = (typ, d[e2 + 5:e2 + 5 + size])
        pos = e2 + 5 + size
    pos += 1
    chans, c = [], attrs["channels"][1]
    p = 0
    while c[p] != 0:
        e = c.index(b"\0", p)
        (pt,) = struct.unpack_from("<i", c, e + 1)
        chans.append((c[p:e].decode(), pt))
        p = e + 17
    x0, y0, x1, y1 = struct.unpack("<4i", attrs["dataWindow"][1])
    w, h = x1 - x0 + 1, y1 - y0 + 1
    comp = attrs["compression"][1][0]
    lines = {0: 1, 2: 1, 3: 16}[comp]
    nchunk = (h + lines - 1) // lines
    offs = struct.unpack_from(f"<{nchunk}Q", d, pos)
    out = {n: np.zeros((h, w)) for n, _ in chans}
    for off in offs:
        y, size = struct.unpack_from("<ii", d, off)
        raw = d[off + 8:off + 8 + size]
        nl = min(lines, y1 + 1 - y)
        need = sum(w * nl * (2 if pt == 1 else 4) for _, pt in chans)
        if comp != 0 and size < need:
            t = np.frombuffer(zlib.decompress(raw), np.uint8).astype(np.int32)
            t = np.cumsum(np.concatenate([t[:1], t[1:] - 128])) & 255
            t = t.astype(np.uint8)
            half = (len(t) + 1) // 2
            u = np.empty_like(t)
            u[0::2], u[1::2] = t[:half], t[half:]
            raw = u.tobytes()
        q = 0
        for li in range(nl):
            for n, pt in chans:
                dt, sz = (np.float16, 2) if pt == 1 else (np.float32, 4)
                out[n][y - y0 + li] = np.frombuffer(raw, dt, w, q)
                q += w * sz
    return out, attrs


def tex_stack(folder, side, terms):
    layers = []
    for j in range(terms):
        ch, _ = read_exr(f"{folder}/{side}_{j:02d}.exr")
        if "Y" in ch:
            layers.append(np.stack([ch["Y"]] * 3, -1))
        else:
            layers.append(np.stack([ch[k] for k in "RGB"], -1))
    return np.stack(layers)  # (J, h, w, 3)


def texture(tex, s, t, wrap_s, wrap_t):
    """GL_LINEAR of one layer stack tex (J, h, w, 3) at (n,) s, t: (J, n, 3)."""
    _, hh, ww, _ = tex.shape

    def axis(c, n, rep):
        u = c * n - 0.5
        i0 = np.floor(u)
        a = u - i0
        i0 = i0.astype(np.int64)
        i1 = i0 + 1
        if rep:
            i0, i1 = i0 % n, i1 % n
        else:
            i0, i1 = np.clip(i0, 0, n - 1), np.clip(i1, 0, n - 1)
        return i0, i1, a

    x0, x1, a = axis(s, ww, wrap_s)
    y0, y1, b = axis(t, hh, wrap_t)
    a, b = a[None, :, None], b[None, :, None]
    return ((1 - a) * (1 - b) * tex[:, y0, x0] + a * (1 - b) * tex[:, y0, x1] +
            (1 - a) * b * tex[:, y1, x0] + a * b * tex[:, y1, x1])


def glsl_defines(src):
    dv = dict(re.findall(r"#define (SB_\w+) (\S+)", src))
    m = re.search(r"sb_scale\[SB_TERMS\] = float\[SB_TERMS\]\(([^)]*)\)", src)
    scale = np.array([float(v) for v in m.group(1).split(",")])
    return dv, scale


def warp_fn(src, name):
    """sb_warp_h / sb_warp_d: x, sqrt(x) or a table (not transcribed)."""
    m = re.search(r"float %s\(float x\) \{ return ([^;]*); \}" % name, src)
    if not m:
        return None
    body = m.group(1).strip()
    if body == "x":
        return lambda x: x
    if body == "sqrt(x)":
        return np.sqrt
    return None


def warp_table(src, name):
    """sb_warp_h/d from a knot table: the binary search's segment lo (the last
    knot <= x, within 0..n-1), t clamped to [0, 1], s = (lo + t) / n."""
    m = re.search(r"const float %s_x\[(\d+)\] = float\[\d+\]\(([^)]*)\)" % name, src)
    if not m:
        return None
    k = np.array([float(v) for v in m.group(2).split(",")])
    n = len(k) - 1

    def w(x):
        lo = np.clip(np.searchsorted(k, x, "right") - 1, 0, n - 1)
        t = np.clip((x - k[lo]) / (k[lo + 1] - k[lo]), 0, 1)
        return (lo + t) / n
    return w


def norm(v):
    return np.linalg.norm(v, axis=-1)


def grid_st(w, theta_max):
    """io's sb_grid_st and hd's sb_hd_st: theta / theta_max, phi / 2 pi."""
    th = np.arctan2(norm(w[:, :2]), w[:, 2])
    ph = np.arctan2(w[:, 1], w[:, 0]) % (2 * np.pi)
    return th / theta_max, ph / (2 * np.pi)


def coords(layout, L, V, theta_max, dv, src):
    n = len(L)
    if layout == "io":
        return grid_st(L, theta_max) + grid_st(V, theta_max)
    if layout == "io-area":
        def st(w):
            cc = 1 - np.cos(theta_max)
            rho = np.sqrt((w[:, 0]**2 + w[:, 1]**2) / (np.maximum(1 + w[:, 2], 1e-30) * cc))
            qx, qy = np.abs(w[:, 0]), np.abs(w[:, 1])
            wa = qy <= qx
            with np.errstate(divide="ignore", invalid="ignore"):
                ratio = np.where(wa, np.where(qx > 0, qy / qx, 0), qx / qy)
            r = rho * (4 / np.pi) * np.arctan(ratio)
            a = np.where(wa, rho, r) * np.sign(np.where(w[:, 0] < 0, -1, 1))
            b = np.where(wa, r, rho) * np.sign(np.where(w[:, 1] < 0, -1, 1))
            return 0.5 * a + 0.5, 0.5 * b + 0.5
        a, b = st(L)
        c, d = st(V)
        return a, b, c, d
    s = L + V
    H = s / norm(s)[:, None]
    wh = warp_fn(src, "sb_warp_h") or warp_table(src, "sb_warp_h")
    wd = warp_fn(src, "sb_warp_d") or warp_table(src, "sb_warp_d")
    if layout == "hd":
        nn = norm(H[:, 1:])
        T = np.stack([nn, -H[:, 0] * H[:, 1] / nn, -H[:, 0] * H[:, 2] / nn], -1)
        Bv = np.cross(H, T)
        D = np.stack([(L * T).sum(1), (L * Bv).sum(1), (L * H).sum(1)], -1)
        a, b = grid_st(H, theta_max)
        c, d = grid_st(D, theta_max)
        return wh(a), b, wd(c), d
    if layout == "iso":
        hxy = norm(H[:, :2])
        cs = H[:, :2] / hxy[:, None]
        x1 = L[:, 0] * cs[:, 0] + L[:, 1] * cs[:, 1]
        y1 = -L[:, 0] * cs[:, 1] + L[:, 1] * cs[:, 0]
        D = np.stack([x1 * H[:, 2] - L[:, 2] * hxy, y1, x1 * hxy + L[:, 2] * H[:, 2]], -1)
        pd = np.arctan2(D[:, 1], D[:, 0])
        pd = np.where(pd < 0, pd + np.pi, pd)
        pd = np.where(pd >= np.pi, pd - np.pi, pd)
        return (wh(np.arctan2(hxy, H[:, 2]) / theta_max), np.full(n, 0.5),
                wd(np.arctan2(norm(D[:, :2]), D[:, 2]) / theta_max), pd / np.pi)
    if layout == "vh":
        vxy = norm(V[:, :2])
        cs = V[:, :2] / vxy[:, None]
        x = H[:, 0] * cs[:, 0] + H[:, 1] * cs[:, 1]
        y = -H[:, 0] * cs[:, 1] + H[:, 1] * cs[:, 0]
        phi = np.arctan2(np.abs(y), x)
        return (wd(np.minimum(np.arctan2(vxy, V[:, 2]) / theta_max, 1)), np.full(n, 0.5),
                wh(np.minimum(np.arctan2(norm(H[:, :2]), H[:, 2]) / theta_max, 1)), phi / np.pi)
    if layout == "rv":
        rows, top = float(dv["SB_RV_ROWS"]), float(dv["SB_RV_TOP"])
        lxy = norm(L[:, :2])
        cs = -L[:, :2] / lxy[:, None]
        ti = np.arctan2(lxy, L[:, 2])
        ct, sti = np.cos(ti), np.sin(ti)
        R = np.stack([sti * cs[:, 0], sti * cs[:, 1], ct], -1)
        e1 = np.stack([ct * cs[:, 0], ct * cs[:, 1], -sti], -1)
        x = (V * e1).sum(1)
        y = V[:, 1] * cs[:, 0] - V[:, 0] * cs[:, 1]
        tr = np.arctan2(np.hypot(x, y), (V * R).sum(1))
        phi = np.arctan2(np.abs(y), x)
        u = np.minimum(ti / top, 1)
        return (u * (rows - 1) + 0.5) / rows, np.full(n, 0.5), np.sqrt(tr / np.pi), phi / np.pi
    if layout == "vndf":
        return vndf_coords(L, V, dv, src)
    raise SystemExit(f"layout {layout}: not transcribed")


def elev(d):
    return np.arctan2(norm(d[:, :2]), d[:, 2])


def azim(d):
    return np.arctan2(d[:, 1], d[:, 0])


class Vndf:
    """vndf.exr (EXR line y = texelFetch row y) and the snippet's constants."""

    def __init__(self, folder, dv, src):
        ch, _ = read_exr(f"{folder}/vndf.exr")
        self.t = [ch["R"], ch["G"], ch["B"]]
        for k in ("VN", "VW", "VH", "NW", "NH", "SW", "SH", "CW", "CH", "VJAC"):
            setattr(self, k.lower(), int(dv["SB_" + k]))
        m = re.search(r"sb_vtheta\[SB_VN\] = float\[SB_VN\]\(([^)]*)\)", src)
        self.theta = np.array([float(v) for v in m.group(1).split(",")])

    def vt(self, c, y, x):
        return self.t[c][y, x]

    def vslice(self, tv):
        k = np.zeros(len(tv), np.int64)
        for i in range(1, self.vn - 1):
            k = np.where(self.theta[i] < tv, i, k)
        w = np.clip((tv - self.theta[k]) / (self.theta[k + 1] - self.theta[k]), 0, 1)
        return k, w

    def vmix(self, c, k, w, x, y):
        a = self.vt(c, k * self.vh + y, x)
        b = self.vt(c, np.minimum(k + 1, self.vn - 1) * self.vh + y, x)
        return np.where(w == 0, a, (1 - w) * a + w * b)

    def invert(self, u, v, k, w):
        x = np.clip(u, 0, 1) * (self.vw - 1)
        y = np.clip(v, 0, 1) * (self.vh - 1)
        ix = np.minimum(x.astype(np.int64), self.vw - 2)
        iy = np.minimum(y.astype(np.int64), self.vh - 2)
        fx, fy = x - ix, y - iy
        m = self.vmix
        c0 = (1 - fy) * m(0, k, w, ix, iy) + fy * m(0, k, w, ix, iy + 1)
        c1 = (1 - fy) * m(0, k, w, ix + 1, iy) + fy * m(0, k, w, ix + 1, iy + 1)
        xs = fx * (c0 + 0.5 * fx * (c1 - c0))
        xs += (1 - fy) * m(1, k, w, ix, iy) + fy * m(1, k, w, ix, iy + 1)
        r0, r1 = m(1, k, w, self.vw - 1, iy), m(1, k, w, self.vw - 1, iy + 1)
        row = (1 - fy) * r0 + fy * r1
        with np.errstate(divide="ignore", invalid="ignore"):
            sx = np.where(row > 0, xs / row, u)
        return sx, fy * (r0 + 0.5 * fy * (r1 - r0)) + m(2, k, w, 0, iy)

    def bilin(self, r0, W, H, px, py):
        x = np.clip(px, 0, 1) * (W - 1)
        y = np.clip(py, 0, 1) * (H - 1)
        ix = np.minimum(x.astype(np.int64), W - 2)
        iy = np.minimum(y.astype(np.int64), H - 2)
        fx, fy = x - ix, y - iy
        t = lambda yy, xx: self.vt(0, r0 + yy, xx)
        return ((1 - fy) * ((1 - fx) * t(iy, ix) + fx * t(iy, ix + 1)) +
                fy * ((1 - fx) * t(iy + 1, ix) + fx * t(iy + 1, ix + 1)))


def um(L, V):
    m = L + V
    m = m / norm(m)[:, None]
    y = (azim(m) - azim(V) + np.pi) / (2 * np.pi)
    return np.sqrt(elev(m) * (2 / np.pi)), y - np.floor(y)


def vndf_coords(L, V, dv, src):
    vd = VNDF
    k, w = vd.vslice(elev(V))
    sx, sy = vd.invert(*um(L, V), k, w)
    return ((k + w + 0.5) / vd.vn, np.full(len(L), 0.5), (sx * (vd.cw - 1) + 0.5) / vd.cw,
            (sy * (vd.ch - 1) + 0.5) / vd.ch)


def vndf_gain(L, V):
    vd = VNDF
    with np.errstate(divide="ignore"):
        g = np.where(L[:, 2] >= 0.001, 1.0, 0.001 / L[:, 2])
    if vd.vjac == 0:
        return g
    u = np.sqrt(elev(V) * (2 / np.pi))
    v = (azim(V) + np.pi) / (2 * np.pi)
    return g * vd.bilin(vd.vn * vd.vh, vd.nw, vd.nh, *um(L, V)) / (
        4 * vd.bilin(vd.vn * vd.vh + vd.nh, vd.sw, vd.sh, u, v))


VNDF = None


def reconstruct(folder, L, V, terms):
    src = open(f"{folder}/sepbrdf.glsl").read()
    dv, scale = glsl_defines(src)
    rep = json.load(open(f"{folder}/report.json"))
    layout = rep["param"]
    theta_max = float(dv.get("SB_THETA_MAX", np.pi / 2))
    global VNDF
    if layout == "vndf":
        VNDF = Vndf(folder, dv, src)
    g = tex_stack(folder, "g", terms)
    h = tex_stack(folder, "h", terms)
    a, b, c, d = coords(layout, L, V, theta_max, dv, src)
    G = texture(g, a, b, dv["SB_WRAP_G_S"] == "1", dv["SB_WRAP_G_T"] == "1")
    Hh = texture(h, c, d, dv["SB_WRAP_H_S"] == "1", dv["SB_WRAP_H_T"] == "1")
    if dv.get("SB_EDGE_H_S") == "1":
        nw = h.shape[2]
        e = np.minimum(c * nw - 0.5, nw - 0.5) - (nw - 1)
        last = texture(h, np.full_like(c, (nw - 0.5) / nw), d, False, dv["SB_WRAP_H_T"] == "1")
        bef = texture(h, np.full_like(c, (nw - 1.5) / nw), d, False, dv["SB_WRAP_H_T"] == "1")
        sel = (e > 0)[None, :, None]
        Hh = np.where(sel, last + (last - bef) * e[None, :, None], Hh)
    prods = G * Hh * scale[:terms, None, None]
    sums = np.cumsum(prods, 0)  # prefix J' = 1..terms
    if dv.get("SB_CLAMP", "1") == "1" or "SB_GAIN" in dv:
        sums = np.maximum(sums, 0)
    if "SB_GAIN" in dv:
        sums = sums * vndf_gain(L, V)[None, :, None]
    form = int(dv["SB_FORM"])
    if form == 1:
        sums = sums / np.maximum(L[:, 2], 0.001)[None, :, None]
    elif form == 2:
        sums = sums / (np.maximum(L[:, 2], 0.001) * np.maximum(V[:, 2], 0.001))[None, :, None]
    inside = (L[:, 2] > 0) & (V[:, 2] > 0)
    inside &= np.arctan2(norm(L[:, :2]), L[:, 2]) <= theta_max
    inside &= np.arctan2(norm(V[:, :2]), V[:, 2]) <= theta_max
    return np.where(inside[None, :, None], sums, 0), rep


def model(spec, L, V):
    name, _, rest = spec.partition(":")
    kv = dict(p.split("=") for p in rest.split(",") if p)

    def rgb(k, dflt):
        v = kv.get(k)
        if v is None:
            return np.array([dflt] * 3)
        p = [float(x) for x in v.split("/")]
        return np.array(p * 3 if len(p) == 1 else p)
    ci, co = L[:, 2], V[:, 2]
    if name == "lambert":
        return np.broadcast_to(rgb("albedo", 0.8) / np.pi, (len(L), 3)).copy()
    if name == "phong":
        n = float(kv.get("n", 20))
        r = np.stack([-L[:, 0], -L[:, 1], L[:, 2]], -1)
        rv = np.maximum((r * V).sum(1), 0)
        gd = float(kv.get("guard", 0.001))
        return rgb("kd", 0.5) + rgb("ks", 0.5) * (rv**n / np.maximum(ci, gd))[:, None]
    if name == "cook-torrance":
        assert kv.get("d", "ggx") == "ggx" and kv.get("g", "smith-schlick") == "smith-schlick"
        r = float(kv.get("roughness", 0.5))
        al = r * r
        s = L + V
        H = s / norm(s)[:, None]
        nh = H[:, 2]
        D = al**2 / (np.pi * (nh**2 * (al**2 - 1) + 1)**2)
        k = (r + 1)**2 / 8
        # Smith-Schlick G / (4 n.l n.v): the cosines cancel
        Gd = 1 / (4 * (ci * (1 - k) + k) * (co * (1 - k) + k))
        f0 = rgb("f0", 0.04)
        vh = np.clip((V * H).sum(1), 0, 1)
        F = f0 + (1 - f0) * ((1 - vh)**5)[:, None]
        return (rgb("kd", 0.5) * rgb("albedo", 0.8) / np.pi +
                rgb("ks", 0.5) * F * (D * Gd)[:, None])
    if name == "blinn-phong":
        s = L + V
        nh = np.maximum((s / norm(s)[:, None])[:, 2], 0)
        return rgb("kd", 0.5) + rgb("ks", 0.5) * (nh**float(kv.get("n", 20)))[:, None]
    if name == "microfacet":  # `sepbrdf list`: GGX D, Schlick-GGX G (Disney k), Schlick F
        assert float(kv.get("anisotropy", 0)) == 0, "anisotropic microfacet: not transcribed"
        r = float(kv.get("roughness", 0.5))
        al, k, gd = r * r, ((1 + r) / 2)**2 / 2, float(kv.get("guard", 0.001))
        met, base = float(kv.get("metallic", 0)), rgb("base", 0.5)
        f0 = (1 - met) * 0.16 * float(kv.get("reflectance", 0.5))**2 + met * base
        s = L + V
        H = s / norm(s)[:, None]
        D = al**2 / (np.pi * (H[:, 2]**2 * (al**2 - 1) + 1)**2)
        G = (np.maximum(ci, gd) / (ci * (1 - k) + k)) * (np.maximum(co, gd) / (co * (1 - k) + k))
        vh = np.clip((V * H).sum(1), 0, 1)
        F = f0 + (1 - f0) * ((1 - vh)**5)[:, None]
        spec = F * (D * G / (4 * np.maximum(ci, gd) * np.maximum(co, gd)))[:, None]
        return spec + (1 - F) * (1 - met) * base / np.pi
    raise SystemExit(f"model {name}: not transcribed")


def hemi(rng, n):
    """uniform on the upper hemisphere: pdf 1/(2 pi)."""
    z = rng.random(n)
    p = 2 * np.pi * rng.random(n)
    s = np.sqrt(1 - z * z)
    return np.stack([s * np.cos(p), s * np.sin(p), z], -1)


CONES = (np.radians(1.0), np.radians(5.0), np.radians(20.0))


def draw_pairs(rng, n):
    """L uniform on the hemisphere; V from 0.4 uniform + 0.2 each of cones of
    1, 5, 20 degrees about L's mirror direction.  Returns L, V and the weight
    (uniform pdf) / (mixture pdf), 0 where V is below the horizon."""
    L = hemi(rng, n)
    r = np.stack([-L[:, 0], -L[:, 1], L[:, 2]], -1)
    V = hemi(rng, n)
    pick = rng.random(n)
    # an orthonormal frame about r
    a = np.where(np.abs(r[:, :1]) < 0.9, [[1.0, 0, 0]], [[0, 1.0, 0]])
    t = np.cross(r, a)
    t /= norm(t)[:, None]
    b = np.cross(r, t)
    for i, c in enumerate(CONES):
        sel = (pick >= 0.4 + 0.2 * i) & (pick < 0.6 + 0.2 * i)
        m = sel.sum()
        cz = 1 - rng.random(m) * (1 - np.cos(c))
        ph = 2 * np.pi * rng.random(m)
        sz = np.sqrt(1 - cz * cz)
        V[sel] = ((sz * np.cos(ph))[:, None] * t[sel] + (sz * np.sin(ph))[:, None] * b[sel] +
                  cz[:, None] * r[sel])
    cosr = np.clip((r * V).sum(1), -1, 1)
    q = 0.4 / (2 * np.pi) * np.ones(n)
    for c in CONES:
        q += 0.2 * (cosr >= np.cos(c)) / (2 * np.pi * (1 - np.cos(c)))
    wgt = np.where(V[:, 2] > 0, (1 / (2 * np.pi)) / q, 0)
    V[:, 2] = np.maximum(V[:, 2], 1e-12)  # weight 0 below: any direction
    V /= norm(V)[:, None]
    return L, V, wgt


def main():
    global REF
    folder = sys.argv[1]
    REF = __import__("os").environ.get("EVAL_REF")
    pairs = int(sys.argv[2]) if len(sys.argv) > 2 else 400000
    rng = np.random.default_rng(int(sys.argv[3]) if len(sys.argv) > 3 else 1)
    rep = json.load(open(f"{folder}/report.json"))
    terms = rep["terms"]
    spec = rep["source"]
    if isinstance(rep.get("measured"), dict) and not REF:  # no model to transcribe (was a ValueError)
        print(f"{folder}: {spec}: a measured table; this evaluator transcribes the analytic models only: "
              "give EVAL_REF=DIR, a set of the same file that reproduces it (an RGL file's vndf at J = slices)")
        return 2
    scene = rep.get("scene")  # its figures are the scene's; the pairs drawn here cover the whole hemisphere
    if scene:
        print(f"{folder}: a scene fit ({scene.get('spec')}): the headline is compared with report.json's "
              "scene.domain_headline (the whole domain), the bands are not (the report's are the scene's)")
    batches, num, den = 20, [], []
    cone = np.radians(rep["bands"]["cone_deg"])
    keys = ["headline", "theta_i_60", "theta_o_60", "specular", "theta_i_80", "theta_i_89"]
    neg = np.zeros(terms)  # the most negative channel where f > 0, over the largest |f| drawn
    fmax = 0.0
    for _ in range(batches):
        L, V, wgt = draw_pairs(rng, pairs // batches)
        if REF:  # a measured file: the reference set (vndf at J = slices: the file)
            refrep = json.load(open(f"{REF}/report.json"))
            f = reconstruct(REF, L, V, refrep["terms"])[0][-1]
        else:
            f = model(spec, L, V)
        ft, _ = reconstruct(folder, L, V, terms)
        q = L[:, 2]**2 * wgt
        if rep["estimate"].get("domain") == "cap":  # --theta-max: both directions within the cap
            tm = float(rep["param_spec"].split("theta_max=")[1].split(",")[0]) if "theta_max=" in rep[
                "param_spec"] else 90.0
            q = q * ((L[:, 2] >= np.cos(np.radians(tm))) & (V[:, 2] >= np.cos(np.radians(tm))))
        e2 = ((ft - f[None])**2).sum(-1) * q[None]
        f2 = (f**2).sum(-1) * q
        r = np.stack([-L[:, 0], -L[:, 1], L[:, 2]], -1)
        masks = [np.ones(len(L), bool), np.arccos(L[:, 2]) > np.radians(60),
                 np.arccos(V[:, 2]) > np.radians(60),
                 np.arccos(np.clip((r * V).sum(1), -1, 1)) < cone,
                 np.arccos(L[:, 2]) > np.radians(80), np.arccos(L[:, 2]) > np.radians(89)]
        live = (wgt > 0)[:, None] & (f > 0)
        neg = np.minimum(neg, np.where(live[None], ft, 0).min(axis=(1, 2)))
        fmax = max(fmax, float(np.abs(f[wgt > 0]).max()))
        num.append([[(e2[j] * m).sum() for m in masks] for j in range(terms)])
        den.append([(f2 * m).sum() for m in masks])
    num, den = np.array(num), np.array(den)  # (B, J, K), (B, K)
    with np.errstate(invalid="ignore", divide="ignore"):  # a band beyond a cap: empty, read as 0
        ratio = np.nan_to_num(np.sqrt(num.sum(0) / den.sum(0)[None]))
        # jackknife standard error over the batches
        jk = np.nan_to_num(np.array([np.sqrt((num.sum(0) - num[i]) / (den.sum(0) - den[i])[None])
                                     for i in range(batches)]))
    se = np.sqrt((batches - 1) / batches * ((jk - jk.mean(0))**2).sum(0))
    bad = 0
    print(f"{folder}: {rep['param_spec'][:60]} form {rep['form']} storage "
          f"{rep['storage']} J = {terms}, {pairs} pairs")
    for j in range(terms):
        e = rep["errors"][j]
        theirs = [e["headline"]] + [e["band_rel"][k] for k in keys[1:]]
        their_se = [e["headline_se"]] + [e["band_rel_se"][k] for k in keys[1:]]
        if scene:
            theirs[0], their_se[0] = scene["domain_headline"][j], scene["domain_headline_se"][j]
        cells = []
        for k in range(1 if scene else len(keys)):
            ok = abs(ratio[j, k] - theirs[k]) <= max(4 * np.hypot(se[j, k], their_se[k]),
                                                    0.02 * theirs[k])
            bad += not ok
            # issue 33's criterion: within 10 % or two combined standard errors
            ok33 = abs(ratio[j, k] - theirs[k]) <= max(2 * np.hypot(se[j, k], their_se[k]),
                                                       0.1 * theirs[k])
            cells.append(f"{keys[k]} {ratio[j, k]:.4g}±{se[j, k]:.2g} vs {theirs[k]:.4g}"
                         f"±{their_se[k]:.2g}" + ("" if ok else " DIFFERS") + ("" if ok33 else " (>10%/2se)"))
        print(f"  J'={j + 1}: " + "; ".join(cells) + f"; negative {neg[j] / fmax:.3g}")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
