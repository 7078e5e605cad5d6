"""The Python package against the CLI and against independent formulas.

Run by ctest (tests/CMakeLists.txt: python.*), with SEPBRDF_LIBRARY (the
build's libsepbrdf.so), SEPBRDF_CLI (the build's `sepbrdf`) and
SEPBRDF_LAYOUT (tests/python_layout) set; PYTHONPATH holds python/."""

import json
import os
import subprocess
import sys

import numpy as np
import pytest

import sepbrdf
from sepbrdf import _lib

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
MEASURED = os.path.join(ROOT, "tests", "data", "measured")
CLI = os.environ.get("SEPBRDF_CLI", os.path.join(ROOT, "build", "sepbrdf"))


def cli_factor(tmp_path, name, *args):
    out = tmp_path / name
    subprocess.run([CLI, "factor", *args, "-o", str(out), "-q"], check=True, capture_output=True)
    return out


def without_times(x):
    """report.json without what varies between runs: wall-clock times."""
    if isinstance(x, dict):
        return {k: without_times(v) for k, v in x.items() if k != "timings" and not k.endswith("_s")}
    if isinstance(x, list):
        return [without_times(v) for v in x]
    return x


def load_report(folder):
    with open(os.path.join(folder, "report.json"), encoding="utf-8") as fp:
        return json.load(fp)


def assert_same_set(a, b):
    """Two output folders hold the same files, byte for byte but for
    report.json's times."""
    names = sorted(os.listdir(a))
    assert names == sorted(os.listdir(b))
    for n in names:
        if n == "report.json":
            assert without_times(load_report(a)) == without_times(load_report(b))
        else:
            with open(os.path.join(a, n), "rb") as fa, open(os.path.join(b, n), "rb") as fb:
                assert fa.read() == fb.read(), n


def unit(v):
    v = np.asarray(v, dtype=np.float64)
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def hemisphere(n, seed):
    rng = np.random.default_rng(seed)
    z = rng.uniform(0.05, 1, n)
    phi = rng.uniform(0, 2 * np.pi, n)
    s = np.sqrt(1 - z * z)
    return np.stack([s * np.cos(phi), s * np.sin(phi), z], axis=-1)


def test_layout():
    """The ctypes structs have the C compiler's offsets and sizes."""
    exe = os.environ.get("SEPBRDF_LAYOUT")
    if not exe:
        pytest.skip("SEPBRDF_LAYOUT not set (ctest sets it)")
    out = subprocess.run([exe], check=True, capture_output=True, text=True).stdout.split("\n")
    structs = {
        "sb_measured_opts_t": _lib.MeasuredOpts,
        "sb_job_opts_t": _lib.JobOpts,
        "sb_source_ops_t": _lib.SourceOps,
    }
    checked = 0
    for line in filter(None, out):
        w = line.split()
        if w[0] == "sizeof":
            assert int(w[2]) == __import__("ctypes").sizeof(structs[w[1]]), line
        else:
            field = getattr(structs[w[0]], w[1])
            assert (field.offset, field.size) == (int(w[2]), int(w[3])), line
        checked += 1
    assert checked == 6 + 28 + 2 + 3


def test_default_equals_cli(tmp_path):
    """factor() with no arguments writes the CLI's default set, byte for byte."""
    cli = cli_factor(tmp_path, "cli")
    fac = sepbrdf.factor()
    assert fac.param == load_report(cli)["param_spec"]
    fac.write(tmp_path / "py")
    assert_same_set(cli, tmp_path / "py")
    # the textures in memory are those written, before float32 rounding
    back = sepbrdf.read(cli)
    assert back.g.shape == fac.g.shape and back.h.shape == fac.h.shape
    assert np.array_equal(back.g, fac.g.astype(np.float32)) and np.array_equal(back.h, fac.h.astype(np.float32))
    assert fac.report["errors"] == load_report(cli)["errors"]


def test_measured_with_options_equals_cli(tmp_path):
    """A measured table with explicit layout, R and J: the CLI's set."""
    path = os.path.join(MEASURED, "cornell_acryl_blue.brdf")
    cli = cli_factor(tmp_path, "cli", path, "--param", "iso", "-r", "16", "-J", "2")
    fac = sepbrdf.factor(path, param="iso", res=16, terms=2)
    assert fac.terms == 2 and fac.param.startswith("iso:")
    fac.write(tmp_path / "py")
    assert_same_set(cli, tmp_path / "py")
    assert fac.warnings  # the CLI warns about this run too (terms kept as fitted)


