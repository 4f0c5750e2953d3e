"""The worked examples of docs/python.md run, in order, as one script."""

import os
import re

from conftest import GRAPHS, REPO


def test_docs_python_md_examples_run(tmp_path, capsys):
    text = (REPO / "docs" / "python.md").read_text()
    blocks = re.findall(r"```python\n(.*?)```", text, re.S)
    assert len(blocks) >= 6
    (tmp_path / "graphs").symlink_to(GRAPHS)
    cwd = os.getcwd()
    os.chdir(tmp_path)
    try:
        ns = {"__name__": "docs_python_md"}
        for i, code in enumerate(blocks):
            exec(compile(code, f"docs/python.md block {i + 1}", "exec"), ns)
    finally:
        os.chdir(cwd)
    out = capsys.readouterr().out
    assert "1 invalid normals (NaN or infinite)" in out
    assert "0 3\n" in out and "1 2\n" in out
    assert (tmp_path / "sphere.ply").stat().st_size > 1000
    assert sorted(p.name for p in (tmp_path / "relit").iterdir()) == [
        "n0.exr", "n0.png", "n1.exr", "n1.png", "n2.exr", "n2.png"]
