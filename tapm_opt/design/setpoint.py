"""The optimal setpoint of one sea state, computed statically (``tapm setpoint``).

The closed-loop layer (:class:`~tapm_opt.control.setpoint_opt.OptimalSetpoint`) takes the mean
environmental load from its estimator and the wave-frequency allowance ``k sigma`` of every line and
riser end from the measured signals. Here both come from the scenario alone:

* the mean load is :func:`~tapm_opt.design.loads.mean_environmental_load` (wind at its mean speed,
  Newman mean drift, current on the hull at rest) at the heading (default the weathervane heading,
  :func:`~tapm_opt.design.tables.weathervane_heading`);
* ``sigma`` is quasi-static: the wave-frequency turret motion of the plant's wave field
  (:meth:`~tapm_opt.plant.environment.WaveField.eta_wf`) over ``exposure`` seconds, mapped through
  the gradient of each line's tension and each riser angle at the optimum (re-evaluated once at the
  first optimum); ``n`` its zero up-crossings in ``exposure`` and ``k`` the Gumbel factor. With the
  scenario's six-degree-of-freedom hull (``vessel.wave_motion.model = "six_dof"`` or a table) each
  line's response also has its fairlead's share of the hull's heave, roll and pitch
  (:meth:`~tapm_opt.plant.environment.WaveField.vertical`, the same realisation), moved as the
  plant moves it (:func:`~tapm_opt.plant.mooring_fem.vertical_offset`: ``(theta z, -phi z,
  z_h + phi y - theta x)`` in {B}): the horizontal part through the same tension gradient, the
  vertical part through ``dT/dz`` at the working point
  (:meth:`~tapm_opt.models.mooring.MooringModel.depth_sensitivity`). The riser's angles take the
  hang-off's horizontal motion only, as the plant's do. Line dynamics add to the dynamic tension in
  deep water, so this ``sigma`` is a lower bound on what the closed loop's monitor measures
  (``docs/controllers.md`` compares them).

For ``unified`` the numeric optimum is compared with [R]'s closed form about the working point (one
linearised step, as the paper's formula) and with the closed form iterated to its fixed point
(re-linearised at each step, as the closed-loop layer does once per period).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Iterable, Mapping

import numpy as np

from ..control.setpoint_opt import METHODS, SetpointOptError, SetpointOptions, SetpointProblem, WorkingPoint
from ..estimation.reliability import gumbel_k
from ..geometry import body_from_turret, rot2_apply, ssa
from ..models.system import System
from ..plant.environment import Environment
from ..plant.mooring_fem import vertical_offset
from .loads import mean_environmental_load
from .tables import weathervane_heading

__all__ = ["StaticSetpoint", "static_setpoint", "wave_frequency_ksigma", "fairlead_wf_motion", "ReliabilityMap",
           "reliability_map"]


@dataclass(frozen=True)
class StaticSetpoint:
    """The answer of :func:`static_setpoint` (positions are turret offsets [m] in {E})."""

    method: str
    sea_state: str
    broken: tuple[str, ...]
    heading: float
    setpoint: np.ndarray
    delta_lines: dict
    delta_riser_top: float | None
    delta_riser_bottom: float | None
    tau_env: np.ndarray
    ksigma_lines: dict
    ksigma_riser: np.ndarray
    working_point: np.ndarray
    numeric: np.ndarray | None = None
    closed_form: np.ndarray | None = None
    closed_form_iterated: np.ndarray | None = None
    info: dict = field(default_factory=dict)

    @property
    def distance(self) -> float | None:
        """Distance between the one-step closed form and the numeric optimum [m] (unified only)."""
        return None if self.closed_form is None else float(np.hypot(*(self.closed_form - self.numeric)))

    @property
    def distance_iterated(self) -> float | None:
        """Distance between the iterated closed form and the numeric optimum [m] (unified only)."""
        return None if self.closed_form_iterated is None else float(
            np.hypot(*(self.closed_form_iterated - self.numeric)))

    def as_json(self) -> dict:
        """The ``tapm setpoint --json`` object (metres, radians as degrees where named ``_deg``)."""
        out = {"method": self.method, "sea_state": self.sea_state, "broken": list(self.broken),
               "heading_deg": math.degrees(self.heading),
               "setpoint": [float(v) for v in self.setpoint],
               "delta_lines": {k: float(v) for k, v in self.delta_lines.items()},
               "delta_riser_top": self.delta_riser_top, "delta_riser_bottom": self.delta_riser_bottom,
               "working_point": [float(v) for v in self.working_point],
               "tau_env": [float(v) for v in self.tau_env],
               "k_sigma_lines": {k: float(v) for k, v in self.ksigma_lines.items()},
               "k_sigma_riser_deg": [math.degrees(float(v)) for v in self.ksigma_riser],
               "solver": self.info}
        if self.closed_form is not None:
            out.update({"numeric": [float(v) for v in self.numeric],
                        "closed_form": [float(v) for v in self.closed_form],
                        "closed_form_iterated": [float(v) for v in self.closed_form_iterated],
                        "distance": self.distance, "distance_iterated": self.distance_iterated})
        return out


def _hull_wf(scenario: Any, sea_state: Any, psi: float, exposure: float, dt: float, seed: int,
             points_B: Any) -> tuple[list[np.ndarray], np.ndarray | None]:
    """Wave-frequency motion (dx, dy) in {E} [m] of body-fixed points (each (2,) in {B}) over
    ``exposure`` s, each shape (N, 2), and the hull's heave [m, down], roll and pitch [rad] (N, 3)
    of the same realisation at the same times (:meth:`WaveField.vertical
    <tapm_opt.plant.environment.WaveField.vertical>`), None without the six-degree-of-freedom
    motion."""
    env = Environment(scenario, sea_state, seed=seed)
    t = np.arange(0.0, float(exposure), float(dt))
    wf = env.waves.eta_wf(t, psi)
    out = []
    for pt in points_B:
        cx, cy = rot2_apply(psi, float(pt[0]), float(pt[1]))
        # R(psi + dpsi) c - R(psi) c ~ dpsi (-c_y, c_x)
        out.append(np.stack([wf[:, 0] - cy * wf[:, 2], wf[:, 1] + cx * wf[:, 2]], axis=1))
    return out, (env.waves.vertical(t, psi) if env.waves.six_dof else None)


def fairlead_wf_motion(prob: SetpointProblem, psi: float, p: Any, vertical: np.ndarray) -> tuple[np.ndarray, ...]:
    """Each modelled fairlead's displacement (x, y, z) in {E} [m], each (N, n_lines), by the hull's
    heave, roll and pitch ``vertical`` (N, 3) at turret offset ``p`` and heading ``psi``
    (:func:`~tapm_opt.plant.mooring_fem.vertical_offset`, the plant's kinematics: ``(theta z, -phi
    z, z_h + phi y - theta x)`` in {B} for the fairlead at ``(x, y, z)`` in {B})."""
    lines = prob.system.lines
    bx, by = body_from_turret(np.asarray(p, float), psi, prob.p_cot_B)
    fx, fy = lines.fairleads(np.array([bx, by, psi]))
    v = np.asarray(vertical, float)
    z_fl = float(prob.system.scenario.turret.fairlead_depth)
    out = vertical_offset(v[:, 0:1], v[:, 1:2], v[:, 2:3], (np.asarray(fx) - bx)[None, :],
                          (np.asarray(fy) - by)[None, :], z_fl, math.cos(psi), math.sin(psi))
    return tuple(np.broadcast_to(o, (len(v), len(fx))) for o in out)


def wave_frequency_ksigma(prob: SetpointProblem, wp: WorkingPoint, p: Any, motion: np.ndarray,
                          exposure: float, motion_hangoff: np.ndarray | None = None,
                          vertical: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Quasi-static ``k sigma`` of every modelled line's tension [N] and of the riser's two angles
    [rad] at turret offset ``p`` under the wave-frequency turret ``motion`` (N, 2) [m] (the riser's
    under its hang-off's, ``motion_hangoff``, default the turret's; at a fixed heading a hang-off
    displacement is a turret-offset displacement) and, when given, the hull's heave, roll and pitch
    ``vertical`` (N, 3) [m, rad, rad] at the same times: each line's tension then also takes its
    fairlead's displacement by them (:func:`fairlead_wf_motion`), horizontally through the tension's
    gradient, vertically through ``dT/dz`` (module docstring). Returns ``(ksigma_lines (n,),
    ksigma_riser (2,), n_maxima (m,))``."""
    _, G = prob.linearise(wp.at(p))              # d delta / d p, rows: lines with an index, riser top, bottom
    scale = np.concatenate([prob.sigma_b[prob.has_index], prob.sigma_r if prob.riser is not None else []])
    Gs = -(G * scale[:, None])                   # d response / d p: tensions [N/m], angles [rad/m]
    m = int(np.sum(prob.has_index))
    mh = motion if motion_hangoff is None else motion_hangoff
    resp_lines = motion @ Gs[:m].T
    if vertical is not None:                     # each fairlead's share of the heave, roll and pitch
        ox, oy, oz = (o[:, prob.has_index] for o in fairlead_wf_motion(prob, wp.psi, p, vertical))
        bx, by = body_from_turret(np.asarray(p, float), wp.psi, prob.p_cot_B)
        dTdz = prob.system.lines.depth_sensitivity(np.array([bx, by, wp.psi]))[prob.has_index]
        resp_lines = resp_lines + (ox * Gs[:m, 0] + oy * Gs[:m, 1] + oz * dTdz)
    resp = np.hstack([resp_lines, mh @ Gs[m:].T])  # WF response of each tension [N] / angle [rad]
    sigma = resp.std(axis=0)
    wd = resp - resp.mean(axis=0)
    n = np.sum((wd[:-1] < 0) & (wd[1:] >= 0), axis=0) * 1.0
    k = np.array([gumbel_k(max(v, 2.0)) for v in n])
    ks = k * sigma
    ks_lines = np.zeros(len(prob.line_ids))
    ks_lines[prob.has_index] = ks[:m]
    ks_riser = ks[m:m + 2] if prob.riser is not None else np.zeros(2)
    return ks_lines, ks_riser, n


