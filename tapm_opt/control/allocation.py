"""Constrained thrust allocation: tau_cmd -> thruster commands (f, alpha) by a QP solved with DAQP
(default) or OSQP.

Extended-thrust formulation (``docs/controllers.md``, "Thrust allocation"). Forces are scaled by
``F_ref`` (largest max_thrust) and moments by ``F_ref L_ref`` (L_ref: largest thruster lever), so
the QP's variables and rows are of order one. Unknowns:

* azimuth i: its force ``u_i`` in {B}, in a local frame turned to the direction ``b_i`` it may
  point to this step: ``u_i = p_i e(b_i) + v_i e(b_i + pi/2)`` (radial p, tangential v), so that
  ``tau = B_i u_i`` with ``B_i`` = :func:`~tapm_opt.models.thrust.extended_columns`;
  ``f_i = |u_i|``, ``alpha_i = atan2(u_i)``;
* tunnel/fixed thruster i: its signed thrust f_i along its fixed direction;
* a slack ``s`` (3,) on the force balance.

The QP (``~``: scaled)::

    minimise    sum_i k_i (f_i / max_thrust_i)^2 + rho_s |s~|^2          (power surrogate + slack)
    subject to  B~ u~ + s~ = tau~                                         (force balance)
                n_k . (p_i, v_i) <= R_i cos(pi/m),  k = 0..m-1            inscribed m-gon, a vertex on b_i
                lp_i <= p_i <= hp_i,  lv_i <= v_i <= hv_i,  lf_i <= f_i <= hf_i

Rates and sectors are linearised about the previous command ``(f_p, alpha_p)``: the direction
intervals, local frames b_i and bounds of one step are those of
:mod:`tapm_opt.control.allocation_step` (narrow, half, free or empty interval).

The returned command is then clipped to the exact limits (|Delta f| <= r dt, f <= max_thrust,
|Delta alpha| within the interval). An idle azimuth (|u_i| <= idle_tol F_ref) gets zero thrust and
keeps alpha_p, or (``steer_idle``) turns within its interval toward its preferred direction
``-W_i^-1 B_i^T y / 2`` (y: the multiplier of the force balance), so that a thruster pointing
away from the demand does not stay there. The step data and this post-processing are the
compiled kernels of :mod:`~tapm_opt.control.allocation_step`, shared by both solvers.

DAQP (``solver="daqp"``, the default) is a dual active-set solver for small dense QPs. The cost
is diagonal (positive definite through the slack and power weights); the bounds on p, v, f are
DAQP's simple bounds, the balance rows equality rows. Two ``daqp.Model`` are set up once, one with
the whole polygon and one with only its two sides at the vertex on b_i, which is the same QP
whenever every live azimuth's rectangle spans at most one side (narrow, hw <= 2 pi / m: the
usual control-loop step). They share one A, bupper and blower buffer (the smaller model uses its
leading rows). Each :meth:`ThrustAllocator.allocate` has the step kernel write the bounds, the
scaled tau and, only when a frame b_i moved, the balance entries of the (p_i, v_i) columns; then
``Model.update`` with what changed (the models keep views of the buffers: bupper, and A when a
frame moved; blower is read in place, which the constructor checks once, else it is passed too)
and ``Model.solve``, warm-started from the previous active set (the model keeps it; after a
failure or a switch of model the next solve starts cold). An exit flag other than
optimal gives the fallback below with the flag's name (:data:`DAQP_STATUS`).

OSQP (``solver="osqp"``) is set up once with this fixed sparsity (the whole polygon). Each call
writes l and u, updates the balance entries of A when the frames b_i moved, warm-starts from the
previous solution, solves and checks ``info.status_val``. Anything but solved (or
solved-inaccurate with a small primal residual) gives the fallback.

The fallback is the saturated weighted pseudo-inverse at the previous azimuths, reported as
``fallback=True`` with ``status="fallback:<reason>"``.

The error and result types and :func:`pseudo_inverse` are in
:mod:`tapm_opt.control.allocation_base`, the cvxpy reference :func:`allocate_reference` in
:mod:`tapm_opt.control.allocation_reference`; all are importable from here.
"""

from __future__ import annotations

import math
import time
from collections.abc import Mapping, Sequence
from typing import Any, NamedTuple

import daqp
import numpy as np
import osqp
import scipy.sparse as sp

from ..config import schema
from ..geometry import ssa
from ..models.thrust import configuration_matrix, extended_columns, merge_sectors
from .allocation_base import AllocationError, AllocationResult, _finite, _positive, _result, _result_view, pseudo_inverse
from .allocation_reference import allocate_reference
from .allocation_step import (
    _BIG,
    _INF,
    C_ANGLE,
    C_ARATE,
    C_BX,
    C_BY,
    C_FMAX,
    C_FMIN,
    C_IP,
    C_IV,
    C_KIND,
    C_NSEC,
    C_RATE,
    C_RIN,
    C_TX,
    C_TY,
    C_W,
    C_X,
    C_Y,
    CODE_FULL,
    CODE_MOVED,
    N_C,
    N_G,
    N_S,
    S_ALPHA,
    S_B,
    S_F,
    S_FAILED,
    _Step,
    arc,
    finish_kernel,
    step_kernel,
)

