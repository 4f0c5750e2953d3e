"""One function per registered operator (``rgbn.ops()``), generated at import from the same
declarations as ``rgbn ops``: ``rgbn.op.filter_gaussian(image, sigma_px=8.0)``, …

Inputs are positional (or by port name), parameters keyword-only with the operator's
defaults; a function returns its only output, or a dict of outputs. Each calls
``rgbn.run_op`` — the node's own code. Type stubs: ``op.pyi`` (``python -m rgbn._opgen``).
"""

from . import _opgen
from ._rgbn import ops as _ops
from ._rgbn import run_op as _run_op

__all__ = []
for _op in _ops():
    _f = _opgen.make(_op, _run_op)
    globals()[_f.__name__] = _f
    __all__.append(_f.__name__)
del _op, _f