def static_setpoint(scenario: Any, sea_state: Any, method: str, *, broken: Iterable[str] = (),
                    heading: float | None = None, options: SetpointOptions | Mapping[str, Any] | None = None,
                    working_point: Any = (0.0, 0.0), exposure: float = 10800.0, seed: int = 0,
                    n_elements: int = 20) -> StaticSetpoint:
    """Optimal turret offset of ``method`` in ``sea_state`` (module docstring).

    Parameters
    ----------
    scenario : Scenario
    sea_state : SeaState or str
    method : {"quadratic", "reliability", "unified"}
    broken : iterable of str
        Lines known broken (left out of the model).
    heading : float or None
        Heading [rad] (None: the weathervane heading with those lines broken).
    options : SetpointOptions or mapping
    working_point : (2,)
        Present turret offset [m]: the start of the numeric solve and the linearisation point of
        the closed form.
    exposure : float
        Period the extreme allowance refers to [s] (3 h by default).
    seed : int
        Seed of the wave field.
    """
    from ..models.riser import RiserModel

    if method not in METHODS:
        raise SetpointOptError(f"method = {method!r} is not one of {', '.join(METHODS)}")
    if not (isinstance(exposure, (int, float)) and math.isfinite(exposure) and exposure >= 60.0):
        raise SetpointOptError(f"exposure = {exposure!r} s must be a number >= 60 s")
    wp0 = np.asarray(working_point, float)
    if wp0.shape != (2,) or not np.all(np.isfinite(wp0)):
        raise SetpointOptError(f"working_point = {wp0.tolist()} must be 2 finite numbers (x [m], y [m])")
    opts = options if isinstance(options, SetpointOptions) else SetpointOptions.from_mapping(options)
    ss = scenario.sea_state(sea_state) if isinstance(sea_state, str) else sea_state
    broken = tuple(dict.fromkeys(str(b) for b in broken))
    system = System.from_scenario(scenario)
    sys_b = system.with_broken(broken) if broken else system
    psi = float(ssa(weathervane_heading(scenario, ss, broken=broken, seed=seed) if heading is None else heading))
    tau = np.asarray(mean_environmental_load(scenario, ss, psi, seed=seed).total, float)
    riser = RiserModel.from_scenario(scenario, ss, n_elements=n_elements) if scenario.riser is not None else None
    prob = SetpointProblem(sys_b, riser, method, opts)
    v_c = np.zeros(2) if riser is None else np.asarray(riser.v_c, float)[:2]
    wp = WorkingPoint(p=wp0, psi=psi, tau_env=tau, ksigma_lines=np.zeros(len(prob.line_ids)), v_c=v_c)
    pts = [scenario.turret.position] + ([scenario.riser.hangoff] if riser is not None else [])
    motions, vert = _hull_wf(scenario, ss, psi, exposure, min(0.5, ss.Tp / 20.0), seed, pts)
    motion, motion_h = motions[0], motions[-1]
    ks_l, ks_r, _ = wave_frequency_ksigma(prob, wp, wp0, motion, exposure, motion_h, vert)
    p_opt = wp0
    for _ in range(2):   # sigma at the optimum, then the optimum with that sigma
        wp = WorkingPoint(p=wp0, psi=psi, tau_env=tau, ksigma_lines=ks_l, ksigma_riser=ks_r, v_c=v_c)
        p_opt, info = prob.solve(wp, starts=(p_opt,))
        ks_l, ks_r, _ = wave_frequency_ksigma(prob, wp, p_opt, motion, exposure, motion_h, vert)
    wp = WorkingPoint(p=wp0, psi=psi, tau_env=tau, ksigma_lines=ks_l, ksigma_riser=ks_r, v_c=v_c)
    p_opt, info = prob.solve(wp, starts=(p_opt,))
    ev = prob.evaluate(p_opt, wp)
    m = int(np.sum(prob.has_index))
    ids = [i for i, h in zip(prob.line_ids, prob.has_index) if h]
    cf = cfi = p_num = None
    if method == "unified":
        p_num, info_p = prob.solve_printed(wp, starts=(p_opt,))
        cf = prob.closed_form_step(wp)
        cfi, _ = prob.closed_form_iterated(wp)
    return StaticSetpoint(
        method=method, sea_state=ss.id, broken=broken, heading=psi, setpoint=p_opt,
        delta_lines=dict(zip(ids, ev["delta"][:m])),
        delta_riser_top=float(ev["delta"][m]) if riser is not None else None,
        delta_riser_bottom=float(ev["delta"][m + 1]) if riser is not None else None,
        tau_env=tau, ksigma_lines=dict(zip(prob.line_ids, ks_l)), ksigma_riser=ks_r, working_point=wp0,
        numeric=p_num, closed_form=cf, closed_form_iterated=cfi,
        info={**info, "J": ev["J"], "F_T": math.sqrt(ev["FT2"])})