__all__ = [
    "AllocationError",
    "AllocationResult",
    "DAQP_DEFAULTS",
    "DAQP_STATUS",
    "OSQP_DEFAULTS",
    "SOLVERS",
    "ThrustAllocator",
    "allocate_reference",
    "pseudo_inverse",
]

#: Solvers of the QP (``ThrustAllocator(solver=...)``).
SOLVERS = ("daqp", "osqp")

_STATUS_NAMES = {int(s): s.name.removeprefix("OSQP_").lower() for s in osqp.SolverStatus}
_SOLVED = int(osqp.SolverStatus.OSQP_SOLVED)
_SOLVED_INACCURATE = int(osqp.SolverStatus.OSQP_SOLVED_INACCURATE)

#: DAQP exit flags (of ``Model.solve`` and ``Model.update``) -> status names; flags > 0 are
#: solutions, reported as "solved" (2, soft-optimal, needs soft constraints: this QP has none).
DAQP_STATUS: dict[int, str] = {
    1: "solved", 2: "soft_optimal", -1: "primal_infeasible", -2: "cycling", -3: "unbounded",
    -4: "max_iter_reached", -5: "nonconvex", -6: "overdetermined_initial", -7: "time_limit_reached",
    -8: "unsupported",
}

#: Default DAQP settings (override with ``daqp_settings=``; keys of ``daqp.Model().settings``).
#: DAQP's own defaults except ``iter_limit``: a warm-started step takes a few active-set changes
#: and a start from rest a few tens, so 1000 only bounds the time of a pathological step.
DAQP_DEFAULTS: dict[str, Any] = dict(iter_limit=1000)

#: Default OSQP settings (override with ``osqp_settings=``). The QP is scaled by construction, so
#: OSQP's Ruiz scaling is off (it slowed rate-limited transients and costs time at every matrix
#: update). Tolerances act on the scaled problem (1e-5 = 1e-5 F_ref). A fixed
#: ``adaptive_rho_interval`` keeps iteration counts reproducible (0 would adapt on timing).
#: ``max_iter`` is generous: rate-limited transients with a demand far beyond reach are LP-like
#: and can take thousands of ADMM iterations (docs/controllers.md, "Thrust allocation").
OSQP_DEFAULTS: dict[str, Any] = dict(
    eps_abs=1e-5, eps_rel=1e-5, eps_prim_inf=1e-6, eps_dual_inf=1e-6, max_iter=10000, polishing=True,
    polish_refine_iter=3, warm_starting=True, adaptive_rho=True, adaptive_rho_interval=25,
    check_termination=10, scaling=0, verbose=False,
)


class DaqpModels(NamedTuple):
    """The two DAQP models of an allocator (set up once): the polygon's two sides at b_i, and
    the whole polygon."""

    two_sides: daqp.Model
    full: daqp.Model


def _index(idx: np.ndarray) -> slice | np.ndarray:
    """``idx`` as a slice when it is a contiguous run (views instead of copies), else itself."""
    if len(idx) == 0 or (np.diff(idx) == 1).all():
        return slice(int(idx[0]), int(idx[-1]) + 1) if len(idx) else slice(0, 0)
    return idx


# -- the allocator -------------------------------------------------------------------------------------

