"""Thrust allocation: the error type, the result object and the weighted pseudo-inverse.

The pieces of :mod:`tapm_opt.control.allocation` that neither the allocator (DAQP or OSQP) nor
the cvxpy reference owns: :class:`AllocationError`, :class:`AllocationResult` (immutable), the weighted
least-norm solution :func:`pseudo_inverse` (the allocator's fallback and the analytic limit the
tests compare the QP with) and the allocator's small helpers (argument checks, read-only results).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from .._checks import finite, positive
from ..errors import TapmError

__all__ = ["AllocationError", "AllocationResult", "pseudo_inverse"]


class AllocationError(TapmError, ValueError):
    """Thrust allocation was given an invalid argument (thruster data, tau shape, thruster id)."""


@dataclass(frozen=True)
class AllocationResult:
    """Thruster commands for one tau_cmd.

    Attributes
    ----------
    f : ndarray, shape (n,)
        Thrust [N]: >= 0 for azimuths (along alpha), signed for tunnel/fixed thrusters
        (in [-max_reverse_thrust, max_thrust]); exactly 0 for failed thrusters.
    alpha : ndarray, shape (n,)
        Thrust directions in {B} [rad] in [-pi, pi): commanded azimuths; the fixed angle of
        tunnel/fixed thrusters.
    tau : ndarray, shape (3,)
        Generalised force the commands produce, ``T(alpha) f`` [N, N, N m].
    slack : ndarray, shape (3,)
        Unmet part ``tau_cmd - tau`` [N, N, N m] (NaN where tau_cmd was not finite).
    status : str
        ``"solved"``, ``"solved_inaccurate"`` (OSQP: accepted, primal residual small) or
        ``"fallback:<reason>"`` (reason: a solver status such as ``max_iter_reached``,
        ``primal_infeasible``, ``non_finite_solution``, or ``invalid_tau``).
    fallback : bool
        True when f, alpha come from the saturated pseudo-inverse (or are zero for invalid tau).
    solve_time : float
        Solver time [s]: DAQP ``update`` + ``solve`` (wall time), OSQP solve + polish (0 when no
        solver was called).
    iterations : int
        Active-set iterations (DAQP) or ADMM iterations (OSQP); 0 when no solver was called.
    message : str
        Human-readable explanation.
    """

    f: np.ndarray
    alpha: np.ndarray
    tau: np.ndarray
    slack: np.ndarray
    status: str
    fallback: bool
    solve_time: float
    iterations: int
    message: str = ""

    @property
    def success(self) -> bool:
        """True when the QP solution was used (not the fallback)."""
        return not self.fallback


def pseudo_inverse(T: Any, tau: Any, weights: Any = None, *, row_scale: Any = None,
                   rcond: float = 1e-10) -> np.ndarray:
    """Weighted least-norm solution of ``T f = tau``.

    Minimises ``sum_i w_i f_i^2`` subject to ``T f = tau``, i.e.
    ``f = W^-1 T^T (T W^-1 T^T)^-1 tau`` when T has full row rank. When ``T f = tau`` has no
    solution (rank-deficient T), returns the least-norm minimiser of ``|S (T f - tau)|`` with
    ``S = diag(row_scale)`` (computed as ``W^-1/2 pinv(S T W^-1/2) S tau``).

    Parameters
    ----------
    T : array_like, shape (3, n)
        Configuration matrix (or extended matrix B) [-, -, m].
    tau : array_like, shape (3,)
        Generalised force [N, N, N m].
    weights : array_like, shape (n,), optional
        w_i > 0 [1/N^2] (default ones). A column with weight inf is not used (f_i = 0).
    row_scale : array_like, shape (3,), optional
        Row scaling S (e.g. ``(1, 1, 1/L_ref)``) for the least-squares case; default ones.
    rcond : float
        Relative cut-off of small singular values (``numpy.linalg.pinv``).

    Returns
    -------
    ndarray, shape (n,)
        Forces [N].
    """
    T = np.asarray(T, dtype=float)
    tau = np.asarray(tau, dtype=float)
    if T.ndim != 2 or tau.shape != (T.shape[0],):
        raise AllocationError(f"pseudo_inverse: T has shape {T.shape} and tau {tau.shape}; expected (k, n) and (k,)")
    w = np.ones(T.shape[1]) if weights is None else np.asarray(weights, dtype=float)
    if w.shape != (T.shape[1],) or not np.all(w > 0):
        raise AllocationError(f"pseudo_inverse: weights must be {T.shape[1]} positive numbers, got {weights!r}")
    S = np.ones(T.shape[0]) if row_scale is None else np.asarray(row_scale, dtype=float)
    wi = 1.0 / np.sqrt(w)  # inf weight -> column unused
    Ts = (S[:, None] * T) * wi[None, :]
    return wi * (np.linalg.pinv(Ts, rcond=rcond) @ (S * tau))


def _new_result(f, alpha, tau, slack, status, fallback, t_solve, it, message) -> AllocationResult:
    """An :class:`AllocationResult` built without the frozen dataclass's ``__init__`` (which sets
    each field through ``object.__setattr__``): the same object, in a third of the time."""
    r = _NEW(AllocationResult)
    d = r.__dict__
    d["f"] = f
    d["alpha"] = alpha
    d["tau"] = tau
    d["slack"] = slack
    d["status"] = status
    d["fallback"] = fallback
    d["solve_time"] = t_solve
    d["iterations"] = it
    d["message"] = message
    return r


_NEW = object.__new__


def _result(f, alpha, tau, slack, status, fallback, t_solve, it, message) -> AllocationResult:
    """An :class:`AllocationResult` whose arrays are made read-only (no copy: they are fresh)."""
    for a in (f, alpha, tau, slack):
        a.setflags(write=False)
    return _new_result(f, alpha, tau, slack, status, fallback, t_solve, it, message)


def _result_view(out, slices, status, t_solve, it, message) -> AllocationResult:
    """A QP result (``fallback=False``) whose f, alpha, tau, slack are read-only views of the
    fresh array ``out`` (``slices``: where each is)."""
    out.setflags(write=False)
    s0, s1, s2, s3 = slices
    return _new_result(out[s0], out[s1], out[s2], out[s3], status, False, t_solve, it, message)


def _finite(name: str, v: Any) -> float:
    return finite(name, v, error=AllocationError, eq="=")


def _positive(name: str, v: Any) -> float:
    return positive(name, v, error=AllocationError, eq="=")
