"""numba compilation shared by the compiled kernels (FEM lines ``plant.fem_kernel``, thrust
allocation ``control.allocation_step``, tabulated mooring load ``models.characteristics``)."""

from __future__ import annotations

from typing import Any, Callable

__all__ = ["numba_available", "jit"]


def numba_available() -> bool:
    """True when numba can be imported (a declared dependency; without it every kernel runs as
    plain Python or numpy, with the same results, slower)."""
    try:
        __import__("numba")
    except ImportError:
        return False
    return True


def jit(fn: Callable, *, fallback: Any = "python") -> Any:
    """``fn`` compiled by numba with numpy floating-point semantics (division by zero gives inf or
    nan, as numpy does), cached on disk when a cache directory can be written, else compiled once
    per process. numba compiles on the first call. Without numba: ``fn`` itself
    (``fallback="python"``) or ``fallback``."""
    try:
        from numba import njit
    except ImportError:  # numba is a declared dependency: this is a safety net
        return fn if fallback == "python" else fallback
    try:
        return njit(cache=True, error_model="numpy")(fn)
    except RuntimeError:  # numba found no writable cache location
        return njit(error_model="numpy")(fn)
