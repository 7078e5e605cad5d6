"""The factor job's options: factor()'s keyword arguments (the CLI's
options, '-' written '_') checked with the CLI's ranges and turned into an
sb_job_opts_t (job.h)."""

import ctypes
import os

import numpy as np

from . import _lib
from ._lib import lib


def _b(s):
    return None if s is None else os.fsencode(s) if isinstance(s, os.PathLike) else str(s).encode()


def _parse_enum(fn, value, what, names):
    out = ctypes.c_int()
    if fn(_b(value), ctypes.byref(out)) != 0:
        raise ValueError(f"{what} '{value}' unknown, need one of {names}")
    return out.value


def _measured_opts(interp=None, neighbours=None, radius=None, white=None, gamut=None, lobe=None):
    mo = _lib.MeasuredOpts()
    if interp is not None:
        mo.interp = _parse_enum(lib.sb_interp_parse, interp, "interp", "nearest, linear, idw, quadratic")
    if neighbours is not None:
        if not 1 <= int(neighbours) <= 64:
            raise ValueError(f"neighbours {neighbours}: need 1..64")
        mo.neighbours = int(neighbours)
    if radius is not None:
        if not 1e-6 <= float(radius) <= 360:
            raise ValueError(f"radius {radius}: need 1e-6..360 degrees")
        mo.radius = float(radius) * np.pi / 180
    if white is not None:
        if white not in ("e", "d65"):
            raise ValueError(f"white '{white}' unknown, need e or d65")
        mo.white = 0 if white == "e" else 1
    if gamut is not None:
        mo.gamut = _parse_enum(lib.sb_gamut_parse, gamut, "gamut", "keep, clip, desaturate")
    if lobe is not None:
        mo.lobe = _parse_enum(lib.sb_lobe_mode_parse, lobe, "lobe", "auto, off, on")
    return mo


_UNITS = {"": 1, "B": 1, "K": 1024, "Ki": 1024, "KiB": 1024, "k": 1024, "kB": 1000, "KB": 1000}
_UNITS.update({"M": 1 << 20, "Mi": 1 << 20, "MiB": 1 << 20, "MB": 10**6})
_UNITS.update({"G": 1 << 30, "Gi": 1 << 30, "GiB": 1 << 30, "GB": 10**9})


def _bytes(v):
    if isinstance(v, (int, np.integer)) and v >= 1:
        return int(v)
    s = str(v).strip()
    num = s.rstrip("BKMGikb")
    unit = s[len(num) :]
    try:
        x = float(num) * _UNITS[unit]
    except (ValueError, KeyError):
        x = 0
    if not 1 <= x < 2**52 or num.startswith(("-", "+")):
        raise ValueError(f"budget '{v}': need a positive size in bytes, e.g. 3200, '16K', '48KiB', '1M'")
    return int(x)


def _channels(v):
    if isinstance(v, str):
        v = [c for c in v if c != ","]
    bits = 0
    for c in v:
        if str(c).upper() not in ("R", "G", "B"):
            raise ValueError(f"channels: '{c}' is not R, G or B")
        bits |= 1 << "RGB".index(str(c).upper())
    if not bits:
        raise ValueError("channels: none given (need R, G and/or B)")
    return bits


def _number(name, v, lo, hi, kind=float):
    x = kind(v)
    if not lo <= x <= hi:
        raise ValueError(f"{name} {v}: need {lo}..{hi}")
    return x


def _job_opts(o, source_spec):
    """sb_job_opts_t from factor()'s keyword arguments (the CLI's options,
    '-' written '_'), with the CLI's ranges."""
    jo = _lib.JobOpts()
    jo.size = ctypes.sizeof(_lib.JobOpts)
    keep = []  # the encoded strings, alive as long as jo

    def s(v):
        keep.append(_b(v))
        return keep[-1]

    jo.source = s(source_spec)
    jo.measured = _measured_opts(
        *(o.pop(k, None) for k in ("interp", "neighbours", "radius", "white", "gamut", "lobe"))
    )
    for k in ("param", "form", "warp", "scene", "shader"):
        v = o.pop(k, None)
        if v is not None:
            setattr(jo, "shaders" if k == "shader" else k, s(v))
    if jo.form is not None:
        _parse_enum(lib.sb_form_parse, jo.form.decode(), "form", "f, cos, cos2")
    w = o.pop("weighted", None)  # None: as auto (weighted); False: unweighted (--unweighted)
    jo.weighted = 0 if w is None else (1 if w else -1)
    for k in ("zero_fill", "plain_terms", "half", "previews"):
        setattr(jo, k, 1 if o.pop(k, False) else 0)
    if "terms" in o:
        jo.terms = _number("terms", o.pop("terms"), 1, 1 << 30, int)
    if "res" in o:
        jo.res = _number("res", o.pop("res"), 2, 512, int)
    if "metric_res" in o:
        jo.metric_res = _number("metric_res", o.pop("metric_res"), 2, 512, int)
    if "max_error" in o:
        jo.max_error = _number("max_error", o.pop("max_error"), 1e-15, 0.999999)
    if "theta_max" in o:
        jo.theta_max_deg = _number("theta_max", o.pop("theta_max"), 1, 90)
    if "seed" in o:
        jo.seed = int(o.pop("seed")) or 1
    if "method" in o:
        names = ", ".join(lib.sb_method_name(m).decode() for m in range(lib.sb_method_count()))  # the registry's
        jo.method = _parse_enum(lib.sb_method_parse, o.pop("method"), "method", names)
    if "channels" in o:
        jo.channels = _channels(o.pop("channels"))
    if "budget" in o:
        jo.budget = _bytes(o.pop("budget"))
    if "cv_folds" in o:
        jo.cv_folds = _number("cv_folds", o.pop("cv_folds"), 1, 100, int)
    if o:
        raise TypeError(f"factor() got unknown option(s) {', '.join(sorted(o))}")
    return jo, keep
