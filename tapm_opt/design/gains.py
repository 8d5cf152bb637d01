"""Gain tables for gain scheduling: PID (pole placement) and LQR per operating condition.

A *condition* is a sea state (its class picks the control modes of [S] Table 3), the mooring
intact or with one line broken, and a vessel heading. For each condition:

1. the **mean environmental load** in {B} at that heading (:func:`mean_environmental_load`):
   wind at the 1-hour mean speed (no gusts, the coefficients of
   :class:`~tapm_opt.plant.environment.Wind`), Newman's mean wave drift
   (:meth:`~tapm_opt.plant.environment.WaveField.mean_drift`) and the current load on the hull,
   ``M nu_dot`` of the rich vessel model :func:`~tapm_opt.models.vessel.vessel_rhs` at rest
   (nu = 0, tau = 0) in the surface current the plant uses;
2. the **offset equilibrium** of the catenary mooring under that load with the heading held at the
   condition's heading by the heading controller (every Table 3 mode set has heading PID with
   integral action): x, y solve ``tau_moor(x, y, psi)[X, Y] + tau_env[X, Y] = 0``; the yaw
   moment the mooring does not balance is the heading controller's steady thrust ``tau_thr``;
3. the design model ([S] eq. 31, catenary restoring load) **linearised there**
   (:func:`~tapm_opt.models.vessel.linearise`), so K is the catenary stiffness at the offset;
4. **PID gains** by per-DOF pole placement (:func:`~tapm_opt.control.pid.design_gains`) and
   **LQR gains** (``control.lqr``) on the same 6-state model, with their closed-loop poles,
   natural periods, damping ratios and (PID) loop-at-a-time stability margins.

``[S]`` = seed survey-tapm-modeling-and-control. Guide: ``docs/gains.md``.
"""

from __future__ import annotations

import inspect
import json
import math
import warnings
from dataclasses import dataclass, field, fields
from pathlib import Path
from types import MappingProxyType
from typing import Any, Iterable, Mapping, Sequence

import control
import numpy as np
import scipy.optimize

from .. import __version__
from .._io import atomic_write_text, csv_text
from ..control.pid import (
    MODE_SETS,
    MODES,
    GainClampWarning,
    PIDGains,
    closed_loop,
    design_gains,
)
from ..errors import TapmError
from ..estimation.lowpass import LowPassEstimator
from ..geometry import ssa
from ..models.mooring import MooringModel
from ..models.vessel import VesselParams, linearise, moored_function, vessel_rhs
from ..plant.environment import Environment

__all__ = [
    "GainTableError",
    "SEA_CLASSES",
    "CLASS_MODE_SETS",
    "DEFAULT_PERIODS",
    "DEFAULT_DAMPING",
    "DEFAULT_INTEGRAL_RATIO",
    "DEFAULT_LQR",
    "ESTIMATOR_CUTOFF",
    "LQRWeights",
    "MeanLoad",
    "Condition",
    "PIDRow",
    "LQRRow",
    "GainRow",
    "GainTable",
    "mean_environmental_load",
    "weathervane_heading",
    "sea_state_class",
    "gain_table",
    "write_gain_tables",
    "load_gain_table",
]

FORMAT = "tapm_opt.gains/1"
_X, _Y, _PSI = 0, 1, 2


class GainTableError(TapmError, ValueError):
    """A gain table cannot be made or read (bad argument, no equilibrium, bad file)."""


#: Sea-state classes, ordered from calm to extreme.
SEA_CLASSES: tuple[str, ...] = ("calm", "normal", "extreme")
#: Control modes of each class ([S] Table 3): calm -> heading PID only (action 1); normal ->
#: heading + surge-sway damping + restoring (1+2+3); extreme -> all four (1+2+3+4).
CLASS_MODE_SETS: Mapping[str, str] = MappingProxyType(
    {"calm": "calm", "normal": "normal_restoring", "extreme": "extreme_restoring"})
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
#: Default cut-off [rad/s] of the position low-pass in the margin loops: the default of
#: :class:`~tapm_opt.estimation.lowpass.LowPassEstimator`, the estimate the closed loop uses.
ESTIMATOR_CUTOFF: float = float(inspect.signature(LowPassEstimator).parameters["omega_c"].default)


