"""Symbolic (CasADi) fairlead tensions of a line whose quasi-static solve has no closed symbolic
form — a composite line (sections and points, :mod:`tapm_opt.models.composite`) — as smooth
interpolants of its exact solution.

``HF(XF)`` and ``VF(XF)`` [N] of one line at its fairlead height are sampled from the line's exact
solve (``MooringModel.line_solver``) on a uniform grid over the distances the line can take, and
interpolated by cubic B-splines (CasADi ``interpolant``, ``"bspline"``), which an NLP
differentiates to any order. The error of a cubic spline through exact samples is
``O(h^4 f'''')`` on smooth stretches and ``O(h^2)`` times the jump of the slope where a section's
regime changes (a joint touching the seabed); with the default 4097 samples over the range it is
checked against the exact solve at the midpoints between samples and reported
(:attr:`LineInterpolant.max_error`, relative to the line's pretension). Measured on fpso's lines
as chain–wire–chain with a buoy over the load tables' range (1469–2455 m): 9e-6 with 4097
samples (2.3e-5 with 2049, 1.3e-5 with 8193: at a kink the spline rings, its error does not fall
steadily with the spacing), 0.7 s per distinct line.

Outside the sampled range the spline would extrapolate; the Function's third output
``closure_error`` [m] is then the distance beyond the range (0 inside), so a caller that checks it —
as ``MooringModel.force_function(kind="catenary")`` does with its ``closure_tol`` — gets NaN rather
than a wrong load, as with the homogeneous lines' root.
"""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np

__all__ = ["LineInterpolant", "line_interpolant"]


@dataclass(frozen=True)
class LineInterpolant:
    """``function(XF) -> (HF, VF, closure_error)`` (CasADi, scalar in and out) over
    [``lo``, ``hi``] [m], and its largest error at the midpoints of the samples relative to
    ``T_ref`` [N]."""

    function: ca.Function
    lo: float
    hi: float
    max_error: float


def line_interpolant(solve, lo: float, hi: float, *, T_ref: float, n: int = 4097,
                     name: str = "line") -> LineInterpolant:
    """Cubic B-spline interpolants of a line's ``HF(XF)`` and ``VF(XF)`` over [lo, hi] [m].

    Parameters
    ----------
    solve : callable
        The line's exact solution ``XF -> CatenarySolution`` (``MooringModel.line_solver(i)``).
    lo, hi : float
        Distance range [m], ``hi > lo >= 0``.
    T_ref : float
        Tension scale [N] of the error check (the line's pretension).
    n : int
        Samples (>= 4).
    """
    if not (np.isfinite(lo) and np.isfinite(hi) and hi > lo >= 0.0):
        raise ValueError(f"range [{lo!r}, {hi!r}] m must be finite with hi > lo >= 0")
    if n < 4:
        raise ValueError(f"n = {n!r} must be >= 4")
    X = np.linspace(lo, hi, n)
    s = solve(X)
    fH = ca.interpolant(f"{name}_HF", "bspline", [X.tolist()], np.asarray(s.HF, float).tolist())
    fV = ca.interpolant(f"{name}_VF", "bspline", [X.tolist()], np.asarray(s.VF, float).tolist())
    Xm = 0.5 * (X[1:] + X[:-1])
    sm = solve(Xm)
    eH = np.abs(np.asarray(fH(Xm[None, :]).full()).ravel() - sm.HF)
    eV = np.abs(np.asarray(fV(Xm[None, :]).full()).ravel() - sm.VF)
    err = float(np.max(np.maximum(eH, eV)) / max(T_ref, 1e-300))
    x = ca.MX.sym("XF")
    beyond = ca.fmax(lo - x, 0.0) + ca.fmax(x - hi, 0.0)
    fn = ca.Function(name, [x], [fH(x), fV(x), beyond], ["XF"], ["HF", "VF", "closure_error"])
    return LineInterpolant(function=fn, lo=float(lo), hi=float(hi), max_error=err)