def phong_glsl(wi, wo):
    """The lecture's phongBRDF, written in numpy: kd + ks max(r.v, 0)^n, kd = ks = 0.5, n = 20."""
    rv = 2 * wi[:, 2] * wo[:, 2] - (wi[:, 0] * wo[:, 0] + wi[:, 1] * wo[:, 1] + wi[:, 2] * wo[:, 2])
    f = 0.5 + 0.5 * np.power(np.maximum(rv, 0.0), 20.0)
    f = np.where((wi[:, 2] > 0) & (wo[:, 2] > 0), f, 0.0)
    return np.stack([f, f, f], axis=-1)


def test_numpy_function_equals_cli_model(tmp_path):
    """A BRDF written as a numpy function factors as the library's own model
    of the same formula does in the CLI."""
    cli = cli_factor(tmp_path, "cli", "phong-glsl", "--param", "iso", "-r", "16", "-J", "2")
    src = sepbrdf.Source.from_function(phong_glsl, isotropic=True, reciprocal=True, gray=True)
    wi, wo = hemisphere(64, 1), hemisphere(64, 2)
    np.testing.assert_allclose(src.eval(wi, wo)[0], sepbrdf.Source("phong-glsl").eval(wi, wo)[0], rtol=1e-14)
    fac = sepbrdf.factor(src, param="iso", res=16, terms=2)
    ref = sepbrdf.read(cli)
    np.testing.assert_allclose(fac.g.astype(np.float32), ref.g, rtol=1e-6, atol=1e-7)
    np.testing.assert_allclose(fac.h.astype(np.float32), ref.h, rtol=1e-6, atol=1e-7)
    for mine, theirs in zip(fac.report["errors"], load_report(cli)["errors"]):
        for k in ("headline", "rel_rms", "comparable"):
            assert mine[k] == pytest.approx(theirs[k], rel=1e-9), k


def test_function_is_called_in_batches():
    """The library hands a Python function whole columns and sets of pairs,
    not one pair a call."""
    calls, pairs = [0], [0]

    def f(wi, wo):
        calls[0] += 1
        pairs[0] += len(wi)
        return phong_glsl(wi, wo)

    src = sepbrdf.Source.from_function(f, isotropic=True, reciprocal=True, gray=True)
    fac = sepbrdf.factor(src, param="iso", res=16, terms=2)
    assert fac.terms == 2 and pairs[0] > 10000 and calls[0] * 20 < pairs[0], (calls, pairs)


def test_function_any_symmetry_and_grey():
    """A plain callable (no symmetries declared) is accepted by factor();
    a grey (n,) result counts for all three channels."""
    fac = sepbrdf.factor(lambda wi, wo: np.full(len(wi), 0.25), param="io", res=8, terms=1)
    wi, wo = hemisphere(16, 3), hemisphere(16, 4)
    np.testing.assert_allclose(fac.eval(wi, wo), 0.25, rtol=1e-9)


def test_errors_carry_the_library_message(tmp_path):
    with pytest.raises(sepbrdf.Error) as e:
        sepbrdf.factor("foo:x=1")
    assert e.value.code == "SB_ERR_UNKNOWN" and "unknown model 'foo'" in str(e.value)
    with pytest.raises(sepbrdf.Error) as e:
        sepbrdf.Source("microfacet:roughness=abc")
    assert e.value.code == "SB_ERR_PARSE" and "roughness" in str(e.value)
    with pytest.raises(sepbrdf.Error) as e:
        sepbrdf.factor(str(tmp_path / "missing.binary"))
    assert e.value.code == "SB_ERR_IO" and "No such file" in str(e.value)
    with pytest.raises(sepbrdf.Error) as e:
        sepbrdf.factor("lambert", param="io", res=4, terms=20)
    assert e.value.code == "SB_ERR_RANGE"
    with pytest.raises(sepbrdf.Error) as e:
        sepbrdf.read(tmp_path / "nothing")
    assert e.value.code == "SB_ERR_IO"
    with pytest.raises(ValueError, match="res 1"):
        sepbrdf.factor(res=1)
    with pytest.raises(ValueError, match="method 'svd' unknown"):
        sepbrdf.factor(method="svd")
    with pytest.raises(sepbrdf.Error, match="shader language 'spirv' unknown"):
        sepbrdf.factor("lambert", param="io", res=4, terms=1, shader="spirv")
    with pytest.raises(TypeError, match="colour"):
        sepbrdf.factor(colour=1)


