"""The C library behind the package: where it is found and the ctypes
prototypes of the functions the package calls (include/sepbrdf/*.h).

The library is looked up, in this order, at
  1. the path in the environment variable SEPBRDF_LIBRARY;
  2. the path written beside this file by `cmake --install` (_install.py);
  3. the system's library path (ctypes.util.find_library("sepbrdf")).
ctypes releases the GIL around every call into the library, so a long
factorisation does not hold up other Python threads."""

import ctypes
import ctypes.util
import os

c_double_p = ctypes.POINTER(ctypes.c_double)

# Every result code of common.h, by value.
RESULT_NAMES = (
    "SB_OK",
    "SB_ERR_ARG",
    "SB_ERR_RANGE",
    "SB_ERR_PARSE",
    "SB_ERR_UNKNOWN",
    "SB_ERR_NOMEM",
    "SB_ERR_OVERFLOW",
    "SB_ERR_IO",
    "SB_ERR_FORMAT",
    "SB_ERR_NUMERIC",
    "SB_ERR_UNSUPPORTED",
)
SIDE_G, SIDE_H = 0, 1
SOURCE_RECIPROCAL, SOURCE_ISOTROPIC, SOURCE_MEASURED, SOURCE_GRAY = 1, 2, 4, 8

# job.h: sb_job_progress_fn; source.h: sb_source_ops_t's functions.
PROGRESS_FN = ctypes.CFUNCTYPE(None, ctypes.c_void_p, ctypes.c_char_p, ctypes.c_double)
EVAL_FN = ctypes.CFUNCTYPE(ctypes.c_int, ctypes.c_void_p, c_double_p, c_double_p, c_double_p)
DESTROY_FN = ctypes.CFUNCTYPE(None, ctypes.c_void_p)
EVAL_MANY_FN = ctypes.CFUNCTYPE(
    None, ctypes.c_void_p, ctypes.c_size_t, c_double_p, c_double_p, c_double_p, ctypes.POINTER(ctypes.c_ubyte)
)


class MeasuredOpts(ctypes.Structure):
    """sb_measured_opts_t (measured.h)."""

    _fields_ = [
        ("format", ctypes.c_char_p),
        ("interp", ctypes.c_int),
        ("neighbours", ctypes.c_size_t),
        ("radius", ctypes.c_double),
        ("white", ctypes.c_int),
        ("gamut", ctypes.c_int),
        ("cv_folds", ctypes.c_size_t),
        ("cv_fold", ctypes.c_size_t),
        ("lobe", ctypes.c_int),
        ("lobe_shape", ctypes.c_void_p),
    ]


class JobOpts(ctypes.Structure):
    """sb_job_opts_t (job.h); the layout is checked against the C compiler's
    in the tests (python_layout)."""

    _fields_ = [
        ("size", ctypes.c_size_t),  # sizeof(sb_job_opts_t) as mirrored here (versioned options)
        ("source", ctypes.c_char_p),
        ("measured", MeasuredOpts),
        ("param", ctypes.c_char_p),
        ("form", ctypes.c_char_p),
        ("warp", ctypes.c_char_p),
        ("weighted", ctypes.c_int),
        ("scene", ctypes.c_char_p),
        ("zero_fill", ctypes.c_int),
        ("res", ctypes.c_size_t),
        ("terms", ctypes.c_size_t),
        ("metric_res", ctypes.c_size_t),
        ("max_error", ctypes.c_double),
        ("theta_max_deg", ctypes.c_double),
        ("method", ctypes.c_int),
        ("seed", ctypes.c_ulonglong),
        ("channels", ctypes.c_uint),
        ("fit_max_iters", ctypes.c_int),
        ("fit_tol", ctypes.c_double),
        ("plain_terms", ctypes.c_int),
        ("half", ctypes.c_int),
        ("previews", ctypes.c_int),
        ("sample_only", ctypes.c_int),
        ("budget", ctypes.c_size_t),
        ("cv_folds", ctypes.c_size_t),
        ("out", ctypes.c_char_p),
        ("progress", PROGRESS_FN),
        ("progress_user", ctypes.c_void_p),
        ("shaders", ctypes.c_char_p),
    ]


class SourceOps(ctypes.Structure):
    """sb_source_ops_t (source.h)."""

    _fields_ = [("eval", EVAL_FN), ("destroy", DESTROY_FN)]


class SourceBatchOps(ctypes.Structure):
    """sb_source_batch_ops_t (source.h)."""

    _fields_ = [("eval_many", EVAL_MANY_FN), ("destroy", DESTROY_FN)]


_P = ctypes.c_void_p
_S = ctypes.c_size_t
_I = ctypes.c_int
_D = ctypes.c_double
_C = ctypes.c_char_p
_R = ctypes.c_int  # sb_result_t
_PP = ctypes.POINTER(ctypes.c_void_p)

