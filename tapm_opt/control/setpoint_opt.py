"""Optimal setpoints: where the vessel should sit so that its lines and its riser are safest, or
its thrusters idlest (survey §4.3.1–4.3.2, eq. 32–37; [R] = seed reliability-setpoint-riser-mooring
§2.2).

Every method optimises the turret offset ``p`` (x, y) [m] (the centre of turret relative to its
field-zero-point position, the position every setpoint refers to) at the present heading, on the
design models with exact derivatives:

* line tensions ``T_i(p)`` from the symbolic elastic catenary (:meth:`MooringModel.tension_function`)
  and the mooring load ``tau_moor(p)`` (:meth:`MooringModel.force_function`);
* riser top and bottom angles ``theta_t(p)``, ``theta_b(p)`` (rad, magnitudes of the angle
  vectors) from the quasi-static tensioned-beam riser (:class:`~tapm_opt.models.riser.RiserModel`)
  under the sea state's current;
* the thrust the setpoint needs: ``tau_thr = -(tau_env + tau_moor(p))`` in {B}, with ``tau_env``
  the estimated mean environmental load (the heading is held, so the load in {B} is unchanged);
  ``F_T^2 = || tau_thr / tau_max ||^2``, each DOF scaled by the thrusters' capacity on it
  (:meth:`ThrusterSet.max_tau`), so that surge, sway and yaw count alike and the figure is 1 at full
  capacity on one DOF.

Reliability indices (survey eq. 32; [R] §2.2, ``delta = (r_t - r_ex) / sigma_t``,
``r_ex = r_m + k sigma_r``):

* line ``i``: ``delta_i(p) = (T_b,i - k_i sigma_i - T_i(p)) / sigma_b,i``, ``T_b`` the mean breaking
  strength (MBS), ``sigma_b`` its standard deviation (``MBS_std``; lines without one have no index);
* riser end ``e`` (top, bottom): ``delta_e(p) = (r_e - k_e sigma_e - theta_e(p)) / sigma_r,e`` with
  ``r_e`` the mean critical angle and ``sigma_r,e`` its standard deviation (scenario ``[riser]``);

with ``k sigma`` (the wave-frequency extreme allowance: Gumbel factor times the standard deviation of
the wave-frequency response) estimated online from the measured tensions and riser angles by the
estimator's reliability monitor (:class:`tapm_opt.estimation.reliability.ReliabilityMonitor`,
handed on as ``Estimate.reliability``).

Costs (``method``):

``"quadratic"`` (survey eq. 34)
    ``L = K_T F_T^2 + K_F (|p| / R_ref)^2``, ``R_ref`` the safe radius.
``"reliability"`` (survey eq. 36)
    ``L = K_T F_T^2 + K_P sum_j Phi(-delta_j)``, the sum over every line's and riser end's index
    (``Phi(-delta)`` is the failure probability of each; their sum bounds the system's).
``"unified"`` ([R] §2.2)
    As printed (``unified_form="printed"``):
    ``L = w_t (delta_s - delta_t)^2 + w_b (delta_s - delta_b)^2 + sum_i w_i (delta_s - delta_i)^2``,
    every index pulled to the threshold ``delta_s`` from either side, with the riser weighted above
    the lines and the bottom angle above the top ([R]: "higher weight added to the riser angles due
    to their criticality"). With every index far above ``delta_s`` that cost drives the vessel to
    where the components are worst, so the default (``"one_sided"``) lets an index pull only below
    ``delta_s + margin``, ``sum w max(0, delta_s + margin - delta)^2``, plus ``anchor (|p - p_o| /
    R_ref)^2`` holding the nominal setpoint ``p_o`` otherwise (the survey's "only activated when
    needed", §4.3.2). The printed cost is solved numerically, or by the closed form of [R]
    (:func:`unified_closed_form`; ``solver="closed_form"``): every index linearised
    about the working point, ``delta_s - delta_j ~ a_j + g_j . dp``, the cost is a 2-D linear least
    squares whose minimiser ``dp = -(sum w g g^T)^-1 sum w a g`` is [R]'s (Delta r_v, beta_op) in
    polar form (:func:`unified_polar`, with the printed coefficients' typos corrected; see
    ``docs/controllers.md``).

Every method keeps the optimum where every index is at least ``delta_s`` (soft constraints with a
stiff quadratic penalty, so a problem with no such point still has an answer: the least violating
one) and inside ``max_offset`` (default the alert radius). The layer re-solves every ``period``
seconds and when the set of known broken lines or lost buoys changes (``Estimate.broken_lines``,
``Estimate.lost_points``; the model is rebuilt without them), and moves the setpoint toward the
optimum at no more than ``max_rate``.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Any, Iterable, Literal, Mapping

import casadi as ca
import numpy as np

from .._checks import finite
from ..errors import TapmError
from ..estimation.lowpass import first_order_step
from ..estimation.reliability import RISER_BOTTOM, RISER_TOP, line_signal
from ..geometry import body_from_turret, rot2_apply, turret_offset
from ..interfaces import Estimate, Setpoint

__all__ = ["SetpointOptError", "SetpointOptions", "SetpointProblem", "OptimalSetpoint", "WorkingPoint",
           "unified_closed_form", "unified_polar", "METHODS", "DELTA_S_DEFAULT"]

#: Methods of :class:`OptimalSetpoint`.
METHODS = ("quadratic", "reliability", "unified")
#: Lower threshold of the reliability index ([R] §3: delta_s = 2 for lines and riser).
DELTA_S_DEFAULT = 2.0
#: Weight of the squared violation of delta >= delta_s (per unit of delta) in every cost.
_PENALTY = 1e3
#: Weight of the squared excess of F_T^2 over thrust_limit^2 in every cost.
_THRUST_PENALTY = 1e6


class SetpointOptError(TapmError, ValueError):
    """Bad settings or inputs of an optimal setpoint."""


def _num(name: str, v: Any, *, lo: float | None = None, strict: bool = False) -> float:
    return finite(name, v, lo=lo, strict=strict, error=SetpointOptError, numbers_only=True)


@dataclass(frozen=True, kw_only=True)
class SetpointOptions:
    """Settings of :class:`OptimalSetpoint` (all optional; ``setpoint_options`` in study files).

    Attributes
    ----------
    K_T : float
        Weight of the squared normalised thrust (eq. 34, 36) [-].
    K_F : float
        Weight of the squared normalised offset ``(|p| / R_ref)^2`` (eq. 34) [-].
    K_P : float
        Weight of the summed failure probabilities ``sum Phi(-delta)`` (eq. 36) [-].
    w_lines, w_top, w_bottom : float
        Weights of the line, riser-top and riser-bottom terms of the unified cost ([R] §2.2) [-].
    delta_s : float
        Reliability-index threshold [-] (also the soft lower bound of every index).
    period : float
        Time between optimisations [s].
    max_rate : float
        Largest speed of the setpoint toward the optimum [m/s].
    max_offset : float or None
        Radius the optimum is kept inside [m] (None: the alert radius, else the safe radius, else
        10 % of the water depth).
    warmup : float
        Time before the first optimisation [s]: the monitor's wave-frequency statistics need a
        few hundred wave periods to settle; until then the setpoint stays where it started.
    solver : {"numeric", "closed_form"}
        ``"unified"`` only: the numeric optimum (IPOPT on the full models) or [R]'s closed form
        about the present working point (then backtracked along the step until every index is at
        least ``delta_s`` on the full models).
    unified_form : {"one_sided", "printed"}
        ``"printed"``: [R]'s cost as printed, every index pulled to ``delta_s`` from either side;
        ``"one_sided"`` (default): only indices below ``delta_s + margin`` pull, and a weak
        ``anchor`` holds the setpoint at the nominal one otherwise (module docstring).
    margin : float
        One-sided unified cost: the indices pull below ``delta_s + margin`` [-].
    anchor : float
        One-sided unified cost: weight of ``(|p - p_o| / R_ref)^2`` toward the nominal setpoint [-].
    thrust_limit : float
        Largest ``F_T`` (thrust needed over capacity, per DOF in the norm) a setpoint may need
        [-]; a stiff penalty beyond it. A setpoint the thrusters cannot hold is no setpoint.
    lf_factor : float
        The layer takes the low-frequency excursion about the setpoint as ``lf_factor`` times the
        RMS distance of the estimated (LF) turret offset from the setpoint in use, about its
        running mean (so the layer's own moves of the setpoint do not count; the ``r_lf`` of
        :class:`WorkingPoint`) [-]; 0: indices at the setpoint only. The default 3 is about the
        Gumbel factor of the few dozen LF maxima of a few hours (periods of a few hundred seconds).
    lf_window : float
        Time constant of that mean and RMS [s].
    """

    K_T: float = 1.0
    K_F: float = 1.0
    K_P: float = 100.0
    w_lines: float = 1.0
    w_top: float = 5.0
    w_bottom: float = 10.0
    delta_s: float = DELTA_S_DEFAULT
    period: float = 30.0
    max_rate: float = 0.05
    max_offset: float | None = None
    warmup: float = 300.0
    solver: Literal["numeric", "closed_form"] = "numeric"
    unified_form: Literal["one_sided", "printed"] = "one_sided"
    margin: float = 1.0
    anchor: float = 1.0
    thrust_limit: float = 0.8
    lf_factor: float = 3.0
    lf_window: float = 600.0

    def __post_init__(self) -> None:
        if self.unified_form not in ("one_sided", "printed"):
            raise SetpointOptError(f"setpoint_options.unified_form = {self.unified_form!r} is not one of "
                                   "'one_sided', 'printed'")
        _num("setpoint_options.thrust_limit", self.thrust_limit, lo=0.0, strict=True)
        for name in ("K_T", "K_F", "K_P", "w_lines", "w_top", "w_bottom", "warmup", "margin", "anchor", "lf_factor"):
            _num(f"setpoint_options.{name}", getattr(self, name), lo=0.0)
        _num("setpoint_options.delta_s", self.delta_s)
        for name in ("period", "max_rate", "lf_window"):
            _num(f"setpoint_options.{name}", getattr(self, name), lo=0.0, strict=True)
        if self.max_offset is not None:
            _num("setpoint_options.max_offset", self.max_offset, lo=0.0, strict=True)
        if self.solver not in ("numeric", "closed_form"):
            raise SetpointOptError(f"setpoint_options.solver = {self.solver!r} is not one of 'numeric', 'closed_form'")

    @classmethod
    def from_mapping(cls, options: Mapping[str, Any] | None, where: str = "setpoint_options") -> "SetpointOptions":
        """Options from a study file's table, unknown keys named."""
        options = dict(options or {})
        known = {f for f in cls.__dataclass_fields__}
        unknown = sorted(set(options) - known)
        if unknown:
            raise SetpointOptError(f"{where}: unknown option(s) {unknown}; known: {', '.join(sorted(known))}")
        try:
            return cls(**options)
        except SetpointOptError as exc:
            prefix = f"{where} " if where.startswith("--") else f"{where}."
            raise SetpointOptError(str(exc).replace("setpoint_options.", prefix, 1)) from None


