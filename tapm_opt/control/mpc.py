"""Model predictive control of a thruster-assisted moored vessel (CasADi; piqp, OSQP, IPOPT, fatrop).

One formulation serves both controllers. :func:`build_problem` (module ``mpc_problem``) writes the
optimal control problem over CasADi symbols, in scaled variables, with multiple shooting:

* prediction model: the design form of the vessel (survey eq. 14–15/31, ``models.vessel``) with the
  mooring restoring model (``"characteristic"``: every line's characteristic centred at the present
  pose, eq. 26–28, its coefficients parameters of the problem; ``"catenary"``; ``"linear"``) and
  the slowly varying environmental load ``b`` in {E} as a parameter, ``tau_env = R(psi)^T b``;
  RK4 over ``dt``;
* decision variables: generalised thrust ``tau`` (allocation afterwards) or the thrusters' force
  components directly (extended thrust; allocation inside the MPC), one move per prediction step or
  held over blocks of steps (``MPCSettings.move_blocks``);
* cost, as least squares plus L1 penalties: thrust power surrogate (so the mooring does the work),
  position error outside a dead band (the TAPM philosophy, survey §4.1) and optionally inside it,
  heading error, velocity, thrust rate, a terminal cost;
* constraints: thrust inside the attainable polytope of the one ``models.system.ThrusterSet`` and
  its change per step inside the same polytope scaled by rate x dt (or the capacity box and rate
  box) — hard; the safe circle and every line's tension limit (soft, exact L1 penalty plus a small
  quadratic one); dead band as a polygon with a slack. Positions are turret offsets
  (``geometry.turret_offset``), expanded to first order in the heading about the present one.

:class:`NonlinearMPC` solves it with an NLP solver (SQP on the Gauss–Newton Hessian with piqp for
its QPs, its real-time iteration, IPOPT, or fatrop). :class:`LinearMPC` solves the same problem
linearised about an operating point that is a parameter (by default the present state): its QP
matrices are CasADi functions of the parameters built once, evaluated each step and handed to piqp
or OSQP; nothing is rebuilt in the loop. With ``qp_solver="daqp"`` the linear MPC's QP, and the
real-time iteration's Gauss–Newton QP, are condensed for the dense active-set solver DAQP
(module ``mpc_condensed``). On a failed solve both apply the shifted previous plan and say so in
their diagnostics.

Size: one module on purpose — both controllers share the per-step machinery (parameters, fault
tolerance, the dead band's budget, warm start, diagnostics); the problem itself is in
``mpc_problem`` and the condensed QPs in ``mpc_condensed``.
"""

from __future__ import annotations

import math
import time
from typing import Any

import casadi as ca
import numpy as np
import scipy.sparse as sp

from ..errors import ModelError
from ..estimation.lowpass import first_order_step
from ..estimation.reliability import RISER_BOTTOM, RISER_TOP, line_signal
from ..geometry import body_from_turret, rot_z, ssa
from ..interfaces import Estimate, Setpoint, ThrusterCommand
from ..models.system import as_system
from ..models.vessel import roll_pitch_moments
from .mpc_problem import (MPCError, MPCSettings, MPCStep, RollPitchWeights, _Problem, build_problem,
                          mooring_parameters, polytope_parameters)

__all__ = ["MPCSettings", "MPCError", "NonlinearMPC", "LinearMPC", "build_problem", "MPCStep", "LINEAR_QP_SOLVERS",
           "NONLINEAR_QP_SOLVERS", "RollPitchWeights", "budgeted_dead_band", "net_load_along"]

#: QP solvers of :class:`LinearMPC`.
LINEAR_QP_SOLVERS = ("piqp", "osqp", "daqp")
#: QP solvers of :class:`NonlinearMPC`: piqp inside CasADi's ``sqpmethod`` (every NLP solver but
#: IPOPT and fatrop, which have their own), or the real-time iteration's Gauss–Newton QP condensed
#: for DAQP (``solver="rti"`` only).
NONLINEAR_QP_SOLVERS = ("piqp", "daqp")

#: piqp's KKT solver for the MPC's QPs (the linear MPC's, the SQP's subproblems): the sparse LDL^T
#: of the KKT system with the equality and inequality rows condensed into it. On the linear MPC's
#: QPs of the benchmark trajectory (fpso; N = 20, 50 and 50 with 8 moves) it gives the default
#: ``sparse_ldlt``'s solutions to 2e-11 in the same iterations in 0.87-0.88 of its time
#: (``benchmarks/bench_mpc_parts.py``, ``docs/performance.md``).
PIQP_KKT_SOLVER = "sparse_ldlt_cond"

#: DAQP's settings for the condensed QPs (``qp_solver="daqp"``): its defaults but the iteration
#: limit (a hot-started step takes a few active-set changes; the limit bounds a pathological one).
DAQP_SETTINGS = {"iter_limit": 2000}
#: Solves of one step's condensed QP at most: the soft rows (one per group) chosen again on the
#: solution while it violates another row of the group most (``control.mpc_condensed``).
DAQP_PASSES = 4
#: Time constant [s] of the low-pass filter that gives the mean environmental load (in {E}) along
#: which the dead band after a break is budgeted (``MPCSettings.dead_band_budget``): the slowly
#: varying drift of the storms here has periods of 100-300 s.
MEAN_LOAD_TIME_CONSTANT = 300.0


# ------------------------------------------------------------------------------------------
# controllers
# ------------------------------------------------------------------------------------------


