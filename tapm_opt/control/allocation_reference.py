"""Thrust allocation: the readable reference of the QP, written with cvxpy (tests and documentation only).

:mod:`tapm_opt.control.allocation` re-exports :func:`allocate_reference`, so this module does not
import it back: the allocator comes in as an argument.
"""

from __future__ import annotations

import math
import time
from typing import Any

import numpy as np

from ..models.thrust import configuration_matrix, extended_columns
from .allocation_base import AllocationError, AllocationResult
from .allocation_step import HALF_PI

__all__ = ["allocate_reference"]


def allocate_reference(allocator: Any, tau_cmd: Any, dt: float | None = None, *,
                       solver: str = "HIGHS", **solver_options: Any) -> AllocationResult:
    """The same QP as :meth:`ThrustAllocator.allocate`, written with cvxpy in the body-frame force
    components u_i (radial and tangential parts as projections on e(b), e(b + pi/2)) and built on
    every call.

    For tests and documentation only (slow). Uses the allocator's current state (previous command,
    failures) and does not change it. ``solver`` and ``solver_options`` go to ``cvxpy.Problem.solve``;
    the default, HiGHS's active-set QP solver, solves these small problems exactly, whereas
    CLARABEL (interior point) hit its iteration limit on some with the heavily weighted slack.
    The step data (intervals, frames, bounds) and the post-processing are shared with the OSQP
    path; the variables, cost and constraints are written out here, independently of the OSQP
    matrices. In the result, ``solve_time`` is the wall time of the cvxpy solve and
    ``iterations`` is 0.

    Parameters
    ----------
    allocator : ThrustAllocator
        The allocator whose QP is rebuilt (its step data, weights and state are read).
    tau_cmd : array_like, shape (3,)
        Commanded generalised force in {B} [N, N, N m].
    dt : float, optional
        Time step [s] of the rate limits (as for :meth:`ThrustAllocator.allocate`).

    Raises
    ------
    AllocationError
        Bad or non-finite tau_cmd, bad dt, or the reference solver did not reach the optimum.
    """
    import cvxpy as cp

    al = allocator
    tau = al._check_tau(tau_cmd)
    if not np.isfinite(tau).all():
        raise AllocationError(f"tau_cmd={tau.tolist()} is not finite")
    g = al._geometry(al._check_dt(dt))
    t0 = time.perf_counter()
    naz, nfx = al._naz, al._nfx
    U = cp.Variable((max(naz, 1), 2))   # scaled azimuth force components (f_x, f_y) in {B}
    ff = cp.Variable(max(nfx, 1))       # scaled tunnel/fixed thrusts
    s = cp.Variable(3)                  # scaled slack
    Bu: Any = s
    for j, i in enumerate(al._iaz):
        Bu = Bu + (extended_columns(al._x[i], al._y[i]) * al._row_scale[:, None]) @ U[j]
    for k, i in enumerate(al._ifx):
        col = configuration_matrix(al._angle0[i:i + 1], al._x[i:i + 1], al._y[i:i + 1])[:, 0]
        Bu = Bu + (col * al._row_scale) * ff[k]
    balance = Bu == tau * al._tau_scale
    cons = [balance]

    def e(a: float) -> np.ndarray:
        return np.array([math.cos(a), math.sin(a)])

    phi = np.arctan2(al._poly_n[:, 1], al._poly_n[:, 0])
    for j in range(naz):
        u, b = U[j], float(g.b[j])
        radial, tangential = e(b) @ u, e(b + HALF_PI) @ u
        cons += [np.array([e(b + ph) for ph in phi]) @ u <= al._Rin[j],  # polygon, a vertex along b
                 radial >= g.lp[j], radial <= g.hp[j], tangential >= g.lv[j], tangential <= g.hv[j]]
    for k in range(nfx):
        cons += [ff[k] >= g.lf[k], ff[k] <= g.hf[k]]
    cost = al.slack_weight * cp.sum_squares(s)
    if naz:
        cost = cost + cp.sum_squares(cp.multiply(np.sqrt(al._wa)[:, None], U[:naz]))
    if nfx:
        cost = cost + cp.sum_squares(cp.multiply(np.sqrt(al._wf), ff[:nfx]))
    prob = cp.Problem(cp.Minimize(cost), cons)
    prob.solve(solver=solver, **solver_options)
    if prob.status != "optimal":
        raise AllocationError(f"reference solve with {solver} ended with status {prob.status!r}")
    x = np.zeros(al._nv + 3)
    if naz:  # to the allocator's variables (p, v) for the shared post-processing
        Uv = np.asarray(U.value)[:naz]
        cb, sb = np.cos(g.b), np.sin(g.b)
        x[:naz] = Uv[:, 0] * cb + Uv[:, 1] * sb
        x[naz:2 * naz] = -Uv[:, 0] * sb + Uv[:, 1] * cb
    if nfx:
        x[2 * naz:al._nv] = ff.value[:nfx]
    # cvxpy's equality dual follows OSQP's convention (P x + q + A^T y = 0) for ``B u + s == tau``
    y = np.asarray(balance.dual_value, dtype=float)
    return al._finish(x, y, tau, g, "solved", time.perf_counter() - t0, 0, commit=False)
