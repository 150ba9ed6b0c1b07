"""Reading ``torch.save`` files that someone else wrote (released checkpoints), without running their code.

:func:`load_tensors_only` always uses ``torch.load(weights_only=True)``: the unpickler builds only
tensors, containers and plain values, plus the extra globals a format is known to need (for example
``argparse.Namespace`` for a checkpoint that stores its training flags). Anything else in the pickle
(an arbitrary class, a function, a ``__reduce__`` payload) is refused before it is built, and every
failure (missing, truncated, not a torch file, a disallowed global) is an :class:`InputError` naming
the file.
"""

from __future__ import annotations

import argparse
import re
from pathlib import Path
from typing import Any, Iterable

import torch

from dyadbench.errors import InputError


def numpy_array_globals() -> list:
    """The numpy globals a pickled float32/float64/int64 ``numpy.ndarray`` needs (numpy 1.x and 2.x names)."""
    import numpy as np

    try:
        from numpy._core.multiarray import _reconstruct
    except ImportError:  # numpy < 2
        from numpy.core.multiarray import _reconstruct
    dtypes = [getattr(np.dtypes, n) for n in ("Float32DType", "Float64DType", "Int64DType", "Int32DType",
                                              "BoolDType") if hasattr(getattr(np, "dtypes", None), n)]
    return [_reconstruct, np.ndarray, np.dtype, *dtypes]


#: Globals of a checkpoint that stores argparse flags holding numpy arrays (TIMAR's release).
NAMESPACE_WITH_ARRAYS = (argparse.Namespace,)


def load_tensors_only(path: str | Path, *, allowed_globals: Iterable = (), what: str = "checkpoint") -> Any:
    """``torch.load(path, weights_only=True)`` on the CPU with only ``allowed_globals`` added.

    ``what`` names the expected content in error messages (e.g. "TIMAR checkpoint").
    """
    path = Path(path)
    if not path.is_file():
        raise InputError(path, f"{what} file not found")
    allowed = list(allowed_globals)
    try:
        with torch.serialization.safe_globals(allowed):
            return torch.load(path, map_location="cpu", weights_only=True)
    except Exception as exc:  # noqa: BLE001 - every failure of a foreign file becomes one clear message
        raise InputError(path, _why_unreadable(exc, what)) from None


def _why_unreadable(exc: Exception, what: str) -> str:
    text = str(exc)
    # torch names a refused global as "Unsupported global: GLOBAL x.y" or, for a blocked module such as
    # os/posix, "unsupported GLOBAL posix.system whose module posix is blocked"
    refused = re.search(r"unsupported (?:global: )?GLOBAL ([\w.]+)", text, flags=re.IGNORECASE)
    if refused:
        return (f"refused to load this {what}: its pickle needs {refused.group(1)}, which is not part of the "
                f"format (loading never runs code from a checkpoint; weights_only=True)")
    first = text.strip().splitlines()[0] if text.strip() else ""
    return f"not a readable {what} (truncated or not a torch.save file: {type(exc).__name__}: {first[:200]})"
