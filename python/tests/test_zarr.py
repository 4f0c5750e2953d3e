"""OME-Zarr stores: what rgbn writes opens in `zarr` 3 and `ome_zarr` (axes, shape, channel
names, levels); what `ome-zarr` writes (NGFF 0.4 on Zarr v2) rgbn reads; bad stores raise
`rgbn.FileError` naming the store and the fault."""

import json
import shutil

import numpy as np
import pytest

import rgbn

zarr = pytest.importorskip("zarr")
ome_reader = pytest.importorskip("ome_zarr.reader")
ome_io = pytest.importorskip("ome_zarr.io")

from conftest import GRAPHS, sphere_normals  # noqa: E402


def image(h, w, mask):
    n, _ = sphere_normals(h, w)
    rng = np.random.default_rng(h * 1000 + w)
    c = rng.uniform(0, 1, size=(h, w, 3)).astype(np.float32)
    m = rng.uniform(0, 1, size=(h, w)).astype(np.float32) if mask else None
    return rgbn.Image(n, c, m)


def levels_of(h, w, chunk):
    """Levels rgbn writes (docs): level k while chunk / 2^k >= 32 and the level's larger side
    >= 32, level 0 always."""
    k = 1
    while chunk % (1 << k) == 0 and chunk >> k >= 32 and max(-(-h // (1 << k)), -(-w // (1 << k))) >= 32:
        k += 1
    return k


@pytest.mark.parametrize("dtype,tol", [("float32", 0.0), ("float16", 1e-3), ("uint16", 2 / 65535)])
@pytest.mark.parametrize("h,w", [(1, 1), (70, 45), (130, 257)])
@pytest.mark.parametrize("mask", [False, True])
def test_rgbn_stores_open_in_zarr_and_ome_zarr_and_round_trip(tmp_path, dtype, tol, h, w, mask):
    img = image(h, w, mask)
    path = tmp_path / "x.zarr"
    rgbn.write(img, path, zarr_dtype=dtype, chunk=64)
    names = ["R", "G", "B", "nx", "ny", "nz"] + (["mask"] if mask else [])

    g = zarr.open_group(str(path), mode="r")
    assert g.metadata.zarr_format == 3
    ome = g.attrs["ome"]
    assert ome["version"] == "0.5"
    ms = ome["multiscales"][0]
    assert [a["name"] for a in ms["axes"]] == ["c", "y", "x"]
    nlev = levels_of(h, w, 64)
    assert [d["path"] for d in ms["datasets"]] == [str(k) for k in range(nlev)]
    a0 = g["0"]
    assert a0.shape == (len(names), h, w) and str(a0.dtype) == dtype
    for k in range(nlev):
        s = 1 << k
        assert g[str(k)].shape == (len(names), -(-h // s), -(-w // s))
        assert ms["datasets"][k]["coordinateTransformations"][0]["scale"] == [1.0, s, s]

    # zarr's own reading of the values: the channels as written.
    got = a0[:]
    if dtype == "float32":
        np.testing.assert_array_equal(got[0:3], np.moveaxis(img.color, 2, 0))
        np.testing.assert_array_equal(got[3:6], np.moveaxis(img.normals, 2, 0))
    if dtype == "uint16":
        np.testing.assert_array_equal(got[3], np.round((np.clip(img.normals[..., 0], -1, 1) + 1) / 2 * 65535))

    nodes = list(ome_reader.Reader(ome_io.parse_url(str(path)))())
    assert nodes, "ome_zarr finds the image"
    node = nodes[0]
    assert node.metadata["channel_names"] == names
    assert [a["name"] for a in node.metadata["axes"]] == ["c", "y", "x"]
    assert [tuple(d.shape) for d in node.data] == [g[str(k)].shape for k in range(nlev)]

    back = rgbn.read(path)
    assert np.max(np.abs(back.color - img.color)) <= tol
    assert np.max(np.abs(back.normals - img.normals)) <= 2 * tol + 3e-7
    if mask:
        assert np.max(np.abs(back.mask - img.mask)) <= tol
    else:
        assert back.mask is None


def test_a_level_is_read_directly_from_the_store(tmp_path):
    img = image(256, 192, False)
    path = tmp_path / "l.zarr"
    rgbn.write(img, path, chunk=128)
    lvl = rgbn.read(path, level=1)
    assert lvl.color.shape == (128, 96, 3)
    # The stored level 1: the 2 x 2 block means of level 0 (unmasked colour).
    want = img.color.reshape(128, 2, 96, 2, 3).astype(np.float64).mean(axis=(1, 3))
    np.testing.assert_allclose(lvl.color, want, atol=1e-6)
    # Standard tools see the same numbers.
    g = zarr.open_group(str(path), mode="r")
    np.testing.assert_array_equal(g["1"][0], lvl.color[..., 0])


def test_an_ome_zarr_0_4_store_written_by_ome_zarr_is_read(tmp_path):
    from ome_zarr.format import FormatV04
    from ome_zarr.writer import write_image

    h, w = 80, 60
    n, _ = sphere_normals(h, w)
    data = np.moveaxis(n, 2, 0).copy()  # (c, y, x)
    path = tmp_path / "v04.zarr"
    root = zarr.open_group(str(path), mode="w", zarr_format=2)
    write_image(
        data,
        root,
        axes="cyx",
        fmt=FormatV04(),
        storage_options={"chunks": (3, 32, 32)},
        metadata={"omero": {"channels": [{"label": l} for l in ("nx", "ny", "nz")]}},
    )
    # ome-zarr 0.18 leaves `metadata` out of a 0.4 store: the channel labels written as 0.4 has them.
    attrs = json.loads((path / ".zattrs").read_text())
    attrs.setdefault("omero", {"channels": [{"label": l} for l in ("nx", "ny", "nz")]})
    (path / ".zattrs").write_text(json.dumps(attrs))
    ms = attrs["multiscales"][0]
    assert ms["version"] == "0.4"
    # Zarr v2 arrays; their names are ome-zarr's choice ("0" or "s0" by version).
    assert (path / ms["datasets"][0]["path"] / ".zarray").exists()
    img = rgbn.read(path)
    np.testing.assert_allclose(img.normals, n, atol=2e-7)
    np.testing.assert_array_equal(img.color, np.full((h, w, 3), 0.75, np.float32))


def write_fresh(tmp_path, name):
    path = tmp_path / f"{name}.zarr"
    rgbn.write(image(70, 70, False), path, chunk=32)
    return path


def edit(path, file, old, new):
    f = path / file
    s = f.read_text()
    assert old in s, (file, old)
    f.write_text(s.replace(old, new, 1))


def test_bad_stores_raise_file_error_naming_the_store_and_the_fault(tmp_path):
    cases = {}

    p = write_fresh(tmp_path, "missing")
    (p / "0" / "c" / "0" / "1" / "1").unlink()
    cases[p] = "chunk 0/c/0/1/1 of level 0"

    p = write_fresh(tmp_path, "truncated")
    f = p / "0" / "c" / "0" / "0" / "2"
    f.write_bytes(f.read_bytes()[:20])
    cases[p] = "truncated or corrupt"

    # The wrong data type: an OME image of int32, written by zarr itself.
    p = tmp_path / "dtype.zarr"
    g = zarr.open_group(str(p), mode="w")
    g.create_array("0", shape=(3, 8, 8), dtype="int32", chunks=(3, 8, 8))[:] = 1
    g.attrs["ome"] = {
        "version": "0.5",
        "multiscales": [{"axes": [{"name": a} for a in "cyx"], "datasets": [{"path": "0"}]}],
        "omero": {"channels": [{"label": l} for l in ("nx", "ny", "nz")]},
    }
    cases[p] = "wrong data type"

    p = write_fresh(tmp_path, "channels")
    edit(p, "zarr.json", '"label": "nz",', '"label": "nz"}, {"label": "extra",')
    cases[p] = "wrong channel count"

    # A Zarr that is not OME: a plain group with an array.
    p = tmp_path / "plain.zarr"
    g = zarr.open_group(str(p), mode="w")
    g.create_array("0", shape=(3, 8, 8), dtype="float32", chunks=(3, 8, 8))[:] = 0
    cases[p] = "not an OME-Zarr image"

    for path, what in cases.items():
        before = sorted(q.relative_to(path) for q in path.rglob("*"))
        # The class rgbn.read raises for any file it cannot decode.
        with pytest.raises(rgbn.FileError) as e:
            rgbn.read(path)
        msg = str(e.value)
        assert what in msg and str(path) in msg, msg
        # Reading leaves the store as it was.
        assert sorted(q.relative_to(path) for q in path.rglob("*")) == before


def test_the_command_line_writes_stores_standard_tools_read(tmp_path, cli):
    src = tmp_path / "in.zarr"
    rgbn.write(image(100, 90, True), src, chunk=32)
    cli(["eval", GRAPHS / "input_image.ron", "--input", f"image={src}", "--stream", "always",
         "--chunk", "32", "-o", f"image={tmp_path / 'out.zarr'}", "-o", f"relit={tmp_path / 'relit.zarr'}"])
    g = zarr.open_group(str(tmp_path / "relit.zarr"), mode="r")
    assert g["0"].shape == (4, 100, 90) and str(g["0"].dtype) == "uint8"
    assert [c["label"] for c in g.attrs["ome"]["omero"]["channels"]] == ["R", "G", "B", "A"]
    out = rgbn.read(tmp_path / "out.zarr")
    assert out.mask is not None and out.normals.shape == (100, 90, 3)
    # Bad input through the command line: exit 2, one line naming the store.
    shutil.rmtree(src / "0" / "c" / "0" / "1")
    r = cli(["eval", GRAPHS / "input_image.ron", "--input", f"image={src}", "-o", f"image={tmp_path / 'o2.zarr'}"],
            check=False)
    assert r.returncode == 2 and "missing" in r.stderr and str(src) in r.stderr, r.stderr
