"""The compiled kernels' module for the plant's per-step calls, imported on first use (it imports
numba, which takes a while) and then kept, so a step does not run an import statement.
Construction-time code (``fem.FEMLines``) imports the module itself, through ``sys.modules``."""

from __future__ import annotations

from typing import Any

_FEM_KERNEL: Any = None


def fem_kernel() -> Any:
    """:mod:`tapm_opt.plant.fem_kernel` (imported the first time, then kept)."""
    global _FEM_KERNEL
    if _FEM_KERNEL is None:
        from . import fem_kernel as module

        _FEM_KERNEL = module
    return _FEM_KERNEL
