"""Bitwise equality where the machine allows it.

The compiled plant and the fast environment paths evaluate their sines and cosines with the C
library (``math.cos``, numba), the numpy reference paths with numpy's ufuncs. numpy dispatches
float64 ``sin``/``cos`` to its own SIMD code on AVX-512 machines, which differs from the C library
in the last bit for some arguments; elsewhere numpy calls the C library and the paths agree to the
bit. The compiled kernels' small matrix products go through the BLAS numba links, numpy's through
its own; both pick their kernels by CPU. :data:`LIBM_TRIG` says whether this machine gives the
same bits both ways (probed over 20 000 arguments and 200 products), and
:func:`assert_same` asserts bit-for-bit equality there and agreement to round-off (relative
``1e-9`` of each column's scale, as a last-bit difference grows over a simulated run) otherwise.
"""

from __future__ import annotations

import math

import numpy as np

_x = np.random.default_rng(0).uniform(-40.0, 40.0, 20000)


def _blas_agrees() -> bool:
    """numba's ``np.dot`` (the BLAS numba links) gives numpy's ``@`` to the bit on small products."""
    try:
        import numba
    except ImportError:
        return True   # no compiled path to compare

    @numba.njit(cache=False)
    def dot(M, v):  # pragma: no cover - compiled
        return np.dot(M, v)

    rng = np.random.default_rng(1)
    for _ in range(200):   # the kernels' shapes: (3, 3) @ (3,), its transpose (Fortran order), (3, n) @ (n,)
        M, v = rng.normal(size=(3, 3)) * 1e6, rng.normal(size=3)
        T, f = rng.normal(size=(3, 6)), rng.normal(size=6) * 1e5
        if not (np.array_equal(dot(M, v), M @ v) and np.array_equal(dot(M.T, v), M.T @ v)
                and np.array_equal(dot(T, f), T @ f)):
            return False
    return True


#: The compiled and the numpy paths can agree to the bit on this machine: numpy's float64 sin and
#: cos are the C library's, and numba's BLAS products are numpy's.
LIBM_TRIG = bool(np.array_equal(np.cos(_x), [math.cos(v) for v in _x])
                 and np.array_equal(np.sin(_x), [math.sin(v) for v in _x]) and _blas_agrees())


def assert_same(a, b, rtol: float = 1e-9) -> None:
    """``a`` and ``b`` bit for bit (:data:`LIBM_TRIG`), else equal to ``rtol`` of each column's
    largest magnitude (the last axis of a 2-D array is its columns)."""
    a, b = np.asarray(a), np.asarray(b)
    assert a.shape == b.shape, (a.shape, b.shape)
    if LIBM_TRIG:
        assert np.array_equal(a, b, equal_nan=True), "not bit-identical"
        return
    scale = np.max(np.abs(b), axis=0, keepdims=True) if b.ndim == 2 else np.max(np.abs(b), initial=0.0)
    err = np.abs(a - b) / np.maximum(scale, 1e-300)
    assert np.all(np.isnan(a) == np.isnan(b)) and np.nanmax(err, initial=0.0) <= rtol, \
        f"differ by {np.nanmax(err, initial=0.0):.3g} of the column scale (> {rtol:g})"