@dataclass(frozen=True)
class WorkingPoint:
    """What the optimisation needs from the estimate and the monitor.

    Attributes
    ----------
    p : (2,) present turret offset [m].
    psi : heading [rad].
    tau_env : (3,) estimated mean environmental load in {B} [N, N, N m].
    ksigma_lines : (n,) extreme allowance k sigma of every modelled line's tension [N].
    ksigma_riser : (2,) extreme allowance of the riser top and bottom angles [rad].
    v_c : (2,) surface current in {E} the riser sees [m/s].
    p_o : (2,) nominal setpoint [m] (the ``anchor`` of the one-sided unified cost).
    r_lf : radius of the low-frequency excursion about the setpoint [m]: every index is taken as
        ``delta(p) - r_lf |grad_p delta(p_0)|`` (gradient at the present offset ``p``), its value
        where that excursion hurts it most, to first order; 0 for the indices at the setpoint itself.
    """

    p: np.ndarray
    psi: float
    tau_env: np.ndarray
    ksigma_lines: np.ndarray
    ksigma_riser: np.ndarray = field(default_factory=lambda: np.zeros(2))
    v_c: np.ndarray = field(default_factory=lambda: np.zeros(2))
    p_o: np.ndarray = field(default_factory=lambda: np.zeros(2))
    r_lf: float = 0.0

    def __post_init__(self) -> None:
        for name, n in (("p", 2), ("tau_env", 3), ("ksigma_riser", 2), ("v_c", 2), ("p_o", 2)):
            v = np.asarray(getattr(self, name), dtype=float)
            if v.shape != (n,) or not np.all(np.isfinite(v)):
                raise SetpointOptError(f"working point {name} = {np.asarray(getattr(self, name)).tolist()} must be "
                                       f"{n} finite numbers")
            object.__setattr__(self, name, v)
        ks = np.asarray(self.ksigma_lines, dtype=float)
        if ks.ndim != 1 or not np.all(np.isfinite(ks)):
            raise SetpointOptError(f"working point ksigma_lines = {ks.tolist()} must be finite numbers, one per line")
        object.__setattr__(self, "ksigma_lines", ks)
        for name in ("psi", "r_lf"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float, np.floating)) and math.isfinite(v)) or (name == "r_lf" and v < 0):
                raise SetpointOptError(f"working point {name} = {v!r} must be a finite number"
                                       + (" >= 0" if name == "r_lf" else ""))

    def at(self, p: Any) -> "WorkingPoint":
        """The same working point with the present offset moved to ``p``."""
        return WorkingPoint(p=np.asarray(p, float), psi=self.psi, tau_env=self.tau_env,
                            ksigma_lines=self.ksigma_lines, ksigma_riser=self.ksigma_riser, v_c=self.v_c, p_o=self.p_o,
                            r_lf=self.r_lf)