class _MPCBase:
    """Shared parts: parameters, warm start by shifting, applying the first move, diagnostics."""

    def __init__(self, system: Any, settings: MPCSettings, *, period: float | None = None):
        if not isinstance(settings, MPCSettings):
            raise MPCError(f"settings must be MPCSettings, got {type(settings).__name__}")
        if period is not None and not (isinstance(period, (int, float)) and math.isfinite(period) and period > 0):
            raise MPCError(f"period = {period!r} must be a positive number [s] or None")
        self.system = as_system(system)
        self.settings = settings
        self.period = float(period) if period is not None else settings.dt
        self.model = self.system.lines
        self._failed: frozenset[str] = frozenset()
        self._bounds_changed = False
        self._prob: _Problem | None = None
        self._shift_map: tuple[np.ndarray, _Problem] | None = None   # _shift's index map and its problem
        self._n_p: tuple[int, _Problem] | None = None                  # the parameters' number and the problem
        self._z: np.ndarray | None = None
        self._u_prev: np.ndarray | None = None
        self.diagnostics: list[MPCStep] = []
        self.plan_u: np.ndarray | None = None
        self._poly: np.ndarray | None = None  # thrust-polytope parameters of the thrusters alive
        self._poly_box: np.ndarray | None = None  # the stand-in box when no polytope has an interior
        # reliability constraints: the riser (its angles are affine in the hang-off position; the
        # current's share is learnt from the measured angles) and the limits the indices give
        self.riser = self.system.riser(None) if settings.reliability else None
        self._theta_lf: np.ndarray | None = None   # low-passed measured riser angles (4,) [rad]
        self._t_theta: float | None = None
        self._b_lf: np.ndarray | None = None       # low-passed estimated load in {E} (3,) [N, N, N m]
        self._t_b: float | None = None
        self._b_mean: np.ndarray | None = None     # its mean and the heading's for the dead band's budget (5,)
        self._t_mean: float | None = None
        self._t_first = 0.0
        self._damaged_lines: dict[Any, Any] = {}   # the mooring without the broken lines (and lost buoys)
        self._lost_models: dict[frozenset, Any] = {}   # the line model without the lost buoys
        self._radius = math.nan                    # the dead band's radius of the last step [m]
        self._log: list[dict] = []                 # the dead band's changes after a break
        # roll-pitch damping (settings.roll_pitch_damping): the measured attitude (phi, theta, p, q)
        # and the low-passed disturbance moment (K, M) of the lines and the environment
        self._attitude: np.ndarray | None = None
        self._rp_dist: np.ndarray | None = None
        self._t_dist: float | None = None

    def set_attitude(self, t: float, attitude: Any) -> None:
        """The motion reference unit's attitude at ``t`` [s]: (roll [rad], pitch [rad], roll rate
        [rad/s], pitch rate [rad/s]) (:attr:`tapm_opt.interfaces.Measurement.attitude`;
        :class:`~tapm_opt.interfaces.AttitudeAware`). With ``settings.roll_pitch_damping`` the next
        solve starts its roll–pitch prediction there (eq. MRP1; upright at rest until the first
        call); ignored without it."""
        if not self.settings.roll_pitch_damping:
            return
        a = np.asarray(attitude, dtype=float)
        if a.shape != (4,) or not np.isfinite(a).all():
            raise MPCError(f"attitude = {a.tolist()} must be 4 finite numbers (roll [rad], pitch [rad], roll rate "
                           "[rad/s], pitch rate [rad/s]): the MPC will not plan from it")
        self._attitude = a.copy()

    @property
    def roll_pitch_disturbance(self) -> np.ndarray | None:
        """The disturbance moment (K, M) [N m] about the centre of gravity of the last solve's
        roll–pitch prediction (eq. MRP2), None without roll–pitch damping."""
        return None if self._rp_dist is None else self._rp_dist.copy()

    def _roll_pitch_parameters(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """The roll–pitch prediction's initial state (phi, theta, p, q) — the last attitude set —
        and its disturbance moment ``d = LP(C (phi, theta) - M_thr)`` (eq. MRP2): the moment that
        holds the measured angles statically less that of the thrust the MPC applied last, through
        a first-order low-pass of ``disturbance_time_constant`` started at zero (0: d = 0)."""
        rpw: RollPitchWeights = self.settings.roll_pitch_damping
        att = np.zeros(4) if self._attitude is None else self._attitude
        T = rpw.disturbance_time_constant
        if T <= 0:
            self._rp_dist = np.zeros(2)
            return att, self._rp_dist
        rp = self.system.vessel.roll_pitch
        tau = np.zeros(3) if self._u_prev is None else self.tau_from_u(self._u_prev)
        x = np.asarray(rp.C) * att[:2] - roll_pitch_moments(rp, tau, np.zeros(3))
        if self._rp_dist is None:
            self._rp_dist, self._t_dist = np.zeros(2), t
        self._rp_dist = _low_pass_step(self._rp_dist, self._t_dist, x, t, T)
        self._t_dist = t
        return att, self._rp_dist

    def log(self) -> list[dict]:
        """The dead band after a break (with ``dead_band_damaged``; ``interfaces.Logged``): a
        record ``{"t", "event": "mode switch", "from", "to": "intact" | "damaged", "radius" [m],
        "broken"}`` (and ``"lost_points"``, [line id, joint] of the buoys reported lost, when there
        are any) whenever the set of broken lines or lost buoys reported changes (the KPI
        ``mode_switches`` counts them), and ``{"t", "event": "dead band", "radius", "broken"}`` whenever the budgeted
        radius has moved 0.5 m since the last record."""
        return [dict(r) for r in self._log]

    @property
    def owns_allocation(self) -> bool:
        """True when the MPC optimises the thruster forces itself (``decision="thrusters"``)."""
        return self.settings.decision == "thrusters"

    def _params(self, est: Estimate, sp: Setpoint) -> np.ndarray:
        """The problem's parameter vector: state, previous thrust, setpoint, load in {E}, the line
        characteristics at the centre pose, the thrust polytope and the dead band's radius
        (``_Problem.p_idx``)."""
        eta, nu = np.asarray(est.eta, float), np.asarray(est.nu, float)
        if eta.shape != (3,) or nu.shape != (3,) or not (_finite(eta) and _finite(nu)):
            raise MPCError(f"estimate eta = {eta.tolist()}, nu = {nu.tolist()} must be finite 3-vectors")
        if not (isinstance(est.t, (int, float, np.floating)) and math.isfinite(est.t)):
            raise MPCError(f"estimate t = {est.t!r} must be a finite time [s]")
        eta_d = np.asarray(sp.eta_d, float).copy()
        tau_env = np.asarray(est.tau_env, float)
        for name, v in (("estimate tau_env", tau_env), ("setpoint eta_d", eta_d)):
            if v.shape != (3,) or not _finite(v):
                raise MPCError(f"{name} = {v.tolist()} must be a finite 3-vector")
        eta_d[2] = eta[2] + ssa(eta_d[2] - eta[2])  # heading setpoint unwrapped next to the heading
        tau_env_E = rot_z(eta[2]) @ tau_env
        b_E = self._load_in_prediction(float(est.t), tau_env_E)
        pi = self._prob.p_idx
        if self._n_p is None or self._n_p[1] is not self._prob:
            self._n_p = (self._prob.p.numel(), self._prob)
        p = np.zeros(self._n_p[0])
        if self._prob.n_poly:
            if self._poly is None:
                self._poly = self._polytope()
            p[pi["poly_A"].start:pi["rate_dt"].stop] = self._poly  # rows, bounds, r dt: consecutive in p
        u_prev = np.zeros(self._n_u) if self._u_prev is None else self._u_prev
        # after a thruster failure the previous move may lie outside what the rest can deliver: the
        # rate rows start from its part inside (else the first move could have no feasible value)
        u_prev = self._into_polytope(u_prev / self._prob.scale["u"]) * self._prob.scale["u"]
        if "rp_dist" in pi:   # roll-pitch damping: the measured attitude and the disturbance moment
            att, p[pi["rp_dist"]] = self._roll_pitch_parameters(float(est.t))
            p[pi["x0"]] = np.concatenate([eta, nu, att])
        else:
            p[pi["x0"]] = np.concatenate([eta, nu])
        p[pi["u_prev"]], p[pi["eta_d"]], p[pi["b"]] = u_prev, eta_d, b_E
        ft = self.settings.fault_tolerance
        lost = frozenset(est.lost_points) if ft else frozenset()
        if pi["moor"].stop > pi["moor"].start:
            moor = mooring_parameters(self._with_lost(lost), self._centre(eta, eta_d))
            if ft and est.broken_lines:
                moor = self._without_broken(moor, frozenset(est.broken_lines))
            p[pi["moor"]] = moor
        p[pi["T_lim"]] = self._tension_limits(est)
        self._radius = math.nan
        if pi["dead_band"].stop > pi["dead_band"].start:
            p[pi["dead_band"]] = self._radius = self._dead_band(float(est.t), eta[2], tau_env_E,
                                                                frozenset(est.broken_lines), eta_d[:2], lost)
        if pi["riser"].stop > pi["riser"].start:
            p[pi["riser"]] = self._riser_parameters(est)
        return p

    def _with_lost(self, lost: frozenset) -> Any:
        """The line model with the buoys ``lost`` ((line id, joint)) gone (the model itself for
        none), built once per set: the same lines, so its characteristics take the intact ones'
        place in the prediction."""
        lost = frozenset(p for p in lost if p[0] in self.model.line_ids)
        if not lost:
            return self.model
        if lost not in self._lost_models:
            self._lost_models[lost] = self.model.with_points_lost(sorted(lost))
        return self._lost_models[lost]

    def _dead_band(self, t: float, psi: float, b_E: np.ndarray, broken: frozenset, centre: np.ndarray,
                   lost: frozenset = frozenset()) -> float:
        """The dead band's radius [m]: ``dead_band``, or once a break (or a buoy loss, ``lost``) is
        reported ``dead_band_damaged``, within the intact thrust budget (:func:`budgeted_dead_band`) with
        ``dead_band_budget``: at the estimated load and heading low-passed over
        ``MEAN_LOAD_TIME_CONSTANT`` (the heading as its unit vector; over the time since the first
        estimate until that has passed, so an early break sees the mean so far, not the filter's
        start), about the setpoint ``centre`` (a turret offset). Logged (:meth:`log`)."""
        st = self.settings   # dead_band_damaged is only set with fault_tolerance (MPCSettings checks)
        if st.dead_band_damaged is None:
            return st.dead_band
        if st.dead_band_budget:   # followed from the start: the break needs them as they were
            m = np.concatenate([b_E, [math.cos(psi), math.sin(psi)]])
            if self._t_mean is None:
                self._t_first = t
            # the running mean over the time so far until MEAN_LOAD_TIME_CONSTANT has passed
            T = min(MEAN_LOAD_TIME_CONSTANT, max(t - self._t_first, 1e-9))
            self._b_mean = _low_pass_step(self._b_mean, self._t_mean, m, t, T)
            self._t_mean = t
        broken = broken & frozenset(self.model.line_ids)
        lost = frozenset(p for p in lost if p[0] in self.model.line_ids and p[0] not in broken)
        if not broken and not lost:
            r = st.dead_band
        elif not st.dead_band_budget:
            r = st.dead_band_damaged
        else:
            key = (broken, lost) if lost else broken
            if key not in self._damaged_lines:
                try:
                    self._damaged_lines[key] = self.model.damaged(broken, lost)
                except ModelError:        # no line left: the thrusters hold it all, no budget to share
                    self._damaged_lines[key] = None
            damaged = self._damaged_lines[key]
            b_mean, psi_mean = self._b_mean[:3], math.atan2(self._b_mean[4], self._b_mean[3])
            r = st.dead_band if damaged is None else budgeted_dead_band(
                self.model, damaged, b_mean, psi_mean, st.dead_band_damaged, st.dead_band, centre)
        ids, pts = sorted(broken), [[lid, j] for lid, j in sorted(lost)]
        extra = {"lost_points": pts} if pts else {}
        last = self._log[-1] if self._log else {"broken": [], "radius": st.dead_band}
        was = bool(last["broken"] or last.get("lost_points"))
        if last["broken"] != ids or last.get("lost_points", []) != pts:
            self._log.append({"t": t, "event": "mode switch", "from": "damaged" if was else "intact",
                              "to": "damaged" if ids or pts else "intact", "radius": r, "broken": ids, **extra})
        elif (ids or pts) and abs(last["radius"] - r) >= 0.5:
            self._log.append({"t": t, "event": "dead band", "radius": r, "broken": ids, **extra})
        return r

    def _condensed_solve(self, evaluate: Any, *args: Any) -> tuple[bool, str, int, np.ndarray]:
        """``CondensedDAQP.solve(*args)`` after ``evaluate()`` (the QP data into their buffers;
        None: evaluated already); bad data inside the QP or its condensing is a failed solve (its
        message the status) and DAQP is set up afresh at the next step."""
        try:
            if evaluate is not None:
                evaluate()
            return self._daqp.solve(*args)
        except (ValueError, RuntimeError, MPCError) as exc:
            self._daqp.reset()
            return False, _error_status(exc), -1, np.full(self._daqp.cq.nz, np.nan)

    def _load_in_prediction(self, t: float, b_E: np.ndarray) -> np.ndarray:
        """The estimated load in {E} through the first-order low-pass filter of time constant
        ``settings.load_time_constant`` [s] (started at the first estimate; 0: unfiltered)."""
        T = self.settings.load_time_constant
        if T <= 0:
            return b_E
        self._b_lf = _low_pass_step(self._b_lf, self._t_b, b_E, t, T)
        self._t_b = t
        return self._b_lf.copy()

    def _without_broken(self, moor: np.ndarray, broken: frozenset) -> np.ndarray:
        """Line characteristics (5 n,) with the lines ``broken`` dropped: their H0, dH/dXF, T0 and
        dT/dXF zeroed (XF0 kept), so they pull nothing and carry no tension in the prediction."""
        out = moor.reshape(5, -1).copy()
        cols = [i for i, lid in enumerate(self.model.line_ids) if lid in broken]
        if cols:
            out[np.ix_([0, 1, 3, 4], cols)] = 0.0
        return out.ravel()

    #: Time constant of the low-pass of the measured riser angles that gives the current's share [s].
    RISER_LF_TIME = 60.0

    def _tension_limits(self, est: Estimate) -> np.ndarray:
        """Allowed fairlead tension of every modelled line [N]: ``tension_utilisation`` x MBS, and
        with ``reliability`` the lower of that and the tension at which the line's index is
        ``delta_s``, ``T_b - k sigma - delta_s sigma_b`` (``k sigma`` from ``est.reliability`` once
        its windows are full; lines without sigma_b keep the utilisation limit), floored at 5 % of
        MBS. The reliability limit only ever tightens the design limit."""
        s, prob = self.settings, self._prob
        T_allow = np.asarray(prob.scale["T_allow"], float)
        if not s.reliability or est.reliability is None or not est.reliability.ready:
            return T_allow
        ks = est.reliability.allowance()
        mbs, std = np.asarray(self.model.MBS, float), np.asarray(self.model.MBS_std, float)
        kl = np.array([ks.get(line_signal(lid), 0.0) for lid in self.model.line_ids])
        rel = np.maximum(mbs - kl - s.delta_s * std, 0.05 * mbs)
        return np.where(std > 0, np.minimum(T_allow, rel), T_allow)

    def _riser_parameters(self, est: Estimate) -> np.ndarray:
        """(limit top, limit bottom, current's share of the top angle (2), of the bottom angle (2))
        [rad]: the limits are the angles at which each end's index is ``delta_s``,
        ``r - k sigma - delta_s sigma_r`` (floored at 0.05 deg); the shares are the low-passed
        measured angles less the hang-off part ``c (p_h - wellhead)`` at the estimated pose
        (zero without measured angles: still water)."""
        rs, R = self.system.scenario.riser, self.riser
        ks = {} if est.reliability is None else est.reliability.allowance()
        floor = math.radians(0.05)
        lim = [max(rs.critical_top_angle - ks.get(RISER_TOP, 0.0) - self.settings.delta_s * rs.critical_top_angle_std,
                   floor),
               max(rs.critical_bottom_angle - ks.get(RISER_BOTTOM, 0.0)
                   - self.settings.delta_s * rs.critical_bottom_angle_std, floor)]
        share = np.zeros(4)
        if est.riser_angles is not None:
            self._theta_lf = _low_pass_step(self._theta_lf, self._t_theta, est.riser_angles, est.t, self.RISER_LF_TIME)
            self._t_theta = est.t
            c = R.coefficients
            d = R.hangoff_E(np.asarray(est.eta, float)) - np.asarray(R.wellhead, float)
            share = self._theta_lf - np.concatenate([c["c_t"] * d, c["c_b"] * d])
        return np.concatenate([lim, share])

    def _polytope(self) -> np.ndarray:
        """Thrust-polytope parameters of the thrusters alive (``polytope_parameters``; a DOF left
        without thrust gets the stand-in box, kept in ``_poly_box``)."""
        ths = self.system.thrusters.without(self._failed) if self._failed else self.system.thrusters
        params, self._poly_box = polytope_parameters(ths, self.settings, self._prob.scale["u"], self._prob.n_poly)
        return params

    def _poly_rows(self) -> tuple[np.ndarray, np.ndarray]:
        """(A_s (n, 3), b (n,)) of the thrust polytope in the scaled thrust (padding included)."""
        n = self._prob.n_poly
        return self._poly[:3 * n].reshape(3, n).T, self._poly[3 * n:4 * n]

    def _into_polytope(self, u_s: np.ndarray) -> np.ndarray:
        """Scaled thrust rows (..., 3) moved into the thrust polytope: a row outside it is scaled
        toward zero onto its boundary (the origin is inside), or clipped when the polytope is the
        stand-in box. Unchanged without a polytope."""
        if not self._prob.n_poly or self._poly is None:
            return u_s
        if self._poly_box is not None:
            return np.clip(u_s, -self._poly_box, self._poly_box)
        A, b = self._poly_rows()
        u2 = np.atleast_2d(u_s)
        over = np.maximum(1.0, np.max(u2 @ A.T / b, axis=1))
        return (u2 / over[:, None]).reshape(np.shape(u_s))

    def _centre(self, eta: np.ndarray, eta_d: np.ndarray) -> np.ndarray:
        """Pose about which the model is centred (``MPCSettings.linearise_about``): the estimate,
        or the body pose that puts the turret at the setpoint with the present heading."""
        if self.settings.linearise_about == "state":
            return eta
        return np.array([*body_from_turret(eta_d[:2], eta[2], self.system.p_cot_B), eta[2]])

    def _shift(self, z: np.ndarray) -> np.ndarray:
        """The plan ``z`` one step on (the warm start and the fallback): states, thrust and slacks
        moved by a step, the last repeated; with move blocking each block takes the shifted plan's
        thrust at its first step. A gather of ``z`` by the index map of :meth:`_shift_reference`
        (the same numbers, built once per problem)."""
        perm = self._shift_map
        if perm is None or perm[1] is not self._prob:
            perm = self._shift_map = (self._shift_reference(np.arange(self._prob.z.numel(), dtype=float))
                                      .astype(np.int64), self._prob)
        return z[perm[0]]

    def _shift_reference(self, z: np.ndarray) -> np.ndarray:
        """:meth:`_shift` written out (the reference its index map is taken from)."""
        prob, N = self._prob, self.settings.horizon
        idx = prob.idx
        out = z.copy()
        X = z[idx["X"]].reshape(N + 1, prob.nx)
        U = z[idx["U"]].reshape(prob.n_moves, self._n_u)[prob.block_of]   # the thrust of every step
        U = np.vstack([U[1:], U[-1:]])
        starts = np.flatnonzero(np.r_[True, np.diff(prob.block_of) != 0])
        out[idx["X"]] = np.vstack([X[1:], X[-1:]]).ravel()
        out[idx["U"]] = U[starts].ravel()
        for key in ("S_db", "S_safe", "S_T", "S_R"):
            sl = z[idx[key]]
            out[idx[key]] = np.concatenate([sl[1:], sl[-1:]])
        return out

    def _initial(self, p: np.ndarray) -> np.ndarray:
        z = np.zeros(self._prob.z.numel())
        X = np.tile(p[self._prob.p_idx["x0"]] / self._prob.scale["x"], self.settings.horizon + 1)
        z[self._prob.idx["X"]] = X
        return z

    def _finish(self, t: float, z: np.ndarray, ok: bool, status: str, solve_time: float, it: int, cost: float) -> np.ndarray:
        idx, M = self._prob.idx, self._prob.n_moves
        fallback = False
        if not ok or not np.all(np.isfinite(z)):
            fallback = True
            if self._z is not None:
                z = self._shift(self._z)
            else:
                z = self._initial(self._last_p)
                z[idx["U"]] = np.tile((self._u_prev if self._u_prev is not None else np.zeros(self._n_u))
                                      / self._prob.scale["u"], M)
        # hard input bounds (and the thrust polytope) are kept even by a fallback plan
        U_s = np.clip(z[idx["U"]].reshape(M, self._n_u), self._prob.lbz[idx["U"]].reshape(M, self._n_u),
                      self._prob.ubz[idx["U"]].reshape(M, self._n_u))
        if fallback:
            U_s = self._into_polytope(U_s)
        U = U_s * self._prob.scale["u"]
        self._z = z
        u0 = U[0]
        self._u_prev = u0.copy()
        self.plan_u = U[self._prob.block_of]   # the thrust of every prediction step
        top = {k: float(np.max(z[idx[k]], initial=0.0)) for k in ("S_safe", "S_T", "S_R", "S_db")}
        soft = max(top[k] for k in ("S_safe", "S_T", "S_R"))
        active = []
        if top["S_R"] > 1e-4:
            active.append("riser")
        if top["S_safe"] > 1e-4:
            active.append("safe_circle")
        if top["S_T"] > 1e-4:
            active.append("tension")
        if top["S_db"] > 1e-4:
            active.append("dead_band")
        us = z[idx["U"]][:self._n_u]
        lo, hi = self._prob.lbz[idx["U"]][:self._n_u], self._prob.ubz[idx["U"]][:self._n_u]
        free = hi > lo  # a failed thruster's column (bounds 0, 0) is not a capacity limit
        at_box = np.any(free & (np.abs(us) >= np.minimum(-lo, hi) - 1e-4))
        if self._prob.n_poly and self._poly is not None:  # a facet of the attainable polytope
            A, b = self._poly_rows()
            at_box = at_box or bool(np.any(A @ us - b >= -1e-4))
        if at_box:
            active.append("thrust_capacity")
        self.diagnostics.append(MPCStep(t=t, success=ok, status=status, solve_time=solve_time, iterations=it,
                                        fallback=fallback, cost=cost, active=tuple(active), max_soft_violation=soft,
                                        dead_band=self._radius))
        return u0

    def last_step(self) -> MPCStep | None:
        """Diagnostics of the latest update (:class:`MPCStep`)."""
        return self.diagnostics[-1] if self.diagnostics else None

    def set_failed_thrusters(self, failed: frozenset[str]) -> None:
        """Thruster feedback reports ``failed``: the thrust bounds of the following solves are those
        of the remaining thrusters (``decision="tau"``: the capacity box of the reduced
        :class:`~tapm_opt.models.system.ThrusterSet`; ``"thrusters"``: zero force for a failed one)."""
        failed = frozenset(failed)
        if failed == self._failed:
            return
        self.system.thrusters.without(failed)  # unknown ids raise here
        self._failed = failed
        self._bounds_changed = True
        self._poly = None  # the attainable polytope of the remaining thrusters, at the next update
        if self._prob is not None:
            self._apply_u_bounds()

    def _apply_u_bounds(self) -> None:
        """Write the thrust bounds of the thrusters that have not failed into the problem (after
        each (re)build and each change of the failed set)."""
        if not (self._failed or self._bounds_changed):
            return  # a problem is built with the intact bounds
        ths = self.system.thrusters.without(self._failed) if self._failed else self.system.thrusters
        self._bounds_changed = False
        M = self._prob.n_moves
        if self.settings.decision == "tau":
            box = ths.capacity_box(self.settings.capacity_fraction) if self.settings.thrust_set == "box" else ths.max_tau()
            lim = np.asarray(box) / self._prob.scale["u"]
            lo, hi = -lim, lim
        else:
            _, lo_si, hi_si, _, _ = ths.extended()
            lo, hi = lo_si / self._prob.scale["u"], hi_si / self._prob.scale["u"]
        sl = self._prob.idx["U"]
        self._prob.lbz[sl], self._prob.ubz[sl] = np.tile(lo, M), np.tile(hi, M)

    def tau_from_u(self, u: np.ndarray) -> np.ndarray:
        """Generalised thrust [N, N, N m] of a decision vector (identity for ``decision="tau"``)."""
        return u if self._prob.B_thr is None else self._prob.B_thr @ u

    def thruster_forces(self, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(f, alpha) of every thruster from the thruster decision vector (``decision="thrusters"``)."""
        f, alpha, col = [], [], 0
        for t in self.system.thrusters.specs:
            if t.kind == "azimuth":
                fx, fy = u[col], u[col + 1]
                f.append(math.hypot(fx, fy))
                alpha.append(math.atan2(fy, fx) if math.hypot(fx, fy) > 1e-6 * t.max_thrust else t.angle)
                col += 2
            else:
                f.append(u[col])
                alpha.append(t.angle)
                col += 1
        return np.array(f), np.array(alpha)

    def thruster_command(self) -> ThrusterCommand:
        """Thrust and azimuth of every thruster for the move applied last (``decision="thrusters"``;
        the :class:`~tapm_opt.interfaces.ThrusterController` method)."""
        ths = self.system.thrusters
        if self._u_prev is None:
            return ThrusterCommand(f=np.zeros(ths.n), alpha=np.array([t.angle for t in ths.specs]))
        f, alpha = self.thruster_forces(self._u_prev)
        return ThrusterCommand(f=f, alpha=alpha)

    def update(self, t: float, estimate: Estimate, setpoint: Setpoint) -> np.ndarray:
        """Solve the MPC at time ``t`` and return the generalised thrust tau (3,) in {B} [N, N, N m]."""
        p = self._params(estimate, setpoint)
        self._last_p = p
        u0 = self._solve(t, p)
        return self.tau_from_u(u0)

    def reset(self) -> None:
        self._z = None
        self._u_prev = None
        self.diagnostics = []
        self._theta_lf = self._t_theta = None
        self._b_lf = self._t_b = None
        self._b_mean = self._t_mean = None
        self._log = []
        self._attitude = self._rp_dist = self._t_dist = None


class NonlinearMPC(_MPCBase):
    """Nonlinear MPC on the design model with the chosen mooring model (CasADi NLP).

    The NLP solver is built once; each :meth:`update` sets the parameters (state estimate, previous
    thrust, setpoint, environmental load, the line characteristics at the centre pose and the
    thrust polytope of the thrusters alive) and warm-starts from the shifted previous solution.

    ``qp_solver="daqp"`` (with ``solver="rti"`` and the Gauss–Newton Hessian): each step's QP —
    the Gauss–Newton QP at the shifted previous plan — is evaluated by CasADi into numpy buffers,
    condensed and solved by DAQP (``control.mpc_condensed``), and the full step is taken: the
    real-time iteration without CasADi's ``sqpmethod`` (its step to 1e-5 of the thrust maxima,
    in about a third of its time at N = 20). A failed DAQP solve applies the shifted plan (no
    OSQP retry).
    """

    #: The SQP's stationarity tolerance relative to the L1 penalty weight ``soft_l1`` (the scale of
    #: the soft constraints' multipliers, so of the Lagrangian's gradient): ``tol_du`` of
    #: ``sqpmethod`` is ``SQP_DUAL_TOLERANCE x max(1, soft_l1)`` (1e-2 with the default 1e3) instead of
    #: its absolute 1e-6. The Gauss-Newton SQP converges linearly where the dynamics' curvature
    #: matters: in the design storm, 57 m off with the thrust saturated after a line break, it
    #: contracted the dual infeasibility by 0.83 per iteration and took 77 iterations to reach
    #: 1e-6 (24 to reach 1e-2), while its first move agreed with the converged one to 1e-8 after
    #: 10 and the cost to 2e-8 after 24.
    SQP_DUAL_TOLERANCE = 1e-5

    def __init__(self, system: Any, settings: MPCSettings = MPCSettings(), *, period: float | None = None,
                 qp_solver: str = "piqp"):
        super().__init__(system, settings, period=period)
        if qp_solver not in NONLINEAR_QP_SOLVERS:
            raise MPCError(f"qp_solver = {qp_solver!r} is not one of {', '.join(NONLINEAR_QP_SOLVERS)}")
        s = settings
        if qp_solver == "daqp" and (s.solver != "rti" or s.hessian != "gauss-newton"):
            raise MPCError(f"qp_solver = 'daqp' needs solver = 'rti' and hessian = 'gauss-newton' (one Gauss-Newton "
                           f"QP per step, condensed), got solver = {s.solver!r}, hessian = {s.hessian!r}")
        self.qp_solver = qp_solver
        prob = build_problem(self.system, settings, model=self.model, riser=self.riser)
        self._prob = prob
        self._n_u = prob.n_u
        self._lam_x = None
        self._lam_g = None
        #: Solves the retry solver (SQP with OSQP) rescued after the first one failed.
        self.retries = 0
        self._retry = None
        self._daqp = None
        if qp_solver == "daqp":
            self._setup_rti_daqp(prob)
            return
        nlp = {"x": prob.z, "p": prob.p, "f": prob.f, "g": prob.g}
        gn = {}
        if s.solver in ("sqp", "rti") and s.hessian == "gauss-newton":
            gn = {"hess_lag": self._gauss_newton(prob)}
        if s.solver == "ipopt":
            opts = {"ipopt.print_level": 0, "print_time": False, "ipopt.max_iter": s.max_iter, "ipopt.tol": 1e-6,
                    "ipopt.warm_start_init_point": "yes", "ipopt.sb": "yes", "ipopt.max_cpu_time": s.max_time}
            self._solver = ca.nlpsol("mpc", "ipopt", nlp, opts)
        elif s.solver in ("sqp", "rti"):
            # SQP on the Gauss-Newton Hessian (convex QP subproblems) with the sparse proximal
            # interior-point piqp for them: the active-set qrqp cycled on the degenerate vertices
            # of the polygons and the thrust polytope (fpso, N = 10, 43 m off: 77 s and no
            # convergence, against 0.1 s with piqp); the same SQP with OSQP is the retry.
            base = {"print_time": False, "print_header": False, "print_iteration": False,
                    "print_status": False, "max_iter": 1 if s.solver == "rti" else s.max_iter,
                    "error_on_fail": False,
                    "tol_du": self.SQP_DUAL_TOLERANCE * max(1.0, s.soft_l1), **gn}
            self._solver = ca.nlpsol("mpc", "sqpmethod", nlp, {
                **base, "qpsol": "piqp",
                "qpsol_options": {"error_on_fail": False, "piqp": {"kkt_solver": PIQP_KKT_SOLVER}}})
            self._retry = ca.nlpsol("mpc_retry", "sqpmethod", nlp, {
                **base, "qpsol": "osqp",
                "qpsol_options": {"error_on_fail": False,
                                  "osqp": {"verbose": False, "eps_abs": 1e-6, "eps_rel": 1e-6,
                                           "max_iter": 4000, "polish": True}}})
        else:
            # a barrier parameter of 0.1 from the start (fatrop's default starts at 10): with the
            # dead-band polygon the default stopped with status 1 after 43 iterations at N = 10,
            # where this converges in 18 to the SQP's answer
            opts = {"print_time": False, "fatrop.print_level": 0, "fatrop.max_iter": s.max_iter,
                    "fatrop.mu_init": 0.1, "fatrop.tol": 1e-6}
            self._solver = ca.nlpsol("mpc", "fatrop", nlp, opts)

    def _setup_rti_daqp(self, prob: _Problem) -> None:
        """``qp_solver="daqp"``: the Gauss–Newton QP of the NLP at a point ``z_lin`` as CasADi
        functions evaluated into numpy buffers (the upper triangle of ``2 J_r^T J_r``, the Jacobians
        of the equality rows and of the others, the cost's gradient, both row blocks and the cost at
        ``z_lin``), condensed and solved by DAQP (``control.mpc_condensed``)."""
        from .mpc_condensed import CondensedDAQP, CondensedQP

        z, p = prob.z, prob.p
        Jr = ca.jacobian(prob.r, z)
        H = ca.triu(2 * ca.mtimes(Jr.T, Jr))
        eq, (g_eq, g_in) = _split_rows(prob)
        J_eq, J_in = ca.jacobian(g_eq, z), ca.jacobian(g_in, z)
        outs = [_nonzeros(H), _nonzeros(J_eq), _nonzeros(J_in), ca.gradient(prob.f, z), g_eq, g_in, prob.f]
        (self._gn_z, self._gn_p), self._gn_data, self._gn_eval = _buffered(ca.Function("gn_qp", [z, p], outs))
        self._f_fun = ca.Function("f", [z, p], [prob.f])
        # the same function evaluated into numpy buffers (no conversion to DM per call)
        (self._f_z, self._f_p), (self._f_out,), self._f_eval = _buffered(self._f_fun)
        self._b_eq = prob.lbg[eq]
        patterns = [(np.array(M.sparsity().row()), np.array(M.sparsity().colind())) for M in (H, J_eq, J_in)]
        self._daqp = CondensedDAQP(CondensedQP(prob, *patterns, lb_in=prob.lbg[~eq], ub_in=prob.ubg[~eq]),
                                   DAQP_SETTINGS, DAQP_PASSES)
        self._slacks = slice(prob.idx["U"].stop, len(prob.lbz))

    @staticmethod
    def _gauss_newton(prob: _Problem) -> ca.Function:
        """Hessian of the Lagrangian for sqpmethod: ``lam_f 2 J_r^T J_r + 1e-8 I`` with ``J_r`` the
        Jacobian of the cost's least-squares residuals (the L1 slack terms are linear). Positive
        definite whatever the multipliers, so every QP subproblem is convex; the curvature of the
        dynamics and constraints is left out (Gauss–Newton SQP), which costs iterations far from
        the solution and not the solution itself."""
        z, p = prob.z, prob.p
        Sym = type(z)
        lam_f, lam_g = Sym.sym("lam_f"), Sym.sym("lam_g", prob.g.numel())
        J = ca.jacobian(prob.r, z)
        H = 2 * lam_f * ca.mtimes(J.T, J) + 1e-8 * Sym.eye(z.numel())
        return ca.Function("nlp_hess_l", [z, p, lam_f, lam_g], [H], ["x", "p", "lam_f", "lam_g"],
                           ["hess_gamma_x_x"])

    #: Status of an accepted real-time iteration (``solver="rti"``): one SQP iteration whose QP
    #: solved, which ``sqpmethod`` reports as its iteration limit.
    RTI_STATUS = "Real_Time_Iteration"

    def _call(self, solver: Any, args: dict) -> tuple[bool, str, int, np.ndarray, float, Any]:
        try:
            sol = solver(**args)
            stats = solver.stats()
            ok, status = bool(stats.get("success", False)), str(stats.get("return_status", "unknown"))
            z, it = np.array(sol["x"]).ravel(), int(stats.get("iter_count", -1))
            if (self.settings.solver == "rti" and not ok and status == "Maximum_Iterations_Exceeded"
                    and it == 1 and np.all(np.isfinite(z))):
                ok, status = True, self.RTI_STATUS
            return ok, status, it, z, float(sol["f"]), sol
        except RuntimeError as exc:  # an evaluation error inside the solver: treat as a failed solve
            return False, _error_status(exc), -1, args["x0"], math.nan, None

    def _solve_rti_daqp(self, t: float, p: np.ndarray) -> np.ndarray:
        """One real-time iteration with the condensed QP in DAQP: the Gauss–Newton QP at the
        shifted previous plan (its slacks set to 0: they enter the rows linearly and the cost
        quadratically, so the QP's slacks are the new plan's), condensed and solved, and the full
        step taken."""
        prob = self._prob
        z_lin = self._shift(self._z) if self._z is not None else self._initial(p)
        z_lin[self._slacks] = 0.0
        t0 = time.perf_counter()
        self._gn_z[:], self._gn_p[:] = z_lin, p
        Hx, Ax, Gx, q, g_eq, g_in, _ = self._gn_data   # the buffers the evaluation fills
        ok, status, it, dz = self._condensed_solve(self._gn_eval, Hx, Ax, Gx, q, self._b_eq, g_eq, g_in,
                                                   prob.lbz - z_lin, prob.ubz - z_lin, np.zeros(self._daqp.cq.nU))
        z = z_lin + dz
        cost = self._cost_at(z, p) if ok else math.nan
        return self._finish(t, z, ok, self.RTI_STATUS if ok else status, time.perf_counter() - t0, it, cost)

    def _cost_at(self, z: np.ndarray, p: np.ndarray) -> float:
        """The NLP's cost at ``z`` with the parameters ``p`` (``self._f_fun(z, p)`` evaluated into
        its buffers)."""
        self._f_z[:], self._f_p[:] = z, p
        self._f_eval()
        return float(self._f_out[0])

    def _solve(self, t: float, p: np.ndarray) -> np.ndarray:
        prob = self._prob
        if self._daqp is not None:
            return self._solve_rti_daqp(t, p)
        z0 = self._shift(self._z) if self._z is not None else self._initial(p)
        args = {"x0": z0, "p": p, "lbx": prob.lbz, "ubx": prob.ubz, "lbg": prob.lbg, "ubg": prob.ubg}
        if self._lam_g is not None:
            args["lam_x0"], args["lam_g0"] = self._lam_x, self._lam_g
        t0 = time.perf_counter()
        ok, status, it, z, cost, sol = self._call(self._solver, args)
        if not ok and self._retry is not None:
            ok2, status2, it2, z2, cost2, sol2 = self._call(self._retry, args)
            it = it + max(it2, 0)
            if ok2:
                self.retries += 1
                ok, status, z, cost, sol = ok2, f"{status2} (retry after {status})", z2, cost2, sol2
        if ok:
            self._lam_x = np.array(sol["lam_x"]).ravel()
            self._lam_g = np.array(sol["lam_g"]).ravel()
        return self._finish(t, z, ok, status, time.perf_counter() - t0, it, cost)


class LinearMPC(_MPCBase):
    """Linear MPC: the same problem with dynamics and tensions linearised about an operating point,
    solved as a sparse QP, set up once.

    The QP is written once with the operating point ``(x_op, u_op, b_op)`` among its parameters
    (``build_problem(..., linear=True)``): its Hessian, constraint matrix, gradient and the constant
    part of its constraints are CasADi functions of the parameters with a fixed sparsity. Each update evaluates them at the
    present operating point — with ``linearise_about="state"`` the state estimate, the previous
    thrust and the load estimate, so the prediction is exact to first order where the vessel is —
    and solves (no problem construction in the loop). ``linearise_about="setpoint"`` linearises
    about the setpoint at rest with the present heading instead.

    ``qp_solver="piqp"`` (default) solves it with the sparse proximal interior-point solver piqp
    (its own package, set up once, the values updated each step; the dynamics as equality rows, the
    rest as two-sided rows and bounds); ``"osqp"`` with OSQP (set up once, values updated,
    warm-started from the shifted plan). In the fpso storm closed loop OSQP stopped at its
    iteration limit or "solved inaccurate" on 2–7 of 720 steps with the thrust polytope in the
    problem; piqp on none. ``"daqp"``: the QP condensed (the states eliminated, the slacks as soft
    rows) and solved by the dual active-set DAQP, hot-started (``control.mpc_condensed``; fastest
    with move blocking: 0.16 of piqp's time at N = 50 with 8 moves, slower than piqp at N = 50
    without blocking). The QP data are evaluated by CasADi straight into numpy arrays (no per-step
    conversion). ``eps_abs``, ``eps_rel``: OSQP's tolerances (piqp keeps its defaults).
    """

    def __init__(self, system: Any, settings: MPCSettings = MPCSettings(), *, qp_solver: str = "piqp",
                 eps_abs: float = 1e-5, eps_rel: float = 1e-5, period: float | None = None):
        super().__init__(system, settings, period=period)
        if qp_solver not in LINEAR_QP_SOLVERS:
            raise MPCError(f"qp_solver = {qp_solver!r} is not one of {', '.join(LINEAR_QP_SOLVERS)}")
        self.qp_solver = qp_solver
        self._eps = (eps_abs, eps_rel)
        prob = build_problem(self.system, settings, linear=True, model=self.model, riser=self.riser)
        self._prob, self._n_u = prob, prob.n_u
        z, p = prob.z, prob.p
        nz = z.numel()
        self._nz = nz
        H = ca.triu(ca.hessian(prob.f, z)[0])   # both solvers read the upper triangle
        if qp_solver == "osqp":
            import osqp

            self._osqp_mod = osqp
            blocks = [ca.jacobian(ca.vertcat(prob.g, z), z)]  # the constraints, then the bounds as rows
            g_parts = [prob.g]
            big = 1e20   # OSQP's infinity
            self._l_g = np.where(np.isfinite(prob.lbg), prob.lbg, -big)
            self._u_g = np.where(np.isfinite(prob.ubg), prob.ubg, big)
        else:
            if qp_solver == "piqp":
                import piqp

                self._piqp_mod = piqp
            eq, g_parts = _split_rows(prob)
            blocks = [ca.jacobian(g, z) for g in g_parts]
            self._b_eq, self._lb_in, self._ub_in = prob.lbg[eq], prob.lbg[~eq], prob.ubg[~eq]
        # the QP in the step from z = 0 at the parameters p: the nonzeros (CSC order) of H and of each
        # constraint block, the gradient q, g(0) of each block and the cost f(0) (the solvers report
        # f(z) - f(0)), evaluated into numpy buffers set up once
        outs = [_nonzeros(H), *(_nonzeros(B) for B in blocks), ca.gradient(prob.f, z), *g_parts, prob.f]
        fun = ca.Function("qp_data", [z, p], outs)
        fun = ca.Function("qp_data_p", [p], fun(ca.DM.zeros(nz), p))
        (self._p_buf,), self._data, self._eval = _buffered(fun)
        self._mats = [(M.sparsity(), np.array(M.sparsity().row()), np.array(M.sparsity().colind())) for M in (H, *blocks)]
        self._qp = None
        self._daqp = None
        if qp_solver == "daqp":
            from .mpc_condensed import CondensedDAQP, CondensedQP

            self._daqp = CondensedDAQP(CondensedQP(prob, *((row, colind) for _, row, colind in self._mats),
                                                   lb_in=self._lb_in, ub_in=self._ub_in),
                                       DAQP_SETTINGS, DAQP_PASSES)

    def _qp_arrays(self, p: np.ndarray) -> list[np.ndarray]:
        """The QP data at the parameters ``p`` (with the operating point set): the nonzeros of H and
        of each constraint block, q, g(0) of each block, f(0), in buffers the next evaluation
        overwrites."""
        self._p_buf[:] = p
        self._eval()
        return self._data

    def _csc(self, i: int, data: np.ndarray) -> sp.csc_matrix:
        """The i-th matrix of the QP data (0: H, then the constraint blocks) with the nonzeros ``data``."""
        spy, row, colind = self._mats[i]
        return sp.csc_matrix((data, row, colind), shape=spy.shape)

    def _solve(self, t: float, p: np.ndarray) -> np.ndarray:
        prob = self._prob
        pi = prob.p_idx
        # operating point: where the vessel is (or the setpoint), with the previous thrust and the load
        eta, eta_d = p[pi["x0"]][:3], p[pi["eta_d"]]
        if self.settings.linearise_about == "state":
            x_op = p[pi["x0"]]
            u_op = p[pi["u_prev"]]
        else:
            x_op = np.concatenate([self._centre(eta, eta_d), np.zeros(3), p[pi["x0"]][6:]])
            u_op = np.zeros(self._n_u)
        p[pi["x_op"]], p[pi["u_op"]], p[pi["b_op"]] = x_op, u_op, p[pi["b"]]
        self._f0 = float(self._qp_arrays(p)[-1][0])
        if self.qp_solver == "piqp":
            return self._solve_piqp(t)
        if self.qp_solver == "daqp":
            return self._solve_daqp(t)
        Hx, Ax, q, g0 = self._data[:4]
        big = 1e20
        lbz = np.where(np.isfinite(prob.lbz), prob.lbz, -big)   # the bounds change with thruster failures
        ubz = np.where(np.isfinite(prob.ubz), prob.ubz, big)
        l = np.concatenate([self._l_g - g0, lbz])
        u = np.concatenate([self._u_g - g0, ubz])
        if self._qp is None:
            self._qp = self._osqp_mod.OSQP()
            self._qp.setup(P=self._csc(0, Hx), q=q, A=self._csc(1, Ax), l=l, u=u, verbose=False,
                           warm_starting=True, eps_abs=self._eps[0], eps_rel=self._eps[1], max_iter=20000,
                           polishing=True)
        else:
            self._qp.update(Px=Hx, Ax=Ax, q=q, l=l, u=u)
        if self._z is not None:
            self._qp.warm_start(x=self._shift(self._z))
        t0 = time.perf_counter()
        res = self._qp.solve(raise_error=False)
        dt = time.perf_counter() - t0
        st = int(res.info.status_val)
        ok = bool(st == int(self._osqp_mod.SolverStatus.OSQP_SOLVED) and res.x is not None
                  and np.all(np.isfinite(res.x)))
        z = np.asarray(res.x, float) if res.x is not None else np.full(self._nz, np.nan)
        cost = float(res.info.obj_val) + self._f0 if ok else math.nan
        return self._finish(t, z, ok, str(res.info.status), dt, int(res.info.iter), cost)

    def _solve_piqp(self, t: float) -> np.ndarray:
        """piqp on the QP data of this step: min 1/2 z'Hz + q'z, the equality rows A z = b, the rest
        h_l <= G z <= h_u, the bounds of z (infinite ones as they are)."""
        prob, piqp = self._prob, self._piqp_mod
        Hx, Ax, Gx, q, g_eq, g_in = self._data[:6]
        P, A, G = self._csc(0, Hx), self._csc(1, Ax), self._csc(2, Gx)
        b, h_l, h_u = self._b_eq - g_eq, self._lb_in - g_in, self._ub_in - g_in
        t0 = time.perf_counter()
        try:
            if self._qp is None:
                self._qp = piqp.SparseSolver()
                self._qp.settings.verbose = False
                self._qp.settings.kkt_solver = getattr(piqp.KKTSolver, PIQP_KKT_SOLVER)
                self._qp.setup(P, q, A, b, G, h_l, h_u, prob.lbz, prob.ubz)
            else:
                self._qp.update(P=P, c=q, A=A, b=b, G=G, h_l=h_l, h_u=h_u, x_l=prob.lbz, x_u=prob.ubz)
            status = self._qp.solve()
            res = self._qp.result
            z = np.array(res.x, float)
            ok = bool(status == piqp.Status.PIQP_SOLVED and np.all(np.isfinite(z)))
            it, cost, status = int(res.info.iter), float(res.info.primal_obj) + self._f0, status.name
        except (ValueError, RuntimeError) as exc:  # bad data inside the QP solver
            ok, status, it, z, cost = False, _error_status(exc), -1, np.full(self._nz, np.nan), math.nan
            self._qp = None   # set up afresh at the next step
        dt = time.perf_counter() - t0
        return self._finish(t, z, ok, status, dt, it, cost if ok else math.nan)

    def _solve_daqp(self, t: float) -> np.ndarray:
        """DAQP on the QP of this step condensed (``control.mpc_condensed``): the states eliminated,
        the slacks as soft rows; set up once, then updated in place with its working set kept (a
        hot start). The plan is expanded back to the sparse QP's variables, and its cost is the
        sparse QP's at that plan."""
        prob = self._prob
        Hx, Ax, Gx, q, g_eq, g_in = self._data[:6]
        if self._z is not None:       # the prediction the soft rows are chosen on: the plan shifted
            u_pred = self._shift(self._z)[prob.idx["U"]]
        else:
            u_pred = np.tile(self._last_p[prob.p_idx["u_prev"]] / prob.scale["u"], prob.n_moves)
        t0 = time.perf_counter()
        ok, status, it, z = self._condensed_solve(None, Hx, Ax, Gx, q, self._b_eq, g_eq, g_in, prob.lbz, prob.ubz,
                                                  u_pred)
        dt = time.perf_counter() - t0
        cost = self._daqp.cq.cost(Hx, q, z) + self._f0 if ok else math.nan
        return self._finish(t, z, ok, status, dt, it, cost)