@dataclass(frozen=True)
class ReliabilityMap:
    """Reliability indices over a grid of turret offsets (:func:`reliability_map`).

    Attributes
    ----------
    x, y : ndarray (n,)
        Grid of turret offsets [m] in {E} (north, east).
    delta_lines : ndarray (n, n)
        Lowest line index at each point, ``[iy, ix]`` (NaN where the catenary has no solution).
    delta_riser : ndarray (n, n) or None
        Lower of the riser's two indices (None without a riser).
    F_T : ndarray (n, n)
        Thrust needed over capacity (module docstring of :mod:`tapm_opt.control.setpoint_opt`).
    delta_s : float
        The threshold: the reliability-safe region is where every index is at least ``delta_s``.
    """

    x: np.ndarray
    y: np.ndarray
    delta_lines: np.ndarray
    delta_riser: np.ndarray | None
    F_T: np.ndarray
    delta_s: float

    @property
    def delta_min(self) -> np.ndarray:
        """Lowest of every index at each point."""
        return self.delta_lines if self.delta_riser is None else np.minimum(self.delta_lines, self.delta_riser)

    @property
    def safe(self) -> np.ndarray:
        """True where every index is at least ``delta_s`` (False where the catenary has no solution)."""
        with np.errstate(invalid="ignore"):
            return self.delta_min >= self.delta_s