def _phi_neg(d):
    """Phi(-d), the standard normal probability below -d (CasADi or numpy)."""
    if isinstance(d, (ca.MX, ca.SX)):
        return 0.5 * (1.0 - ca.erf(d / math.sqrt(2.0)))
    from scipy.special import ndtr
    return ndtr(-np.asarray(d, float))


class SetpointProblem:
    """The setpoint optimisation of one line configuration (module docstring).

    Parameters
    ----------
    system : System
        Its ``lines`` are the modelled (intact or reduced) line system.
    riser : RiserModel or None
        The riser model (None: no riser terms).
    method : {"quadratic", "reliability", "unified"}
    options : SetpointOptions
    """

    def __init__(self, system: Any, riser: Any, method: str, options: SetpointOptions = SetpointOptions()):
        if method not in METHODS:
            raise SetpointOptError(f"setpoint = {method!r} is not one of {', '.join(METHODS)}")
        self.system, self.riser, self.method, self.o = system, riser, method, options
        lines = system.lines
        sc = system.scenario
        self.line_ids = tuple(lines.line_ids)
        self.T_b = np.asarray(lines.MBS, float)
        self.sigma_b = np.asarray(lines.MBS_std, float)
        self.has_index = self.sigma_b > 0
        self.p_cot_B = np.asarray(system.p_cot_B, float)
        tmax = np.asarray(system.thrusters.max_tau(), float)
        self.tau_max = np.where(tmax > 0, tmax, 1.0)
        lim = system.limits
        self.R_ref = float(lim.safe_radius or lim.alert_radius or 0.1 * sc.environment.water_depth)
        self.R_max = float(options.max_offset or lim.alert_radius or lim.safe_radius
                           or 0.1 * sc.environment.water_depth)
        if riser is not None:
            rs = sc.riser
            self.r_crit = np.array([rs.critical_top_angle, rs.critical_bottom_angle], float)
            self.sigma_r = np.array([rs.critical_top_angle_std, rs.critical_bottom_angle_std], float)
        self._build()

    # -- symbolic --------------------------------------------------------------------------
    def _build(self) -> None:
        n = len(self.line_ids)
        p = ca.MX.sym("p", 2)
        psi = ca.MX.sym("psi")
        tau_env = ca.MX.sym("tau_env", 3)
        ks = ca.MX.sym("ksigma_lines", n)
        kr = ca.MX.sym("ksigma_riser", 2)
        v_c = ca.MX.sym("v_c", 2)
        bx, by = body_from_turret(p, psi, self.p_cot_B)
        eta = ca.vertcat(bx, by, psi)
        lines = self.system.lines
        T = lines.tension_function("catenary")(eta)
        tau_m = lines.force_function("catenary")(eta)
        tau_thr = -(tau_env + tau_m)
        FT2 = ca.sumsqr(tau_thr / ca.DM(self.tau_max))
        idx = np.flatnonzero(self.has_index)
        d_lines = (ca.DM(self.T_b[idx]) - ks[idx.tolist()] - T[idx.tolist()]) / ca.DM(self.sigma_b[idx])
        deltas = [d_lines]
        w = [np.full(len(idx), self.o.w_lines)]
        theta = ca.DM.zeros(2)
        if self.riser is not None:
            hx, hy = rot2_apply(psi, float(self.riser.hangoff_B[0]), float(self.riser.hangoff_B[1]))
            th_t, th_b = self.riser.angle_function()(ca.vertcat(bx + hx, by + hy), v_c)
            eps2 = 1e-12
            theta = ca.vertcat(ca.sqrt(ca.sumsqr(th_t) + eps2), ca.sqrt(ca.sumsqr(th_b) + eps2))
            deltas.append((ca.DM(self.r_crit) - kr - theta) / ca.DM(self.sigma_r))
            w.append(np.array([self.o.w_top, self.o.w_bottom]))
        delta_qs = ca.vertcat(*deltas)
        # the vessel swings about its setpoint at low frequency: each index is taken where that
        # excursion (radius r_lf, measured on line by the layer) hurts it most, to first order with
        # the gradient at the working point: delta - r_lf |grad delta(p_0)| (the allowance a
        # parameter, so the Hessian needs no third derivative of the catenary)
        lf = ca.MX.sym("lf_allowance", delta_qs.numel())
        delta = delta_qs - lf
        wts = np.concatenate(w)
        o = self.o
        p_o = ca.MX.sym("p_o", 2)
        J_printed = ca.sum1(ca.DM(wts) * (o.delta_s - delta) ** 2)   # [R] §2.2 as printed
        if self.method == "quadratic":
            J = o.K_T * FT2 + o.K_F * ca.sumsqr(p) / self.R_ref ** 2
        elif self.method == "reliability":
            J = o.K_T * FT2 + o.K_P * ca.sum1(_phi_neg(delta))
        elif o.unified_form == "printed":
            J = J_printed
        else:
            J = (ca.sum1(ca.DM(wts) * ca.fmax(o.delta_s + o.margin - delta, 0.0) ** 2)
                 + o.anchor * ca.sumsqr(p - p_o) / self.R_ref ** 2)
        viol = ca.fmax(o.delta_s - delta, 0.0)
        over = ca.fmax(FT2 - o.thrust_limit ** 2, 0.0)
        J_total = J + _PENALTY * ca.sumsqr(viol) + _THRUST_PENALTY * over ** 2
        par = ca.vertcat(psi, tau_env, ks, kr, v_c, p_o, lf)
        self._n_delta = delta_qs.numel()
        self._grad_qs = ca.Function("setpoint_grad", [p, par], [ca.jacobian(delta_qs, p)])
        self.n_par = par.numel()
        self._eval = ca.Function("setpoint_eval", [p, par], [J, J_total, delta, T, theta, tau_thr, FT2, J_printed],
                                 ["p", "par"], ["J", "J_total", "delta", "T", "theta", "tau_thr", "FT2", "J_printed"])
        self._printed = (p, par, J_printed)
        self._jac = ca.Function("setpoint_lin", [p, par], [delta, ca.jacobian(delta, p)], ["p", "par"],
                                ["delta", "ddelta_dp"])
        self.delta_weights = wts
        self._many: tuple | None = None
        nlp = {"x": p, "p": par, "f": J_total, "g": ca.sumsqr(p)}
        self._solver = ca.nlpsol("setpoint_nlp", "ipopt", nlp, {
            "ipopt.print_level": 0, "print_time": False, "ipopt.sb": "yes", "ipopt.max_iter": 100,
            "ipopt.tol": 1e-8, "ipopt.acceptable_tol": 1e-6, "error_on_fail": False})

    def _par(self, wp: WorkingPoint) -> np.ndarray:
        ks = np.asarray(wp.ksigma_lines, float)
        if ks.shape != (len(self.line_ids),):
            raise SetpointOptError(f"ksigma_lines has shape {ks.shape}, expected ({len(self.line_ids)},) for lines "
                                   f"{list(self.line_ids)}")
        par = np.concatenate([[wp.psi], np.asarray(wp.tau_env, float), ks, np.asarray(wp.ksigma_riser, float),
                              np.asarray(wp.v_c, float), np.asarray(wp.p_o, float), np.zeros(self._n_delta)])
        if wp.r_lf > 0:
            G = np.asarray(self._grad_qs(np.asarray(wp.p, float), par)).reshape(-1, 2)
            par[-self._n_delta:] = float(wp.r_lf) * np.hypot(G[:, 0], G[:, 1])
        return par

    def evaluate(self, p: Any, wp: WorkingPoint) -> dict:
        """Cost, indices (lines with an index, then riser top and bottom), tensions [N], riser
        angles [rad], thrust needed in {B} and F_T^2 at turret offset ``p``."""
        out = self._eval(p=np.asarray(p, float), par=self._par(wp))
        return {k: (float(v) if k in ("J", "J_total", "FT2", "J_printed") else np.asarray(v).ravel())
                for k, v in out.items()}

    def evaluate_many(self, P: Any, wp: WorkingPoint) -> dict:
        """:meth:`evaluate` at many turret offsets ``P`` (2, N) at once: every output with the
        points along its last axis (``J``, ``FT2`` shape (N,); ``delta`` (m, N) ...)."""
        P = np.asarray(P, float)
        if P.ndim != 2 or P.shape[0] != 2:
            raise SetpointOptError(f"offsets have shape {P.shape}, expected (2, N)")
        N = P.shape[1]
        if self._many is None or self._many[0] != N:
            self._many = (N, self._eval.map(N, "serial"))
        par = np.repeat(self._par(wp)[:, None], N, axis=1)
        out = self._many[1](p=P, par=par)
        scalars = ("J", "J_total", "FT2", "J_printed")
        return {k: np.asarray(v).reshape(N) if k in scalars else np.asarray(v).reshape(-1, N) for k, v in out.items()}

    def solve(self, wp: WorkingPoint, starts: Iterable[Any] = (), *, warm: bool = False) -> tuple[np.ndarray, dict]:
        """Numeric optimum (IPOPT from each start — the present offset, the nominal setpoint, the
        origin and ``starts`` — the best converged one; ``warm``: from ``starts`` only, the layer's
        re-solve from its previous optimum). Returns ``(p_opt, info)``, info ``{"J", "success",
        "status", "starts"}``."""
        return self._multistart(self._solver, wp, starts, warm=warm)

    def _multistart(self, solver: Any, wp: WorkingPoint, starts: Iterable[Any], *,
                    warm: bool = False) -> tuple[np.ndarray, dict]:
        par = self._par(wp)
        cands = [] if warm else [np.asarray(wp.p, float), np.asarray(wp.p_o, float), np.zeros(2)]
        cands += [np.asarray(s, float) for s in starts]
        uniq: list[np.ndarray] = []
        for x0 in cands:
            if np.all(np.isfinite(x0)) and not any(np.allclose(x0, u, atol=1e-6) for u in uniq):
                uniq.append(x0)
        best, info = None, {"success": False, "status": "no start converged", "starts": len(uniq)}
        for x0 in uniq:
            r = float(np.hypot(*x0))
            if r > self.R_max:
                x0 = x0 * (0.99 * self.R_max / r)
            sol = solver(x0=x0, p=par, lbg=0.0, ubg=self.R_max ** 2)
            st = solver.stats()
            f = float(sol["f"])
            if not math.isfinite(f):
                continue
            ok = bool(st.get("success", False))
            # a converged start beats any that stopped early (iteration limit, ...); then the cost
            if best is None or (ok and not best[2]) or (ok == best[2] and f < best[1] - 1e-12):
                best = (np.asarray(sol["x"]).ravel(), f, ok)
                info = {"success": ok, "status": str(st.get("return_status", "")), "J": f, "starts": len(uniq)}
        if best is None:
            return np.asarray(wp.p, float), info
        return best[0], info

    def solve_printed(self, wp: WorkingPoint, starts: Iterable[Any] = ()) -> tuple[np.ndarray, dict]:
        """Numeric optimum of [R]'s unified cost as printed, with no constraint but ``max_offset``:
        the reference of the closed form (:meth:`closed_form_step`)."""
        if not hasattr(self, "_solver_printed"):
            p, par, J = self._printed
            self._solver_printed = ca.nlpsol("setpoint_printed", "ipopt", {"x": p, "p": par, "f": J, "g": ca.sumsqr(p)}, {
                "ipopt.print_level": 0, "print_time": False, "ipopt.sb": "yes", "ipopt.max_iter": 200,
                "ipopt.tol": 1e-10, "error_on_fail": False})
        return self._multistart(self._solver_printed, wp, starts)

    def closed_form_step(self, wp: WorkingPoint) -> np.ndarray:
        """One step of [R]'s closed form from the working point: the minimiser of the printed
        unified cost with every index linearised there (:func:`unified_closed_form`), unprojected."""
        d0, G = self.linearise(wp)
        return np.asarray(wp.p, float) + unified_closed_form(d0, G, self.delta_weights, self.o.delta_s)

    def closed_form_iterated(self, wp: WorkingPoint, *, tol: float = 1e-4, max_iter: int = 100) -> tuple[np.ndarray, int]:
        """The closed form re-linearised at each new point (a Gauss-Newton iteration on the
        printed cost, each step halved until the cost decreases) to its fixed point; returns the
        point and the number of steps."""
        p = np.asarray(wp.p, float)
        f = self.evaluate(p, wp)["J_printed"]
        for it in range(1, max_iter + 1):
            wpi = wp.at(p)
            step = self.closed_form_step(wpi) - p
            s = 1.0
            while s > 1e-6:
                q = p + s * step
                fq = self.evaluate(q, wp)["J_printed"]
                if fq <= f:
                    break
                s *= 0.5
            if s <= 1e-6:
                return p, it
            p, f = q, fq
            if float(np.hypot(*(s * step))) < tol:
                return p, it
        return p, max_iter

    def linearise(self, wp: WorkingPoint) -> tuple[np.ndarray, np.ndarray]:
        """Indices and their gradient d delta / d p (m, 2) [1/m] at the working point."""
        out = self._jac(p=np.asarray(wp.p, float), par=self._par(wp))
        return np.asarray(out["delta"]).ravel(), np.asarray(out["ddelta_dp"]).reshape(-1, 2)

    def closed_form(self, wp: WorkingPoint) -> tuple[np.ndarray, dict]:
        """[R]'s closed-form unified optimum about the working point (the printed cost, one
        linearised step), halved until, on the full models, every index is at least ``delta_s``
        and the thrust needed within ``thrust_limit`` — or, from a start that already breaks
        them, until the step improves both the lowest index and the thrust excess."""
        o = self.o
        ev0 = self.evaluate(wp.p, wp)
        dp = unified_closed_form(ev0["delta"], self.linearise(wp)[1], self.delta_weights, o.delta_s)
        p0 = np.asarray(wp.p, float)
        lim2 = o.thrust_limit ** 2
        ok0 = bool(np.all(ev0["delta"] >= o.delta_s - 1e-9) and ev0["FT2"] <= lim2)
        s = 1.0
        for _ in range(12):
            p = p0 + s * dp
            r = float(np.hypot(*p))
            if r > self.R_max:
                p = p * (self.R_max / r)
            ev = self.evaluate(p, wp)
            ok = bool(np.all(ev["delta"] >= o.delta_s - 1e-9) and ev["FT2"] <= lim2)
            better = (ev["delta"].min() >= ev0["delta"].min() - 1e-9
                      and max(ev["FT2"] - lim2, 0.0) <= max(ev0["FT2"] - lim2, 0.0) + 1e-12)
            if ok or (not ok0 and better):
                return p, {"success": ok, "status": "closed form" if ok else "closed form: bounds still broken",
                           "step": s}
            s *= 0.5
        return p0, {"success": ok0, "status": "closed form: no step keeps the bounds", "step": 0.0}