def net_load_along(lines: Any, b_E: np.ndarray, psi: float, radius: float, direction: np.ndarray,
                   centre: Any = (0.0, 0.0)) -> float:
    """Mean environmental plus mooring load [N] along the unit vector ``direction`` in {E} on the
    vessel at rest with heading ``psi`` [rad] whose turret offset is ``centre + radius *
    direction`` [m] (``centre``: a turret offset, default the field zero point):
    ``(b_E + R(psi) tau_moor) . direction`` over (x, y). The thrusters hold the vessel there by
    pushing this much against ``direction`` (positive: the mooring alone does not hold it there).

    Parameters
    ----------
    lines : MooringModel
        The mooring (``models.mooring``; a damaged one from ``MooringModel.without``).
    b_E : array (3,)
        Environmental load in {E} [N, N, N m].
    """
    c = np.asarray(centre, float)
    xy = body_from_turret(c + radius * direction, psi, lines.p_cot_B)
    tau_moor = np.asarray(lines.force_fast(np.array([xy[0], xy[1], psi])), float)
    return float((b_E[:2] + rot_z(psi)[:2, :2] @ tau_moor[:2]) @ direction)


def budgeted_dead_band(intact: Any, damaged: Any, b_E: Any, psi: float, r_damaged: float, r_intact: float,
                       centre: Any = (0.0, 0.0)) -> float:
    """The dead band's radius [m] after a line break within the intact thrust budget
    (``MPCSettings.dead_band_budget``).

    The budget is the thrust along the mean environmental load ``b_E`` that holds the intact
    vessel (mooring ``intact``) with its turret ``r_damaged`` from the dead band's centre along that
    load, ``B = max(0, net_load_along(intact, ..., r_damaged))``. The result is the smallest radius
    ``r`` in [``r_damaged``, ``r_intact``] at which the damaged mooring needs at most that budget,
    ``net_load_along(damaged, ..., r) <= B`` (the net load falls as the turret moves out along the
    load and the lines take it up; found by bisection on the bracket to 1 cm); ``r_intact`` if
    even there it needs more, ``r_damaged`` if it needs no more there.

    Only the thrust along the load is budgeted: it is the part the dead band's radius moves. The
    load across it that a break leaves (after a side break of fpso in its design storm about
    2 MN, against 0.1 MN intact) has to be carried at any radius. Quasi-static: the vessel at rest
    at the mean load; the slowly varying and wave-frequency loads, which the dead band's margin to
    the safe circle is for, are left out.

    Parameters
    ----------
    intact, damaged : MooringModel
        The mooring before and after the break (``MooringModel.without``).
    b_E : array (3,)
        Mean environmental load in {E} [N, N, N m]; below 1 N in the horizontal plane (or not
        finite) there is no load to budget and the result is ``r_damaged``.
    psi : float
        Heading [rad].
    r_damaged, r_intact : float
        The dead band's radius after and before the break [m]; ``r_damaged >= r_intact`` returns
        ``r_damaged``.
    centre : array (2,)
        The dead band's centre, a turret offset [m] (the position setpoint).
    """
    b_E = np.asarray(b_E, float)
    load = float(np.hypot(b_E[0], b_E[1]))
    if r_damaged >= r_intact or not load >= 1.0 or not math.isfinite(load):
        return float(r_damaged)
    e = b_E[:2] / load
    budget = max(0.0, net_load_along(intact, b_E, psi, r_damaged, e, centre))

    def excess(r: float) -> float:
        return net_load_along(damaged, b_E, psi, r, e, centre) - budget

    if excess(r_damaged) <= 0.0:
        return float(r_damaged)
    if excess(r_intact) > 0.0:
        return float(r_intact)
    lo, hi = float(r_damaged), float(r_intact)
    while hi - lo > 0.01:
        mid = 0.5 * (lo + hi)
        lo, hi = (lo, mid) if excess(mid) <= 0.0 else (mid, hi)
    return hi