def _vec(name: str, value: Any, n: int = 3, *, positive: bool = False) -> np.ndarray:
    try:
        arr = np.broadcast_to(np.asarray(value, dtype=float), (n,)).copy()
    except (TypeError, ValueError):
        raise GainTableError(f"{name}={value!r} must be a number or {n} numbers") from None
    if not np.all(np.isfinite(arr)) or (positive and np.any(arr <= 0.0)):
        rule = "finite and > 0" if positive else "finite"
        raise GainTableError(f"{name}={arr.tolist()} must be {rule}")
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
        Acceptable thrust (X [N], Y [N], N [N m]), > 0; None: ``tau_share`` times the thrust
        capacity of the scenario's thrusters (sum of |f_max| in X and Y, sum of |f_max| times the
        lever arm in N).
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


# --- mean environmental load ----------------------------------------------------------------

@dataclass(frozen=True, kw_only=True, eq=False)
class MeanLoad:
    """Mean environmental load in {B} at one heading, each (X [N], Y [N], N [N m]).

    Attributes
    ----------
    wind, drift, current, total : ndarray, shape (3,)
    """

    wind: np.ndarray
    drift: np.ndarray
    current: np.ndarray
    total: np.ndarray


def mean_environmental_load(scenario: Any, sea_state: Any, psi: float, *,
                            seed: int = 0) -> MeanLoad:
    """Mean wind, wave-drift and current load on the vessel at rest with heading ``psi``.

    * wind: ``-1/2 rho_a V_rw^2 (c_x cos(gamma) A_F, c_y sin(gamma) A_L, c_n sin(2 gamma) A_L
      L_pp)`` with the mean speed ``Wind.mean_speed`` (no gusts) and the coefficients
      ``Wind.params`` — the formula of :meth:`~tapm_opt.plant.environment.Wind.tau_wind`;
    * drift: :meth:`~tapm_opt.plant.environment.WaveField.mean_drift` (Newman), which depends a
      little on ``seed`` through the random wave frequencies;
    * current: ``M nu_dot`` of :func:`~tapm_opt.models.vessel.vessel_rhs` (rich form) at nu = 0,
      tau = 0 in the surface current (as the plant): linear and quadratic damping and the
      Coriolis/Munk terms on nu_r = -nu_c.

    Parameters
    ----------
    scenario : Scenario
    sea_state : SeaState or str
    psi : float
        Heading [rad].
    seed : int
        Seed of :class:`~tapm_opt.plant.environment.Environment`.

    Returns
    -------
    MeanLoad
    """
    env = Environment(scenario, sea_state, seed=seed)
    psi = float(psi)
    wind = env.wind
    p, ves = wind.params, scenario.vessel
    rho_a = scenario.environment.air_density
    k = -0.5 * rho_a * np.array([p.c_x * ves.wind_area_frontal, p.c_y * ves.wind_area_lateral,
                                 2.0 * p.c_n * ves.wind_area_lateral * ves.length_pp])
    b = wind.direction - psi
    u_rw, v_rw = -wind.mean_speed * math.cos(b), -wind.mean_speed * math.sin(b)
    V_rw = math.hypot(u_rw, v_rw)
    tau_wind = k * np.array([V_rw * u_rw, V_rw * v_rw, u_rw * v_rw])
    tau_drift = np.asarray(env.waves.mean_drift(psi), dtype=float)
    params = VesselParams.from_scenario(scenario)
    _, nu_dot = vessel_rhs(np.array([0.0, 0.0, psi]), np.zeros(3), np.zeros(3),
                           np.asarray(env.current.surface[:2], dtype=float), params, form="rich")
    tau_current = params.M @ np.asarray(nu_dot, dtype=float)
    parts = [_ro(a) for a in (tau_wind, tau_drift, tau_current)]
    return MeanLoad(wind=parts[0], drift=parts[1], current=parts[2],
                    total=_ro(tau_wind + tau_drift + tau_current))


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


# --- table rows ---------------------------------------------------------------------------

def _ro(a: Any, dtype: Any = float) -> np.ndarray:
    arr = np.array(a, dtype=dtype)
    arr.flags.writeable = False
    return arr


@dataclass(frozen=True, kw_only=True)
class Condition:
    """Operating condition of one table row.

    Attributes
    ----------
    sea_state : str
        Sea-state id of the scenario.
    sea_class : str
        One of :data:`SEA_CLASSES`.
    mode_set : str
        Key of :data:`~tapm_opt.control.pid.MODE_SETS` for the class (:data:`CLASS_MODE_SETS`).
    broken : str
        ``"intact"`` or the id of the one broken line.
    heading : float
        Vessel heading held by the heading controller [rad].
    weathervane : bool
        True if ``heading`` is the weathervane heading of the condition (asked for with
        ``headings=["weathervane"]``), where the mooring balances the yaw moment without thrust.
    """

    sea_state: str
    sea_class: str
    mode_set: str
    broken: str
    heading: float
    weathervane: bool = False

    @property
    def label(self) -> str:
        h = "weathervane" if self.weathervane else f"{math.degrees(self.heading):g}deg"
        return f"{self.sea_state}/{self.broken}/{h}"