def unified_closed_form(delta0: Any, grad: Any, weights: Any, delta_s: float) -> np.ndarray:
    """Minimiser ``dp`` (2,) [m] of the linearised unified cost of [R] §2.2.

    ``delta_j(p0 + dp) ~ delta0_j + grad_j . dp``, so ``delta_s - delta_j = a_j + g_j . dp`` with
    ``a_j = delta_s - delta0_j`` and ``g_j = -grad_j``; ``L = sum w_j (a_j + g_j . dp)^2`` has its
    minimum at ``dp = -(sum w g g^T)^-1 sum w a g`` (a singular matrix, e.g. every gradient
    parallel, gives the least-norm solution).
    """
    d0 = np.asarray(delta0, float)
    G = -np.asarray(grad, float)
    w = np.asarray(weights, float)
    a = delta_s - d0
    H = (G * w[:, None]).T @ G
    b = (G * w[:, None]).T @ a
    return -np.linalg.lstsq(H, b, rcond=None)[0]


def unified_polar(c_lines: Any, beta_lines: Any, a_lines: Any, sigma_lines: Any, w_lines: Any,
                  riser: Iterable[tuple[float, float, float, float]] = ()) -> tuple[float, float]:
    """[R]'s closed form in its printed polar form, ``(Delta r_v, beta_op)``.

    Lines: ``T_i = T_oi + c_i Delta r sin(beta + beta_oi)`` (so the tension gradient is
    ``c_i (sin beta_oi, cos beta_oi)``), ``a_i = delta_s - (T_t,i - T_oi - k_i sigma_r,i) / sigma_t,i``
    (the index's shortfall at the working point), weight ``w_i``; riser ends ``(w, c, a, sigma_t)``
    with the angle ``theta = theta_o + c Delta r cos beta`` (the 2-D riser of [R]). With the
    coefficients

    * ``K11m = sum w c a cos(beta_o) / sigma``, ``K12m = sum w c a sin(beta_o) / sigma``,
    * ``K21m = sum w c^2 cos^2(beta_o) / sigma^2``, ``K22m = sum w c^2 sin(beta_o) cos(beta_o) / sigma^2``,
      ``K23m = sum w c^2 sin^2(beta_o) / sigma^2``,
    * ``K11r = sum_riser w c a / sigma``, ``K21r = sum_riser w c^2 / sigma^2``,

    ``tan beta_op = (K11m K23m - K12m K22m - K22m K11r + K11m K21r) / (K12m K21m - K11m K22m + K21m K11r)``
    and ``Delta r_v = -(K11m sin b + (K12m + K11r) cos b) / (K21m sin^2 b + 2 K22m sin b cos b +
    (K23m + K21r) cos^2 b)``. [R] prints ``beta_o1`` for every line in K22m and K23m (read
    ``beta_oi``), the line weight ``w_1 c_1 / sigma_t1`` in the first term of K11r (read the riser
    top's), leaves K21r's riser term out of the printed denominator's cos^2 coefficient only by
    grouping, and carries the riser terms with the opposite sign (an angle decreasing along +x) and
    no overall minus; the forms here are the minimiser of the same cost, equal to
    :func:`unified_closed_form` (tested).
    """
    c = np.asarray(c_lines, float)
    bo = np.asarray(beta_lines, float)
    a = np.asarray(a_lines, float)
    s = np.asarray(sigma_lines, float)
    w = np.asarray(w_lines, float)
    K11m = float(np.sum(w * c * a * np.cos(bo) / s))
    K12m = float(np.sum(w * c * a * np.sin(bo) / s))
    K21m = float(np.sum(w * c ** 2 * np.cos(bo) ** 2 / s ** 2))
    K22m = float(np.sum(w * c ** 2 * np.sin(bo) * np.cos(bo) / s ** 2))
    K23m = float(np.sum(w * c ** 2 * np.sin(bo) ** 2 / s ** 2))
    K11r = K21r = 0.0
    for wr, cr, ar, sr in riser:
        K11r += wr * cr * ar / sr
        K21r += wr * cr ** 2 / sr ** 2
    num = K11m * K23m - K12m * K22m - K22m * K11r + K11m * K21r
    den = K12m * K21m - K11m * K22m + K21m * K11r
    beta = math.atan2(num, den)
    sb, cb = math.sin(beta), math.cos(beta)
    q = K21m * sb ** 2 + 2 * K22m * sb * cb + (K23m + K21r) * cb ** 2
    dr = -(K11m * sb + (K12m + K11r) * cb) / q if q > 0 else 0.0
    return dr, beta


