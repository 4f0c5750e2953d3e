"""Graphs: results equal the command line's bit for bit, the cache recomputes only what an
edit reaches, errors carry the command line's messages."""

import filecmp
import re

import numpy as np
import pytest

import rgbn
from conftest import GRAPHS

# Every example graph; those with a graph input get the repository's image (and mask).
EXAMPLES = sorted(p for p in GRAPHS.glob("*.ron")) + sorted((GRAPHS / "paper").glob("*.ron"))
DATA_IMAGE = GRAPHS / "data" / "image.exr"
DATA_MASK = GRAPHS / "data" / "mask.png"

EXT = {"rgbn": "exr", "scalar": "exr", "mask": "exr", "picture": "png", "number": "txt"}

# Sums over the image taken in parallel (curl statistics, the conjugate-gradient solves' dot
# products) are added in a fixed order (`raster::par::OrderedReduce`), so every output,
# numbers included, is compared bit for bit.


def same_tree(a, b):
    """Whether files (or folders, recursively) `a` and `b` hold the same bytes."""
    if a.is_dir():
        names = sorted(p.name for p in a.iterdir())
        return b.is_dir() and names == sorted(p.name for p in b.iterdir()) and all(
            same_tree(a / n, b / n) for n in names)
    return b.is_file() and filecmp.cmp(a, b, shallow=False)


def bindings(g):
    out = {}
    for name, ty in g.inputs.items():
        out[name] = DATA_IMAGE if ty == "rgbn" else DATA_MASK
    return out


@pytest.mark.parametrize("graph", EXAMPLES, ids=lambda p: p.relative_to(GRAPHS).as_posix())
def test_eval_equals_rgbn_eval_bit_for_bit(graph, tmp_path, cli):
    g = rgbn.Graph.load(graph)
    files = bindings(g)
    cli_dir, py_dir = tmp_path / "cli", tmp_path / "py"
    cli_dir.mkdir()
    py_dir.mkdir()
    args = ["eval", graph, "--stream", "never"]
    for name, path in files.items():
        args += ["-i", f"{name}={path}"]
    for name, ty in g.outputs.items():
        args += ["-o", f"{name}={cli_dir / (name + '.' + EXT[ty])}"]
    cli(args, cwd=cli_dir)
    # Python: images bound from memory (read as the load node reads them), masks by path.
    inputs = {n: (rgbn.read(p) if g.inputs[n] == "rgbn" else p) for n, p in files.items()}
    out = g.eval(inputs=inputs, out_dir=py_dir)
    assert set(out) == set(g.outputs)
    for name, ty in g.outputs.items():
        ours = py_dir / (name + "." + EXT[ty])
        value = out[name]
        if ty == "number":
            theirs = float(cli_dir.joinpath(name + ".txt").read_text())
            assert value == theirs or (np.isnan(value) and np.isnan(theirs)), name
            continue
        rgbn.write(value, ours, mask=(ty == "mask"))
        assert filecmp.cmp(ours, cli_dir / ours.name, shallow=False), f"{graph.name}: {name} differs"
    # Files the graph writes itself (save nodes) are equal too.
    for f in cli_dir.iterdir():
        if f.name.split(".")[0] not in g.outputs:
            assert same_tree(f, py_dir / f.name), f"{graph.name}: {f.name} differs"


def test_set_then_eval_recomputes_only_downstream_nodes():
    # graphs/input_image.ron: input "image" → sharpen (node 1) → relight (node 2). The
    # evaluator is lazy: a node found in the cache is a hit and is not descended into.
    g = rgbn.Graph.load(GRAPHS / "input_image.ron")
    img = rgbn.read(DATA_IMAGE)
    first = g.eval(inputs={"image": img})
    assert (g.hits, g.misses) == (0, 3)  # bound input, sharpen, relight
    g.eval(inputs={"image": img})
    assert (g.hits, g.misses) == (2, 0)  # both outputs' nodes cached
    g.set("sharpen.amount", 2.5)
    out = g.eval(inputs={"image": img}, outputs=["relit"])
    status = {(s["op"]): s["status"] for s in g.stats}
    assert status == {"bound.rgbn": "hit", "filter.sharpen": "miss", "relight": "miss"}
    assert (g.hits, g.misses) == (1, 2)
    assert not np.array_equal(out["relit"], first["relit"])
    g.set("2.exposure_ev", 0.5)  # relight, by node id
    g.eval(inputs={"image": img}, outputs=["relit"])
    assert [(s["op"], s["status"]) for s in g.stats] == [("filter.sharpen", "hit"), ("relight", "miss")]
    assert g.get("sharpen.amount") == 2.5 and g.get("2.exposure_ev") == 0.5
    # The same pixels in a new Image are the same content: all hits.
    g.eval(inputs={"image": rgbn.Image(img.normals.copy(), img.color.copy())}, outputs=["relit"])
    assert (g.hits, g.misses) == (1, 0)
    g.clear_cache()
    g.eval(inputs={"image": img}, outputs=["relit"])
    assert (g.hits, g.misses) == (0, 3)


def test_an_array_bound_input_equals_the_file_bound_one():
    g = rgbn.Graph.load(GRAPHS / "input_image.ron")
    by_file = g.eval(inputs={"image": DATA_IMAGE})
    img = rgbn.read(DATA_IMAGE)
    by_array = g.eval(inputs={"image": rgbn.Image(np.array(img.normals), np.array(img.color))})
    np.testing.assert_array_equal(by_array["relit"], by_file["relit"])
    np.testing.assert_array_equal(by_array["image"].normals, by_file["image"].normals)


def test_graph_errors_carry_the_command_line_messages(cli, tmp_path):
    g = rgbn.Graph.load(GRAPHS / "demo.ron")
    with pytest.raises(rgbn.InputError) as e:
        g.set("sharpen.amont", 1.0)
    r = cli(["eval", GRAPHS / "demo.ron", "--set", "sharpen.amont=1.0"], check=False)
    assert r.stderr.strip() == f"rgbn: {e.value}"
    assert 'did you mean "amount"' in str(e.value)
    with pytest.raises(rgbn.InputError) as e:
        g.set("sharpen.amount", "lots")
    r = cli(["eval", GRAPHS / "demo.ron", "--set", "sharpen.amount=lots"], check=False)
    assert r.stderr.strip() == f"rgbn: {e.value}"
    with pytest.raises(rgbn.InputError, match=r'unknown graph output "relt" \(did you mean "relit"\?\)'):
        g.eval(outputs=["relt"])
    gi = rgbn.Graph.load(GRAPHS / "input_image.ron")
    with pytest.raises(rgbn.InputError, match=r'graph input "image" is needed but not given'):
        gi.eval()
    with pytest.raises(rgbn.FileError):
        rgbn.Graph.load(tmp_path / "missing.ron")
    bad = tmp_path / "bad.ron"
    bad.write_text("(version: 1, nodes: [")
    r = cli(["check", bad], check=False)
    with pytest.raises(rgbn.Error) as e:
        rgbn.Graph.load(bad)
    assert r.stderr.strip() == f"rgbn: {e.value}"


def test_outputs_have_the_documented_types():
    g = rgbn.Graph.load(GRAPHS / "demo.ron")
    out = g.eval()
    assert isinstance(out["image"], rgbn.Image)
    assert out["relit"].dtype == np.uint8 and out["relit"].shape[2] == 4
    assert isinstance(out["curl"], float)
    assert re.match(r"rgbn\.Graph\(.*demo\.ron: \d+ nodes\)", repr(g))