@dataclass(frozen=True, kw_only=True, eq=False)
class PIDRow:
    """PID design of one condition (:func:`~tapm_opt.control.pid.design_gains`).

    Attributes
    ----------
    periods, damping : ndarray, shape (3,)
        Designed undamped natural periods [s] and relative damping (surge, sway, yaw).
    integral_ratio : float
        Integral pole a / w.
    Kp, Ki, Kd : ndarray, shape (3,)
        Gain diagonals [N/m, N/m, N m/rad], [N/(m s), ..., N m/(rad s)], [N s/m, ..., N m s/rad].
    designed_poles, decoupled_poles : ndarray, shape (3, 3), complex
        Row i: poles asked for DOF i, and achieved on the decoupled DOF i [1/s].
    poles, natural_periods, damping_ratios : ndarray, shape (9,)
        Coupled MIMO closed loop with all four modes (python-control), by magnitude; 2 pi/|p| [s]
        and -Re(p)/|p|.
    stable : bool
        All ``poles`` in the open left half plane.
    poles_modes : ndarray, complex
        Coupled closed loop with only the condition's mode set (what the scheduler runs).
    stable_modes : bool
    gain_margin, phase_margin, crossover, delay_margin : ndarray, shape (3,)
        Loop-at-a-time margins per DOF (see ``docs/gains.md``): gain margin [-] (ratio, inf if
        the phase never crosses -180 deg), phase margin [deg], gain-crossover frequency
        [rad/s] and delay margin phase_margin / crossover [s].
    clamped : tuple of str
        Gains that came out negative and were set to 0 (the poles are then not as designed).
    """

    periods: np.ndarray
    damping: np.ndarray
    integral_ratio: float
    Kp: np.ndarray
    Ki: np.ndarray
    Kd: np.ndarray
    designed_poles: np.ndarray
    decoupled_poles: np.ndarray
    poles: np.ndarray
    natural_periods: np.ndarray
    damping_ratios: np.ndarray
    stable: bool
    poles_modes: np.ndarray
    stable_modes: bool
    gain_margin: np.ndarray
    phase_margin: np.ndarray
    crossover: np.ndarray
    delay_margin: np.ndarray
    clamped: tuple[str, ...] = ()

    @property
    def gains(self) -> PIDGains:
        """The gains as :class:`~tapm_opt.control.pid.PIDGains` (diagonal)."""
        return PIDGains(Kp=self.Kp, Ki=self.Ki, Kd=self.Kd)


@dataclass(frozen=True, kw_only=True, eq=False)
class LQRRow:
    """LQR design of one condition: ``tau = tau_thr - K (x - x_op)``, x = (eta, nu).

    Attributes
    ----------
    Q : ndarray, shape (6,)
        State weight diagonal (1/eta_ref^2, 1/nu_ref^2).
    R : ndarray, shape (3,)
        Input weight diagonal 1/tau_ref^2.
    K : ndarray, shape (3, 6)
        State-feedback gain (``control.lqr``) [N/m, ..., N m s/rad].
    poles, natural_periods, damping_ratios : ndarray, shape (6,)
        eig(A - B K) by magnitude, 2 pi/|p| [s], -Re(p)/|p|.
    stable : bool
    """

    Q: np.ndarray
    R: np.ndarray
    K: np.ndarray
    poles: np.ndarray
    natural_periods: np.ndarray
    damping_ratios: np.ndarray
    stable: bool


