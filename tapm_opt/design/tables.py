"""Gain tables for gain scheduling: PID (pole placement) and LQR per operating condition.

A *condition* is a sea state (its class picks the control modes of [S] Table 3), the mooring
intact or with one line broken, and a vessel heading. For each condition:

1. the **mean environmental load** in {B} at that heading
   (:func:`~tapm_opt.design.loads.mean_environmental_load`);
2. the **offset equilibrium** of the catenary mooring under that load with the heading held at the
   condition's heading by the heading controller (every Table 3 mode set has heading PID with
   integral action): :meth:`~tapm_opt.models.mooring.MooringModel.equilibrium` with ``psi``
   held, x, y solve ``tau_moor(x, y, psi)[X, Y] + tau_env[X, Y] = 0``; the yaw moment the
   mooring does not balance is the heading controller's steady thrust ``tau_thr``;
3. the design model ([S] eq. 31, catenary restoring load) **linearised there**
   (:func:`~tapm_opt.models.vessel.linearise`), so K is the catenary stiffness at the offset;
4. **PID gains** by per-DOF pole placement (:func:`~tapm_opt.control.pid_design.design_gains`) and
   **LQR gains** (``control.lqr``) on the same 6-state model, with their closed-loop poles,
   natural periods, damping ratios and (PID) loop-at-a-time stability margins
   (:mod:`tapm_opt.design.margins`).

The rows and their files are :mod:`tapm_opt.control.gain_table`. ``[S]`` = seed
survey-tapm-modeling-and-control. Guide: ``docs/gains.md``.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass
from types import MappingProxyType
from typing import Any, Iterable, Mapping, Sequence

import control
import numpy as np
import scipy.optimize

from .. import __version__
from .._checks import vector
from .._io import readonly
from ..control.gain_table import (
    FORMAT,
    Condition,
    GainRow,
    GainTable,
    GainTableError,
    LQRRow,
    PIDRow,
)
# the sea-state classes and their mode sets ([S] Table 3) are the controllers' (the supervisor
# switches with them); re-exported here with the tables built on them
from ..control.pid import CLASS_MODE_SETS, MODE_SETS, SEA_CLASSES, GainClampWarning
from ..control.pid_design import check_integral_ratio, closed_loop, design_gains
from ..errors import TapmError
from ..geometry import ssa
from ..models.mooring import MooringModel
from ..models.system import ThrusterSet
from ..models.vessel import VesselParams, linearise, moored_function
from .loads import MeanLoad, mean_environmental_load
from .margins import ESTIMATOR_CUTOFF, loop_lag, margins, sorted_damp

__all__ = [
    "SEA_CLASSES",
    "CLASS_MODE_SETS",
    "DEFAULT_PERIODS",
    "DEFAULT_DAMPING",
    "DEFAULT_INTEGRAL_RATIO",
    "DEFAULT_LQR",
    "LQRWeights",
    "sea_state_class",
    "weathervane_heading",
    "gain_table",
]

_X, _Y, _PSI = 0, 1, 2

#: Sea-state ids recognised as a class without a ``classes`` mapping.
_ID_CLASSES = MappingProxyType({"calm": "calm", "normal": "normal", "extreme": "extreme",
                                "storm": "extreme"})
#: Hs thresholds [m] for ids that are not recognised: calm below the first, extreme from the
#: second (ASSUMPTION, after the WMO sea-state code: calm up to code 4 "moderate", Hs <= 2.5 m;
#: extreme from code 8 "very high", Hs >= 9 m).
_HS_CALM, _HS_EXTREME = 2.5, 9.0

#: Default undamped natural periods (surge, sway, yaw) [s] per class: long in calm seas (little
#: thrust, the mooring does the work), shorter in extreme seas (tighter position keeping). The
#: extreme periods are about as short as the 40 s estimator low-pass and a 5 s thrust lag allow
#: with a phase margin of about 30 deg on the fpso (docs/gains.md).
DEFAULT_PERIODS: Mapping[str, tuple[float, float, float]] = MappingProxyType({
    "calm": (250.0, 250.0, 200.0), "normal": (200.0, 200.0, 160.0),
    "extreme": (180.0, 180.0, 140.0)})
#: Default relative damping (surge, sway, yaw) per class. Higher damping raises the crossover
#: frequency (about 2 zeta w) and so erodes the margin against the estimator lag.
DEFAULT_DAMPING: Mapping[str, tuple[float, float, float]] = MappingProxyType({
    "calm": (0.7, 0.7, 0.7), "normal": (0.7, 0.7, 0.7), "extreme": (0.7, 0.7, 0.7)})
#: Default integral ratio a / w per class ([S] Table 2 integral action, slow).
DEFAULT_INTEGRAL_RATIO: Mapping[str, float] = MappingProxyType(
    {"calm": 0.1, "normal": 0.1, "extreme": 0.1})


def _vec(name: str, value: Any, n: int = 3, *, positive: bool = False) -> np.ndarray:
    arr = vector(name, value, n, lo=0.0 if positive else None, strict=True, broadcast=True, error=GainTableError,
                 eq="=")
    arr.flags.writeable = False
    return arr


@dataclass(frozen=True, kw_only=True, eq=False)
class LQRWeights:
    """Bryson weights of the LQR on the 6-state linearised vessel.

    ``Q = diag(1/eta_ref^2, 1/nu_ref^2)``, ``R = diag(1/tau_ref^2)``: the deviation that costs as
    much as the thrust ``tau_ref``.

    Parameters
    ----------
    eta_ref : array_like, shape (3,)
        Acceptable deviation (x [m], y [m], psi [rad]) from the operating point, > 0.
    nu_ref : array_like, shape (3,)
        Acceptable velocity (u [m/s], v [m/s], r [rad/s]), > 0.
    tau_ref : array_like, shape (3,), optional
        Acceptable thrust (X [N], Y [N], N [N m]), > 0; None: the capacity box of the
        scenario's thrusters, ``ThrusterSet.from_scenario(scenario).capacity_box(tau_share)``
        = ``tau_share * max_tau()`` (:class:`~tapm_opt.models.system.ThrusterSet`, the one
        capacity model: the largest |X|, |Y|, |N| each attainable alone, by linear programming
        over every thruster's attainable forces; failed thrusters excluded).
    tau_share : float
        Fraction of the capacity used when ``tau_ref`` is None, in (0, 1].
    """

    eta_ref: np.ndarray
    nu_ref: np.ndarray
    tau_ref: np.ndarray | None = None
    tau_share: float = 0.3

    def __post_init__(self) -> None:
        object.__setattr__(self, "eta_ref", _vec("eta_ref", self.eta_ref, positive=True))
        object.__setattr__(self, "nu_ref", _vec("nu_ref", self.nu_ref, positive=True))
        if self.tau_ref is not None:
            object.__setattr__(self, "tau_ref", _vec("tau_ref", self.tau_ref, positive=True))
        share = float(self.tau_share)
        if not 0.0 < share <= 1.0:
            raise GainTableError(f"tau_share={self.tau_share!r} must be in (0, 1]")
        object.__setattr__(self, "tau_share", share)


_DEG = math.pi / 180.0
#: Default LQR weights per class: larger tolerated deviations and less thrust in calm seas.
DEFAULT_LQR: Mapping[str, LQRWeights] = MappingProxyType({
    "calm": LQRWeights(eta_ref=(20.0, 20.0, 5.0 * _DEG), nu_ref=(0.5, 0.5, 0.2 * _DEG),
                       tau_share=0.1),
    "normal": LQRWeights(eta_ref=(10.0, 10.0, 3.0 * _DEG), nu_ref=(0.3, 0.3, 0.1 * _DEG),
                         tau_share=0.3),
    "extreme": LQRWeights(eta_ref=(5.0, 5.0, 2.0 * _DEG), nu_ref=(0.2, 0.2, 0.1 * _DEG),
                          tau_share=0.6),
})


def sea_state_class(sea_state: Any, classes: Mapping[str, str] | None = None) -> str:
    """Class of a sea state: ``classes[id]``, else the id itself if it is ``calm``/``normal``/
    ``extreme`` (``storm`` -> extreme), else by Hs: < 2.5 m calm, >= 9 m extreme, else normal."""
    sid = sea_state.id
    if classes and sid in classes:
        cls = classes[sid]
        if cls not in SEA_CLASSES:
            raise GainTableError(f"classes[{sid!r}]={cls!r} is not one of {SEA_CLASSES}")
        return cls
    if sid in _ID_CLASSES:
        return _ID_CLASSES[sid]
    return "calm" if sea_state.Hs < _HS_CALM else "extreme" if sea_state.Hs >= _HS_EXTREME \
        else "normal"


# --- design of one condition ----------------------------------------------------------------

def _offset_equilibrium(moor: MooringModel, tau_env: np.ndarray, psi: float) -> np.ndarray:
    """Pose where the mooring balances the horizontal load with the heading held at ``psi``
    (:meth:`~tapm_opt.models.mooring.MooringModel.equilibrium`)."""
    try:
        return moor.equilibrium(tau_env, psi=psi)
    except TapmError:
        raise GainTableError(
            f"no mooring equilibrium for the mean load {tau_env[:2].tolist()} N at heading "
            f"{math.degrees(psi):g} deg with lines {list(moor.line_ids)}: the catenary cannot "
            f"hold it (reduce the sea state or choose another heading)") from None


def _lqr_tau_ref(lqr: LQRWeights, thrusters: ThrusterSet) -> np.ndarray:
    """``tau_ref`` of the LQR weights: given, or ``thrusters.capacity_box(tau_share)``."""
    if lqr.tau_ref is not None:
        return lqr.tau_ref
    if not thrusters.n:
        raise GainTableError("the scenario has no thrusters: give LQRWeights(tau_ref=...)")
    tau_ref = thrusters.capacity_box(lqr.tau_share)
    if not np.all(tau_ref > 0.0):
        none = [d for d, t in zip("XYN", tau_ref) if not t > 0.0]
        raise GainTableError(f"the thrusters have no capacity in {none} (ThrusterSet.max_tau() "
                             f"= {thrusters.max_tau().tolist()}): give LQRWeights(tau_ref=...)")
    return tau_ref


def _design_condition(scenario: Any, params: VesselParams, thrusters: ThrusterSet,
                      cond: Condition, load: MeanLoad, *, periods: np.ndarray,
                      damping: np.ndarray, integral_ratio: float, lqr: LQRWeights, lag: Any,
                      D_moor: Any) -> GainRow:
    broken = () if cond.broken == "intact" else (cond.broken,)
    moor = MooringModel.from_scenario(scenario, broken=broken)
    ref = np.asarray(scenario.turret.position, dtype=float)  # the PID acts on the turret offset
    tau_env = load.total
    eta = _offset_equilibrium(moor, tau_env, cond.heading)
    tau_thr = np.array([0.0, 0.0, -(moor.force(eta)[_PSI] + tau_env[_PSI])])
    # linearised at eta, where the characteristic kind has the catenary's exact Jacobian; composite
    # lines have no symbolic catenary
    kind = "characteristic" if moor.has_composite else "catenary"
    fn = moored_function(params, moor.force_function(kind, eta0=eta), D_moor=D_moor)
    plant = linearise(fn, np.r_[eta, np.zeros(3)], tau_thr0=tau_thr, tau_env0=tau_env,
                      outputs="state")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", GainClampWarning)  # reported in PIDRow.clamped
        d = design_gains(plant, periods=periods, damping=damping, integral_ratio=integral_ratio,
                         reference_point=ref)
    gm, pm, wgc, dm = margins(plant, d.gains, lag, reference_point=ref)
    cl_modes = closed_loop(plant, d.gains, cond.mode_set, reference_point=ref)
    p_modes = np.asarray(cl_modes.poles(), dtype=complex)
    p_modes = p_modes[np.lexsort((p_modes.imag, np.abs(p_modes)))]
    pid = PIDRow(
        periods=readonly(d.periods), damping=readonly(d.damping),
        integral_ratio=float(d.integral_ratio), Kp=readonly(np.diag(d.gains.Kp)),
        Ki=readonly(np.diag(d.gains.Ki)), Kd=readonly(np.diag(d.gains.Kd)),
        designed_poles=readonly(d.designed_poles, complex),
        decoupled_poles=readonly(d.decoupled_poles, complex), poles=readonly(d.poles, complex),
        natural_periods=readonly(d.natural_periods), damping_ratios=readonly(d.damping_ratios),
        stable=d.stable, poles_modes=readonly(p_modes, complex),
        stable_modes=bool(np.all(p_modes.real < 0.0)), gain_margin=gm, phase_margin=pm,
        crossover=wgc, delay_margin=dm, clamped=tuple(d.clamped))

    A, B = np.asarray(plant.A, dtype=float), np.asarray(plant.B, dtype=float)
    Q = 1.0 / np.r_[lqr.eta_ref, lqr.nu_ref] ** 2
    R = 1.0 / np.asarray(_lqr_tau_ref(lqr, thrusters)) ** 2
    K_lqr, _, _ = control.lqr(A, B, np.diag(Q), np.diag(R))
    K_lqr = np.asarray(K_lqr, dtype=float)
    lp, lT, lz = sorted_damp(A - B @ K_lqr)
    lqr_row = LQRRow(Q=readonly(Q), R=readonly(R), K=readonly(K_lqr), poles=readonly(lp, complex),
                     natural_periods=readonly(lT), damping_ratios=readonly(lz),
                     stable=bool(np.all(lp.real < 0.0)))
    return GainRow(condition=cond, tau_env=readonly(tau_env), tau_wind=load.wind,
                   tau_drift=load.drift, tau_current=load.current, tau_thr=readonly(tau_thr),
                   eta=readonly(eta), M=readonly(d.M), D=readonly(d.D), K=readonly(d.K),
                   A=readonly(A), B=readonly(B), pid=pid, lqr=lqr_row,
                   p_cot_B=readonly(scenario.turret.position))


def _per_class(name: str, value: Any, defaults: Mapping[str, Any], convert) -> dict[str, Any]:
    """A per-class setting: None -> defaults; a mapping class -> value (missing classes take the
    default); anything else -> the same value for every class."""
    if value is None:
        return {c: convert(defaults[c]) for c in SEA_CLASSES}
    if isinstance(value, Mapping):
        unknown = set(value) - set(SEA_CLASSES)
        if unknown:
            raise GainTableError(f"{name} has unknown class(es) {sorted(unknown)}; classes are "
                                 f"{SEA_CLASSES}")
        return {c: convert(value.get(c, defaults[c])) for c in SEA_CLASSES}
    conv = convert(value)
    return {c: conv for c in SEA_CLASSES}


def _lqr_weights(v: Any) -> LQRWeights:
    if not isinstance(v, LQRWeights):
        raise GainTableError(f"lqr_weights must be LQRWeights or a mapping class -> LQRWeights, "
                             f"got {type(v).__name__}")
    return v


def _ratio(v: Any) -> float:
    return check_integral_ratio(v, error=GainTableError)


def _headings(headings: Any) -> list[float | str]:
    if isinstance(headings, (str, float, int)):
        headings = [headings]
    out: list[float | str] = []
    try:
        for h in headings:
            if h == "weathervane":
                out.append("weathervane")
                continue
            v = float(h)
            if not math.isfinite(v):
                raise ValueError
            out.append(v)
    except (TypeError, ValueError):
        raise GainTableError(f"headings={headings!r} must be headings [rad] or 'weathervane'") \
            from None
    if not out:
        raise GainTableError("headings is empty; give at least one heading [rad]")
    return list(dict.fromkeys(out))


def _yaw_moment(scenario: Any, moor: MooringModel, sea_state: Any, psi: float,
                seed: int) -> tuple[float, float]:
    """(N_moor + N_env at the offset equilibrium with heading psi [N m], |mean load XY| [N])."""
    tau = mean_environmental_load(scenario, sea_state, psi, seed=seed).total
    eta = _offset_equilibrium(moor, tau, psi)
    return float(moor.force(eta)[_PSI] + tau[_PSI]), float(math.hypot(tau[_X], tau[_Y]))


def weathervane_heading(scenario: Any, sea_state: Any, *, broken: Iterable[str] = (),
                        seed: int = 0, n_scan: int = 36) -> float:
    """Heading [rad] at which the mooring balances the mean yaw moment without thrust.

    The yaw moment on the hull at its offset equilibrium, ``N(psi) = N_moor + N_env`` (for a free
    turret ``N_env - x_cot Y_env``: the mean load's moment about the turret), is scanned at
    ``n_scan`` headings and refined with Brent's method at each sign change from + to - (a
    stable weathervane: turning further brings a restoring moment). Of several stable headings
    the one with the smallest horizontal mean load is returned.

    Parameters
    ----------
    scenario : Scenario
    sea_state : SeaState or str
    broken : iterable of str
        Broken line ids (matter for a locked turret only).
    seed : int
        Environment seed.
    n_scan : int
        Number of scanned headings over a full turn.

    Raises
    ------
    GainTableError
        No stable weathervane heading (or the mooring cannot hold the load at any heading).
    """
    if not isinstance(sea_state, str):
        sea_state = sea_state.id
    moor = MooringModel.from_scenario(scenario, broken=broken)
    grid = np.linspace(-math.pi, math.pi, int(n_scan) + 1)
    vals = []
    for psi in grid:
        try:
            vals.append(_yaw_moment(scenario, moor, sea_state, psi, seed)[0])
        except GainTableError:
            vals.append(math.nan)
    found = []
    for a, b, fa, fb in zip(grid[:-1], grid[1:], vals[:-1], vals[1:]):
        if fa > 0.0 > fb:
            psi = scipy.optimize.brentq(
                lambda p: _yaw_moment(scenario, moor, sea_state, p, seed)[0], a, b, xtol=1e-10)
            found.append((_yaw_moment(scenario, moor, sea_state, psi, seed)[1], float(ssa(psi))))
        elif fa == 0.0 and (np.isnan(fb) or fb < 0.0):
            found.append((_yaw_moment(scenario, moor, sea_state, a, seed)[1], float(ssa(a))))
    if not found:
        raise GainTableError(f"no stable weathervane heading in sea state {sea_state!r} with "
                             f"broken lines {list(broken)}: give fixed headings")
    return min(found)[1]


def _broken_list(scenario: Any, broken: Any) -> list[str]:
    ids = [ln.id for ln in scenario.lines]
    if isinstance(broken, str):
        if broken == "each":
            return ["intact", *ids]
        broken = [broken]
    try:
        chosen = [str(b) for b in broken]
    except TypeError:
        raise GainTableError(f"broken={broken!r} must be 'each', a line id or a sequence of "
                             f"line ids") from None
    unknown = [b for b in chosen if b not in ids and b != "intact"]
    if unknown:
        raise GainTableError(f"broken line id(s) {unknown} not in the scenario; lines are {ids}")
    return ["intact", *[b for b in dict.fromkeys(chosen) if b != "intact"]]


def gain_table(scenario: Any, *, sea_states: Sequence[str] | None = None,
               classes: Mapping[str, str] | None = None, broken: str | Iterable[str] = "each",
               headings: Sequence[float | str] = (0.0,), periods: Any = None, damping: Any = None,
               integral_ratio: Any = None, lqr_weights: Any = None, seed: int = 0,
               D_moor: Any = None, thrust_time_constant: float | None = None,
               estimator_cutoff: float | None = ESTIMATOR_CUTOFF,
               row_designs: Mapping[tuple[str, str], Mapping[str, Any]] | None = None) -> GainTable:
    """PID and LQR gains for every (sea state, mooring state, heading) of a scenario.

    Parameters
    ----------
    scenario : Scenario
    sea_states : sequence of str, optional
        Sea-state ids; default every sea state of the scenario.
    classes : mapping str -> str, optional
        Class (``"calm"``, ``"normal"``, ``"extreme"``) of sea-state ids; others are classed by
        :func:`sea_state_class`. The class picks the mode set (:data:`CLASS_MODE_SETS`) and the
        default design parameters.
    broken : "each", line id or sequence of line ids
        Mooring states besides ``"intact"`` (always included): ``"each"`` = every single line
        broken in turn; ``()`` = intact only.
    headings : sequence of float or "weathervane"
        Vessel headings [rad], held by the heading controller; ``"weathervane"`` adds the
        heading of :func:`weathervane_heading` for each sea state and mooring state.
    periods, damping : float, array_like (3,) or mapping class -> value, optional
        Designed natural periods [s] and relative damping (surge, sway, yaw); default
        :data:`DEFAULT_PERIODS`, :data:`DEFAULT_DAMPING` per class.
    integral_ratio : float or mapping class -> float, optional
        a / w; default :data:`DEFAULT_INTEGRAL_RATIO`.
    lqr_weights : LQRWeights or mapping class -> LQRWeights, optional
        Default :data:`DEFAULT_LQR`.
    seed : int
        Environment seed (the mean wave drift depends slightly on the random wave frequencies).
    D_moor : array_like, shape (3, 3), optional
        Linear mooring damping [N s/m, N s, N m s] added to the design model; default zero.
    thrust_time_constant : float, optional
        First-order thrust lag [s] in the margin loops; default the largest
        ``time_constant`` of the scenario's thrusters (0: none).
    estimator_cutoff : float or None
        Cut-off [rad/s] of the critically damped low-pass on the measured position in the margin
        loops; default :data:`~tapm_opt.design.margins.ESTIMATOR_CUTOFF`, that of
        :class:`~tapm_opt.estimation.lowpass.LowPassEstimator` (2 pi / 40 s); None: no filter
        (an ideal PID on the moored vessel then usually has an infinite gain margin).
    row_designs : mapping (sea-state id, mooring state) -> mapping, optional
        The PID design of particular conditions — ``periods``, ``damping``, ``integral_ratio``
        (each optional) — in place of the class's: e.g. the designs ``tapm tune`` selected per sea
        state and mooring condition (``[tuning] per``; ``tapm gains --designs``). The mooring state
        is ``"intact"`` or a line id.

    Returns
    -------
    GainTable
        One row per condition, in the order sea state, mooring state, heading (as given).

    Raises
    ------
    GainTableError
        Bad arguments, unknown ids, or a load the mooring cannot hold.
    """
    if sea_states is None:
        chosen = list(scenario.sea_states)
    else:
        if isinstance(sea_states, str):
            sea_states = [sea_states]
        chosen = []
        for sid in sea_states:
            try:
                chosen.append(scenario.sea_state(str(sid)))
            except KeyError as exc:
                raise GainTableError(f"sea_states: {exc.args[0]}") from None
    if not chosen:
        raise GainTableError("no sea state: the scenario defines none and none was given")
    mooring_states = _broken_list(scenario, broken)
    heads = _headings(headings)

    per_T = _per_class("periods", periods, DEFAULT_PERIODS, lambda v: _vec("periods", v, positive=True))
    per_z = _per_class("damping", damping, DEFAULT_DAMPING, lambda v: _vec("damping", v, positive=True))
    per_r = _per_class("integral_ratio", integral_ratio, DEFAULT_INTEGRAL_RATIO, _ratio)
    per_q = _per_class("lqr_weights", lqr_weights, DEFAULT_LQR, _lqr_weights)
    if thrust_time_constant is None:
        thrust_time_constant = max((float(t.time_constant) for t in scenario.thrusters), default=0.0)
    T_thr = float(thrust_time_constant)
    if not (math.isfinite(T_thr) and T_thr >= 0.0):
        raise GainTableError(f"thrust_time_constant={thrust_time_constant!r} must be >= 0 [s]")
    if estimator_cutoff is not None and not (math.isfinite(float(estimator_cutoff))
                                             and float(estimator_cutoff) > 0.0):
        raise GainTableError(f"estimator_cutoff={estimator_cutoff!r} must be > 0 [rad/s] or None")
    lag = loop_lag(T_thr, None if estimator_cutoff is None else float(estimator_cutoff))

    params = VesselParams.from_scenario(scenario)
    thrusters = ThrusterSet.from_scenario(scenario)
    rows, class_of = [], {}
    for ss in chosen:
        cls = sea_state_class(ss, classes)
        class_of[ss.id] = cls
        loads: dict[float, MeanLoad] = {}
        vanes: dict[str | None, float] = {}  # free turret: independent of the mooring state
        for b in mooring_states:
            for h in heads:
                wv = h == "weathervane"
                if wv:
                    key = b if scenario.turret.mode == "locked" else None
                    if key not in vanes:
                        vanes[key] = weathervane_heading(
                            scenario, ss, broken=() if b == "intact" else (b,), seed=seed)
                psi = vanes[key] if wv else float(h)
                if psi not in loads:
                    loads[psi] = mean_environmental_load(scenario, ss, psi, seed=seed)
                cond = Condition(sea_state=ss.id, sea_class=cls, mode_set=CLASS_MODE_SETS[cls],
                                 broken=b, heading=psi, weathervane=wv)
                own = dict((row_designs or {}).get((ss.id, b), {}))
                rows.append(_design_condition(
                    scenario, params, thrusters, cond, loads[psi],
                    periods=_vec("periods", own["periods"], positive=True) if "periods" in own else per_T[cls],
                    damping=_vec("damping", own["damping"], positive=True) if "damping" in own else per_z[cls],
                    integral_ratio=_ratio(own["integral_ratio"]) if "integral_ratio" in own else per_r[cls],
                    lqr=per_q[cls], lag=lag, D_moor=D_moor))
    used = sorted(set(class_of.values()), key=SEA_CLASSES.index)
    meta = {
        "format": FORMAT,
        "scenario": scenario.name,
        "tapm_opt_version": __version__,
        "seed": int(seed),
        "sea_state_classes": class_of,
        "mode_sets": {c: {"name": CLASS_MODE_SETS[c], "modes": list(MODE_SETS[CLASS_MODE_SETS[c]])}
                      for c in used},
        "design": {c: {"periods_s": per_T[c].tolist(), "damping": per_z[c].tolist(),
                       "integral_ratio": per_r[c], "lqr_eta_ref": per_q[c].eta_ref.tolist(),
                       "lqr_nu_ref": per_q[c].nu_ref.tolist(),
                       "lqr_tau_ref": None if per_q[c].tau_ref is None else per_q[c].tau_ref.tolist(),
                       "lqr_tau_share": per_q[c].tau_share} for c in used},
        "row_designs": {f"{k[0]}/{k[1]}": {n: (np.asarray(v, dtype=float).tolist() if n != "integral_ratio" else float(v))
                                           for n, v in d.items() if n in ("periods", "damping", "integral_ratio")}
                        for k, d in (row_designs or {}).items()},
        "lqr_capacity": {"model": "tau_ref = ThrusterSet.capacity_box(tau_share) = tau_share * "
                                  "max_tau (largest |X|, |Y|, |N| each attainable alone, LP)",
                         "max_tau": thrusters.max_tau().tolist()
                         if thrusters.n and any(per_q[c].tau_ref is None for c in used) else None},
        "D_moor": None if D_moor is None else np.asarray(D_moor, dtype=float).tolist(),
        "margins": {"method": "loop-at-a-time at the plant input, other DOFs closed, coupled "
                              "linearised model, all four modes, times the loop lag",
                    "thrust_time_constant_s": T_thr,
                    "estimator_cutoff_rad_s": estimator_cutoff},
        "headings": [h if isinstance(h, str) else float(h) for h in heads],
        "heading_rule": "heading held by the heading controller; x, y from the mooring balance; "
                        "tau_thr[2] is the yaw moment it holds",
        "units": {"eta": "m, m, rad", "tau": "N, N, N m", "K": "N/m, N/rad | N, N m/rad",
                  "periods": "s", "phase_margin": "deg", "crossover": "rad/s",
                  "delay_margin": "s", "heading": "rad"},
    }
    return GainTable(rows=tuple(rows), meta=meta)
