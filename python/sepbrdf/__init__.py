"""sepbrdf from Python: factor a BRDF into texture pairs g_j(wi), h_j(wo),

    f_r(wi, wo) ~ sum_j g_j(wi) . h_j(wo),

with the C library that the `sepbrdf` command runs, and numpy arrays in and
out.

    import sepbrdf
    fac = sepbrdf.factor("microfacet:base=gold,roughness=0.5", terms=4)
    fac.g.shape            # (J, height, width, channels), float64
    fac.report["errors"]   # report.json as a dict
    fac.eval(wi, wo)       # the reconstruction, arrays of unit directions
    fac.write("out")       # the same files as `sepbrdf factor -o out`

Directions are unit vectors in the local shading frame (z the normal), both
pointing away from the surface: wi towards the light, wo towards the
viewer.  f_r is RGB in 1/sr.  Failures raise sepbrdf.Error with the
library's message."""

import ctypes
import json
import os
import threading

import numpy as np

from . import _lib
from ._lib import lib
from ._options import _b, _job_opts, _measured_opts

__all__ = ["Error", "Source", "Factorisation", "factor", "read", "version"]

DEFAULT_SOURCE = "microfacet:base=gold,roughness=0.5"
"""The source of a factorisation that names none (as the CLI's)."""


def version():
    """The package's version, which is the C library's: "MAJOR.MINOR.PATCH"."""
    return lib.sb_version().decode()


class Error(Exception):
    """A failure reported by the library.

    Attributes: code, the library's result code by name (e.g.
    "SB_ERR_UNKNOWN"); message, its detailed message (e.g. "unknown model
    'foo'")."""

    def __init__(self, code, message):
        self.code = code
        self.message = message
        super().__init__(message)


class _Context:
    """An sb_context_t for one call, turning result codes into Error."""

    def __init__(self):
        ptr = ctypes.c_void_p()
        if lib.sb_context_create(ctypes.byref(ptr)) != 0:
            raise MemoryError("sepbrdf: cannot create a context")
        self.ptr = ptr

    def close(self):
        lib.sb_context_destroy(self.ptr)
        self.ptr = None

    def check(self, r, what=None):
        if r == 0:
            return
        code = _lib.RESULT_NAMES[r] if 0 <= r < len(_lib.RESULT_NAMES) else str(r)
        msg = (lib.sb_context_last_error(self.ptr) or b"").decode("utf-8", "replace")
        if not msg:
            msg = lib.sb_result_message(r).decode()
        raise Error(code, f"{what}: {msg}" if what else msg)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


def _dirs(a, name):
    a = np.asarray(a, dtype=np.float64)
    if a.shape[-1:] != (3,):
        raise ValueError(f"{name}: need directions of shape (..., 3), got {a.shape}")
    return a


# ---- sources -----------------------------------------------------------------


