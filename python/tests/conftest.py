"""Shared helpers: the repository's folders and the `rgbn` command-line binary to compare with.

The command line is found through ``RGBN_CLI`` (CI sets it to the binary `cargo test` built),
else ``target/release/rgbn`` or ``target/debug/rgbn`` of the repository. Tests that compare
with it skip when there is none, unless ``RGBN_REQUIRE_CLI=1`` (CI), where that is a failure.
"""

import os
import pathlib
import subprocess

import numpy as np
import pytest

REPO = pathlib.Path(__file__).resolve().parents[2]
GRAPHS = REPO / "graphs"


def cli_path():
    env = os.environ.get("RGBN_CLI")
    if env:
        return pathlib.Path(env)
    for kind in ("release", "debug"):
        for target in (os.environ.get("CARGO_TARGET_DIR"), REPO / "target"):
            if target:
                p = pathlib.Path(target) / kind / "rgbn"
                if p.exists():
                    return p
    return None


@pytest.fixture(scope="session")
def cli():
    """Runs the `rgbn` binary: cli(args, cwd=...) → CompletedProcess (text)."""
    path = cli_path()
    if path is None or not path.exists():
        if os.environ.get("RGBN_REQUIRE_CLI") == "1":
            pytest.fail(f"RGBN_REQUIRE_CLI=1 but no rgbn binary (RGBN_CLI={os.environ.get('RGBN_CLI')})")
        pytest.skip("no rgbn binary: set RGBN_CLI or build it (cargo build)")

    def run(args, cwd=None, check=True):
        r = subprocess.run([str(path), *map(str, args)], cwd=cwd, capture_output=True, text=True)
        if check and r.returncode != 0:
            raise AssertionError(f"rgbn {' '.join(map(str, args))} failed ({r.returncode}): {r.stderr}")
        return r

    return run


def sphere_normals(h, w, r=None):
    """Unit normals of a hemisphere of radius ``r`` px centred in an h×w image (flat outside),
    OpenGL frame (+y up), and its height (0 outside)."""
    r = r or 0.45 * min(h, w)
    y, x = np.mgrid[0:h, 0:w].astype(np.float64)
    dx = x - (w - 1) / 2
    dy = -(y - (h - 1) / 2)
    rho2 = dx**2 + dy**2
    inside = rho2 < r * r
    z = np.where(inside, np.sqrt(np.maximum(r * r - rho2, 0)), 0.0)
    n = np.zeros((h, w, 3))
    n[..., 2] = 1
    n[inside, 0] = dx[inside] / r
    n[inside, 1] = dy[inside] / r
    n[inside, 2] = z[inside] / r
    n /= np.linalg.norm(n, axis=2, keepdims=True)
    return n.astype(np.float32), z


def smooth_bump(h, w):
    """A band-limited height (sum of low-frequency cosines) and its exact normals in the
    averaged edge model's continuum limit: n = normalize(-∂z/∂x, -∂z/∂y, 1), y up."""
    y, x = np.mgrid[0:h, 0:w].astype(np.float64)
    yu = -y  # y up
    a, b = 2 * np.pi / w, 2 * np.pi / h
    z = 3.0 * np.cos(a * x) * np.cos(b * yu) + 2.0 * np.sin(2 * a * x)
    p = -3.0 * a * np.sin(a * x) * np.cos(b * yu) + 4.0 * a * np.cos(2 * a * x)
    q = -3.0 * b * np.cos(a * x) * np.sin(b * yu)
    n = np.stack([-p, -q, np.ones_like(p)], axis=2)
    n /= np.linalg.norm(n, axis=2, keepdims=True)
    return n.astype(np.float32), z
