"""rgbn from Python: RGBN images (colour + normals) as NumPy arrays, node graphs, operators.

Everything here calls the same Rust code as the ``rgbn`` command line and the graph nodes;
see ``docs/python.md`` in the repository for a guide with worked examples.

- :class:`Image` — normals (H×W×3), linear colour (H×W×3) and an optional mask (H×W), float32;
  :func:`read`, :func:`write`, :func:`read_color`, :func:`read_mask`.
- :class:`Graph` — a ``.ron`` graph with a lazy cache: ``load``, ``set``, ``eval``, ``hits``,
  ``misses``.
- :func:`ops` — every operator with its ports and parameters (``rgbn ops``); :mod:`rgbn.op` has
  one function per operator, generated from those declarations; :func:`run_op` runs any of them.
- :func:`filter`, :func:`integrate`, :func:`integrate_depth`, :func:`capture`, :func:`render`,
  :func:`info` — the common cases.
- :class:`Error` (:class:`InputError`, :class:`FileError`, :class:`EvalError`) with the
  command line's one-line messages; :class:`RepairWarning` for repaired normals.
"""

from . import _rgbn
from ._rgbn import (  # noqa: F401
    Error,
    EvalError,
    FileError,
    Graph,
    Image,
    InputError,
    RepairWarning,
    __version__,
    capture,
    filter,
    info,
    integrate,
    integrate_depth,
    ops,
    planar_copies,
    read,
    read_color,
    read_mask,
    render,
    run_op,
    write,
)

__all__ = [
    "Error",
    "EvalError",
    "FileError",
    "Graph",
    "Image",
    "InputError",
    "RepairWarning",
    "capture",
    "filter",
    "info",
    "integrate",
    "integrate_depth",
    "op",
    "ops",
    "planar_copies",
    "read",
    "read_color",
    "read_mask",
    "render",
    "run_op",
    "write",
]


def main(args=None):
    """Runs the ``rgbn`` command line with ``args`` (default: ``sys.argv[1:]``); returns the
    exit code."""
    import sys

    return _rgbn.main(list(sys.argv[1:] if args is None else args))


def _cli_entry():
    import sys

    sys.exit(main())


from . import op  # noqa: E402  (generated from ops(), needs the names above)
