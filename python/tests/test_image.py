"""Images as arrays: construction without copies, validation as the command line validates,
read/write round trips for each format."""

import warnings

import numpy as np
import pytest

import rgbn
from conftest import GRAPHS, sphere_normals


def unit(h=16, w=20, seed=0):
    rng = np.random.default_rng(seed)
    n = rng.normal(size=(h, w, 3)).astype(np.float32)
    n[..., 2] = np.abs(n[..., 2]) + 0.5
    n /= np.linalg.norm(n, axis=2, keepdims=True)
    return n


def test_c_contiguous_float32_arrays_are_kept_not_copied():
    n = unit()
    c = np.random.default_rng(1).random((16, 20, 3), dtype=np.float32)
    m = np.ones((16, 20), np.float32)
    before = rgbn.planar_copies()
    img = rgbn.Image(n, c, m)
    assert img.normals is n and img.color is c and img.mask is m
    assert rgbn.planar_copies() == before, "Image() made a planar copy"
    assert not img.is_planar and img.shape == (16, 20)
    # A call into Rust reads it through one planar copy per array...
    out = rgbn.filter(img, "gauss:1")
    assert rgbn.planar_copies() == before + 3
    # ...and an Image rgbn returned is handed on without one.
    rgbn.filter(out, "gauss:1")
    assert out.is_planar and rgbn.planar_copies() == before + 3


def test_returned_arrays_are_read_only_and_equal_the_planes():
    n = unit()
    out = rgbn.filter(rgbn.Image(n), "scale:1")
    assert not out.normals.flags.writeable
    np.testing.assert_allclose(out.normals, n, atol=2e-6)
    assert out.normals is out.normals  # made once
    np.testing.assert_array_equal(out.color, np.full((16, 20, 3), 0.75, np.float32))


def test_a_non_contiguous_array_is_copied_once_and_accepted():
    n = unit(20, 16).transpose(1, 0, 2)  # a view: not C-contiguous
    img = rgbn.Image(n)
    assert img.normals is not n and img.normals.flags.c_contiguous
    np.testing.assert_array_equal(img.normals, n)


@pytest.mark.parametrize(
    "arr, message",
    [
        (np.zeros((4, 4), np.float32), "normals must have shape (H, W, 3), got (4, 4)"),
        (np.zeros((4, 4, 4), np.float32), "normals must have shape (H, W, 3), got (4, 4, 4)"),
        (np.zeros((4, 4, 3), np.float64), "normals must be float32, got float64 (convert with .astype(numpy.float32))"),
        ([[1.0, 2.0, 3.0]], "normals must be a NumPy array of shape (H, W, 3), got list"),
        (np.zeros((0, 4, 3), np.float32), "image has no pixels (4×0)"),
    ],
)
def test_bad_arrays_are_input_errors_with_one_line_messages(arr, message):
    with pytest.raises(rgbn.InputError) as e:
        rgbn.Image(arr)
    assert message in str(e.value)
    assert "\n" not in str(e.value)
    assert isinstance(e.value, rgbn.Error)


def test_sizes_must_agree():
    with pytest.raises(rgbn.InputError, match=r"size mismatch: mask is 3×4 but the image is 5×4: mask"):
        rgbn.Image(unit(4, 5), mask=np.ones((4, 3), np.float32))
    with pytest.raises(rgbn.InputError, match=r"size mismatch: colour image is 5×3 but the image is 5×4: color"):
        rgbn.Image(unit(4, 5), color=np.ones((3, 5, 3), np.float32))


def test_nan_and_zero_normals_are_repaired_as_the_command_line_repairs_them():
    n = unit()
    n[0, 0] = np.nan
    n[1, 1] = 0
    n[2, 2] *= 3  # not unit length
    with pytest.warns(rgbn.RepairWarning, match=r"repaired 1 NaN/inf and 1 zero-length normals \(now \(0,0,1\)\), renormalised 1, zeroed 0 non-finite colour values: normals"):
        img = rgbn.Image(n)
    assert img.is_planar
    np.testing.assert_array_equal(img.normals[0, 0], [0, 0, 1])
    np.testing.assert_array_equal(img.normals[1, 1], [0, 0, 1])
    np.testing.assert_allclose(np.linalg.norm(img.normals[2, 2]), 1, atol=1e-6)
    assert img.repaired["non_finite_normal"] == 1 and img.repaired["zero_length_normal"] == 1
    assert img.repaired["non_unit"] == 1
    with pytest.raises(rgbn.InputError, match=r"^1 invalid normals \(NaN or infinite\); drop --strict to repair them to \(0,0,1\): normals$"):
        rgbn.Image(n, strict=True)


