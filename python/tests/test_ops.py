"""Operators: the declarations of `rgbn ops`, and the functions equal to the command line or
to analytic expectations."""

import filecmp
import inspect
import pathlib
import re

import numpy as np
import pytest

import rgbn
from conftest import GRAPHS, smooth_bump, sphere_normals
from rgbn import _opgen

PKG = pathlib.Path(rgbn.__file__).parent


def test_ops_are_the_declarations_rgbn_ops_prints(cli):
    text = cli(["ops"]).stdout
    ops = rgbn.ops()
    headers = re.findall(r"^(\S+) — (.+) \[(\w+)\]$", text, re.M)
    assert [(o["id"], o["title"], o["category"]) for o in ops] == headers[: len(ops)]
    for o in ops:
        block = text.split(f"\n{o['id']} — ", 1)[1] if not text.startswith(o["id"] + " — ") else text
        block = block.split("\n\n", 1)[0]
        assert re.findall(r"^    param (\w+):", block, re.M) == [p["name"] for p in o["params"]]
        assert re.findall(r"^    in  (\w+):", block, re.M) == [p["name"] for p in o["inputs"]]
        assert re.findall(r"^    out (\w+):", block, re.M) == [p["name"] for p in o["outputs"]]
        for p in o["params"]:
            assert p["doc"] and p["doc"] in block


def test_op_functions_and_stub_are_generated_from_the_declarations():
    ops = rgbn.ops()
    for o in ops:
        f = getattr(rgbn.op, _opgen.name_of(o["id"]))
        assert f.__doc__ == _opgen.docstring(o)
        sig = inspect.signature(f)
        for p in o["params"]:
            if p["name"] not in {i["name"] for i in o["inputs"]}:
                assert sig.parameters[p["name"]].default == p["default"]
    stub = (PKG / "op.pyi").read_text()
    assert stub == _opgen.stub(ops), "op.pyi is stale: python -m rgbn._opgen > python/rgbn/op.pyi"


def test_an_op_function_runs_the_node():
    n, _ = sphere_normals(32, 32)
    img = rgbn.Image(n)
    out = rgbn.op.filter_gaussian(img, sigma_px=2.0)
    direct = rgbn.run_op("filter.gaussian", {"image": img}, {"sigma_px": 2.0})
    np.testing.assert_array_equal(out.normals, direct["image"].normals)
    with pytest.raises(rgbn.InputError, match=r'unknown parameter "sigma" of filter.gaussian \(did you mean "sigma_px"\?\)'):
        rgbn.op.filter_gaussian(img, sigma=2.0)
    with pytest.raises(rgbn.InputError, match=r'unknown operator "filter.gauss" \(did you mean "filter.gaussian"\?\)'):
        rgbn.run_op("filter.gauss", {"image": img})
    with pytest.raises(rgbn.InputError, match=r'parameter "sigma_px": -1 is out of range \[0\.05\d*, 4096\]: filter.gaussian'):
        rgbn.op.filter_gaussian(img, sigma_px=-1.0)


@pytest.mark.parametrize("kernels, extra", [(["gauss:3"], []), (["sharpen:2,1", "box:2"], ["--border", "clamp"])])
def test_filter_equals_rgbn_filter_bit_for_bit(tmp_path, cli, kernels, extra):
    src = GRAPHS / "data" / "image.exr"
    theirs = tmp_path / "cli.exr"
    args = ["filter", src, "-o", theirs, "--stream", "never", *extra]
    for k in kernels:
        args += ["-k", k]
    cli(args)
    border = extra[1] if extra else "mirror"
    out = rgbn.filter(rgbn.read(src), kernels if len(kernels) > 1 else kernels[0], border=border)
    ours = tmp_path / "py.exr"
    rgbn.write(out, ours)
    assert filecmp.cmp(ours, theirs, shallow=False)
    with pytest.raises(rgbn.InputError) as e:
        rgbn.filter(out, "gaus:3")
    r = cli(["filter", src, "-o", tmp_path / "x.exr", "-k", "gaus:3"], check=False)
    assert r.stderr.strip() == f"rgbn: {e.value}"