class Source:
    """A BRDF: an analytic model, a measured table, or a Python function.

    Source(spec) opens a model spec "MODEL[:key=value,...]" (as `sepbrdf
    list` names them) or a measured file (MERL .binary, RGL .bsdf, Cornell
    .brdf, scattered tables ...).  Keyword arguments set how a measured
    table is interpolated, as the CLI's options of the same names: interp
    ("nearest", "linear", "idw", "quadratic"), neighbours (1..64), radius
    (degrees), white ("e" or "d65"), gamut ("keep", "clip",
    "desaturate") and lobe ("auto", "off", "on").  Source.from_function(f) wraps a Python function."""

    def __init__(self, spec=None, *, interp=None, neighbours=None, radius=None, white=None, gamut=None, lobe=None):
        self.spec = str(spec) if spec is not None else DEFAULT_SOURCE
        self._keep = None
        self._errors = []
        mo = _measured_opts(interp, neighbours, radius, white, gamut, lobe)
        ptr = ctypes.c_void_p()
        with _Context() as ctx:
            ctx.check(lib.sb_job_source_open(ctx.ptr, _b(self.spec), ctypes.byref(mo), ctypes.byref(ptr)))
        self._ptr = ptr

    @classmethod
    def from_function(
        cls, f, *, isotropic=False, reciprocal=False, gray=False, description="python function"
    ):
        """A source whose f_r(wi, wo) is the Python function f, evaluated in batches.

        f takes two float64 arrays of unit directions of shape (n, 3) (wi
        towards the light, wo towards the viewer, local frame, z the normal)
        and returns f_r in 1/sr as an array of shape (n, 3) (RGB) or (n,)
        (grey); a non-finite value marks a pair as unknown (excluded from
        the fit, as an unmeasured cell).  The library passes whole batches:
        a column of the sampled matrix, a replicate of the error
        estimator's pairs, a line of the warp scan (n from tens to
        thousands; n = 1 where it asks for one pair), from its worker
        threads, each call under the GIL.  Declare the symmetries that
        hold, so that the library may use them: isotropic (depends on
        phi_o - phi_i only), reciprocal (f(wi, wo) == f(wo, wi)), gray
        (R == G == B).  An exception raised by f is raised again by the call
        that used the source."""
        self = cls.__new__(cls)
        self.spec = description
        self._errors = []
        lock = threading.Lock()

        def many_cb(_self, n, wi, wo, rgb, known):
            out = np.ctypeslib.as_array(rgb, (n, 3))
            ok = np.ctypeslib.as_array(known, (n,))
            try:
                a = np.ctypeslib.as_array(wi, (n, 3)).copy()
                b = np.ctypeslib.as_array(wo, (n, 3)).copy()
                v = np.asarray(f(a, b), dtype=np.float64)
                if v.shape == (n,):
                    v = np.repeat(v[:, None], 3, axis=1)
                elif v.shape != (n, 3) and n == 1 and v.size == 3:
                    v = v.reshape(1, 3)
                if v.shape != (n, 3):
                    raise ValueError(f"the function returned shape {v.shape} for {n} pairs, need ({n}, 3) or ({n},)")
                finite = np.isfinite(v).all(axis=1)
                out[:] = np.where(finite[:, None], v, 0.0)
                ok[:] = finite
            except BaseException as e:  # noqa: B036 - kept and raised by the caller
                with lock:
                    if not self._errors:
                        self._errors.append(e)
                out[:] = 0.0
                ok[:] = 0

        ops = _lib.SourceBatchOps(_lib.EVAL_MANY_FN(many_cb), _lib.DESTROY_FN(0))
        flags = (
            (_lib.SOURCE_ISOTROPIC if isotropic else 0)
            | (_lib.SOURCE_RECIPROCAL if reciprocal else 0)
            | (_lib.SOURCE_GRAY if gray else 0)
        )
        ptr = ctypes.c_void_p()
        with _Context() as ctx:
            r = lib.sb_source_create_batched(
                ctx.ptr, ctypes.byref(ops), None, flags, _b(description), ctypes.byref(ptr)
            )
            ctx.check(r)
        self._keep = (ops, many_cb)  # the C side holds pointers into these
        self._ptr = ptr
        return self

    def __del__(self):
        if getattr(self, "_ptr", None):
            lib.sb_source_destroy(self._ptr)
            self._ptr = None

    def _raise_pending(self):
        if self._errors:
            e = self._errors[0]
            self._errors.clear()
            raise e

    @property
    def description(self):
        """What the library says the source is (model and parameters, or the table's description)."""
        return lib.sb_source_description(self._ptr).decode("utf-8", "replace")

    @property
    def isotropic(self):
        """Whether f_r depends on phi_o - phi_i only."""
        return bool(lib.sb_source_flags(self._ptr) & _lib.SOURCE_ISOTROPIC)

    @property
    def reciprocal(self):
        """Whether f_r(wi, wo) == f_r(wo, wi)."""
        return bool(lib.sb_source_flags(self._ptr) & _lib.SOURCE_RECIPROCAL)

    @property
    def measured(self):
        """Whether the source is a measured table (some pairs may be unknown)."""
        return bool(lib.sb_source_flags(self._ptr) & _lib.SOURCE_MEASURED)

    def eval(self, wi, wo):
        """f_r(wi, wo) in 1/sr for arrays of unit directions of shape
        (..., 3) (broadcast against each other): returns (rgb, known), rgb
        of shape (..., 3) and known a boolean array of shape (...) (False
        where a table has no value; rgb is 0 there)."""
        wi, wo = np.broadcast_arrays(_dirs(wi, "wi"), _dirs(wo, "wo"))
        shape = wi.shape[:-1]
        a = np.ascontiguousarray(wi.reshape(-1, 3))
        b = np.ascontiguousarray(wo.reshape(-1, 3))
        out = np.zeros_like(a)
        known = np.zeros(len(a), dtype=bool)
        pa, pb, po = a.ctypes.data, b.ctypes.data, out.ctypes.data
        for i in range(len(a)):
            known[i] = lib.sb_source_eval(self._ptr, pa + 24 * i, pb + 24 * i, po + 24 * i) != 0
        self._raise_pending()
        return out.reshape(shape + (3,)), known.reshape(shape)


