"""The MPC's optimal control problem, written once as CasADi expressions (see
:mod:`tapm_opt.control.mpc` for the controllers that solve it).

:class:`MPCSettings` holds the weights, limits and solver options; :func:`build_problem` writes the
problem over CasADi symbols in scaled variables with multiple shooting — the prediction model (the
design form of the vessel with the chosen mooring model and the slowly varying environmental load),
the thrust decision (generalised thrust in the attainable polytope of the one ``ThrusterSet`` or
its capacity box, or the thrusters' force components), the cost as least squares plus L1
penalties, and the hard and soft constraints, all position terms on the turret offset. With
``linear=True`` the dynamics and tensions are linearised about an operating point that is a
parameter, and the problem is a QP whose matrices are functions of the parameters.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, Literal

import casadi as ca
import numpy as np

from ..errors import ModelError, TapmError
from ..geometry import R2, rot_z
from ..interfaces import ControllerStep
from ..models.mooring import MooringModel
from ..models.system import ATTAINABLE_DIRECTIONS, CAPACITY_FRACTION, as_system
from ..models.vessel import moored_function, roll_pitch_moments, roll_pitch_rhs

__all__ = ["MPCSettings", "MPCError", "MPCStep", "RollPitchWeights", "build_problem"]


class MPCError(TapmError, ValueError):
    """Bad MPC settings or arguments."""


@dataclass(frozen=True, kw_only=True)
class RollPitchWeights:
    """Roll–pitch damping in the MPC (``MPCSettings.roll_pitch_damping``; survey §4.2.3,
    ``docs/controllers.md`` "Roll–pitch damping in the MPC", eq. MRP1–MRP4): the prediction model
    carries the hull's low-frequency roll and pitch ``(phi, theta, p, q)``
    (:func:`~tapm_opt.models.vessel.roll_pitch_rhs`) under the moments of the planned thrust
    (:func:`~tapm_opt.models.vessel.roll_pitch_moments`) and a constant disturbance moment, and the
    cost charges the predicted rates and angles.

    Attributes
    ----------
    w_roll_rate, w_pitch_rate : float
        Weights on (p / rate_ref)^2 and (q / rate_ref)^2 at every predicted step [-].
    w_roll, w_pitch : float
        Weights on ((phi - phi_eq) / angle_ref)^2 and ((theta - theta_eq) / angle_ref)^2 [-], with
        phi_eq, theta_eq the static heel and trim of the disturbance moment alone (d / C); 0
        (default): the rates only, so the MPC does not fight the static heel.
    rate_ref : float
        Normalisation of the roll and pitch rates [rad/s] (default 0.1 deg/s).
    angle_ref : float
        Normalisation of the roll and pitch angles [rad] (default 1 deg).
    disturbance_time_constant : float
        The moments of the lines and the environment in the prediction [s]: a constant over the
        horizon, estimated as ``d = LP(C x_meas - M_thr)`` — the static moment that balances the
        measured roll and pitch less the moment of the MPC's own applied thrust — through a
        first-order low-pass filter of this time constant, started at zero (the hull upright at
        rest). 0: left out (d = 0).
    """

    w_roll_rate: float = 1.0
    w_pitch_rate: float = 1.0
    w_roll: float = 0.0
    w_pitch: float = 0.0
    rate_ref: float = math.radians(0.1)
    angle_ref: float = math.radians(1.0)
    disturbance_time_constant: float = 300.0

    def __post_init__(self) -> None:
        for name in ("w_roll_rate", "w_pitch_rate", "w_roll", "w_pitch", "disturbance_time_constant"):
            v = getattr(self, name)
            if isinstance(v, bool) or not (isinstance(v, (int, float)) and math.isfinite(v) and v >= 0):
                raise MPCError(f"MPCSettings.roll_pitch_damping.{name} = {v!r} must be a number >= 0")
            object.__setattr__(self, name, float(v))
        for name in ("rate_ref", "angle_ref"):
            v = getattr(self, name)
            if isinstance(v, bool) or not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
                raise MPCError(f"MPCSettings.roll_pitch_damping.{name} = {v!r} must be a positive number")
            object.__setattr__(self, name, float(v))

    @classmethod
    def from_option(cls, value: Any) -> RollPitchWeights | None:
        """From the option's value: false or None (off), true (the defaults), a table of the
        attributes, or an instance."""
        if value is False or value is None:
            return None
        if value is True:
            return cls()
        if isinstance(value, cls):
            return value
        if isinstance(value, Mapping):
            names = [f.name for f in dataclasses.fields(cls)]
            unknown = sorted(str(k) for k in value if k not in names)
            if unknown:
                raise MPCError(f"MPCSettings.roll_pitch_damping: unknown option(s) {unknown}; options are "
                               f"{', '.join(names)}")
            return cls(**dict(value))
        raise MPCError(f"MPCSettings.roll_pitch_damping = {value!r} must be true, false or a table of "
                       f"{', '.join(f.name for f in dataclasses.fields(cls))}")


@dataclass(frozen=True, kw_only=True)
class MPCSettings:
    """Settings of :class:`NonlinearMPC` and :class:`LinearMPC` (weights are dimensionless: every
    term is normalised by the reference values below).

    The defaults here are the formulation's neutral ones. The tuned defaults that ``tapm simulate``
    and study files use (dead band, thrust and rate weights, fault tolerance, the fast solver
    paths) are stated once, in the controller-kind registry: ``tapm_opt.design.build(system,
    "lmpc")`` gives that controller (``docs/controllers.md``).

    Attributes
    ----------
    horizon : int
        Prediction steps N.
    move_blocks : tuple of int or None
        Move blocking: the lengths, in prediction steps, of the blocks over which the thrust
        decision is held (they sum to ``horizon``), e.g. ``(1, 1, 2, 4, 8, 14)`` at N = 30; None
        (this class's default; the registry's is ``"auto"``): a move at every step. The states, the
        soft constraints and the cost are still predicted at every step; only the thrust is held, so the thrust polytope and its rate rows
        are written once per block (the change between two blocks happens in one step, so it keeps
        the per-step rate limit). Fewer moves make a long horizon cheaper: at N = 50 with 8 blocks
        the QP has 24 thrust variables instead of 150 and 8 instead of 50 sets of polytope rows.
    dt : float
        Prediction step [s]; also the default re-solve period.
    substeps : int
        RK4 steps per prediction step.
    mooring : {"characteristic", "catenary", "linear"}
        Mooring model in the prediction: ``"characteristic"`` — each line's horizontal tension
        linear in its anchor–fairlead distance about the pose of ``linearise_about`` (eq. 26–28,
        coefficients from the elastic catenary there, :func:`mooring_parameters`); ``"catenary"``
        and ``"linear"`` as ``models.mooring.MooringModel.force_function``.
    decision : {"tau", "thrusters"}
        Optimise the generalised thrust (allocation after) or the thruster forces directly.
    solver : {"sqp", "rti", "ipopt", "fatrop"}
        NLP solver of :class:`NonlinearMPC` (SQP: CasADi ``sqpmethod`` with the sparse
        interior-point ``piqp`` for its QP subproblems, retried with OSQP when it fails; RTI: the
        real-time iteration of Diehl, Bock & Schlöder (2005) — the same SQP stopped after one
        iteration from the shifted previous solution, so each step solves one QP linearised along
        the predicted trajectory and the iterations spread over the steps (``max_iter`` is not
        used); IPOPT; fatrop).
    w_thrust, w_rate : float
        Weights on (tau / tau_ref)^2 (or (f_i / f_max,i)^2) and on its change per step; tau_ref is
        ``ThrusterSet.max_tau()`` (``thrust_set="polytope"``) or the capacity box (``"box"``).
    w_position : float
        Weight on (distance outside the dead band / r_ref)^2.
    w_position_in : float
        Weight on (position error / r_ref)^2 everywhere (0: free inside the dead band).
    w_heading, w_velocity : float
        Weights on (heading error / psi_ref)^2 and (nu / nu_ref)^2.
    w_terminal : float
        Multiplier of the state terms at the end of the horizon.
    dead_band : float
        Radius of the dead band of the turret offset about the position setpoint [m] (0: none).
    dead_band_damaged : float or None
        With ``fault_tolerance``: the dead band's radius [m] once the estimate reports a broken
        line (None: ``dead_band`` throughout). The damaged mooring has lost its redundancy and
        restores less, so the thrusters take over more of the station keeping (survey §4.4: the
        fault is accommodated by modifying the control parameters, not the structure). Needs
        ``dead_band > 0`` (the radius is a parameter of the dead band's rows).
    dead_band_budget : bool
        With ``dead_band_damaged``: tighten only as far as the intact thrust budget allows
        (:func:`~tapm_opt.control.mpc.budgeted_dead_band`). The budget is the mean thrust along
        the mean environmental load (the part the radius moves) that would hold the intact vessel
        ``dead_band_damaged`` from the setpoint along that load; after the break the MPC holds the
        tightest radius in [``dead_band_damaged``, ``dead_band``] that the damaged mooring lets it
        hold within that budget (quasi-static, at the estimated load and heading low-passed over
        300 s). A lee or side break leaves the mooring restoring at least as much along the load,
        and the dead band shrinks to ``dead_band_damaged``; a weather-side break takes restoring
        away, the thrusters already carry the lost line's load, and the dead band stays nearer
        ``dead_band``. False: ``dead_band_damaged`` after any break.
    safe_radius : float or None
        Soft constraint radius of the turret offset about the field zero point [m] (None: from the
        scenario, or none).
    tension_utilisation : float or None
        Soft tension limit as a fraction of MBS (None: the scenario's ``limits.tension_utilisation``).
    soft_l1, soft_l2 : float
        Exact (L1) and quadratic penalties on the normalised soft-constraint violations.
    r_ref, psi_ref, nu_ref, r_rate_ref : float
        Normalisation: position [m], heading [rad], speed [m/s], yaw rate [rad/s].
    thrust_set : {"polytope", "box"}
        ``decision="tau"``: the thrust the MPC may plan. ``"polytope"``: inside
        ``ThrusterSet.attainable_polytope(polytope_directions)``, what the thrusters can deliver
        together, and its change per step inside the same polytope scaled by the slowest
        thruster's rate-to-thrust ratio times dt (a rate limit on the thrust vector, so on its
        magnitude too); ``"box"``: ``ThrusterSet.capacity_box(capacity_fraction)`` and
        ``rate_box`` on each component (the one capacity model, ``models.system``).
    capacity_fraction : float
        ``thrust_set="box"``: the fraction of each single-DOF maximum of the box.
    polytope_directions : int
        ``thrust_set="polytope"``: support directions of the attainable polytope.
    linearise_about : {"state", "setpoint"}
        Where the mooring characteristics (``mooring="characteristic"``) are centred, and where
        :class:`LinearMPC` linearises the dynamics: the present state estimate (default: the
        model is exact where the vessel is), or the setpoint at rest with the present heading.
    hessian : {"gauss-newton", "exact"}
        SQP and RTI only: the Gauss–Newton Hessian of the least-squares cost (positive
        semi-definite by construction, regularised by ``1e-8``) or the exact Hessian of the
        Lagrangian.
    polygon_sides : int
        Sides of the polygons approximating circles (dead band, safe circle, thrust circles).
    max_iter : int
        Iteration limit of the NLP solver (SQP iterations or IPOPT iterations). The Gauss–Newton
        SQP usually needs 2–4; it converges only linearly where the dynamics' curvature matters,
        and needed up to 46 in the storms of ``studies/mpc_sweep.toml`` (30, the earlier limit,
        made two solves there fail).
    max_time : float
        Wall-clock limit of one IPOPT solve [s]; SQP is bounded by ``max_iter`` and its QP solver's
        own iteration limit.
    reliability : bool
        Reliability constraints (survey eq. 32; reliability seed §2.2) as soft constraints of the
        prediction: every line's tension at most the lower of ``tension_utilisation`` x MBS and
        ``T_b - k sigma - delta_s sigma_b`` (its index at least ``delta_s``), and, with a riser, both riser
        angles inside ``r - k sigma - delta_s sigma_r`` (as inscribed octagons). ``k sigma`` comes
        online from the controller's reliability monitor; the current's share of the riser angles
        from the measured angles (:class:`~tapm_opt.control.mpc.NonlinearMPC`).
    delta_s : float
        Reliability-index threshold of those constraints [-].
    fault_tolerance : bool
        When the estimate reports broken lines (``Estimate.broken_lines``), drop them from the
        prediction: their characteristics (``mooring="characteristic"``, the only kind whose lines
        are parameters) are zeroed, so the predicted mooring load and tensions are those of the
        lines left, with no new problem. Buoys reported lost (``Estimate.lost_points``) leave their
        lines' characteristics those of the line without the buoy
        (``MooringModel.with_points_lost``); the dead band treats them as damage too.
    load_time_constant : float
        Time constant [s] of a first-order low-pass filter through which the estimated
        environmental load (``Estimate.tau_env``, taken into {E}) enters the prediction, which
        holds it constant over the horizon; 0 (default): the estimate as it comes. Filtering moves
        the MPC along its offset-energy trade-off: measured behind the EKF, 200 s gave the main
        job 50.0 m / 5 s outside the safe circle / 18.13 MWh against 50.7 m / 21 s / 19.43 MWh,
        but in the sweep's collinear storm 5-19 % less energy for up to 7.4 m more offset and more
        time outside (docs/estimation.md).
    roll_pitch_damping : bool, table or RollPitchWeights
        roll-pitch damping in the prediction (survey §4.2.3, docs/controllers.md; a scenario with
        vessel.roll_pitch): true, or a table of w_roll_rate, w_pitch_rate (default 1 each), w_roll,
        w_pitch (default 0), rate_ref [rad/s] (default 0.1 deg/s), angle_ref [rad] (default 1 deg),
        disturbance_time_constant [s] (default 300; 0: the lines' and environment's moments left
        out); false (default): the 3-DOF prediction. The prediction then carries the hull's
        low-frequency roll and pitch under the planned thrust's moments and the cost charges their
        rates (:class:`RollPitchWeights`).
    """

    horizon: int = 20
    move_blocks: tuple[int, ...] | None = None
    dt: float = 5.0
    substeps: int = 1
    mooring: Literal["characteristic", "catenary", "linear"] = "characteristic"
    decision: Literal["tau", "thrusters"] = "tau"
    solver: Literal["sqp", "rti", "ipopt", "fatrop"] = "sqp"
    w_thrust: float = 1.0
    w_rate: float = 1.0
    w_position: float = 1.0
    w_position_in: float = 0.0
    w_heading: float = 1.0
    w_velocity: float = 1.0
    w_terminal: float = 5.0
    dead_band: float = 0.0
    dead_band_damaged: float | None = None
    dead_band_budget: bool = True
    safe_radius: float | None = None
    tension_utilisation: float | None = None
    soft_l1: float = 1e3
    soft_l2: float = 1e2
    r_ref: float = 10.0
    psi_ref: float = math.radians(10.0)
    nu_ref: float = 0.5
    r_rate_ref: float = math.radians(0.5)
    thrust_set: Literal["polytope", "box"] = "polytope"
    capacity_fraction: float = CAPACITY_FRACTION
    polytope_directions: int = ATTAINABLE_DIRECTIONS
    linearise_about: Literal["state", "setpoint"] = "state"
    hessian: Literal["gauss-newton", "exact"] = "gauss-newton"
    polygon_sides: int = 16
    max_iter: int = 100
    max_time: float = 10.0
    reliability: bool = False
    delta_s: float = 2.0
    fault_tolerance: bool = False
    load_time_constant: float = 0.0
    roll_pitch_damping: Any = False

    def __post_init__(self) -> None:
        object.__setattr__(self, "roll_pitch_damping", RollPitchWeights.from_option(self.roll_pitch_damping) or False)
        pos = ("dt", "r_ref", "psi_ref", "nu_ref", "r_rate_ref", "capacity_fraction", "max_time")
        nonneg = ("w_thrust", "w_rate", "w_position", "w_position_in", "w_heading", "w_velocity", "w_terminal",
                  "dead_band", "soft_l1", "soft_l2", "load_time_constant")
        for name in pos:
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
                raise MPCError(f"MPCSettings.{name} = {v!r} must be a positive number")
        for name in nonneg:
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v >= 0):
                raise MPCError(f"MPCSettings.{name} = {v!r} must be a number >= 0")
        for name in ("reliability", "fault_tolerance", "dead_band_budget"):
            if not isinstance(getattr(self, name), bool):
                raise MPCError(f"MPCSettings.{name} = {getattr(self, name)!r} must be true or false")
        if self.fault_tolerance and self.mooring != "characteristic":
            raise MPCError(f"MPCSettings.fault_tolerance needs mooring = 'characteristic' (the lines are parameters "
                           f"of the problem only then), got mooring = {self.mooring!r}")
        if not (isinstance(self.delta_s, (int, float)) and math.isfinite(self.delta_s)):
            raise MPCError(f"MPCSettings.delta_s = {self.delta_s!r} must be a finite number")
        for name, lo in (("horizon", 1), ("substeps", 1), ("polygon_sides", 3), ("max_iter", 1),
                         ("polytope_directions", 8)):
            v = getattr(self, name)
            if not (isinstance(v, int) and v >= lo):
                raise MPCError(f"MPCSettings.{name} = {v!r} must be a whole number >= {lo}")
        for name, allowed in (("mooring", ("characteristic", "catenary", "linear")), ("decision", ("tau", "thrusters")),
                              ("solver", ("sqp", "rti", "ipopt", "fatrop")), ("thrust_set", ("polytope", "box")),
                              ("linearise_about", ("state", "setpoint")), ("hessian", ("gauss-newton", "exact"))):
            if getattr(self, name) not in allowed:
                raise MPCError(f"MPCSettings.{name} = {getattr(self, name)!r} is not one of {', '.join(allowed)}")
        mb = self.move_blocks
        if mb is not None:
            if isinstance(mb, np.ndarray) and mb.ndim == 1:
                mb = mb.tolist()   # an array of whole numbers is a list of them
            if not (isinstance(mb, (list, tuple)) and mb
                    and all(isinstance(b, (int, float, np.integer, np.floating))
                            and not isinstance(b, (bool, np.bool_)) and math.isfinite(b)
                            and float(b).is_integer() and b >= 1 for b in mb)):
                raise MPCError(f"MPCSettings.move_blocks = {mb!r} must be a list of whole numbers >= 1 (block lengths "
                               "in prediction steps) or None")
            mb = tuple(int(b) for b in mb)   # 2.0 from a command line is 2
            if isinstance(self.horizon, int) and sum(mb) != self.horizon:
                raise MPCError(f"MPCSettings.move_blocks = {list(mb)} sums to {sum(mb)}, not to horizon = "
                               f"{self.horizon}")
            object.__setattr__(self, "move_blocks", mb)
        v = self.dead_band_damaged
        if v is not None:
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
                raise MPCError(f"MPCSettings.dead_band_damaged = {v!r} must be a positive number [m] or None")
            if self.dead_band <= 0:
                raise MPCError(f"MPCSettings.dead_band_damaged = {v!r} needs a dead band (dead_band > 0, got "
                               f"{self.dead_band!r})")
            if not self.fault_tolerance:
                raise MPCError(f"MPCSettings.dead_band_damaged = {v!r} needs fault_tolerance = true (it is the "
                               "dead band once a line break is known)")
        for name, what, hi in (("safe_radius", "a positive number", math.inf),
                               ("tension_utilisation", "a number in (0, 1]", 1.0)):
            v = getattr(self, name)
            if v is not None and not (isinstance(v, (int, float)) and math.isfinite(v) and 0 < v <= hi):
                raise MPCError(f"MPCSettings.{name} = {v!r} must be {what} or None")


@dataclass(frozen=True, kw_only=True)
class MPCStep(ControllerStep):
    """Diagnostics of one MPC update: a :class:`~tapm_opt.interfaces.ControllerStep` with the
    optimal cost, the largest normalised soft-constraint violation and the dead band's radius [m]
    (NaN: none)."""

    cost: float = math.nan
    max_soft_violation: float = 0.0
    dead_band: float = math.nan


# ------------------------------------------------------------------------------------------
# the problem
# ------------------------------------------------------------------------------------------



@dataclass
class _Problem:
    z: ca.SX | ca.MX
    p: ca.SX | ca.MX
    f: Any
    g: Any
    lbz: np.ndarray
    ubz: np.ndarray
    lbg: np.ndarray
    ubg: np.ndarray
    idx: dict
    scale: dict
    n_u: int
    B_thr: np.ndarray | None
    #: Least-squares residuals: ``f = sumsqr(r) + soft_l1 * (sum of the L1 slacks)``.
    r: Any = None
    #: Slices of the parameter vector (``x0``, ``u_prev``, ``eta_d``, ``b``, ``T_lim`` — each
    #: line's allowed tension [N] —, and when present ``moor`` — the line characteristics —,
    #: ``poly_A``, ``poly_b``, ``rate_dt``, ``riser`` — angle limits and the current's shares —,
    #: and for the linear problem ``x_op``, ``u_op``, ``b_op``; with roll-pitch damping ``x0`` and
    #: ``x_op`` have 10 states and ``rp_dist`` is the disturbance moment (K, M) [N m]).
    p_idx: dict | None = None
    #: Rows of the thrust polytope (padded: a row of zeros with bound 1 is always met).
    n_poly: int = 0
    linear: bool = False
    #: The thrust move that acts at each prediction step (N,): ``arange(N)`` without move blocking.
    block_of: np.ndarray | None = None
    #: States per prediction step: 6 (eta, nu), or 10 with roll-pitch damping (eta, nu, phi, theta,
    #: p, q; ``MPCSettings.roll_pitch_damping``).
    nx: int = 6

    @property
    def n_moves(self) -> int:
        """Thrust moves in the decision (the number of move blocks; N without blocking)."""
        return int(self.block_of[-1]) + 1


def _polygon(n: int) -> np.ndarray:
    """Outward unit normals of a regular n-gon circumscribing the unit circle."""
    a = 2 * np.pi * np.arange(n) / n
    return np.stack([np.cos(a), np.sin(a)], axis=1)


def _turret(eta: Any, p_cot_B: np.ndarray, psi_op: Any) -> Any:
    """Turret offset of the CasADi pose ``eta`` (``geometry.turret_offset``) expanded to first
    order in the heading about ``psi_op`` (a number or a CasADi parameter):
    ``p + R2(psi_op) c - c + R2'(psi_op) c (psi - psi_op)``, linear in eta. The error is
    ``|c| (1 - cos(psi - psi_op))`` (1.4 m for the fpso's 91 m at 10 deg); the expansion keeps the
    position terms convex, so the SQP's Hessian stays as definite as without the turret."""
    c = ca.DM(np.asarray(p_cot_B, float))
    Rp = ca.mtimes(R2(psi_op), c)
    dRp = ca.vertcat(-Rp[1], Rp[0])
    return eta[0:2] + Rp - c + dRp * (eta[2] - psi_op)


def mooring_parameters(model: MooringModel, eta_c: np.ndarray) -> np.ndarray:
    """Line characteristics of ``mooring="characteristic"`` centred at the pose ``eta_c``
    (``MooringModel.characteristics``, survey eq. 26–28): H0, dH/dXF, XF0, T0, dT/dXF of every line,
    concatenated row by row, shape (5 n,). Read from the model's tabulated catenary
    (``model.load_evaluator().characteristics``: the tensions within 1e-9, the slopes within 3e-7
    of the largest exact slope on the built-in scenarios; exact beyond the tables), about 60 us
    against 0.8 ms for the catenary solve of fpso's 12 lines."""
    return model.load_evaluator().characteristics(eta_c).ravel()


def polytope_parameters(thrusters: Any, settings: MPCSettings, u_ref: np.ndarray,
                        n_rows: int) -> tuple[np.ndarray, np.ndarray | None]:
    """Parameters of the thrust polytope in the scaled thrust ``u = tau / u_ref``: the rows
    ``A_s = A diag(u_ref)`` (column-major, ``n_rows`` x 3, padded with zero rows), their bounds ``b``
    (padding: 1) and the rate factor ``r dt`` (``ThrusterSet.rate_ratio()`` times dt), from
    ``thrusters.attainable_polytope`` (failed thrusters excluded).

    When the thrusters leave a DOF without any thrust, no polytope has an interior: the capacity
    box of what remains (zero on that DOF) stands in, as the rows ``+-e_j``. Returns
    ``(parameters, box)`` with ``box`` the scaled half-widths of that stand-in, else None."""
    As = np.zeros((n_rows, 3))
    bs = np.ones(n_rows)
    try:
        A, b = thrusters.attainable_polytope(settings.polytope_directions)
        A, box = A * u_ref[None, :], None
    except ModelError:
        box = np.asarray(thrusters.capacity_box(settings.capacity_fraction)) / u_ref
        A, b = np.vstack([np.eye(3), -np.eye(3)]), np.concatenate([box, box])
    if len(b) > n_rows:
        raise MPCError(f"the attainable polytope has {len(b)} facets, more than the {n_rows} rows reserved")
    As[:len(b)] = A
    bs[:len(b)] = b
    return np.concatenate([As.ravel(order="F"), bs, [thrusters.rate_ratio() * settings.dt]]), box


def build_problem(system: Any, settings: MPCSettings, *, linear: bool = False,
                  model: MooringModel | None = None, riser: Any = None) -> _Problem:
    """Write the MPC problem (module docstring of ``control.mpc``) as CasADi expressions.

    Parameters
    ----------
    system : System or Scenario
        The vessel, line system and thrusters (a scenario is built into its :class:`System`).
    linear : bool
        False: nonlinear prediction. True: the dynamics are linearised about the operating point
        ``(x_op, u_op, b_op)`` and the tensions about ``x_op``'s pose — both parameters, so one
        problem serves every operating point — and the heading error is used unwrapped: the
        problem is a QP whose matrices are functions of the parameters.
    model : MooringModel, optional
        The line model of the prediction (default: the system's).
    riser : RiserModel, optional
        With ``settings.reliability``: the riser whose angles are kept inside their limits.

    Returns the decision vector ``z`` (scaled), parameters ``p`` in SI (slices in ``p_idx``), cost
    ``f`` with its least-squares residuals ``r``, constraints ``g`` with bounds, and index maps.
    """
    s = settings
    N = s.horizon
    system = as_system(system)
    if not system.thrusters.n:
        raise MPCError(f"scenario {system.name!r} has no thrusters: there is nothing to control")
    vp = system.vessel
    moor = model or system.lines
    n_lines = moor.n_lines
    p_cot = np.asarray(system.p_cot_B, float)
    kind = s.mooring
    rhs = moored_function(vp, None, form="design")
    # thrust variables
    B_thr, u_lo, u_hi, kinds, owner = system.thrusters.extended()
    fmax = np.maximum(np.abs(u_lo), np.abs(u_hi))
    fmax = np.where(fmax > 0, fmax, system.thrusters.f_max[owner])  # a failed thruster keeps its scale
    rate = system.thrusters.rate[owner]
    n_poly = 0
    if s.decision == "tau":
        n_u = 3
        Bu = np.eye(3)
        if s.thrust_set == "box":
            cap = np.asarray(system.thrusters.capacity_box(s.capacity_fraction), float)
            u_ref = cap
            rate_s = np.asarray(system.thrusters.rate_box(s.capacity_fraction), float) / cap
        else:
            u_ref = np.asarray(system.thrusters.max_tau(), float)  # each DOF alone: scale and outer box
            rate_s = None
            n_poly = 2 * s.polytope_directions  # at most 2 n - 4 facets of a hull of n points
        u_lo_s, u_hi_s = -np.ones(3), np.ones(3)
    else:
        n_u = B_thr.shape[1]
        u_ref = fmax
        u_lo_s, u_hi_s = u_lo / fmax, u_hi / fmax
        rate_s = rate / fmax
        Bu = B_thr
    x_ref = np.array([s.r_ref, s.r_ref, s.psi_ref, s.nu_ref, s.nu_ref, s.r_rate_ref])
    # roll-pitch damping: the state (eta, nu) augmented with (phi, theta, p, q) (eq. MRP1)
    rpw = s.roll_pitch_damping or None
    rpv = vp.roll_pitch
    if rpw is not None and rpv is None:
        raise MPCError(f"MPCSettings.roll_pitch_damping: scenario {system.name!r} has no low-frequency roll and "
                       "pitch (give its vessel a [vessel.roll_pitch] table)")
    nx = 6
    if rpw is not None:
        nx = 10
        x_ref = np.concatenate([x_ref, [rpw.angle_ref, rpw.angle_ref, rpw.rate_ref, rpw.rate_ref]])
    util = system.limits.tension_utilisation if s.tension_utilisation is None else s.tension_utilisation
    T_allow = util * np.asarray(moor.MBS, float)
    R_safe = system.limits.safe_radius if s.safe_radius is None else s.safe_radius
    polyg = _polygon(s.polygon_sides)

    Sym = ca.MX if kind == "catenary" else ca.SX
    use_riser = bool(s.reliability and riser is not None)
    sizes = [("x0", nx), ("u_prev", n_u), ("eta_d", 3), ("b", 3),
             ("moor", 5 * n_lines if kind == "characteristic" else 0),
             ("poly_A", 3 * n_poly), ("poly_b", n_poly), ("rate_dt", 1 if n_poly else 0),
             ("T_lim", n_lines), ("riser", 6 if use_riser else 0), ("dead_band", 1 if s.dead_band > 0 else 0)]
    if rpw is not None:
        sizes += [("rp_dist", 2)]   # the disturbance moment (K, M) about the CG [N m] (eq. MRP2)
    if linear:
        sizes += [("x_op", nx), ("u_op", n_u), ("b_op", 3)]
    p_idx, at = _layout(sizes)
    p = Sym.sym("p", at)
    x0, u_prev, eta_d, b_E = (p[p_idx[k]] for k in ("x0", "u_prev", "eta_d", "b"))

    # mooring restoring load and fairlead tensions of a pose, as expressions of the symbols
    def mooring_terms(eta_e: Any, mp: Any) -> tuple[Any, Any]:
        if kind == "characteristic":
            return moor.characteristic_load(eta_e, [mp[i * n_lines:(i + 1) * n_lines] for i in range(5)])
        if kind == "linear":
            tau = moor.force_function("linear").expand()(eta_e)
            return tau, moor.tension_function("characteristic").expand()(eta_e)
        return moor.force_function("catenary")(eta_e), moor.tension_function("catenary")(eta_e)

    # discrete dynamics (RK4) in SI, with thrust tau = Bu u
    SymF = ca.MX if kind == "catenary" else ca.SX
    xs, us, bs = SymF.sym("x", nx), SymF.sym("u", n_u), SymF.sym("b", 3)
    ms = SymF.sym("m", 5 * n_lines if kind == "characteristic" else 0)
    ds = [SymF.sym("d", 2)] if rpw is not None else []   # the roll-pitch disturbance moment
    h = s.dt / s.substeps
    xk = xs
    tau_u = ca.mtimes(ca.DM(Bu), us)
    if rpw is not None:   # the planned thrust's roll and pitch moments (eq. RP4) plus the disturbance
        moment_rp = roll_pitch_moments(rpv, tau_u, ca.DM.zeros(3)) + ds[0]
    for _ in range(s.substeps):
        def fx(xx):
            if rpw is not None:
                tau_env = ca.mtimes(rot_z(xx[2]).T, bs) + mooring_terms(xx[0:3], ms)[0]
                return ca.vertcat(rhs(xx[0:6], tau_u, tau_env, ca.DM.zeros(2)),
                                  roll_pitch_rhs(xx[6:10], moment_rp, rpv))
            tau_env = ca.mtimes(rot_z(xx[2]).T, bs) + mooring_terms(xx[0:3], ms)[0]
            return rhs(xx, tau_u, tau_env, ca.DM.zeros(2))
        k1 = fx(xk)
        k2 = fx(xk + h / 2 * k1)
        k3 = fx(xk + h / 2 * k2)
        k4 = fx(xk + h * k3)
        xk = xk + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    es = SymF.sym("e", 3)
    F = ca.Function("F", [xs, us, bs, ms, *ds], [xk])
    Tfun = ca.Function("T", [es, ms], [mooring_terms(es, ms)[1]])
    mp = p[p_idx["moor"]]
    dist_p = [p[p_idx["rp_dist"]]] if rpw is not None else []   # (the disturbance enters exactly: affine)
    if linear:
        x_op, u_op, b_op = (p[p_idx[k]] for k in ("x_op", "u_op", "b_op"))
        parts = ca.Function("F_parts", [xs, us, bs, ms, *ds], [xk, ca.jacobian(xk, xs), ca.jacobian(xk, us),
                                                               ca.jacobian(xk, bs)])
        F0, A, Bm, G = parts(x_op, u_op, b_op, mp, *dist_p)
        T0, JT = ca.Function("T_parts", [es, ms], [Tfun(es, ms), ca.jacobian(Tfun(es, ms), es)])(x_op[0:3], mp)

        def step(xx, uu, bb):
            return F0 + ca.mtimes(A, xx - x_op) + ca.mtimes(Bm, uu - u_op) + ca.mtimes(G, bb - b_op)

        def tension(ee):
            return T0 + ca.mtimes(JT, ee - x_op[0:3])
        psi_lin = x_op[2]
    else:
        def step(xx, uu, bb):
            return F(xx, uu, bb, mp, *dist_p)

        def tension(ee):
            return Tfun(ee, mp)
        psi_lin = x0[2]  # the turret offset is expanded about the present heading
    if n_poly:
        PA = ca.reshape(p[p_idx["poly_A"]], n_poly, 3)
        Pb = p[p_idx["poly_b"]]
        rdt = p[p_idx["rate_dt"]]

    # decision variables (scaled): X (6 x N+1), U (n_u x M, one move per block: M = N without
    # move blocking), slacks: dead band, safe, tension, riser (N each)
    block_of = block_index(s.move_blocks, N)
    M = int(block_of[-1]) + 1
    nX, nU = nx * (N + 1), n_u * M
    idx, n_z = _layout([("X", nX), ("U", nU), ("S_db", N), ("S_safe", N), ("S_T", N), ("S_R", N)])
    z = Sym.sym("z", n_z)
    X = ca.reshape(z[idx["X"]], nx, N + 1)
    U = ca.reshape(z[idx["U"]], n_u, M)
    S_db, S_safe, S_T, S_R = (z[idx[k]] for k in ("S_db", "S_safe", "S_T", "S_R"))
    Dx, Du = ca.DM(x_ref), ca.DM(u_ref)
    T_lim = p[p_idx["T_lim"]]
    if use_riser:
        rp = p[p_idx["riser"]]          # angle limits (top, bottom) [rad], current shares (2 + 2) [rad]
        c_t, c_b = float(riser.coefficients["c_t"]), float(riser.coefficients["c_b"])
        h_B = np.asarray(riser.hangoff_B, float)
        wh = ca.DM(np.asarray(riser.wellhead, float))
        octa = _polygon(8)

    g, lbg, ubg = [], [], []
    res = []  # least-squares residuals
    f_lin = 0

    def sq(weight: float, v: Any) -> None:
        if weight > 0:
            res.append(math.sqrt(weight) * v)

    g.append(X[:, 0] - x0 / Dx)
    lbg += [0.0] * nx
    ubg += [0.0] * nx
    if rpw is not None:   # the static heel and trim of the disturbance moment alone (eq. MRP3)
        rp_eq = ca.vertcat(dist_p[0][0] / rpv.C[0], dist_p[0][1] / rpv.C[1])
    u_last = u_prev / Du
    for k in range(N):
        j = int(block_of[k])
        uk = U[:, j]
        xk_si = X[:, k] * Dx
        xn = step(xk_si, uk * Du, b_E)
        g.append(X[:, k + 1] - xn / Dx)
        lbg += [0.0] * nx
        ubg += [0.0] * nx
        new_move = k == 0 or block_of[k - 1] != j   # the thrust rows only where a move starts
        if new_move and n_poly:
            # the attainable thrust, and its change within the same polytope scaled by r dt
            g.append(ca.mtimes(PA, uk) - Pb)
            lbg += [-ca.inf] * n_poly
            ubg += [0.0] * n_poly
            g.append(ca.mtimes(PA, uk - u_last) - rdt * Pb)
            lbg += [-ca.inf] * n_poly
            ubg += [0.0] * n_poly
        elif new_move:
            # thrust rate (hard)
            g.append(uk - u_last)
            lbg += list(-rate_s * s.dt)
            ubg += list(rate_s * s.dt)
        # thrust circles of azimuths and the rate of their force vectors (thruster decision):
        # |f| <= f_max and |f_k - f_k-1| <= rate dt, as inscribed polygons (so the magnitude too
        # changes by at most rate dt)
        if s.decision == "thrusters" and new_move:
            col = 0
            while col < n_u:
                if kinds[col] == "az":
                    uv = uk[col:col + 2]
                    duv = uv - u_last[col:col + 2]
                    for nrm in polyg:
                        g.append(nrm[0] * uv[0] + nrm[1] * uv[1])
                        lbg.append(-ca.inf)
                        ubg.append(math.cos(math.pi / s.polygon_sides))  # inscribed polygon
                        g.append(nrm[0] * duv[0] + nrm[1] * duv[1])
                        lbg.append(-ca.inf)
                        ubg.append(rate_s[col] * s.dt * math.cos(math.pi / s.polygon_sides))
                    col += 2
                else:
                    col += 1
        sq(s.w_thrust, uk)
        if new_move:
            sq(s.w_rate, uk - u_last)
        u_last = uk
        # state terms at k+1
        xe = X[:, k + 1] * Dx
        w_state = s.w_terminal if k == N - 1 else 1.0
        p_t = _turret(xe[0:3], p_cot, psi_lin)  # turret offset: the point safety refers to
        dp = p_t - eta_d[0:2]
        if s.dead_band > 0:
            for nrm in polyg:
                g.append((nrm[0] * dp[0] + nrm[1] * dp[1] - p[p_idx["dead_band"]]) / s.r_ref - S_db[k])
                lbg.append(-ca.inf)
                ubg.append(0.0)
            sq(w_state * s.w_position, S_db[k])
        else:
            # no dead band: the distance itself, squared (the polygon's slack would put 16
            # degenerate faces through the setpoint, on which the active-set QP solver cycles)
            sq(w_state * s.w_position, dp / s.r_ref)
        sq(w_state * s.w_position_in, dp / s.r_ref)
        dpsi = xe[2] - eta_d[2]
        # 2 (1 - cos dpsi) = (2 sin(dpsi / 2))^2: the periodic heading error as a square
        sq(w_state * s.w_heading, (dpsi if linear else 2.0 * ca.sin(dpsi / 2.0)) / s.psi_ref)
        sq(w_state * s.w_velocity, ca.vertcat(xe[3:5] / s.nu_ref, xe[5] / s.r_rate_ref))
        if rpw is not None:   # roll-pitch damping: the predicted rates (and angles about the static ones)
            sq(w_state * rpw.w_roll_rate, xe[8] / rpw.rate_ref)
            sq(w_state * rpw.w_pitch_rate, xe[9] / rpw.rate_ref)
            sq(w_state * rpw.w_roll, (xe[6] - rp_eq[0]) / rpw.angle_ref)
            sq(w_state * rpw.w_pitch, (xe[7] - rp_eq[1]) / rpw.angle_ref)
        # soft: safe circle of the turret offset about the field zero point, line tensions
        if R_safe is not None:
            for nrm in polyg:
                g.append((nrm[0] * p_t[0] + nrm[1] * p_t[1]) / R_safe - S_safe[k])
                lbg.append(-ca.inf)
                ubg.append(1.0)
        T = tension(xe[0:3])
        g.append(T / T_lim - S_T[k])
        lbg += [-ca.inf] * n_lines
        ubg += [1.0] * n_lines
        if use_riser:
            # riser angles, affine in the hang-off position (models.riser): theta = c (p_h - wellhead)
            # + the current's share; inside inscribed octagons of the limits (linear rows)
            p_h = _turret(xe[0:3], h_B, psi_lin) + ca.DM(h_B)
            for j, (c_e, sh) in enumerate(((c_t, rp[2:4]), (c_b, rp[4:6]))):
                th = c_e * (p_h - wh) + sh
                for nrm in octa:
                    g.append((nrm[0] * th[0] + nrm[1] * th[1]) / rp[j] - S_R[k])
                    lbg.append(-ca.inf)
                    ubg.append(math.cos(math.pi / 8))
        f_lin += s.soft_l1 * (S_safe[k] + S_T[k] + S_R[k])
        sq(s.soft_l2, ca.vertcat(S_safe[k], S_T[k], S_R[k]))
    g = ca.vertcat(*g)
    r = ca.vertcat(*res)
    cost = ca.sumsqr(r) + f_lin
    lbz = np.concatenate([np.full(nX, -np.inf), np.tile(u_lo_s, M), np.zeros(4 * N)])
    ubz = np.concatenate([np.full(nX, np.inf), np.tile(u_hi_s, M), np.full(4 * N, np.inf)])
    # slacks of constraints that are not there are held at zero
    for block, absent in (("S_db", s.dead_band <= 0), ("S_safe", R_safe is None), ("S_R", not use_riser)):
        if absent:
            ubz[idx[block]] = 0.0
    scale = {"x": x_ref, "u": u_ref, "T_allow": T_allow, "R_safe": R_safe, "p_cot_B": p_cot}
    return _Problem(z=z, p=p, f=cost, g=g, lbz=lbz, ubz=ubz, lbg=np.array(lbg, float), ubg=np.array(ubg, float),
                    idx=idx, scale=scale, n_u=n_u, B_thr=Bu if s.decision == "thrusters" else None, r=r,
                    p_idx=p_idx, n_poly=n_poly, linear=linear, block_of=block_of, nx=nx)


def _layout(blocks: list[tuple[str, int]]) -> tuple[dict[str, slice], int]:
    """Named consecutive blocks of a vector (the decision vector ``z``, the parameters ``p``):
    ``({name: slice}, total length)``."""
    out, at = {}, 0
    for name, n in blocks:
        out[name] = slice(at, at + int(n))
        at += int(n)
    return out, at


def block_index(move_blocks: tuple[int, ...] | None, horizon: int) -> np.ndarray:
    """The move acting at each of the ``horizon`` prediction steps (``MPCSettings.move_blocks``):
    ``arange(horizon)`` without blocking, else block j repeated over its length."""
    if move_blocks is None:
        return np.arange(horizon)
    return np.repeat(np.arange(len(move_blocks)), move_blocks)