class OptimalSetpoint:
    """A :class:`~tapm_opt.interfaces.SetpointLayer` that chases the optimum of ``method``.

    The wave-frequency allowances ``k sigma`` come with the estimate (``Estimate.reliability``,
    the estimator's :class:`~tapm_opt.estimation.reliability.ReliabilityMonitor`: signals named
    ``"line <id>"``, ``"riser top"``, ``"riser bottom"``); without them the indices are the
    quasi-static ones (``k sigma = 0``).

    Parameters
    ----------
    system : System
        The intact system (lines known broken are dropped from its model, buoys known lost taken
        off their lines, when the estimate says so).
    method : {"quadratic", "reliability", "unified"}
    riser : RiserModel, optional
    options : SetpointOptions or mapping
    eta_d : (3,)
        Starting setpoint (turret offset x [m], y [m], heading [rad]); the heading is kept.
    v_c : (2,), optional
        Surface current in {E} the riser model sees [m/s] (default: the riser model's own).
    current_source : callable, optional
        ``() -> (2,) or None``: an estimated surface current in {E} [m/s] read at every
        optimisation in place of ``v_c`` (e.g. :meth:`CurrentEstimating.surface_current
        <tapm_opt.estimation.current_profile.CurrentEstimating.surface_current>`); ``v_c`` while
        it returns None.
    """

    def __init__(self, system: Any, method: str, *, riser: Any = None,
                 options: SetpointOptions | Mapping[str, Any] | None = None, eta_d: Any = (0.0, 0.0, 0.0),
                 v_c: Any = None, current_source: Any = None):
        if method not in METHODS:
            raise SetpointOptError(f"setpoint = {method!r} is not one of {', '.join(METHODS)}")
        self.options = options if isinstance(options, SetpointOptions) else SetpointOptions.from_mapping(options)
        if self.options.solver == "closed_form" and (method != "unified" or self.options.unified_form != "printed"):
            raise SetpointOptError(f"setpoint_options.solver = 'closed_form' is [R]'s closed form of the printed unified "
                                   f"cost: it needs setpoint = 'unified' with unified_form = 'printed' (got setpoint = "
                                   f"{method!r}, unified_form = {self.options.unified_form!r})")
        eta_d = np.asarray(eta_d, float)
        if eta_d.shape != (3,) or not np.all(np.isfinite(eta_d)):
            raise SetpointOptError(f"eta_d = {eta_d.tolist()} must be 3 finite numbers (x [m], y [m], psi [rad])")
        self.system0, self.method, self.riser = system, method, riser
        self.eta_d0 = eta_d
        self.line_ids = tuple(ln.id for ln in system.scenario.lines)
        self.v_c = np.zeros(2) if v_c is None and riser is None else np.asarray(
            riser.v_c if v_c is None else v_c, float)[:2]
        if current_source is not None and not callable(current_source):
            raise SetpointOptError(f"current_source = {current_source!r} must be a function () -> (2,) or None")
        self.current_source = current_source
        self._problems: dict[frozenset, SetpointProblem] = {}
        self.history: list[dict] = []
        self.reset()

    def reset(self) -> None:
        self.p = self.eta_d0[:2].copy()
        self.target = self.p.copy()
        self._t: float | None = None
        self._t_solve: float | None = None
        self._broken: frozenset = frozenset()
        self._lost: frozenset = frozenset()
        self._p_mean: np.ndarray | None = None   # running mean of the estimated turret offset from the setpoint [m]
        self._solved_for: Any = None  # broken lines (and lost buoys) of the latest optimisation
        self._ms_lf = 0.0      # running mean square of its distance from that mean [m^2]
        self.history = []

    def log(self) -> list[dict]:
        """Every optimisation: time [s], target turret offset [m], lines known broken, solver status."""
        return self.history

    def problem(self, broken: frozenset, lost_points: frozenset = frozenset()) -> SetpointProblem:
        """The optimisation for this set of broken lines and lost buoys ((line id, joint)), built
        once per set (keyed by the broken lines alone when no buoy is lost)."""
        lost = frozenset(p for p in lost_points if p[0] not in broken)
        key = (broken, lost) if lost else broken
        if key not in self._problems:
            sys_b = self.system0.with_broken(sorted(broken)) if broken else self.system0
            if lost:
                sys_b = sys_b.with_lost_points(sorted(lost))
            self._problems[key] = SetpointProblem(sys_b, self.riser, self.method, self.options)
        return self._problems[key]

    def working_point(self, estimate: Estimate, broken: frozenset) -> WorkingPoint:
        """The optimisation's inputs from the estimate and its reliability statistics."""
        ks = {} if estimate.reliability is None else estimate.reliability.allowance()
        v_c = None if self.current_source is None else self.current_source()
        return WorkingPoint(p=np.array(turret_offset(estimate.eta, self.system0.p_cot_B), float),
                            psi=float(estimate.eta[2]), tau_env=np.asarray(estimate.tau_env, float),
                            ksigma_lines=np.array([ks.get(line_signal(i), 0.0) for i in self.line_ids if i not in broken]),
                            ksigma_riser=np.array([ks.get(RISER_TOP, 0.0), ks.get(RISER_BOTTOM, 0.0)]),
                            v_c=self.v_c if v_c is None else v_c, p_o=self.eta_d0[:2], r_lf=self.r_lf)

    @property
    def r_lf(self) -> float:
        """The low-frequency excursion radius the optimisation allows for [m]."""
        return self.options.lf_factor * math.sqrt(self._ms_lf)

    def update(self, t: float, estimate: Estimate) -> Setpoint:
        eta = np.asarray(estimate.eta, float)
        if eta.shape != (3,) or not np.all(np.isfinite(eta)) or not math.isfinite(float(t)):
            raise SetpointOptError(f"estimate at t = {t!r} s: eta = {eta.tolist()} must be 3 finite numbers "
                                   "(x [m], y [m], psi [rad])")
        broken = frozenset(estimate.broken_lines)
        lost = frozenset(estimate.lost_points)
        dt = 0.0 if self._t is None else max(t - self._t, 0.0)
        self._t = float(t)
        # the LF excursion is that of the offset from the setpoint in use: the layer's own moves of
        # the setpoint (which the vessel follows) are not excursion
        e_now = np.array(turret_offset(estimate.eta, self.system0.p_cot_B), float) - self.p
        if self._p_mean is None:
            self._p_mean = e_now
        elif dt > 0:
            T = self.options.lf_window
            self._p_mean = first_order_step(self._p_mean, e_now, dt, T)
            self._ms_lf = first_order_step(self._ms_lf, float(np.sum((e_now - self._p_mean) ** 2)), dt, T)
        due = (self._t_solve is None and t >= self.options.warmup) or (
            self._t_solve is not None and t - self._t_solve >= self.options.period - 1e-9) or (
            (broken != self._broken or lost != self._lost) and t >= 0)
        if due:
            self._broken, self._lost = broken, lost
            prob = self.problem(broken, lost)
            wp = self.working_point(estimate, broken)
            w0 = time.perf_counter()
            if self.method == "unified" and self.options.solver == "closed_form":
                target, info = prob.closed_form(wp)
            else:
                warm = self._solved_for == (broken, lost)
                target, info = prob.solve(wp, starts=(self.target,) if warm else (self.target, self.p), warm=warm)
                if warm and not info["success"]:   # the re-solve stopped early: every start
                    target, info = prob.solve(wp, starts=(self.target, self.p))
                if not info["success"]:
                    # no start converged: move only to a point inside the offset limit that costs
                    # less than the present target (on this problem: after a break, the reduced one)
                    J_keep = prob.evaluate(self.target, wp)["J_total"]
                    J_new = float(info.get("J", math.nan))
                    ok = (math.isfinite(J_new) and float(np.hypot(*np.asarray(target, float))) <= prob.R_max + 1e-9
                          and (J_new < J_keep or not math.isfinite(J_keep)))
                    if not ok:
                        target, info = self.target, {**info, "J": J_keep, "kept": True}
            self.target = np.asarray(target, float)
            self._t_solve = float(t)
            self._solved_for = (broken, lost)
            extra = {"lost_points": [[lid, j] for lid, j in sorted(lost)]} if lost else {}
            self.history.append({"t": float(t), "target": self.target.tolist(), "broken": sorted(broken),
                                 **extra, "r_lf": self.r_lf, "solve_time": time.perf_counter() - w0, **info})
        step = self.target - self.p
        dist = float(np.hypot(*step))
        lim = self.options.max_rate * dt
        self.p = self.target.copy() if dist <= lim else self.p + step * (lim / dist)
        return Setpoint(eta_d=np.array([self.p[0], self.p[1], self.eta_d0[2]]))