def reliability_map(scenario: Any, sea_state: Any, *, broken: Iterable[str] = (), heading: float = 0.0,
                    tau_env: Any = None, ksigma_lines: Any = None, ksigma_riser: Any = None,
                    half_width: float | None = None, n: int = 41, delta_s: float | None = None,
                    n_elements: int = 20) -> ReliabilityMap:
    """Every line's and the riser's reliability index over a square grid of turret offsets, on the
    design models (catenary, quasi-static riser in ``sea_state``'s current) with the allowances
    ``k sigma`` given (default: zero, the quasi-static indices).

    Parameters
    ----------
    scenario : Scenario
    sea_state : SeaState, str or None
        Only its current matters (the riser); None: still water.
    broken : iterable of str
        Lines left out.
    heading : float
        Heading [rad] (the fairlead positions follow it).
    tau_env : (3,), optional
        Mean environmental load in {B} for ``F_T`` (default zero).
    ksigma_lines : (n_lines,) or mapping id -> value, optional
        [N]; ``ksigma_riser`` (2,) [rad].
    half_width : float, optional
        Grid from -half_width to +half_width [m] (default 1.25 x the alert radius, else the safe
        radius, else 8 % of the water depth).
    n : int
        Points per axis (>= 3).
    delta_s : float, optional
        The threshold (default :data:`~tapm_opt.control.setpoint_opt.DELTA_S_DEFAULT`).
    """
    from ..control.setpoint_opt import DELTA_S_DEFAULT
    from ..models.riser import RiserModel

    if not (isinstance(n, (int, np.integer)) and n >= 3):
        raise SetpointOptError(f"n = {n!r} must be a whole number >= 3")
    ss = scenario.sea_state(sea_state) if isinstance(sea_state, str) else sea_state
    broken = tuple(dict.fromkeys(str(b) for b in broken))
    system = System.from_scenario(scenario)
    sys_b = system.with_broken(broken) if broken else system
    riser = RiserModel.from_scenario(scenario, ss, n_elements=n_elements) if scenario.riser is not None else None
    opts = SetpointOptions(delta_s=DELTA_S_DEFAULT if delta_s is None else float(delta_s))
    prob = SetpointProblem(sys_b, riser, "unified", opts)
    ids = prob.line_ids
    if ksigma_lines is None:
        ks = np.zeros(len(ids))
    elif isinstance(ksigma_lines, Mapping):
        ks = np.array([float(ksigma_lines.get(i, 0.0)) for i in ids])
    else:
        allk = np.asarray(ksigma_lines, float)
        every = [ln.id for ln in scenario.lines]
        ks = allk if allk.shape == (len(ids),) else np.array([allk[every.index(i)] for i in ids])
    kr = np.zeros(2) if ksigma_riser is None else np.asarray(ksigma_riser, float)
    lim = scenario.limits
    hw = float(half_width or 1.25 * (lim.alert_radius or lim.safe_radius or 0.08 * scenario.environment.water_depth))
    x = np.linspace(-hw, hw, int(n))
    y = np.linspace(-hw, hw, int(n))
    X, Y = np.meshgrid(x, y)
    wp = WorkingPoint(p=np.zeros(2), psi=float(heading), tau_env=np.zeros(3) if tau_env is None else
                      np.asarray(tau_env, float), ksigma_lines=ks, ksigma_riser=kr,
                      v_c=np.zeros(2) if riser is None else np.asarray(riser.v_c, float)[:2])
    out = prob.evaluate_many(np.stack([X.ravel(), Y.ravel()]), wp)
    m = int(np.sum(prob.has_index))
    d = out["delta"]
    dl = np.min(d[:m], axis=0).reshape(X.shape) if m else np.full(X.shape, np.inf)
    dr = np.min(d[m:m + 2], axis=0).reshape(X.shape) if riser is not None else None
    return ReliabilityMap(x=x, y=y, delta_lines=dl, delta_riser=dr, F_T=np.sqrt(out["FT2"]).reshape(X.shape),
                          delta_s=opts.delta_s)