# ---- factorisations ----------------------------------------------------------


def _texture_array(f, side):
    terms, channels = lib.sb_factors_terms(f), lib.sb_factors_channels(f)
    w, h = ctypes.c_size_t(), ctypes.c_size_t()
    lib.sb_factors_size(f, side, ctypes.byref(w), ctypes.byref(h))
    out = np.empty((terms, h.value, w.value, channels))
    for j in range(terms):
        for c in range(channels):
            p = lib.sb_factors_tex_const(f, side, j, c)
            out[j, :, :, c] = np.ctypeslib.as_array(p, (h.value * w.value,)).reshape(h.value, w.value)
    return out


def _report(job):
    buf, size = ctypes.c_void_p(), ctypes.c_size_t()
    fp = _lib.libc.open_memstream(ctypes.byref(buf), ctypes.byref(size))
    if not fp:
        raise MemoryError("sepbrdf: cannot open a memory stream for the report")
    lib.sb_job_report(job, fp)
    _lib.libc.fclose(fp)
    try:
        return json.loads(ctypes.string_at(buf, size.value).decode("utf-8"))
    finally:
        _lib.libc.free(buf)


class Factorisation:
    """Texture pairs g_j, h_j of a BRDF, from factor() or read().

    Attributes:
      g, h      float64 arrays (J, height, width, channels): texture j of the
                row side (g, the light's side on io layouts) and the column
                side (h), texel (x, y) at [j, y, x, c], as in g_JJ.exr
      sigma     (J, channels): the weight of each term (singular values)
      param     the parameterisation's spec (report.json's param_spec)
      form      what was factored: "f", "cos" or "cos2"
      report    report.json's content as a dict (None for a set read from a
                folder without one)
      warnings  the run's warnings (list of str)"""

    def __init__(self):
        raise TypeError("use sepbrdf.factor() or sepbrdf.read()")

    @classmethod
    def _from(cls, factors, param, form, job=None, source=None, report=None, warnings=(), keep=None):
        self = cls.__new__(cls)
        self._job, self._source = job, source
        self._keep = keep  # the job's option strings: the job refers to them until it is destroyed
        self._factors, self._param, self._form = factors, param, form
        self._owned = job is None  # factors and param read from files are ours to free
        self._sampler = None
        self.g = _texture_array(factors, _lib.SIDE_G)
        self.h = _texture_array(factors, _lib.SIDE_H)
        J, C = self.g.shape[0], self.g.shape[3]
        self.sigma = np.array([[lib.sb_factors_sigma(factors, j, c) for c in range(C)] for j in range(J)])
        self.param = lib.sb_param_spec(param).decode()
        self.form = lib.sb_form_name(form).decode()
        self.report = report
        self.warnings = list(warnings)
        return self

    def __del__(self):
        if getattr(self, "_sampler", None):
            lib.sb_sampler_destroy(self._sampler)
        if getattr(self, "_owned", False):
            lib.sb_factors_destroy(self._factors)
            lib.sb_param_destroy(self._param)
        if getattr(self, "_job", None):
            lib.sb_job_destroy(self._job)
        self._job = self._sampler = None
        self._owned = False

    def __repr__(self):
        return f"<sepbrdf.Factorisation {self.param} form {self.form}, J = {self.terms}>"

    @property
    def terms(self):
        """J, the number of texture pairs."""
        return self.g.shape[0]

    def headline(self, terms=None):
        """The headline error (relative L2 of f cos theta_i, as a shader
        returns it, estimated on random pairs) after `terms` terms (default
        all); None for a set read from a folder without report.json."""
        terms = self.terms if terms is None else int(terms)
        if self._job is not None:
            return lib.sb_job_headline(self._job, terms)
        if self.report:
            for e in self.report.get("errors", []):
                if e.get("terms") == terms:
                    return e.get("headline")
        return None

    def eval(self, wi, wo, terms=None):
        """The reconstruction sum_j g_j(wi) h_j(wo), divided back by the
        form's cosines, exactly as the C library and the GLSL snippet
        evaluate it (bilinear texture lookups), for arrays of unit
        directions of shape (..., 3) broadcast against each other; returns
        RGB of shape (..., 3), 0 outside the domain.  terms: the first J'
        terms only (default all)."""
        terms = self.terms if terms is None else int(terms)
        if not 1 <= terms <= self.terms:
            raise ValueError(f"terms {terms}: need 1..{self.terms}")
        wi, wo = np.broadcast_arrays(_dirs(wi, "wi"), _dirs(wo, "wo"))
        shape = wi.shape[:-1]
        a = np.ascontiguousarray(wi.reshape(-1, 3))
        b = np.ascontiguousarray(wo.reshape(-1, 3))
        out = np.zeros_like(a)
        pa, pb, po = a.ctypes.data, b.ctypes.data, out.ctypes.data
        f, p, form, ev = self._factors, self._param, self._form, lib.sb_factors_eval
        for i in range(len(a)):
            ev(f, p, form, terms, pa + 24 * i, pb + 24 * i, po + 24 * i)
        return out.reshape(shape + (3,))

    def _get_sampler(self):
        if self._sampler is None:
            s = ctypes.c_void_p()
            with _Context() as ctx:
                r = lib.sb_sampler_create(ctx.ptr, self._factors, self._param, self._form, ctypes.byref(s))
                ctx.check(r, "sample")
            self._sampler = s
        return self._sampler

    def sample(self, wo, u):
        """Importance-sample light directions for viewing directions wo
        (..., 3) from uniform numbers u (..., 2) in [0, 1), with the
        factored sampler (non-negative factors only: factor with
        method="nmf"; others raise Error).  Returns (wi, pdf, rgb, ok):
        wi (..., 3) unit, pdf (...) in 1/sr, rgb (..., 3) the reconstruction
        at (wi, wo), ok (...) False where no direction resulted (then all
        zero)."""
        s = self._get_sampler()
        wo = _dirs(wo, "wo")
        u = np.asarray(u, dtype=np.float64)
        if u.shape[-1:] != (2,):
            raise ValueError(f"u: need shape (..., 2), got {u.shape}")
        shape = np.broadcast_shapes(wo.shape[:-1], u.shape[:-1])
        a = np.ascontiguousarray(np.broadcast_to(wo, shape + (3,)).reshape(-1, 3))
        b = np.ascontiguousarray(np.broadcast_to(u, shape + (2,)).reshape(-1, 2))
        n = len(a)
        wi, rgb = np.zeros((n, 3)), np.zeros((n, 3))
        pdf, ok = np.zeros(n), np.zeros(n, dtype=bool)
        pa, pb, pw, pp, pr = (x.ctypes.data for x in (a, b, wi, pdf, rgb))
        for i in range(n):
            ok[i] = lib.sb_sample(s, pa + 24 * i, pb + 16 * i, pw + 24 * i, pp + 8 * i, pr + 24 * i) != 0
        return wi.reshape(shape + (3,)), pdf.reshape(shape), rgb.reshape(shape + (3,)), ok.reshape(shape)

    def pdf(self, wo, wi):
        """The density (1/sr, solid angle) with which sample() draws wi for
        wo, arrays of shape (..., 3); 0 outside the domain."""
        s = self._get_sampler()
        wo, wi = np.broadcast_arrays(_dirs(wo, "wo"), _dirs(wi, "wi"))
        shape = wo.shape[:-1]
        a = np.ascontiguousarray(wo.reshape(-1, 3))
        b = np.ascontiguousarray(wi.reshape(-1, 3))
        pa, pb = a.ctypes.data, b.ctypes.data
        return np.array([lib.sb_pdf(s, pa + 24 * i, pb + 24 * i) for i in range(len(a))]).reshape(shape)

    def write(self, folder):
        """Write the output set into `folder` (created if missing), the same
        files `sepbrdf factor -o folder` writes with the same options
        (g_JJ.exr, h_JJ.exr, report.json, sepbrdf.glsl, sampler.bin for
        method="nmf", PNG previews with previews=True), published as one
        unit.  Only for results of factor(); raises Error on failure."""
        if self._job is None:
            raise Error("SB_ERR_ARG", "write: only a result of sepbrdf.factor() can be written again")
        with _Context() as ctx:
            ctx.check(lib.sb_job_write(ctx.ptr, self._job, _b(os.fspath(folder))), os.fspath(folder))
        self.report = _report(self._job)  # with the stored errors the write measured