def test_function_exception_is_raised():
    def bad(wi, wo):
        raise ZeroDivisionError("in the user's function")

    with pytest.raises(ZeroDivisionError, match="user's function"):
        sepbrdf.factor(bad, param="io", res=4, terms=1)


def test_eval_is_the_texture_product_at_texel_centres():
    """On io (form f) the pair of cell centres (theta, phi) = ((i + 1/2) / R
    pi / 2, (k + 1/2) / R 2 pi) reads texel (x = i, y = k) of each texture,
    so the reconstruction there is sum_j g_j[y_i, x_i] h_j[y_o, x_o]."""
    R = 8
    fac = sepbrdf.factor("modified-phong:n=8", param="io", form="f", res=R, terms=3, plain_terms=True)
    rng = np.random.default_rng(5)
    cells = rng.integers(0, R, size=(50, 4))

    def direction(i, k):
        t, p = (i + 0.5) / R * np.pi / 2, (k + 0.5) / R * 2 * np.pi
        return np.stack([np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)], axis=-1)

    wi, wo = direction(cells[:, 0], cells[:, 1]), direction(cells[:, 2], cells[:, 3])
    want = np.einsum("jnc,jnc->nc", fac.g[:, cells[:, 1], cells[:, 0], :], fac.h[:, cells[:, 3], cells[:, 2], :])
    np.testing.assert_allclose(fac.eval(wi, wo), want, rtol=1e-10, atol=1e-14)
    # fewer terms: the first ones only
    want1 = fac.g[0, cells[:, 1], cells[:, 0], :] * fac.h[0, cells[:, 3], cells[:, 2], :]
    np.testing.assert_allclose(fac.eval(wi, wo, terms=1), want1, rtol=1e-10, atol=1e-14)


def test_eval_follows_the_source_and_broadcasts():
    fac = sepbrdf.factor()
    src = sepbrdf.Source()
    wi, wo = hemisphere(400, 6), hemisphere(400, 7)
    f, known = src.eval(wi, wo)
    assert known.all()
    err = np.linalg.norm((fac.eval(wi, wo) - f) * wi[:, 2:]) / np.linalg.norm(f * wi[:, 2:])
    assert err < 0.02  # the headline (f cos theta_i) is 1e-3 at J = 4
    assert fac.eval(wi[:5, None, :], wo[None, :7, :]).shape == (5, 7, 3)
    with pytest.raises(ValueError):
        fac.eval(wi[:, :2], wo)


def test_read_back_evaluates_as_written(tmp_path):
    fac = sepbrdf.factor("microfacet:roughness=0.3", param="hd", res=16, terms=2)
    fac.write(tmp_path / "set")
    back = sepbrdf.read(tmp_path / "set")
    assert back.param == fac.param and back.form == fac.form and back.terms == 2
    assert back.report["errors"][1]["headline"] == fac.headline(2)
    wi, wo = hemisphere(100, 8), hemisphere(100, 9)
    np.testing.assert_allclose(back.eval(wi, wo), fac.eval(wi, wo), rtol=1e-5, atol=1e-6)
    with pytest.raises(sepbrdf.Error):
        back.write(tmp_path / "again")


def test_sampler_nmf(tmp_path):
    """Non-negative factors come with a sampler: the density sample()
    returns is pdf() at the drawn direction, and it integrates to 1."""
    cli = cli_factor(tmp_path, "cli", "modified-phong:n=10", "--method", "nmf", "--param", "io", "-r", "8", "-J", "2")
    fac = sepbrdf.factor("modified-phong:n=10", method="nmf", param="io", res=8, terms=2)
    fac.write(tmp_path / "py")
    assert_same_set(cli, tmp_path / "py")
    assert "sampler.bin" in os.listdir(tmp_path / "py")
    wo = unit([0.3, 0.1, 0.9])
    u = np.random.default_rng(10).uniform(size=(2000, 2))
    wi, pdf, rgb, ok = fac.sample(wo, u)
    assert ok.mean() > 0.9 and np.all(pdf[ok] > 0)
    np.testing.assert_allclose(np.linalg.norm(wi[ok], axis=-1), 1, rtol=1e-12)
    np.testing.assert_allclose(fac.pdf(wo, wi[ok]), pdf[ok], rtol=1e-9)
    np.testing.assert_allclose(rgb[ok], fac.eval(wi[ok], wo), rtol=1e-9, atol=1e-15)
    # Monte Carlo over uniform hemisphere directions: E[pdf / (1 / 2 pi)] = 1
    d = hemisphere(20000, 11)
    d = d[d[:, 2] > 0]
    z = np.random.default_rng(12).uniform(0, 1, 40000)
    p = np.random.default_rng(13).uniform(0, 2 * np.pi, 40000)
    s = np.sqrt(1 - z * z)
    d = np.stack([s * np.cos(p), s * np.sin(p), z], axis=-1)
    assert np.mean(fac.pdf(wo, d)) * 2 * np.pi == pytest.approx(1, abs=0.05)
    svd = sepbrdf.factor("modified-phong:n=10", param="io", res=8, terms=2)
    with pytest.raises(sepbrdf.Error, match="sample"):
        svd.sample(wo, u[:1])