def _finite(v: np.ndarray) -> bool:
    """True when every element of the float array ``v`` is finite (the sum first: one float for the
    usual case; a sum that overflows is checked element by element)."""
    return math.isfinite(float(v.sum())) or bool(np.isfinite(v).all())


def _low_pass_step(x_lf: np.ndarray | None, t_lf: float | None, x: Any, t: float, T: float) -> np.ndarray:
    """First-order low-pass filter of time constant ``T`` [s], exact for ``x`` held since ``t_lf``:
    the filtered value at ``t`` from the one at ``t_lf``; it starts at ``x`` and holds its value
    should time go back."""
    x = np.array(x, float)
    if x_lf is None or t_lf is None:
        return x
    return first_order_step(x_lf, x, t - t_lf, T)


def _split_rows(prob: _Problem) -> tuple[np.ndarray, list]:
    """The problem's rows split into the equality rows (the dynamics and the initial state: equal
    finite bounds) and the others: ``(mask of the equality rows, [g_eq, g_in])``."""
    eq = np.isfinite(prob.lbg) & (prob.lbg == prob.ubg)
    rows = np.arange(len(prob.lbg))
    return eq, [prob.g[rows[eq].tolist()], prob.g[rows[~eq].tolist()]]


def _error_status(exc: BaseException) -> str:
    """A solver's exception as the step's status: ``"error: "`` and its first line (120 characters)."""
    return f"error: {str(exc).splitlines()[0][:120] if str(exc) else type(exc).__name__}"


def _buffered(fun: ca.Function) -> tuple[list[np.ndarray], list[np.ndarray], Any]:
    """``fun`` evaluated into numpy buffers set up once: ``(inputs, outputs, evaluate)`` — write
    the inputs in place, call ``evaluate()``, read the outputs (overwritten by the next call)."""
    ins = [np.zeros(fun.numel_in(i)) for i in range(fun.n_in())]
    outs = [np.zeros(fun.numel_out(i)) for i in range(fun.n_out())]
    buf, call = fun.buffer()
    for i, arr in enumerate(ins):
        buf.set_arg(i, memoryview(arr))
    for i, arr in enumerate(outs):
        buf.set_res(i, memoryview(arr))

    def evaluate(_buf: Any = buf) -> None:   # the buffer lives as long as this function
        call()

    return ins, outs, evaluate


def _nonzeros(M: Any) -> Any:
    """The structural nonzeros of a sparse CasADi matrix as a column (column-major: CSC order)."""
    return M.nz[:] if M.nnz() else type(M)(0, 1)