# name: (restype, argtypes)
_PROTOTYPES = {
    "sb_version": (_C, []),
    "sb_result_name": (_C, [_I]),
    "sb_result_message": (_C, [_I]),
    "sb_context_create": (_R, [_PP]),
    "sb_context_destroy": (None, [_P]),
    "sb_context_last_error": (_C, [_P]),
    "sb_context_clear_error": (None, [_P]),
    "sb_job_source_open": (_R, [_P, _C, ctypes.POINTER(MeasuredOpts), _PP]),
    "sb_job_run": (_R, [_P, ctypes.POINTER(JobOpts), _PP]),
    "sb_job_run_source": (_R, [_P, _P, ctypes.POINTER(JobOpts), _PP]),
    "sb_job_write": (_R, [_P, _P, _C]),
    "sb_job_report": (None, [_P, _P]),
    "sb_job_destroy": (None, [_P]),
    "sb_job_factors": (_P, [_P]),
    "sb_job_param": (_P, [_P]),
    "sb_job_form": (_I, [_P]),
    "sb_job_warning_count": (_S, [_P]),
    "sb_job_warning": (_C, [_P, _S]),
    "sb_job_headline": (_D, [_P, _S]),
    "sb_source_create": (_R, [_P, ctypes.POINTER(SourceOps), _P, ctypes.c_uint, _C, _PP]),
    "sb_source_create_batched": (_R, [_P, ctypes.POINTER(SourceBatchOps), _P, ctypes.c_uint, _C, _PP]),
    "sb_source_batched": (_I, [_P]),
    "sb_source_destroy": (None, [_P]),
    "sb_source_eval": (_I, [_P, _P, _P, _P]),
    "sb_source_flags": (ctypes.c_uint, [_P]),
    "sb_source_description": (_C, [_P]),
    "sb_factors_read_exr": (_R, [_P, _C, _PP]),
    "sb_factors_param": (_R, [_P, _P, _PP, ctypes.POINTER(ctypes.c_int)]),
    "sb_factors_destroy": (None, [_P]),
    "sb_factors_terms": (_S, [_P]),
    "sb_factors_channels": (_S, [_P]),
    "sb_factors_size": (None, [_P, _I, ctypes.POINTER(_S), ctypes.POINTER(_S)]),
    "sb_factors_tex_const": (c_double_p, [_P, _I, _S, _S]),
    "sb_factors_sigma": (_D, [_P, _S, _S]),
    "sb_factors_get_meta": (_C, [_P, _C]),
    "sb_factors_eval": (_I, [_P, _P, _I, _S, _P, _P, _P]),
    "sb_param_destroy": (None, [_P]),
    "sb_param_spec": (_C, [_P]),
    "sb_form_name": (_C, [_I]),
    "sb_form_parse": (_R, [_C, ctypes.POINTER(ctypes.c_int)]),
    "sb_method_parse": (_R, [_C, ctypes.POINTER(ctypes.c_int)]),
    "sb_method_name": (_C, [_I]),
    "sb_method_count": (ctypes.c_size_t, []),
    "sb_interp_parse": (_R, [_C, ctypes.POINTER(ctypes.c_int)]),
    "sb_gamut_parse": (_R, [_C, ctypes.POINTER(ctypes.c_int)]),
    "sb_lobe_mode_parse": (_R, [_C, ctypes.POINTER(ctypes.c_int)]),
    "sb_sampler_create": (_R, [_P, _P, _P, _I, _PP]),
    "sb_sampler_destroy": (None, [_P]),
    "sb_sample": (_I, [_P, _P, _P, _P, _P, _P]),
    "sb_pdf": (_D, [_P, _P, _P]),
}


def _candidates():
    env = os.environ.get("SEPBRDF_LIBRARY")
    if env:
        return [env]
    paths = []
    try:
        from . import _install  # written by `cmake --install`

        paths.append(os.path.normpath(os.path.join(os.path.dirname(__file__), _install.LIBRARY)))
    except ImportError:
        pass
    found = ctypes.util.find_library("sepbrdf")
    if found:
        paths.append(found)
    return paths


def load():
    """Load the shared library and declare its prototypes; raises OSError
    naming the places tried when none holds it."""
    tried = []
    for path in _candidates():
        try:
            lib = ctypes.CDLL(path)
        except OSError as e:
            tried.append(f"{path} ({e})")
            continue
        for name, (res, args) in _PROTOTYPES.items():
            fn = getattr(lib, name)
            fn.restype = res
            fn.argtypes = args
        return lib
    raise OSError(
        "sepbrdf: the C library libsepbrdf.so was not found"
        + (": tried " + "; ".join(tried) if tried else "")
        + " (install it with `cmake --install build`, or set SEPBRDF_LIBRARY to its path)"
    )


lib = load()

# The C runtime: report.json is written to a FILE *, read back through
# open_memstream (POSIX 2008).
libc = ctypes.CDLL(ctypes.util.find_library("c"))
libc.open_memstream.restype = ctypes.c_void_p
libc.open_memstream.argtypes = [ctypes.POINTER(ctypes.c_void_p), ctypes.POINTER(ctypes.c_size_t)]
libc.fclose.argtypes = [ctypes.c_void_p]
libc.fclose.restype = ctypes.c_int
libc.free.argtypes = [ctypes.c_void_p]
libc.free.restype = None