def test_strict_messages_equal_the_command_line(tmp_path, cli):
    # An 8-bit mid-grey normal map decodes to zero-length normals (the CLI's own example).
    grey = np.full((6, 7, 4), 128, np.uint8)
    grey[..., 3] = 255
    f = tmp_path / "grey.png"
    rgbn.write(grey, f)
    r = cli(["info", "--strict", f], check=False)
    assert r.returncode == 2
    with pytest.raises(rgbn.InputError) as e:
        rgbn.read(f, strict=True)
    assert r.stderr.strip() == f"rgbn: {e.value}"
    n = np.zeros((6, 7, 3), np.float32)
    with pytest.raises(rgbn.InputError) as e2:
        rgbn.Image(n, strict=True)
    assert str(e2.value) == str(e.value).replace(str(f), "normals")


def test_missing_file_is_a_file_error_with_the_command_line_message(tmp_path, cli):
    missing = tmp_path / "nope.exr"
    r = cli(["info", missing], check=False)
    with pytest.raises(rgbn.FileError) as e:
        rgbn.read(missing)
    assert r.stderr.strip() == f"rgbn: {e.value}"
    with pytest.raises(rgbn.FileError, match="output folder does not exist"):
        rgbn.write(rgbn.Image(unit()), tmp_path / "no" / "x.exr")


def roundtrip_cases():
    return [
        ("x.exr", {}, 0.0),
        ("x.exr", {"half": True}, 1e-3),
        ("x.png", {"bits": 16}, 2 / 65535 * 1.01),
        ("x.png", {"bits": 8}, 2 / 255 * 1.01),
        ("x.tif", {"bits": 16}, 2 / 65535 * 1.01),
        ("x.png", {"bits": 16, "dx": True}, 2 / 65535 * 1.01),
    ]


@pytest.mark.filterwarnings("ignore::rgbn.RepairWarning")  # 8-bit normals read back renormalised
@pytest.mark.parametrize("name, opts, tol", roundtrip_cases())
def test_normals_round_trip_through_each_format(tmp_path, name, opts, tol):
    n, _ = sphere_normals(24, 30)
    c = np.random.default_rng(3).random((24, 30, 3), dtype=np.float32)
    m = (np.arange(24 * 30).reshape(24, 30) % 3 > 0).astype(np.float32)
    img = rgbn.Image(n, c, m)
    path = tmp_path / name
    rgbn.write(img, path, **opts)
    back = rgbn.read(path, dx=opts.get("dx", False))
    assert back.shape == (24, 30)
    # Read normals are renormalised after decoding: compare within the quantisation step.
    assert np.abs(back.normals - n).max() <= tol + 1e-6
    if name.endswith(".exr") and not opts:
        np.testing.assert_array_equal(back.normals, n)
        np.testing.assert_array_equal(back.color, c)
        np.testing.assert_array_equal(back.mask, m)
    if name.endswith(".exr"):
        assert back.mask is not None


def test_colour_round_trip_png_srgb_and_exr_linear(tmp_path):
    c = np.random.default_rng(4).random((10, 12, 3), dtype=np.float32)
    img = rgbn.Image(sphere_normals(10, 12)[0], c)
    rgbn.write(img, tmp_path / "c.exr", color=True)
    np.testing.assert_array_equal(rgbn.read_color(tmp_path / "c.exr"), c)
    rgbn.write(img, tmp_path / "c.png", color=True, bits=16)
    back = rgbn.read_color(tmp_path / "c.png")
    assert np.abs(back - c).max() < 2e-4  # 16-bit sRGB steps


def test_masks_scalars_and_pictures_are_written(tmp_path):
    m = np.linspace(0, 1, 48, dtype=np.float32).reshape(6, 8)
    rgbn.write(m, tmp_path / "m.png", mask=True)
    assert np.abs(rgbn.read_mask(tmp_path / "m.png") - m).max() <= 0.5 / 65535 + 1e-7
    rgbn.write(m, tmp_path / "m.exr", mask=True)
    np.testing.assert_array_equal(rgbn.read_mask(tmp_path / "m.exr"), m)
    with pytest.raises(rgbn.InputError, match="scalar fields are written as .exr"):
        rgbn.write(m, tmp_path / "h.png")


def test_read_takes_the_repository_image_and_separate_mask():
    img = rgbn.read(GRAPHS / "data" / "image.exr", mask=GRAPHS / "data" / "mask.png")
    assert img.mask is not None and img.mask.shape == img.shape
    assert img.normals.dtype == np.float32 and img.normals.shape == (*img.shape, 3)
    np.testing.assert_allclose(np.linalg.norm(img.normals, axis=2), 1, atol=1e-5)


def test_with_mask_shares_the_rest():
    img = rgbn.Image(unit())
    m = np.zeros((16, 20), np.float32)
    m[4:10, 5:15] = 1
    masked = img.with_mask(m)
    np.testing.assert_array_equal(masked.mask, m)
    np.testing.assert_array_equal(masked.normals, img.normals)
    assert masked.with_mask(None).mask is None
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        rgbn.Image(unit())  # clean input: no warning