@dataclass(frozen=True, kw_only=True, eq=False)
class GainRow:
    """One condition of a :class:`GainTable`.

    Attributes
    ----------
    condition : Condition
    tau_env : ndarray, shape (3,)
        Mean environmental load in {B} [N, N, N m] (``tau_wind + tau_drift + tau_current``).
    tau_wind, tau_drift, tau_current : ndarray, shape (3,)
        Its parts [N, N, N m].
    tau_thr : ndarray, shape (3,)
        Thrust at the operating point: (0, 0, N) with N the yaw moment the heading controller
        holds, ``-(N_moor + N_env)`` [N, N, N m].
    eta : ndarray, shape (3,)
        Offset equilibrium (x [m], y [m], psi [rad]) in {E}.
    M, D, K : ndarray, shape (3, 3)
        Design model at ``eta``: mass incl. added mass, damping, and the catenary stiffness seen
        by {B}-frame errors ``K = MooringModel.stiffness(eta) R(psi)`` [N/m, N/rad, N m/rad].
    A, B : ndarray, shapes (6, 6), (6, 3)
        Linearised design model, states (eta, nu), inputs tau in {B}.
    pid : PIDRow
    lqr : LQRRow
    """

    condition: Condition
    tau_env: np.ndarray
    tau_wind: np.ndarray
    tau_drift: np.ndarray
    tau_current: np.ndarray
    tau_thr: np.ndarray
    eta: np.ndarray
    M: np.ndarray
    D: np.ndarray
    K: np.ndarray
    A: np.ndarray
    B: np.ndarray
    pid: PIDRow
    lqr: LQRRow

    @property
    def offset(self) -> float:
        """Horizontal distance of the equilibrium from the field zero point [m]."""
        return float(math.hypot(self.eta[_X], self.eta[_Y]))


@dataclass(frozen=True, eq=False)
class GainTable:
    """Rows of gains per condition and the settings that made them.

    Attributes
    ----------
    rows : tuple of GainRow
    meta : dict
        JSON-serialisable: format, scenario, code version, sea-state classes, design settings,
        margin settings, units.
    """

    rows: tuple[GainRow, ...]
    meta: dict = field(default_factory=dict)

    def __len__(self) -> int:
        return len(self.rows)

    def __iter__(self):
        return iter(self.rows)

    @property
    def sea_states(self) -> tuple[str, ...]:
        return tuple(dict.fromkeys(r.condition.sea_state for r in self.rows))

    @property
    def broken(self) -> tuple[str, ...]:
        return tuple(dict.fromkeys(r.condition.broken for r in self.rows))

    @property
    def headings(self) -> tuple[float, ...]:
        return tuple(dict.fromkeys(r.condition.heading for r in self.rows))

    def find(self, sea_state: str, broken: str = "intact",
             heading: float | str = 0.0) -> GainRow:
        """The row of ``sea_state`` and ``broken`` (``"intact"`` or a line id) whose heading is
        nearest to ``heading`` [rad] (wrapped with ``ssa``); ``heading="weathervane"`` selects
        the weathervane row.

        Raises
        ------
        GainTableError
            No row for that sea state and mooring state.
        """
        cands = [r for r in self.rows
                 if r.condition.sea_state == str(sea_state) and r.condition.broken == str(broken)]
        if not cands:
            raise GainTableError(
                f"no gain-table row for sea_state={sea_state!r}, broken={broken!r}; the table "
                f"has sea states {list(self.sea_states)} and mooring states {list(self.broken)}")
        if heading == "weathervane":
            wv = [r for r in cands if r.condition.weathervane]
            if not wv:
                raise GainTableError(f"no weathervane row for sea_state={sea_state!r}, "
                                     f"broken={broken!r}; make the table with "
                                     f"headings=[..., 'weathervane']")
            return wv[0]
        try:
            h = float(heading)
        except (TypeError, ValueError):
            raise GainTableError(f"heading={heading!r} must be a heading [rad] or "
                                 f"'weathervane'") from None
        return min(cands, key=lambda r: abs(ssa(r.condition.heading - h)))

    # -- serialisation -------------------------------------------------------------------
    def to_dict(self) -> dict:
        """Plain JSON-able dict (complex as ``{"re": ..., "im": ...}``, inf/nan as strings)."""
        return {"meta": _enc(self.meta), "rows": [_dc_to_dict(r) for r in self.rows]}

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> GainTable:
        """Inverse of :meth:`to_dict`."""
        try:
            meta = _dec(data["meta"])
            if meta.get("format") != FORMAT:
                raise GainTableError(f"not a gain table: format={meta.get('format')!r}, expected "
                                     f"{FORMAT!r}")
            rows = tuple(_from(GainRow, r) for r in data["rows"])
        except (KeyError, TypeError, ValueError) as exc:
            if isinstance(exc, GainTableError):
                raise
            raise GainTableError(f"malformed gain table: {type(exc).__name__}: {exc}") from None
        return cls(rows=rows, meta=meta)


# --- JSON encoding (without the code that made it) ------------------------------------------

def _enc_float(v: float) -> float | str:
    return v if math.isfinite(v) else repr(v)  # 'inf', '-inf', 'nan'