class ThrustAllocator:
    """QP thrust allocation with a DAQP or OSQP solver set up once (module docstring).

    Parameters
    ----------
    thrusters : sequence of tapm_opt.config.Thruster
        Kind, position (x, y) in {B} [m], angle [rad], max_thrust, max_reverse_thrust [N],
        max_thrust_rate [N/s], max_azimuth_rate [rad/s] or None (instantaneous), forbidden_sectors
        ((from, to) [rad], counter-clockwise from ``from`` to ``to``; azimuths only).
    weights : array_like (n,) or mapping id -> weight, optional
        Relative thrust weights k_i > 0 [-] (default 1); thruster i costs ``k_i (f_i / max_thrust_i)^2``.
    slack_weight : float
        rho_s [-]: cost of a slack of F_ref (force) or F_ref L_ref (moment), relative to one
        thruster at full thrust with k_i = 1.
    polygon_sides : int
        m >= 4: sides of the inscribed polygon replacing an azimuth's thrust circle, with a vertex
        along the direction b_i (capacity lost between vertices at most 1 - cos(pi/m): 1.9 % for 16).
    dt : float
        Default time step [s] of the rate limits (``allocate(tau_cmd, dt)`` overrides it).
    idle_tol : float
        An azimuth with |u_i| <= idle_tol F_ref is idle: f = 0, alpha kept or steered [-].
    steer_idle : bool
        Turn idle azimuths toward their preferred direction (module docstring).
    accept_tol : float
        OSQP only: a ``solved_inaccurate`` result is used when its primal residual (scaled units,
        fractions of F_ref) is at most this [-]; its optimality may then be approximate.
    solver : {"daqp", "osqp"}, optional
        QP solver. Default "daqp", or "osqp" when ``osqp_settings`` is given.
    daqp_settings : mapping, optional
        Overrides of :data:`DAQP_DEFAULTS` (solver "daqp" only).
    osqp_settings : mapping, optional
        Overrides of :data:`OSQP_DEFAULTS` (solver "osqp" only).

    Attributes
    ----------
    ids : tuple of str
        Thruster ids, in order.
    n : int
        Number of thrusters.
    dt : float
        Default time step [s].
    F_ref, L_ref : float
        Force [N] and length [m] scales of the QP.
    solver_name : str
        "daqp" or "osqp".
    """

    def __init__(self, thrusters: Sequence[schema.Thruster], *, weights: Any = None, slack_weight: float = 1e6,
                 polygon_sides: int = 16, dt: float = 0.1, idle_tol: float = 1e-4, steer_idle: bool = True,
                 accept_tol: float = 1e-3, solver: str | None = None, daqp_settings: Mapping[str, Any] | None = None,
                 osqp_settings: Mapping[str, Any] | None = None):
        if solver is None:
            solver = "osqp" if osqp_settings is not None else "daqp"
        if not isinstance(solver, str) or solver not in SOLVERS:
            raise AllocationError(f"solver={solver!r} must be one of {list(SOLVERS)}")
        if solver == "daqp" and osqp_settings is not None:
            raise AllocationError(f"osqp_settings={dict(osqp_settings)!r} given with solver='daqp'")
        if solver == "osqp" and daqp_settings is not None:
            raise AllocationError(f"daqp_settings={dict(daqp_settings)!r} given with solver='osqp'")
        self.solver_name = solver
        self._daqp = solver == "daqp"
        ths = tuple(thrusters)
        if not ths:
            raise AllocationError("thrusters is empty: nothing to allocate")
        self.ids: tuple[str, ...] = tuple(str(th.id) for th in ths)
        if len(set(self.ids)) != len(self.ids):
            raise AllocationError(f"thruster ids {list(self.ids)} are not unique")
        self.n = len(ths)
        self.dt = _positive("dt", dt)
        self.slack_weight = _positive("slack_weight", slack_weight)
        self.idle_tol = _positive("idle_tol", idle_tol)
        self.accept_tol = _positive("accept_tol", accept_tol)
        self.steer_idle = bool(steer_idle)
        if isinstance(polygon_sides, bool) or not isinstance(polygon_sides, (int, np.integer)) or polygon_sides < 4:
            raise AllocationError(f"polygon_sides={polygon_sides!r} must be an integer >= 4")
        self.polygon_sides = int(polygon_sides)
        self._parse_thrusters(ths)
        self._k = self._parse_weights(weights)
        self._w_phys = self._k / self._fmax**2                 # weight of f_i^2 [1/N^2]
        wt = self._k * (self.F_ref / self._fmax) ** 2          # weight of the scaled force squared
        self._wa, self._wf = wt[self._iaz], wt[self._ifx]
        self._build_tables()
        self._failed = np.zeros(self.n, dtype=bool)
        self.reset()
        if self._daqp:
            self._setup_daqp(daqp_settings)
        else:
            self._setup_osqp(osqp_settings)

    def _parse_thrusters(self, ths: tuple[schema.Thruster, ...]) -> None:
        x, y, ang, fmax, fmin, rate, arate, sectors = ([] for _ in range(8))
        for i, th in enumerate(ths):
            p = f"thrusters[{i}] ({th.id!r})"
            if th.kind not in ("azimuth", "tunnel", "fixed"):
                raise AllocationError(f"{p}.kind={th.kind!r} must be 'azimuth', 'tunnel' or 'fixed'")
            az = th.kind == "azimuth"
            pos = tuple(th.position) if isinstance(th.position, (tuple, list, np.ndarray)) else ()
            if len(pos) != 2:
                raise AllocationError(f"{p}.position={th.position!r} must be two numbers (x, y) [m]")
            x.append(_finite(f"{p}.position[0]", pos[0]))
            y.append(_finite(f"{p}.position[1]", pos[1]))
            ang.append(_finite(f"{p}.angle", th.angle))
            fmax.append(_positive(f"{p}.max_thrust", th.max_thrust))
            rev = 0.0 if az else _finite(f"{p}.max_reverse_thrust", th.max_reverse_thrust)
            if rev < 0.0:
                raise AllocationError(f"{p}.max_reverse_thrust={th.max_reverse_thrust!r} must be >= 0 [N]")
            fmin.append(-rev)
            rate.append(_positive(f"{p}.max_thrust_rate", th.max_thrust_rate))
            ar = th.max_azimuth_rate if az else None
            arate.append(_INF if ar is None else _positive(f"{p}.max_azimuth_rate", ar))
            if th.forbidden_sectors and not az:
                raise AllocationError(f"{p}.forbidden_sectors are only allowed for azimuth thrusters, not {th.kind!r}")
            sectors.append(merge_sectors(th.forbidden_sectors, p, error=AllocationError) if az else ((), ()))
        self._x, self._y = np.array(x), np.array(y)
        self._azimuth = np.array([th.kind == "azimuth" for th in ths])
        self._angle0 = ssa(np.array(ang))
        self._fmax, self._fmin, self._rate = np.array(fmax), np.array(fmin), np.array(rate)
        self.F_ref = F = float(self._fmax.max())
        self.L_ref = L = max(1.0, float(np.hypot(self._x, self._y).max()))
        self._tau_scale = np.array([1.0 / F, 1.0 / F, 1.0 / (F * L)])
        self._row_scale = np.array([1.0, 1.0, 1.0 / L])
        self._iaz = np.flatnonzero(self._azimuth)
        self._ifx = np.flatnonzero(~self._azimuth)
        self._naz, self._nfx = len(self._iaz), len(self._ifx)
        self._arate = np.array(arate)[self._iaz]
        self._sectors = [sectors[i] for i in self._iaz]
        self._R = self._fmax[self._iaz] / F                          # scaled azimuth capacity
        self._Rin = self._R * math.cos(math.pi / self.polygon_sides)  # polygon apothem
        self._ffmin, self._ffmax = self._fmin[self._ifx] / F, self._fmax[self._ifx] / F

    def _build_tables(self) -> None:
        """The kernels' constant, state and step arrays (:mod:`~tapm_opt.control.allocation_step`)."""
        naz, nfx, F, m = self._naz, self._nfx, self.F_ref, self.polygon_sides
        self._nv = nv = 2 * naz + nfx
        S = self._row_scale
        # balance columns of an azimuth: B_i (e(b), e(b + pi/2)) with B_i = extended_columns
        Bx = np.stack([extended_columns(self._x[i], self._y[i])[:, 0] for i in self._iaz], axis=1) if naz else np.zeros((3, 0))
        By = np.stack([extended_columns(self._x[i], self._y[i])[:, 1] for i in self._iaz], axis=1) if naz else np.zeros((3, 0))
        self._Bf = Bf = configuration_matrix(self._angle0[self._ifx], self._x[self._ifx], self._y[self._ifx])
        iaz, ifx = self._iaz, self._ifx
        C = np.zeros((N_C, self.n))
        C[C_KIND, iaz] = 1.0
        C[C_IP, iaz], C[C_IV, iaz] = np.arange(naz), naz + np.arange(naz)
        C[C_IP, ifx] = 2 * naz + np.arange(nfx)
        C[C_RATE] = self._rate / F
        C[C_ARATE, iaz] = self._arate
        C[C_FMIN, ifx], C[C_FMAX, ifx] = self._ffmin, self._ffmax
        C[C_FMAX, iaz], C[C_RIN, iaz] = self._R, self._Rin
        C[C_X], C[C_Y] = self._x, self._y
        C[C_W, iaz], C[C_W, ifx] = self._wa, self._wf
        C[C_BX:C_BX + 3, iaz], C[C_BY:C_BY + 3, iaz] = Bx * S[:, None], By * S[:, None]
        C[C_TX:C_TX + 3, iaz], C[C_TY:C_TY + 3, iaz] = Bx * F, By * F
        C[C_TX:C_TX + 3, ifx] = Bf * F
        C[C_ANGLE] = self._angle0
        C[C_NSEC, iaz] = [len(s[0]) for s in self._sectors]
        self._C = C
        kmax = max([1] + [len(s[0]) for s in self._sectors])
        self._Sec = np.zeros((self.n, 2 * kmax))
        for j, (starts, widths) in enumerate(self._sectors):
            self._Sec[iaz[j], :len(starts)] = starts
            self._Sec[iaz[j], kmax:kmax + len(widths)] = widths
        self._S = np.zeros((N_S, self.n))
        self._S[S_ALPHA] = self._angle0
        self._S[S_B] = np.nan                      # no frame written yet
        self._G = np.zeros((N_G, self.n))
        self._iaz_ix, self._ifx_ix = _index(iaz), _index(ifx)   # the columns of G (slices when contiguous)
        self._nout = nout = 2 * self.n + 6
        self._slices = (slice(0, self.n), slice(self.n, 2 * self.n), slice(2 * self.n, 2 * self.n + 3),
                        slice(2 * self.n + 3, nout))
        # p column: cos b Bx + sin b By, v column: cos b By - sin b Bx (OSQP's matrix update)
        self._Kc = np.concatenate([Bx * S[:, None], By * S[:, None]])
        self._Ks = np.concatenate([By * S[:, None], -Bx * S[:, None]])
        phi = (2.0 * np.arange(m) + 1.0) * math.pi / m           # polygon normals, vertex at 0
        self._poly_n = np.stack([np.cos(phi), np.sin(phi)], axis=1)
        self._Pd = np.empty(nv + 3)                             # diagonal of the QP's Hessian
        self._Pd[:naz] = self._Pd[naz:2 * naz] = 2.0 * self._wa
        self._Pd[2 * naz:nv] = 2.0 * self._wf
        self._Pd[nv:] = 2.0 * self.slack_weight
        # DAQP data: columns [p, v, f, s]; bounds [simple bounds of p, v, f (nv); balance (3);
        # polygon sides]; rows of A [balance (3); sides]. Sides in the order 0, m-1, 1, ..., m-2
        # (the two at the vertex on b first), azimuths within a side: the two-sided model's
        # data are the leading rows.
        order = [0, m - 1] + list(range(1, m - 1))
        mA = 3 + naz * m
        A = np.zeros((mA, nv + 3))
        A[:3, 2 * naz:nv] = Bf * S[:, None]
        A[:3, nv:] = np.eye(3)
        for q, k in enumerate(order):
            for j in range(naz):
                A[3 + q * naz + j, j], A[3 + q * naz + j, naz + j] = self._poly_n[k]
        self._A = A
        self._bu = np.full(nv + mA, _BIG)
        self._bl = np.full(nv + mA, -_BIG)
        self._bu[nv + 3:] = np.tile(self._Rin, m)
        self._bu[nv:nv + 3] = self._bl[nv:nv + 3] = 0.0

    def _setup_daqp(self, daqp_settings: Mapping[str, Any] | None) -> None:
        settings = dict(DAQP_DEFAULTS)
        settings.update(daqp_settings or {})
        known = daqp.Model().settings
        for key in settings:
            if key not in known:
                raise AllocationError(f"daqp_settings: unknown setting {key!r} (known: {sorted(known)})")
        nv, naz = self._nv, self._naz
        H = np.diag(self._Pd)
        q = np.zeros(nv + 3)
        self._step_args = (self._C, self._Sec, self._S, self.polygon_sides, self._tau_scale, self._G, True,
                           self._A, self._bu, self._bl)
        self._finish_args = (self._G, self._C, self._S, self.F_ref, self.L_ref, self.idle_tol, self.steer_idle, True)
        step_kernel(self.dt, np.zeros(3), *self._step_args)
        models, views = [], []
        for rows in (3 + 2 * naz, self._A.shape[0]):
            A, bu, bl = self._A[:rows], self._bu[:nv + rows], self._bl[:nv + rows]
            sense = np.zeros(nv + rows, dtype=np.intc)
            sense[nv:nv + 3] = 5                       # equality (active, immutable): the force balance
            mod = daqp.Model()
            try:
                mod.settings = settings
            except (TypeError, ValueError, OverflowError) as e:
                raise AllocationError(f"daqp_settings={dict(daqp_settings or {})!r}: {e}") from None
            flag, _ = mod.setup(H, q, A, bu, bl, sense)
            if flag < 0:  # cannot happen with positive weights
                raise AllocationError(f"DAQP setup failed: {DAQP_STATUS.get(flag, flag)}")
            models.append(mod)
            views.append((A, bu, bl, sense))
        self._solver: Any = DaqpModels(*models)
        self._views = views
        self._ms = nv                                  # lam[nv:nv + 3]: multipliers of the balance rows
        self._stale = [False, False]                   # a model's A is older than the buffer
        self._k_last = -1                              # the model of the previous solve (-1: start cold)
        self._shared_bl = self._probe_shared_blower()

    def _probe_shared_blower(self) -> bool:
        """Whether the models read ``blower`` from this allocator's buffer (daqp.Model keeps views
        of contiguous float64 arrays), so that ``update(bupper=...)`` also sees new lower bounds:
        raise one lower bound in the buffer only and check the solution moves to it."""
        ok = True
        for mod, (A, bu, bl, sense) in zip(self._solver, self._views):
            lo = bl[0]
            bl[0] = bu[0]
            mod.update(bupper=bu, sense=sense)
            x, _, flag, _ = mod.solve()
            ok &= bool(flag > 0 and abs(x[0] - bu[0]) <= 1e-9 * max(1.0, abs(bu[0])))
            bl[0] = lo
            mod.update(bupper=bu, blower=bl, sense=sense)
        return ok

    def _setup_osqp(self, osqp_settings: Mapping[str, Any] | None) -> None:
        """Columns [p (naz), v (naz), f (nfx), s (3)]; rows [balance (3), bounds (nv, one per
        column), polygons (naz m)]."""
        naz, nfx, m, nv = self._naz, self._nfx, self.polygon_sides, self._nv
        self._rp = rp = 3 + nv
        nr = rp + naz * m
        Bf = self._Bf
        rows: list[int] = []
        cols: list[int] = []
        vals: list[float] = []
        dyn = [(r, c0 + j) for c0 in (0, naz) for r in range(3) for j in range(naz)]
        for r, c in dyn:
            rows.append(r), cols.append(c), vals.append(1.0)     # structural non-zeros; values set on update
        for k in range(nfx):
            for r in range(3):
                if Bf[r, k] != 0.0:
                    rows.append(r), cols.append(2 * naz + k), vals.append(Bf[r, k] * self._row_scale[r])
        for r in range(3):
            rows.append(r), cols.append(nv + r), vals.append(1.0)
        for c in range(nv):
            rows.append(3 + c), cols.append(c), vals.append(1.0)
        for k in range(m):
            for j in range(naz):
                rows += [rp + k * naz + j, rp + k * naz + j]
                cols += [j, naz + j]
                vals += [self._poly_n[k, 0], self._poly_n[k, 1]]
        A = sp.csc_matrix((vals, (rows, cols)), shape=(nr, nv + 3))
        A.sort_indices()
        self._Ax_idx = np.array([A.indptr[c] + int(np.searchsorted(A.indices[A.indptr[c]:A.indptr[c + 1]], r))
                                 for r, c in dyn], dtype=np.int64)
        self._l = np.full(nr, -_BIG)
        self._u = np.full(nr, _BIG)
        self._u[rp:] = np.repeat(self._Rin[None, :], m, axis=0).ravel()
        self._l[:3] = self._u[:3] = 0.0
        settings = dict(OSQP_DEFAULTS)
        settings.update(osqp_settings or {})
        self._solver = osqp.OSQP()
        try:
            self._solver.setup(sp.diags(self._Pd, format="csc"), np.zeros(nv + 3), A, self._l, self._u, **settings)
        except (ValueError, TypeError, AttributeError) as e:
            raise AllocationError(f"osqp_settings={dict(osqp_settings or {})!r}: {e}") from None
        # the compiled solver behind osqp.OSQP: update/solve without the Python wrapper's overhead
        raw = getattr(self._solver, "_solver", None)
        needed = ("update_data_vec", "update_data_mat", "solve", "info", "solution")
        self._raw = raw if raw is not None and all(hasattr(raw, a) for a in needed) else None
        self._b_last = np.full(naz, np.nan)      # forces the first A update

    @classmethod
    def from_scenario(cls, scenario: schema.Scenario, **kw: Any) -> ThrustAllocator:
        """Build from ``scenario.thrusters``; keywords as for the constructor."""
        return cls(scenario.thrusters, **kw)

    def _parse_weights(self, weights: Any) -> np.ndarray:
        k = np.ones(self.n)
        if weights is None:
            return k
        if isinstance(weights, Mapping):
            for key, v in weights.items():
                k[self.index(key)] = _positive(f"weights[{key!r}]", v)
            return k
        try:
            arr = np.asarray(weights, dtype=float)
        except (TypeError, ValueError):
            arr = np.empty(0)
        if arr.shape != (self.n,) or not np.all(np.isfinite(arr) & (arr > 0)):
            raise AllocationError(f"weights={weights!r} must be {self.n} positive finite numbers "
                                  "(one per thruster) or a mapping id -> weight")
        return arr.copy()

    # -- state ---------------------------------------------------------------------------------
    @property
    def solver(self) -> Any:
        """The solver, set up once in the constructor and never rebuilt: :class:`DaqpModels`
        (two ``daqp.Model``) or the ``osqp.OSQP`` object."""
        return self._solver

    @property
    def failed(self) -> np.ndarray:
        """Failed thrusters, shape (n,) bool (a copy)."""
        return self._failed.copy()

    @property
    def f_prev(self) -> np.ndarray:
        """Previous command f, shape (n,) [N], the reference of the rate limits (a copy)."""
        return self._S[S_F] * self.F_ref

    @property
    def alpha_prev(self) -> np.ndarray:
        """Previous command alpha, shape (n,) [rad] (a copy)."""
        return self._S[S_ALPHA].copy()

    @property
    def weights(self) -> np.ndarray:
        """Weight w_i of f_i^2 in the cost, ``k_i / max_thrust_i^2``, shape (n,) [1/N^2] (a copy)."""
        return self._w_phys.copy()

    @property
    def f_min(self) -> np.ndarray:
        """Lowest thrust per thruster: 0 for azimuths, -max_reverse_thrust otherwise [N] (a copy)."""
        return self._fmin.copy()

    @property
    def f_max(self) -> np.ndarray:
        """max_thrust per thruster [N] (a copy)."""
        return self._fmax.copy()

    def index(self, thruster: int | str) -> int:
        """Index of a thruster given by index or id; AllocationError naming it if there is none."""
        if isinstance(thruster, (int, np.integer)) and not isinstance(thruster, bool):
            if 0 <= thruster < self.n:
                return int(thruster)
        elif isinstance(thruster, str) and thruster in self.ids:
            return self.ids.index(thruster)
        raise AllocationError(f"thruster={thruster!r}: no such thruster (ids {list(self.ids)}, or an index 0..{self.n - 1})")

    def set_failed(self, thruster: int | str, failed: bool = True) -> None:
        """Mark a thruster failed (exactly zero force from the next allocation on) or working again.

        The QP is not rebuilt: the thruster's bounds become ``[0, 0]``. A re-enabled thruster
        starts from zero thrust at its last azimuth.
        """
        i = self.index(thruster)
        self._failed[i] = bool(failed)
        self._S[S_FAILED] = self._failed
        f = self.f_prev
        f[i] = 0.0
        self._set_prev(f, self.alpha_prev)

    def reset(self, f: Any = None, alpha: Any = None) -> None:
        """Set the previous command (the reference of the rate limits), e.g. to measured thruster states.

        Parameters
        ----------
        f : array_like, shape (n,), optional
            Thrusts [N] (default zeros); clipped to [f_min, f_max]. An azimuth pointing into a
            forbidden sector is taken as idle (f = 0).
        alpha : array_like, shape (n,), optional
            Azimuths [rad] (default: the scenario angles); ignored for tunnel/fixed thrusters.
        """
        f = np.zeros(self.n) if f is None else self._vector("f", f)
        a = self._angle0 if alpha is None else self._vector("alpha", alpha)
        self._set_prev(np.clip(f, self._fmin, self._fmax), ssa(np.where(self._azimuth, a, self._angle0)))

    def _set_prev(self, f: np.ndarray, alpha: np.ndarray) -> None:
        """Write the previous command into the kernels' state: zero for failed thrusters and for
        azimuths pointing into a forbidden sector."""
        f = np.where(self._failed, 0.0, f)
        for i in self._iaz:
            K = int(self._C[C_NSEC, i])
            if K:
                lo, hi = arc(float(alpha[i]), self._Sec[i], K)
                if lo > 0.0 or hi < 0.0:
                    f[i] = 0.0
        self._S[S_F] = f / self.F_ref
        self._S[S_ALPHA] = np.where(self._azimuth, alpha, self._angle0)

    def _vector(self, name: str, v: Any) -> np.ndarray:
        try:
            a = np.array(v, dtype=float)
        except (TypeError, ValueError):
            raise AllocationError(f"{name}={v!r} is not numeric") from None
        if a.shape != (self.n,):
            raise AllocationError(f"{name} has shape {a.shape}, expected ({self.n},) (one per thruster)")
        bad = np.flatnonzero(~np.isfinite(a))
        if bad.size:
            i = int(bad[0])
            raise AllocationError(f"{name}[{i}]={float(a[i])!r} for thruster {self.ids[i]!r} is not finite")
        return a

    # -- step data and post-processing (shared by both solvers and the cvxpy reference) --------------
    def _step(self, dt: float, tau: np.ndarray) -> _Step | None:
        """The step data in the allocator's buffers (None when tau is not finite)."""
        code = step_kernel(dt, tau, self._C, self._Sec, self._S, self.polygon_sides, self._tau_scale, self._G,
                           False, self._A, self._bu, self._bl)
        return None if code < 0 else _Step(self._G, self._iaz_ix, self._ifx_ix, bool(code & CODE_FULL))

    def _geometry(self, dt: float) -> _Step:
        """Direction intervals, local frames and bounds of one step (a copy; state unchanged)."""
        g = self._step(dt, np.zeros(3))
        return g._replace(G=g.G.copy())

    def _finish(self, x: np.ndarray, y: np.ndarray, tau: np.ndarray, g: _Step, status: str,
                t_solve: float, it: int, *, commit: bool) -> AllocationResult | None:
        """Clip a (scaled) QP solution to the exact limits; azimuths, idle steering, tau, slack.
        None (state unchanged) when x is not finite."""
        out = np.empty(self._nout)
        if finish_kernel(np.array(x, dtype=float), np.array(y, dtype=float), 0, tau, g.G,
                         self._C, self._S, self.F_ref, self.L_ref, self.idle_tol, self.steer_idle, commit, out):
            return None
        msg = "QP solution" if status == "solved" else f"QP solution accepted with {self.solver_name.upper()} status {status}"
        return _result_view(out, self._slices, status, t_solve, it, msg)

    # -- allocation ------------------------------------------------------------------------------------
    def _check_tau(self, tau_cmd: Any) -> np.ndarray:
        try:
            tau = np.array(tau_cmd, dtype=float)      # fresh, C-contiguous: one compiled kernel type
        except (TypeError, ValueError):
            raise AllocationError(f"tau_cmd={tau_cmd!r} is not numeric (expected (X, Y, N) [N, N, N m])") from None
        if tau.shape != (3,):
            raise AllocationError(f"tau_cmd has shape {tau.shape}, expected (3,) = (X, Y, N) [N, N, N m]")
        return tau

    def _check_dt(self, dt: Any) -> float:
        return self.dt if dt is None else _positive("dt", dt)

    def allocate(self, tau_cmd: Any, dt: float | None = None) -> AllocationResult:
        """Thruster commands for the generalised force tau_cmd; advances the rate-limit state.

        Never raises for numerical trouble: a non-finite tau_cmd gives zero thrust, a failed or
        inaccurate solve the saturated pseudo-inverse, both with ``fallback=True``.

        Parameters
        ----------
        tau_cmd : array_like, shape (3,)
            Commanded generalised force (X, Y, N) in {B} [N, N, N m].
        dt : float, optional
            Time since the previous command [s] (default: the constructor's dt).

        Returns
        -------
        AllocationResult

        Raises
        ------
        AllocationError
            tau_cmd not numeric or not of shape (3,), dt not a positive number (programming errors).
        """
        tau = self._check_tau(tau_cmd)
        dt = self.dt if dt is None else _positive("dt", dt)
        if self._daqp:
            return self._allocate_daqp(tau, dt)
        return self._allocate_osqp(tau, dt)

    def _invalid_tau(self, tau: np.ndarray, dt: float) -> AllocationResult:
        return self._fallback(tau, dt, "invalid_tau", f"tau_cmd={tau.tolist()} is not finite: zero thrust", 0.0, 0)

    def _allocate_daqp(self, tau: np.ndarray, dt: float) -> AllocationResult:
        code = step_kernel(dt, tau, *self._step_args)
        if code < 0:
            return self._invalid_tau(tau, dt)
        k = code & CODE_FULL
        stale = self._stale
        if code & CODE_MOVED:
            stale[0] = stale[1] = True
        model = self._solver[k]
        A, bu, bl, sense = self._views[k]
        t0 = time.perf_counter()
        if k != self._k_last:       # the other model's active set is old (or a solve failed): start cold
            flag = model.update(A=A, bupper=bu, blower=bl, sense=sense)
            self._k_last = k
            stale[k] = False
        elif stale[k]:
            flag = model.update(A=A, bupper=bu) if self._shared_bl else model.update(A=A, bupper=bu, blower=bl)
            stale[k] = False
        else:
            flag = model.update(bupper=bu) if self._shared_bl else model.update(bupper=bu, blower=bl)
        it = 0
        if flag >= 0:
            x, _, flag, info = model.solve()
            it = info["iterations"]
            if flag > 0:
                out = np.empty(self._nout)
                if not finish_kernel(x, info["lam"], self._ms, tau, *self._finish_args, out):
                    t = time.perf_counter() - t0
                    return _result_view(out, self._slices, "solved", t, it,
                                        "QP solution" if flag == 1 else f"QP solution (DAQP: {DAQP_STATUS[flag]})")
                flag, name = 0, "non_finite_solution"
            else:
                name = DAQP_STATUS.get(flag, f"exitflag_{flag}")
        else:
            name = DAQP_STATUS.get(flag, f"exitflag_{flag}")
        t = time.perf_counter() - t0
        stale[k] = True             # the next solve: a fresh matrix and a cold start
        self._k_last = -1
        msg = f"DAQP: {name} (exit flag {flag}, iter={it}); saturated pseudo-inverse at the previous azimuths"
        return self._fallback(tau, dt, name, msg, t, it)

    def _allocate_osqp(self, tau: np.ndarray, dt: float) -> AllocationResult:
        g = self._step(dt, tau)
        if g is None:
            return self._invalid_tau(tau, dt)
        naz, nv, l, u = self._naz, self._nv, self._l, self._u
        l[:3] = u[:3] = tau * self._tau_scale
        l[3:3 + naz], u[3:3 + naz], l[3 + naz:3 + 2 * naz], u[3 + naz:3 + 2 * naz] = g.lp, g.hp, g.lv, g.hv
        if self._nfx:
            l[3 + 2 * naz:3 + nv], u[3 + 2 * naz:3 + nv] = g.lf, g.hf
        self._update_matrices(g)
        self._update(l=l, u=u)
        st, prim_res, t_solve, it, x, y = self._solve()
        name = _STATUS_NAMES.get(st, f"status_{st}")
        if st == _SOLVED or (st == _SOLVED_INACCURATE and prim_res <= self.accept_tol):
            res = self._finish(x, y, tau, g, name, t_solve, it, commit=True)
            if res is not None:
                return res
            name = "non_finite_solution"
        elif st == _SOLVED_INACCURATE:
            name = "inaccurate"
        msg = f"OSQP: {name} (prim_res={prim_res:.3g}, iter={it}); saturated pseudo-inverse at the previous azimuths"
        return self._fallback(tau, dt, name, msg, t_solve, it)

    def _update_matrices(self, g: _Step) -> None:
        """Push the balance entries of the azimuths' (p, v) columns for the frames b to OSQP."""
        if (g.b == self._b_last).all():
            return
        self._b_last = g.b.copy()
        vals = self._Kc * np.cos(g.b)
        vals += self._Ks * np.sin(g.b)
        self._update(Ax=vals.ravel(), Ax_idx=self._Ax_idx)

    def _update(self, **kw: Any) -> None:
        raw = self._raw
        if raw is None:
            self._solver.update(**kw)
            return
        if "l" in kw:
            raw.update_data_vec(None, kw["l"], kw["u"])
        if "Ax" in kw or "Px" in kw:
            raw.update_data_mat(kw.get("Px"), None, kw.get("Ax"), kw.get("Ax_idx"))

    def _solve(self) -> tuple[int, float, float, int, np.ndarray, np.ndarray]:
        """(status_val, prim_res, solve + polish time, iterations, x, y)."""
        raw = self._raw
        if raw is None:
            res = self._solver.solve(raise_error=False)
            info, x, y = res.info, res.x, res.y
        else:
            raw.solve()
            info, sol = raw.info, raw.solution
            x, y = sol.x, sol.y
        return (int(info.status_val), float(info.prim_res), float(info.solve_time + info.polish_time),
                int(info.iter), x, y)

    def _fallback(self, tau: np.ndarray, dt: float, reason: str, message: str, t_solve: float, it: int) -> AllocationResult:
        """Saturated weighted pseudo-inverse at the previous azimuths (zero thrust for invalid tau)."""
        alpha = self.alpha_prev
        ok = ~self._failed
        f = np.zeros(self.n)
        if reason != "invalid_tau":
            T = configuration_matrix(alpha, self._x, self._y)
            f = pseudo_inverse(T, tau, np.where(ok, self._w_phys, _INF), row_scale=self._row_scale)
            rdt = self._rate * dt
            f_prev = self.f_prev
            lo = np.maximum(self._fmin, f_prev - rdt)
            hi = np.minimum(self._fmax, f_prev + rdt)
            f = np.where(ok, np.clip(f, np.minimum(lo, hi), hi), 0.0)
            if not np.isfinite(f).all():  # cannot happen with finite data; never return NaN
                f = np.zeros(self.n)
                message += "; pseudo-inverse not finite: zero thrust"
        tau_a = configuration_matrix(alpha, self._x, self._y) @ f
        self._set_prev(f, alpha)
        return _result(f, alpha, tau_a, tau - tau_a, f"fallback:{reason}", True, t_solve, it, message)

    def cost(self, result: AllocationResult) -> float:
        """QP cost of a result, ``sum_i k_i (f_i / max_thrust_i)^2 + rho_s |slack~|^2`` [-]."""
        s = np.asarray(result.slack) * self._tau_scale
        return float(np.sum(self._k * (np.asarray(result.f) / self._fmax) ** 2) + self.slack_weight * (s @ s))