def read(folder):
    """Read an output set written by `sepbrdf factor` or
    Factorisation.write(): the textures, the parameterisation and form
    from their headers, and report.json when present.  Returns a
    Factorisation (its eval, sample and pdf work as on a fresh one);
    raises Error (e.g. SB_ERR_IO for a missing folder)."""
    folder = os.fspath(folder)
    f, p, form = ctypes.c_void_p(), ctypes.c_void_p(), ctypes.c_int()
    with _Context() as ctx:
        ctx.check(lib.sb_factors_read_exr(ctx.ptr, _b(folder), ctypes.byref(f)), folder)
        r = lib.sb_factors_param(ctx.ptr, f, ctypes.byref(p), ctypes.byref(form))
        if r != 0:
            lib.sb_factors_destroy(f)
            ctx.check(r, folder)
    report = None
    path = os.path.join(folder, "report.json")
    if os.path.exists(path):
        with open(path, encoding="utf-8") as fp:
            report = json.load(fp)
    return Factorisation._from(f, p, form.value, report=report)


# ---- the factor job ----------------------------------------------------------


def factor(source=None, *, progress=None, **options):
    """Factor a BRDF as `sepbrdf factor` does, and return a Factorisation.

    source: a model spec or measured file (str or path; default
    DEFAULT_SOURCE, the gold microfacet), a Source, or a Python function
    f(wi, wo) -> rgb (see Source.from_function; a function is taken as
    anisotropic and non-reciprocal: wrap it in Source.from_function to
    declare its symmetries).

    Options, the CLI's with '-' written '_' (docs/guide.md, `sepbrdf factor
    --help`): terms (-J), res (-r), param ("auto", a kind such as "iso", or
    a whole spec "iso:th=64,td=62,pd=16"), form ("f", "cos", "cos2"), warp
    ("uniform", "merl", "adaptive", "auto"), weighted (None: as auto, solid
    angle; True; False: --unweighted), scene, zero_fill,
    plain_terms, metric_res, method ("auto", "full", "topk", "randomized",
    "nmf", "stream"), max_error, channels ("R,B" or ["R", "B"]), theta_max
    (degrees), seed, half, budget (bytes: 16384 or "16K"), previews, shader
    (the snippet also in "hlsl", "msl", "wgsl" or "all": sepbrdf.hlsl,
    sepbrdf.metal, sepbrdf.wgsl beside sepbrdf.glsl in write()), and for
    measured tables interp,
    neighbours, radius (degrees), white, gamut, lobe, cv_folds (scattered tables:
    the folds of the cross-validated error, report["errors"][j]["cv_headline"]).
    progress: None or a function progress(label, fraction) called as the
    job goes on (on the calling thread).

    The call releases the GIL while the library works.  Raises Error with
    the library's message (a bad spec: code SB_ERR_UNKNOWN or
    SB_ERR_PARSE), ValueError for an option value out of its range,
    TypeError for an unknown option."""
    src = None
    if callable(source) and not isinstance(source, Source):
        src = Source.from_function(source)
    elif isinstance(source, Source):
        src = source
    spec = src.spec if src is not None else (os.fspath(source) if source is not None else None)
    jo, keep = _job_opts(dict(options), spec)
    if progress is not None:

        def cb(_user, label, fraction):
            progress(label.decode(), fraction)

        jo.progress = _lib.PROGRESS_FN(cb)
        keep.append(jo.progress)
    job = ctypes.c_void_p()
    with _Context() as ctx:
        if src is None:
            r = lib.sb_job_run(ctx.ptr, ctypes.byref(jo), ctypes.byref(job))
        else:
            r = lib.sb_job_run_source(ctx.ptr, src._ptr, ctypes.byref(jo), ctypes.byref(job))
        if src is not None and src._errors:
            lib.sb_job_destroy(job)
            src._raise_pending()
        if r != 0:
            lib.sb_job_destroy(job)
        ctx.check(r)
    warnings = [lib.sb_job_warning(job, i).decode() for i in range(lib.sb_job_warning_count(job))]
    return Factorisation._from(
        lib.sb_job_factors(job),
        lib.sb_job_param(job),
        lib.sb_job_form(job),
        job=job,
        source=src,
        report=_report(job),
        warnings=warnings,
        keep=(jo, keep),
    )