def _enc(obj: Any) -> Any:
    if isinstance(obj, np.ndarray):
        if np.iscomplexobj(obj):
            return {"re": _enc(obj.real), "im": _enc(obj.imag)}
        return _enc(obj.tolist())
    if isinstance(obj, (bool, np.bool_)):
        return bool(obj)
    if isinstance(obj, (float, np.floating)):
        return _enc_float(float(obj))
    if isinstance(obj, (int, np.integer)):
        return int(obj)
    if isinstance(obj, Mapping):
        return {str(k): _enc(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_enc(v) for v in obj]
    return obj


def _dec(obj: Any) -> Any:
    if isinstance(obj, str) and obj in ("inf", "-inf", "nan"):
        return float(obj)
    if isinstance(obj, list):
        return [_dec(v) for v in obj]
    if isinstance(obj, dict):
        return {k: _dec(v) for k, v in obj.items()}
    return obj


def _arr(value: Any) -> np.ndarray:
    if isinstance(value, dict) and set(value) == {"re", "im"}:
        return _ro(np.asarray(_dec(value["re"]), dtype=float)
                   + 1j * np.asarray(_dec(value["im"]), dtype=float), complex)
    return _ro(np.asarray(_dec(value), dtype=float))


def _dc_to_dict(obj: Any) -> dict:
    out = {}
    for f in fields(obj):
        v = getattr(obj, f.name)
        out[f.name] = _dc_to_dict(v) if isinstance(v, (PIDRow, LQRRow, Condition)) else _enc(v)
    return out


def _from(cls: type, data: Mapping[str, Any]) -> Any:
    kw = {}
    for f in fields(cls):
        v = data[f.name]
        if f.type == "bool":
            kw[f.name] = bool(v)
        elif f.type == "str":
            kw[f.name] = str(v)
        elif f.type == "float":
            kw[f.name] = float(_dec(v))
        elif f.type.startswith("tuple"):
            kw[f.name] = tuple(str(s) for s in v)
        elif f.type == "Condition":
            kw[f.name] = _from(Condition, v)
        elif f.type == "PIDRow":
            kw[f.name] = _from(PIDRow, v)
        elif f.type == "LQRRow":
            kw[f.name] = _from(LQRRow, v)
        else:
            kw[f.name] = _arr(v)
    return cls(**kw)


# --- design of one condition ----------------------------------------------------------------

def _offset_equilibrium(moor: MooringModel, tau_env: np.ndarray, psi: float) -> np.ndarray:
    """(x, y) where the mooring balances the horizontal load at heading psi (held), by Powell's
    method with the exact stiffness; load continuation if the direct solve fails."""
    scale = max(float(np.max(np.abs(tau_env[:2]))), 1.0e3)

    def solve(load, guess):
        def f(xy):
            return (moor.force(np.r_[xy, psi])[:2] + load[:2]) / scale

        def jac(xy):
            return -moor.stiffness(np.r_[xy, psi])[:2, :2] / scale

        try:
            sol = scipy.optimize.root(f, guess, jac=jac, method="hybr")
            ok = bool(np.all(np.isfinite(sol.x))) and float(np.max(np.abs(f(sol.x)))) <= 1e-9
        except TapmError:
            return None
        return np.array(sol.x) if ok else None

    xy = solve(tau_env, np.zeros(2))
    if xy is None:  # continuation in the load from the unloaded equilibrium
        xy = np.zeros(2)
        for s in np.linspace(0.0, 1.0, 11):
            xy = solve(s * tau_env, xy)
            if xy is None:
                break
    if xy is None:
        raise GainTableError(
            f"no mooring equilibrium for the mean load {tau_env[:2].tolist()} N at heading "
            f"{math.degrees(psi):g} deg with lines {list(moor.line_ids)}: the catenary cannot "
            f"hold it (reduce the sea state or choose another heading)")
    return np.r_[xy, psi]


def _sorted_damp(A: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    sys = control.ss(A, np.zeros((A.shape[0], 1)), np.eye(A.shape[0]), 0.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        wn, zeta, poles = control.damp(sys, doprint=False)
    order = np.lexsort((poles.imag, np.abs(poles)))
    wn, zeta, poles = wn[order], zeta[order], poles[order]
    with np.errstate(divide="ignore"):
        periods = np.where(wn > 0.0, 2.0 * np.pi / np.where(wn > 0.0, wn, 1.0), np.inf)
    return poles, periods, zeta


def _loop_lag(thrust_time_constant: float, estimator_cutoff: float | None) -> Any:
    lag = control.tf([1.0], [1.0])
    if thrust_time_constant > 0.0:
        lag = lag * control.tf([1.0], [thrust_time_constant, 1.0])
    if estimator_cutoff is not None:
        wc = estimator_cutoff
        lag = lag * control.tf([wc**2], [1.0, 2.0 * wc, wc**2])
    return lag


def _margins(plant: control.StateSpace, gains: PIDGains, lag: Any) -> tuple[np.ndarray, ...]:
    """Loop-at-a-time margins: loop i broken at the plant input, the other two closed (coupled
    model, all four modes), times the loop lag."""
    cl = closed_loop(plant, gains, MODES)
    out = np.zeros((4, 3))
    for i in range(3):
        T = cl[3 + i, i]  # load added at input i -> command i, all loops closed
        L = -control.feedback(T, 1.0) * lag  # T = -L/(1+L)  <=>  L = -T/(1+T)
        gm, pm, _, _, wgc, _ = control.stability_margins(L)
        gm, pm, wgc = float(gm), float(pm), float(wgc)
        if gm > _GM_INF:  # the phase reaches -180 deg only asymptotically (round-off crossing)
            gm = math.inf
        dm = math.radians(pm) / wgc if (math.isfinite(wgc) and wgc > 0.0) else math.inf
        out[:, i] = gm, pm, wgc, dm
    return tuple(_ro(r) for r in out)


_GM_INF = 1.0e6  # gain margins above this are reported as inf


def _thrust_capacity(scenario: Any) -> np.ndarray:
    th = scenario.thrusters
    fmax = np.array([t.max_thrust for t in th], dtype=float)
    arm = np.array([math.hypot(t.position[0], t.position[1]) for t in th], dtype=float)
    return np.array([fmax.sum(), fmax.sum(), float(np.sum(fmax * arm))])


def _design_condition(scenario: Any, params: VesselParams, cond: Condition, load: MeanLoad, *,
                      periods: np.ndarray, damping: np.ndarray, integral_ratio: float,
                      lqr: LQRWeights, lag: Any, D_moor: Any) -> GainRow:
    broken = () if cond.broken == "intact" else (cond.broken,)
    moor = MooringModel.from_scenario(scenario, broken=broken)
    tau_env = load.total
    eta = _offset_equilibrium(moor, tau_env, cond.heading)
    tau_thr = np.array([0.0, 0.0, -(moor.force(eta)[_PSI] + tau_env[_PSI])])
    fn = moored_function(params, moor.force_function("catenary", eta0=eta), D_moor=D_moor)
    plant = linearise(fn, np.r_[eta, np.zeros(3)], tau_thr0=tau_thr, tau_env0=tau_env,
                      outputs="state")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", GainClampWarning)  # reported in PIDRow.clamped
        d = design_gains(plant, periods=periods, damping=damping, integral_ratio=integral_ratio)
    gm, pm, wgc, dm = _margins(plant, d.gains, lag)
    cl_modes = closed_loop(plant, d.gains, cond.mode_set)
    p_modes = np.asarray(cl_modes.poles(), dtype=complex)
    p_modes = p_modes[np.lexsort((p_modes.imag, np.abs(p_modes)))]
    pid = PIDRow(
        periods=_ro(d.periods), damping=_ro(d.damping), integral_ratio=float(d.integral_ratio),
        Kp=_ro(np.diag(d.gains.Kp)), Ki=_ro(np.diag(d.gains.Ki)), Kd=_ro(np.diag(d.gains.Kd)),
        designed_poles=_ro(d.designed_poles, complex), decoupled_poles=_ro(d.decoupled_poles, complex),
        poles=_ro(d.poles, complex), natural_periods=_ro(d.natural_periods),
        damping_ratios=_ro(d.damping_ratios), stable=d.stable, poles_modes=_ro(p_modes, complex),
        stable_modes=bool(np.all(p_modes.real < 0.0)), gain_margin=gm, phase_margin=pm,
        crossover=wgc, delay_margin=dm, clamped=tuple(d.clamped))

    A, B = np.asarray(plant.A, dtype=float), np.asarray(plant.B, dtype=float)
    tau_ref = lqr.tau_ref
    if tau_ref is None:
        if not scenario.thrusters:
            raise GainTableError("the scenario has no thrusters: give LQRWeights(tau_ref=...)")
        tau_ref = lqr.tau_share * _thrust_capacity(scenario)
    Q = 1.0 / np.r_[lqr.eta_ref, lqr.nu_ref] ** 2
    R = 1.0 / np.asarray(tau_ref) ** 2
    K_lqr, _, _ = control.lqr(A, B, np.diag(Q), np.diag(R))
    K_lqr = np.asarray(K_lqr, dtype=float)
    lp, lT, lz = _sorted_damp(A - B @ K_lqr)
    lqr_row = LQRRow(Q=_ro(Q), R=_ro(R), K=_ro(K_lqr), poles=_ro(lp, complex),
                     natural_periods=_ro(lT), damping_ratios=_ro(lz),
                     stable=bool(np.all(lp.real < 0.0)))
    return GainRow(condition=cond, tau_env=_ro(tau_env), tau_wind=load.wind, tau_drift=load.drift,
                   tau_current=load.current, tau_thr=_ro(tau_thr), eta=_ro(eta), M=_ro(d.M),
                   D=_ro(d.D), K=_ro(d.K), A=_ro(A), B=_ro(B), pid=pid, lqr=lqr_row)


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
    try:
        r = float(v)
    except (TypeError, ValueError):
        raise GainTableError(f"integral_ratio={v!r} must be a number >= 0") from None
    if not (math.isfinite(r) and r >= 0.0):
        raise GainTableError(f"integral_ratio={v!r} must be finite and >= 0")
    return r


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
               estimator_cutoff: float | None = ESTIMATOR_CUTOFF) -> GainTable:
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
        loops; default :data:`ESTIMATOR_CUTOFF`, that of
        :class:`~tapm_opt.estimation.lowpass.LowPassEstimator` (2 pi / 40 s); None: no filter
        (an ideal PID on the moored vessel then usually has an infinite gain margin).

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
    lag = _loop_lag(T_thr, None if estimator_cutoff is None else float(estimator_cutoff))

    params = VesselParams.from_scenario(scenario)
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
                rows.append(_design_condition(
                    scenario, params, cond, loads[psi], periods=per_T[cls], damping=per_z[cls],
                    integral_ratio=per_r[cls], lqr=per_q[cls], lag=lag, D_moor=D_moor))
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


# --- files ----------------------------------------------------------------------------------

_CSV_COLUMNS = (
    "sea_state", "class", "mode_set", "broken", "heading_deg", "weathervane", "x_m", "y_m", "psi_deg",
    "offset_m", "X_env_N", "Y_env_N", "N_env_Nm", "N_thr_Nm", "K11_N_per_m", "K22_N_per_m",
    "K33_Nm_per_rad", "T_surge_s", "T_sway_s", "T_yaw_s", "zeta_surge", "zeta_sway", "zeta_yaw",
    "Kp_x", "Kp_y", "Kp_psi", "Ki_x", "Ki_y", "Ki_psi", "Kd_x", "Kd_y", "Kd_psi",
    "cl_min_damping", "cl_max_period_s", "stable", "stable_modes",
    "gm_surge", "gm_sway", "gm_yaw", "pm_surge_deg", "pm_sway_deg", "pm_yaw_deg",
    "dm_surge_s", "dm_sway_s", "dm_yaw_s", "clamped",
    "lqr_min_damping", "lqr_max_period_s", "lqr_stable")


def _longest(T: np.ndarray) -> float:
    """Longest finite natural period [s] (inf if none)."""
    fin = T[np.isfinite(T)]
    return float(np.max(fin)) if fin.size else math.inf


def _csv_row(r: GainRow) -> list[Any]:
    c, p, q = r.condition, r.pid, r.lqr
    return [c.sea_state, c.sea_class, c.mode_set, c.broken, math.degrees(c.heading),
            int(c.weathervane),
            float(r.eta[0]), float(r.eta[1]), math.degrees(r.eta[2]), r.offset,
            *map(float, r.tau_env), float(r.tau_thr[2]), *map(float, np.diag(r.K)),
            *map(float, p.periods), *map(float, p.damping), *map(float, p.Kp), *map(float, p.Ki),
            *map(float, p.Kd), float(np.min(p.damping_ratios)), _longest(p.natural_periods),
            int(p.stable), int(p.stable_modes), *map(float, p.gain_margin),
            *map(float, p.phase_margin), *map(float, p.delay_margin), len(p.clamped),
            float(np.min(q.damping_ratios)), _longest(q.natural_periods), int(q.stable)]


def _fmt_cutoff(wc: float | None) -> str:
    return "none" if wc is None else f"{wc:.4g} rad/s (2π/{2 * math.pi / wc:.3g} s)"


def _md(table: GainTable) -> str:
    m = table.meta
    lines = [f"# Gain table — {m.get('scenario', '?')}", "",
             f"tapm_opt {m.get('tapm_opt_version', '?')}, environment seed {m.get('seed')}. "
             "Guide: docs/gains.md. Full numbers: gains.json (gains.csv: one line per row).", "",
             "Sea-state classes and mode sets ([S] Table 3): "
             + ", ".join(f"{s} → {c} ({m['mode_sets'][c]['name']})"
                         for s, c in m.get("sea_state_classes", {}).items()) + ".", "",
             f"Margins: {m['margins']['method']}; thrust lag "
             f"{m['margins']['thrust_time_constant_s']:g} s, estimator cut-off "
             f"{_fmt_cutoff(m['margins']['estimator_cutoff_rad_s'])}.", "",
             "ψ: heading held, (wv) = weathervane heading; N_thr: yaw moment the heading "
             "controller holds there; PM/GM/DM per DOF surge/sway/yaw; DM = delay margin.", "",
             "| sea state | broken | ψ [°] | x, y [m] | N_thr [MN m] | K11, K22 [kN/m] | "
             "T_n [s] | ζ | Kp x, y [kN/m] | PM [°] s/s/y | GM s/s/y | DM [s] min | PID | LQR ζ min |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in table.rows:
        c, p = r.condition, r.pid
        ok = ("stable" if p.stable else "UNSTABLE") + (f", {len(p.clamped)} clamped" if p.clamped else "")
        lines.append(
            f"| {c.sea_state} ({c.sea_class}) | {c.broken} | {math.degrees(c.heading):.1f}"
            f"{' (wv)' if c.weathervane else ''} | "
            f"{r.eta[0]:.1f}, {r.eta[1]:.1f} | {r.tau_thr[2] / 1e6:.1f} | "
            f"{r.K[0, 0] / 1e3:.1f}, {r.K[1, 1] / 1e3:.1f} | "
            f"{'/'.join(f'{t:g}' for t in p.periods)} | {'/'.join(f'{z:g}' for z in p.damping)} | "
            f"{p.Kp[0] / 1e3:.0f}, {p.Kp[1] / 1e3:.0f} | "
            f"{'/'.join(f'{v:.0f}' for v in p.phase_margin)} | "
            f"{'/'.join(f'{v:.2f}' for v in p.gain_margin)} | {float(np.min(p.delay_margin)):.1f} | "
            f"{ok} | {float(np.min(r.lqr.damping_ratios)):.2f} |")
    return "\n".join(lines) + "\n"


def write_gain_tables(table: GainTable, out_dir: str | Path) -> list[Path]:
    """Write ``gains.json`` (everything), ``gains.csv`` (one line per row) and ``gains.md``
    (summary) into ``out_dir`` (created), each atomically.

    Returns
    -------
    list of Path
        The three files, in the order json, csv, md.
    """
    if not isinstance(table, GainTable):
        raise GainTableError(f"table must be a GainTable, got {type(table).__name__}")
    out = Path(out_dir)
    text_json = json.dumps(table.to_dict(), indent=1, allow_nan=False) + "\n"
    units = ("units: m, rad shown in deg where named _deg, N, N m; K = catenary stiffness seen by "
             "{B} errors; T/zeta designed; gm ratio, pm deg, dm s (loop-at-a-time with lag)")
    text_csv = csv_text(_CSV_COLUMNS, (_csv_row(r) for r in table.rows),
                        comments=[f"gain table {FORMAT}, scenario {table.meta.get('scenario')}",
                                  units])
    return [atomic_write_text(out / "gains.json", text_json),
            atomic_write_text(out / "gains.csv", text_csv),
            atomic_write_text(out / "gains.md", _md(table))]


def load_gain_table(path: str | Path) -> GainTable:
    """Read a gain table from ``gains.json`` (or a folder holding it).

    Raises
    ------
    GainTableError
        Missing or unreadable file, or not a gain table.
    """
    p = Path(path)
    if p.is_dir():
        p = p / "gains.json"
    try:
        data = json.loads(p.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise GainTableError(f"no gain table at {p}") from None
    except (OSError, json.JSONDecodeError) as exc:
        raise GainTableError(f"cannot read the gain table {p}: {exc}") from None
    if not isinstance(data, dict):
        raise GainTableError(f"{p} does not hold a gain table (a JSON object)")
    return GainTable.from_dict(data)