def test_integrate_recovers_an_analytic_height():
    n, z = smooth_bump(64, 80)
    for method in ("poisson_dct", "masked_poisson", "bilateral"):
        h = rgbn.integrate(rgbn.Image(n), method)
        assert h.shape == (64, 80) and h.dtype == np.float32
        want = z - z.mean()
        err = np.abs((h - h.mean()) - want).max()
        assert err < 0.02 * np.ptp(want), (method, err)


def test_integrate_keeps_a_depth_jump_with_bilateral_and_mask():
    # Two flat planes facing the viewer at different depths: normals cannot see the jump,
    # but a mask that separates them gives two domains; the sphere is integrated inside.
    n, z = sphere_normals(48, 48, r=20)
    mask = (z > 0).astype(np.float32)
    h = rgbn.integrate(rgbn.Image(n), "masked_poisson", mask=mask, tolerance=1e-8)
    inside = mask > 0
    want = z[inside] - z[inside].mean()
    got = h[inside] - h[inside].mean()
    # Normals near the rim are steep: judge the inner disc.
    inner = (z > 0.5 * z.max())[inside]
    assert np.abs(got[inner] - want[inner]).max() < 0.35


def test_integrate_depth_with_a_pinhole_camera_is_minus_the_height():
    n, _ = smooth_bump(40, 50)
    K = np.array([[500.0, 0, 24.5], [0, 500.0, 19.5], [0, 0, 1]])
    h = rgbn.integrate(rgbn.Image(n), "poisson_dct", camera=K)
    d = rgbn.integrate_depth(rgbn.Image(n), "poisson_dct", camera=K)
    np.testing.assert_array_equal(d, -h)
    # Geometric mean of Z over the domain is fx (the integrator's scale convention).
    assert abs(np.exp(np.log(d.astype(np.float64)).mean()) - 500.0) < 0.5
    with pytest.raises(rgbn.InputError, match="3×3"):
        rgbn.integrate_depth(rgbn.Image(n), camera=np.eye(2))


def test_render_equals_rgbn_render(tmp_path, cli):
    src = GRAPHS / "data" / "image.exr"
    for view, args, kw in [
        ("relit", ["--light", "0.3,0.5,0.8", "--exposure", "0.5"], {"light": (0.3, 0.5, 0.8), "exposure": 0.5}),
        ("curl", [], {}),
        ("toon", ["--param", "toon_levels=3"], {"toon_levels": 3}),
    ]:
        png = tmp_path / f"{view}.png"
        cli(["render", src, "--view", view, "-o", png, "--stream", "never", *args])
        rgba = rgbn.render(rgbn.read(src), view=view, **kw)
        ours = tmp_path / f"{view}.py.png"
        rgbn.write(rgba, ours)
        assert filecmp.cmp(ours, png, shallow=False), view
    with pytest.raises(rgbn.InputError, match=r'unknown view "relt" \(did you mean "relit"'):
        rgbn.render(rgbn.read(src), view="relt")


def rust_e(x, digits=3):
    """Rust's `{:.3e}`: no exponent padding or plus sign (6.472e-1, 2.320e0)."""
    m, e = f"{x:.{digits}e}".split("e")
    return f"{m}e{int(e)}"


def test_info_equals_rgbn_info(cli):
    src = GRAPHS / "data" / "image.exr"
    text = cli(["info", src]).stdout
    d = rgbn.info(rgbn.read(src))
    assert f"size:        {d['width']}×{d['height']}" in text
    curl = f"relative RMS {rust_e(d['curl_relative'])} (RMS {rust_e(d['curl_rms'])}, max |c| {rust_e(d['curl_max'])})"
    assert curl in text
    assert f"F = {rust_e(d['F'])} (0:" in text
    assert f"with green flipped F = {rust_e(d['F_green_flipped'])}" in text
    assert f"green:       {d['green_line']}" in text
    assert f"RMS |g| = {d['rms_gradient']:.4f}" in text
    assert ("OpenGL (+y) most likely" in text) == (d["green"] == "as read")