def test_progress_and_options(tmp_path):
    seen = []
    fac = sepbrdf.factor(
        "lambert:albedo=0.5/0.4/0.3", param="io", res=8, terms=1, channels="R,B", progress=lambda l, x: seen.append((l, x))
    )
    assert fac.report["channels"] == ["R", "B"]
    assert np.all(fac.g[..., 1] == 0) and np.all(fac.g[..., 0] != 0) and np.all(fac.g[..., 2] != 0)
    # io named alone screens its forms (f, cos) as auto would, then samples the kept one
    assert seen and all(label in ("screening", "sampling") and 0 <= x <= 1 for label, x in seen)
    assert any(label == "sampling" for label, _ in seen)
    cli = cli_factor(tmp_path, "cli", "lambert", "--budget", "4K", "--half", "-J", "1", "--shader", "hlsl,msl")
    fac = sepbrdf.factor("lambert", budget="4K", half=True, terms=1, shader="hlsl,msl")
    fac.write(tmp_path / "py")
    assert_same_set(cli, tmp_path / "py")
    assert {"sepbrdf.hlsl", "sepbrdf.metal"} <= set(os.listdir(tmp_path / "py"))


def test_installed_package(tmp_path):
    """`cmake --install` puts the package where python3 finds it under the
    prefix, and the package finds the installed library without help."""
    build = os.environ.get("SEPBRDF_BUILD_DIR")
    if not build:
        pytest.skip("SEPBRDF_BUILD_DIR not set (ctest sets it)")
    prefix = tmp_path / "prefix"
    subprocess.run(["cmake", "--install", build, "--prefix", str(prefix)], check=True, capture_output=True)
    env = {k: v for k, v in os.environ.items() if k not in ("SEPBRDF_LIBRARY", "PYTHONPATH", "LD_LIBRARY_PATH")}
    env["PYTHONPATH"] = str(prefix / os.environ["SEPBRDF_PYTHON_DIR"])
    code = (
        "import sepbrdf, sepbrdf._lib as l; f = sepbrdf.factor('lambert', param='io', res=4, terms=1); "
        "print(sepbrdf.__file__); print(l.lib._name); print(f.g.shape)"
    )
    run = subprocess.run([sys.executable, "-c", code], env=env, cwd=tmp_path, capture_output=True, text=True)
    assert run.returncode == 0, run.stderr
    pkg, library, shape = run.stdout.split("\n")[:3]
    assert pkg.startswith(str(prefix)) and os.path.realpath(library).startswith(os.path.realpath(prefix))
    assert shape == "(1, 4, 4, 3)"


def test_measured_lobe_option():
    """lobe="off" reads a Cornell table's values as measured: beside the
    acrylic's highlight, between its samples, the two differ; an unknown
    mode is refused with the CLI's words."""
    path = os.path.join(MEASURED, "cornell_acryl_blue.brdf")
    on, off = sepbrdf.Source(path), sepbrdf.Source(path, lobe="off")
    t = np.radians([47.0, 52.0, 57.0])
    wi = np.stack([np.sin(t), 0 * t, np.cos(t)], axis=-1)
    wo = np.stack([-np.sin(t + 0.03), 0 * t, np.cos(t + 0.03)], axis=-1)
    a, ka = on.eval(wi, wo)
    b, kb = off.eval(wi, wo)
    assert ka.all() and kb.all() and np.all(a >= 0)
    assert not np.allclose(a, b, rtol=1e-2)
    with pytest.raises(ValueError, match="lobe 'sometimes' unknown"):
        sepbrdf.Source(path, lobe="sometimes")