def test_info_finds_a_flipped_green_channel():
    n, _ = smooth_bump(48, 48)
    d = rgbn.info(rgbn.Image(n))
    assert d["green"] == "as read" and d["green_reason"] is None and d["green_contrast"] > 0.9
    flipped = n * np.array([1, -1, 1], np.float32)
    d = rgbn.info(rgbn.Image(flipped))
    assert d["green"] == "flipped" and d["F"] > 10 * d["F_green_flipped"]
    assert d["green_contrast"] < -0.9 and d["green_line"].startswith("DirectX (-y) most likely")


def test_info_says_uncertain_without_relief():
    d = rgbn.info(rgbn.Image(np.dstack([np.zeros((32, 32, 2)), np.ones((32, 32))]).astype(np.float32)))
    assert d["green"] == "uncertain" and d["green_reason"] == "too little relief"
    assert d["relief_plaquettes"] == 0


def test_capture_recovers_the_normals_of_a_lambertian_sphere():
    n, z = sphere_normals(40, 40, r=18)
    mask = (z > 0).astype(np.float32)
    albedo = np.array([0.8, 0.5, 0.3], np.float32)
    lights = np.array([[0.3, 0.2, 0.93], [-0.4, 0.1, 0.91], [0.1, -0.45, 0.89], [0.0, 0.0, 1.0], [-0.2, -0.3, 0.93]], np.float32)
    lights /= np.linalg.norm(lights, axis=1, keepdims=True)
    photos = [(np.clip(n @ l, 0, None)[..., None] * albedo).astype(np.float32) for l in lights]
    img = rgbn.capture(photos, lights, mask=mask, method="ls")
    inner = (z > 0.6 * z.max())
    assert np.abs(img.normals[inner] - n[inner]).max() < 1e-4
    np.testing.assert_allclose(img.color[inner], np.broadcast_to(albedo, img.color[inner].shape), atol=1e-4)
    stack = np.stack(photos)
    np.testing.assert_array_equal(rgbn.capture(stack, lights, mask=mask, method="ls").normals, img.normals)
    with pytest.raises(rgbn.InputError, match="at least 3 photos"):
        rgbn.capture(photos[:2], lights[:2])
    with pytest.raises(rgbn.InputError, match=r'unknown method "lsq"'):
        rgbn.capture(photos, lights, method="lsq")


def test_a_pen_takes_many_paths_as_lists_or_dicts_and_their_heights_add():
    n = np.zeros((96, 96, 3), np.float32)
    n[..., 2] = 1.0
    img = rgbn.Image(n)
    closed = {"points": [(20, 50), (60, 50), (40, 90)], "closed": True, "params": {"profile": "step", "height_px": -2.0}}
    two = rgbn.op.pen(img, paths=[[(10, 10), (50, 20)], closed])
    a = rgbn.op.pen(img, paths=[[(10, 10), (50, 20)]])
    # The closed path alone, in the command line's text form, its own parameters the node's.
    b = rgbn.op.pen(a["image"], paths="20:50,60:50,40:90,closed", profile="step", height_px=-2.0)
    h2, ha, hb = (np.asarray(x["height"]) for x in (two, a, b))
    assert np.abs(h2 - (ha + hb)).max() < 1e-5
    assert h2.min() < -1.9, "the step lowers the inside"
    assert two["image"].normals.tolist() != img.normals.tolist()
    with pytest.raises(rgbn.InputError, match="did you mean \"width_px\""):
        rgbn.op.pen(img, paths=[{"points": [(1, 1), (5, 5)], "params": {"widht_px": 3}}])
