"""Sea-state supervisor and the controllers it switches ([S] §4.5, Fig. 9, Tables 2–3).

[S] §4.5 (after Nguyen and Sørensen): a supervisor "automatically determines the current sea
state, based on monitoring of the wave peak frequency and the mean environmental load", and a
hysteresis switching logic selects the controller of that sea state. This module has the three
parts of that loop:

:class:`SeaStateSupervisor`
    estimates three features on-line from the :class:`~tapm_opt.interfaces.Estimate`, over a
    trailing window (default 600 s):

    * ``amplitude`` A_s [m]: significant amplitude of the wave-frequency (WF) motion,
      ``2 sqrt(m0)`` with ``m0`` the mean of ``x_f^2 + y_f^2``, where (x_f, y_f) is
      ``estimate.eta_wf[:2]`` (the estimator's WF motion in {E}) band-passed to the wave band
      (default periods 5–40 s: 4th-order Butterworth high-pass at 40 s, 2nd-order low-pass at
      5 s; the high-pass removes the LF motion the estimator's low-pass leaves in ``eta_wf``,
      the low-pass part of the sensor noise). For a sinusoid of amplitude a on one axis
      A_s = sqrt(2) a; for a Gaussian sea it is the mean of the highest third of the amplitudes.
    * ``period`` T_z [s]: mean zero-up-crossing period of that motion, from the spectral moments
      (Rice): ``omega_z = sqrt(m2/m0)``, with ``m2`` the mean of the squared finite-difference
      rate; the finite difference is inverted exactly for a sinusoid,
      ``omega_z = (2/dt) asin((dt/2) sqrt(m2/m0))``, so a sinusoid reads its own period at any
      ``dt`` below half its period.
    * ``load`` L [N]: mean magnitude of the estimated slowly varying environmental load
      ``|estimate.tau_env[:2]|`` (wind + drift + current, from the estimator's load balance).

    Each sample costs O(1) (recursive filters, running sums over the window). The features are
    compared with the **expected** features of each of the scenario's sea states (below) at the
    window's mean heading, in the normalised space ``z_j = ln(f_j) / s_j`` (``scales`` s_j:
    0.15 for the amplitude, 0.10 for the period, 0.15 for the load, i.e. about the relative
    error one may accept in each), and the nearest sea state is the candidate. Switching has
    hysteresis: the candidate replaces the active sea state only when its distance is smaller
    by ``margin`` (default 1.0 normalised unit) and at least ``dwell`` (default 300 s) has passed
    since the last switch. Until ``warm_up`` (default the filter settling time 80 s plus the
    window) the initial sea state holds; the first decision is a plain nearest choice. Every
    switch is an event ``{"t", "event": "sea state", "from", "to", "features", ...}``.

:class:`SupervisedController`
    a :class:`~tapm_opt.interfaces.Controller` that feeds the supervisor and switches either a
    :class:`~tapm_opt.control.scheduled.GainScheduledPID` (``select`` the row of the detected
    sea state, the reported broken line and the heading) or a plain
    :class:`~tapm_opt.control.pid.TAPMPID` (``set_modes`` to the mode set of the detected sea
    state's class, [S] Table 3: calm -> heading; normal -> heading + damping + restoring;
    extreme -> heading + damping + restoring + mean; ``control.pid.CLASS_MODE_SETS``).

The supervisor takes its references (the expected features of each sea state) as arguments.
Computing them runs the plant's wave and load models, which is design-time work:
:func:`tapm_opt.design.supervisor.sea_state_supervisor` builds a supervisor for a scenario and
:func:`tapm_opt.design.supervisor.supervised_pid` either form of the controller for a system.

**Expected features** (:func:`~tapm_opt.design.supervisor.sea_state_supervisor`) come from the
models the plant uses, not from fitted numbers:

* WF motion: the plant's first-order wave model
  (:meth:`tapm_opt.plant.environment.WaveField.eta_wf`, seed ``seed``) sampled at ``dt`` over
  ``reference_duration`` (1 h) at the two headings where the waves are head-on (beta = 0: the
  hull's surge response S_0(t)) and abeam (beta = pi/2: its sway response S_1(t)); each is
  passed through the complement of the estimator's low-pass (``eta_wf`` = measured - filtered
  pose of :class:`~tapm_opt.estimation.lowpass.LowPassEstimator`, cut-off
  ``estimator_cutoff``: :func:`~tapm_opt.estimation.lowpass.estimator_complement`) and the supervisor's band-pass, and its moments m0, m2 are taken. At
  heading psi (beta = wave direction - psi) the plant's WF motion in {E} is
  ``R(psi) (cos(beta) S_0, sin(beta) S_1)``, so ``x^2 + y^2 = cos^2(beta) S_0^2 +
  sin^2(beta) S_1^2`` exactly and ``m_k(psi) = cos^2(beta) m_k,0 + sin^2(beta) m_k,1``; the
  GNSS noise (``scenario.sensors.gnss_std``, white at the sample rate) through the same filters
  adds ``2 sigma^2 sum h_n^2`` to m0 (and the like to m2). On the fpso (0.5 m GNSS noise) the
  WF motion of the calm and normal sea states (head seas: 1–20 cm of significant amplitude, the
  surge response of a 305 m hull is small at those wave periods) is below the noise, so there
  the load tells them apart; from the storm up the WF motion stands out. An observer's ``eta_wf``
  (``estimator_cutoff=None``) is its estimate of the WF motion, which filters the GNSS noise out:
  the noise term is then left out (``gnss_std`` defaults to 0). In fpso closed loop with the EKF
  the measured amplitude is 0.71 m against 0.77 m expected in the storm (it would be 1.14 m with
  the noise term), 0.31 against 0.22 m in the normal sea.
* load: ``|tau_xy|`` of :func:`tapm_opt.design.loads.mean_environmental_load` (mean wind at the
  mean speed, Newman mean drift, current on the hull at rest) at the heading, cached per
  ``heading_step`` (5°).

``[S]`` = seed survey-tapm-modeling-and-control.

Size: one module on purpose — the three parts of the supervisor's loop (features, the switching
logic, the switched controller) share the sea-state classes and the hysteresis state.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass
from types import MappingProxyType
from typing import Any, Callable, Mapping, Sequence

import numpy as np

from .._checks import finite, vector
from ..geometry import ssa
from ..interfaces import ControllerStep, Estimate, FaultAware, Setpoint
from .pid import CLASS_MODE_SETS, MODE_SETS, SEA_CLASSES, ControlError, TAPMPID, _resolve_modes
from .scheduled import GainScheduledPID

__all__ = [
    "SupervisorError",
    "FEATURES",
    "DEFAULT_SCALES",
    "DEFAULT_BAND",
    "SeaStateFeatures",
    "SeaStateReference",
    "WaveMotionStatistics",
    "wave_band_sos",
    "spectral_features",
    "SeaStateSupervisor",
    "SupervisedController",
    "class_mode_sets",
]

#: The supervisor's features, in the order of :class:`SeaStateFeatures`.
FEATURES: tuple[str, ...] = ("amplitude", "period", "load")
#: Scale s_j of ln(feature) in the distance (about the relative error accepted in each): the
#: estimated features of the fpso closed-loop runs are within 7 % (amplitude), 5 % (period) and
#: 10 % (load) of the expected ones, and adjacent fpso sea states are 6–7 scale units apart
#: (docs: "Sea-state supervisor").
DEFAULT_SCALES: Mapping[str, float] = MappingProxyType({"amplitude": 0.15, "period": 0.10, "load": 0.15})
#: Wave band of the WF-motion filters (shortest, longest period) [s].
DEFAULT_BAND: tuple[float, float] = (5.0, 40.0)
#: Floors of the features before the logarithm (amplitude [m], period [s], load [N]).
_FLOORS = {"amplitude": 1e-3, "period": 1e-3, "load": 1e3}
_HP_ORDER, _LP_ORDER = 4, 2


class SupervisorError(ControlError):
    """Bad supervisor settings or an estimate the supervisor cannot use (names field and value)."""


# --- small checks ---------------------------------------------------------------------------

def _pos(name: str, value: Any, *, allow_zero: bool = False) -> float:
    return finite(name, value, lo=0.0, strict=not allow_zero, error=SupervisorError)


def _finite_vec(name: str, value: Any, n: int) -> np.ndarray:
    return vector(name, value, n, error=SupervisorError)


# --- features -------------------------------------------------------------------------------

@dataclass(frozen=True)
class SeaStateFeatures:
    """The supervisor's features of a sea state (measured or expected).

    Attributes
    ----------
    amplitude : float
        Significant amplitude of the band-passed WF motion, 2 sqrt(m0) [m].
    period : float
        Mean zero-up-crossing period of that motion [s].
    load : float
        Mean |tau_env,xy| [N].
    """

    amplitude: float
    period: float
    load: float

    def as_dict(self) -> dict:
        """JSON-ready ``{"amplitude_m", "period_s", "load_N"}``."""
        return {"amplitude_m": float(self.amplitude), "period_s": float(self.period),
                "load_N": float(self.load)}

    def get(self, name: str) -> float:
        return float(getattr(self, name))


def spectral_features(m0: float, m2: float, dt: float) -> tuple[float, float]:
    """(significant amplitude 2 sqrt(m0) [m], mean zero-up-crossing period [s]) from the mean
    squared motion ``m0`` [m^2] and the mean squared finite-difference rate ``m2`` [m^2/s^2] of
    samples ``dt`` [s] apart; the rate is inverted exactly for a sinusoid (module docstring).
    A zero signal has period nan."""
    if not (m0 > 0.0 and m2 > 0.0):
        return 2.0 * math.sqrt(max(m0, 0.0)), math.nan
    s = min(1.0, 0.5 * dt * math.sqrt(m2 / m0))
    return 2.0 * math.sqrt(m0), 2.0 * math.pi / ((2.0 / dt) * math.asin(s))


def wave_band_sos(dt: float, band: tuple[float, float] | None = DEFAULT_BAND) -> np.ndarray:
    """Second-order sections of the supervisor's wave-band filter at sample period ``dt`` [s]:
    a 4th-order Butterworth high-pass at ``1/band[1]`` Hz and a 2nd-order Butterworth low-pass at
    ``1/band[0]`` Hz (bilinear, ``scipy.signal.butter``); ``band=None``: no filter (shape (0, 6)).

    Raises
    ------
    SupervisorError
        A band that is not 0 < short < long period, or a short period below 2.5 dt (too close to
        the Nyquist period 2 dt).
    """
    import scipy.signal

    dt = _pos("dt", dt)
    if band is None:
        return np.zeros((0, 6))
    try:
        lo, hi = (float(b) for b in band)
    except (TypeError, ValueError):
        raise SupervisorError(f"band = {band!r} must be (shortest, longest) wave period [s] or None") from None
    if not (math.isfinite(lo) and math.isfinite(hi) and 0.0 < lo < hi):
        raise SupervisorError(f"band = {band!r} must be (shortest, longest) period [s] with 0 < shortest < longest")
    if lo < 2.5 * dt:
        raise SupervisorError(f"band[0] = {lo:g} s is too short for dt = {dt:g} s: it must be at least 2.5 dt "
                              f"(the Nyquist period is 2 dt)")
    fs = 1.0 / dt
    hp = scipy.signal.butter(_HP_ORDER, 1.0 / hi, "highpass", fs=fs, output="sos")
    lp = scipy.signal.butter(_LP_ORDER, 1.0 / lo, "lowpass", fs=fs, output="sos")
    return np.vstack([hp, lp])


class _SOS2:
    """Two channels through the same second-order sections (transposed direct form II, as
    ``scipy.signal.sosfilt``), one sample at a time in plain floats."""

    def __init__(self, sos: np.ndarray):
        self._c = [tuple(float(v) for v in row) for row in sos]
        self.reset()

    def reset(self) -> None:
        self._z = [[0.0, 0.0, 0.0, 0.0] for _ in self._c]  # z1, z2 of channel x; z1, z2 of y

    def __call__(self, x: float, y: float) -> tuple[float, float]:
        for (b0, b1, b2, _a0, a1, a2), z in zip(self._c, self._z):
            ox = b0 * x + z[0]
            z[0] = b1 * x - a1 * ox + z[1]
            z[1] = b2 * x - a2 * ox
            oy = b0 * y + z[2]
            z[2] = b1 * y - a1 * oy + z[3]
            z[3] = b2 * y - a2 * oy
            x, y = ox, oy
        return x, y


class _Window:
    """Trailing-window means of a few channels over ``length`` seconds: O(1) amortised per
    sample (running sums, recomputed exactly once per window turnover against round-off)."""

    def __init__(self, length: float, n: int):
        self.length, self.n = float(length), int(n)
        self.reset()

    def reset(self) -> None:
        self._q: deque = deque()
        self._sum = [0.0] * self.n
        self._pops = 0

    def push(self, t: float, values: Sequence[float]) -> None:
        self._q.append((t, tuple(values)))
        for i, v in enumerate(values):
            self._sum[i] += v
        while self._q and self._q[0][0] <= t - self.length:
            _, old = self._q.popleft()
            for i, v in enumerate(old):
                self._sum[i] -= v
            self._pops += 1
        if self._pops >= len(self._q):
            self._pops = 0
            self._sum = [math.fsum(s[1][i] for s in self._q) for i in range(self.n)]

    def __len__(self) -> int:
        return len(self._q)

    def mean(self) -> list[float]:
        k = len(self._q)
        return [s / k for s in self._sum] if k else [math.nan] * self.n


class WaveMotionStatistics:
    """On-line significant amplitude and mean zero-up-crossing period of a 2-D motion (x, y).

    Each sample passes through the wave-band filter (:func:`wave_band_sos`); the trailing window
    (``window`` [s]) holds ``x_f^2 + y_f^2`` and ``((x_f - x_f,prev)^2 + (y_f - y_f,prev)^2) /
    dt^2``; :func:`spectral_features` of their means gives the amplitude and period. Samples of
    the first ``settle`` seconds (the filter transient, default twice the longest band period)
    are not used. O(1) per sample.

    Parameters
    ----------
    dt : float
        Sample period [s]; samples must come ``dt`` apart (within 1 %).
    window : float
        Trailing window [s].
    band : (float, float) or None
        Wave band (shortest, longest period) [s]; None: no filter.
    settle : float, optional
        Filter settling time [s] (default ``2 band[1]``, 0 without a band).
    """

    def __init__(self, dt: float = 1.0, window: float = 600.0, band: tuple[float, float] | None = DEFAULT_BAND,
                 settle: float | None = None):
        self.dt = _pos("dt", dt)
        self.window = _pos("window", window)
        if self.window < 10.0 * self.dt:
            raise SupervisorError(f"window = {window!r} s must be at least 10 dt = {10 * self.dt:g} s")
        self.sos = wave_band_sos(self.dt, band)
        self.band = None if band is None else (float(band[0]), float(band[1]))
        self.settle = (0.0 if band is None else 2.0 * self.band[1]) if settle is None else _pos(
            "settle", settle, allow_zero=True)
        self._filter = _SOS2(self.sos)
        self._win = _Window(self.window, 2)
        self.reset()

    def reset(self) -> None:
        self._filter.reset()
        self._win.reset()
        self._t0: float | None = None
        self._t: float | None = None
        self._prev: tuple[float, float] | None = None

    def update(self, t: float, x: float, y: float) -> None:
        """Feed the motion (x [m], y [m]) at time t [s].

        Raises
        ------
        SupervisorError
            Non-finite input, time running backwards, or a sample interval other than ``dt``.
        """
        if not (math.isfinite(t) and math.isfinite(x) and math.isfinite(y)):
            raise SupervisorError(f"wave motion sample t = {t!r}, x = {x!r}, y = {y!r} must be finite")
        if self._t is not None:
            step = t - self._t
            if step < 0.0:
                raise SupervisorError(f"t = {t!r} s is before the previous sample at {self._t!r} s")
            if step == 0.0:
                return
            if abs(step - self.dt) > 0.01 * self.dt:
                raise SupervisorError(f"sample interval {step:g} s (t = {t:g} s) is not dt = {self.dt:g} s: feed "
                                      f"the supervisor every dt (give dt = the controller's update period)")
        else:
            self._t0 = t
        self._t = t
        xf, yf = self._filter(x, y)
        prev, self._prev = self._prev, (xf, yf)
        if prev is None or t - self._t0 < self.settle:
            return
        rate2 = ((xf - prev[0]) ** 2 + (yf - prev[1]) ** 2) / (self.dt * self.dt)
        self._win.push(t, (xf * xf + yf * yf, rate2))

    @property
    def samples(self) -> int:
        """Samples in the window."""
        return len(self._win)

    @property
    def moments(self) -> tuple[float, float]:
        """(m0 [m^2], m2 [m^2/s^2]) of the window (nan before the first usable sample)."""
        m0, m2 = self._win.mean()
        return m0, m2

    @property
    def features(self) -> tuple[float, float]:
        """(significant amplitude 2 sqrt(m0) [m], mean zero-up-crossing period [s]) of the window,
        from one evaluation of its moments (nan before the first usable sample)."""
        m0, m2 = self.moments
        return (math.nan, math.nan) if math.isnan(m0) else spectral_features(m0, m2, self.dt)

    @property
    def amplitude(self) -> float:
        """Significant amplitude 2 sqrt(m0) [m] (nan before the first usable sample)."""
        return self.features[0]

    @property
    def period(self) -> float:
        """Mean zero-up-crossing period [s] (nan before the first usable sample)."""
        return self.features[1]


# --- references: the expected features of each sea state ------------------------------------

@dataclass(frozen=True, eq=False)
class SeaStateReference:
    """A sea state the supervisor can choose, with its expected features.

    Attributes
    ----------
    sea_state : str
        Sea-state id.
    sea_class : str
        Its class (``"calm"``, ``"normal"``, ``"extreme"``), which picks the mode set.
    expected : callable
        ``expected(psi) -> SeaStateFeatures``: the features expected at heading psi [rad].
    info : dict
        JSON-ready description of where the expectation comes from (model numbers).
    """

    sea_state: str
    sea_class: str
    expected: Callable[[float], SeaStateFeatures]
    info: Mapping[str, Any] | None = None

    @classmethod
    def constant(cls, sea_state: str, sea_class: str, *, amplitude: float, period: float,
                 load: float) -> SeaStateReference:
        """A reference with heading-independent expected features (amplitude [m], period [s],
        load [N], each > 0)."""
        f = SeaStateFeatures(_pos("amplitude", amplitude), _pos("period", period), _pos("load", load))
        return cls(sea_state=str(sea_state), sea_class=str(sea_class), expected=lambda psi: f,
                   info={"kind": "constant", **f.as_dict()})


# --- the supervisor -------------------------------------------------------------------------

class SeaStateSupervisor:
    """On-line sea-state detection with hysteresis switching ([S] §4.5, Fig. 9; module
    docstring).

    Parameters
    ----------
    references : sequence of SeaStateReference
        The sea states to choose from (unique ids), with their expected features;
        :func:`tapm_opt.design.supervisor.sea_state_supervisor` builds them from a scenario's
        models.
    dt : float
        Sample period [s]: :meth:`update` must be called every ``dt`` (the controller's period;
        the runner's control period, 1 s by default).
    window : float
        Trailing window of the features [s] (default 600 s: some 40–80 wave periods).
    band : (float, float) or None
        Wave band of the WF-motion filter (shortest, longest period) [s]; None: unfiltered.
    warm_up : float, optional
        Time after the first sample before the first decision [s]; default the filter settling
        time plus ``window``.
    dwell : float
        Minimum time between two switches [s].
    margin : float
        Hysteresis margin in normalised distance units: a candidate must be nearer than the
        active sea state by this much.
    scales : mapping, optional
        ``{feature: s_j}``: scale of ln(feature) in the distance (default :data:`DEFAULT_SCALES`).
    features : sequence of str
        Features used (subset of :data:`FEATURES`); e.g. ``("load",)`` for an estimator that
        gives no ``eta_wf`` (the plant's truth).
    initial : str, optional
        Sea state before the first decision (default the first reference).
    heading_step : float
        Heading bin [rad] of the cached expected features (default 5°).

    Raises
    ------
    SupervisorError
        Bad settings (the message names the field and the value).
    """

    def __init__(self, references: Sequence[SeaStateReference], *, dt: float = 1.0, window: float = 600.0,
                 band: tuple[float, float] | None = DEFAULT_BAND, warm_up: float | None = None,
                 dwell: float = 300.0, margin: float = 1.0, scales: Mapping[str, float] | None = None,
                 features: Sequence[str] = FEATURES, initial: str | None = None,
                 heading_step: float = math.radians(5.0)):
        refs = tuple(references) if not isinstance(references, SeaStateReference) else (references,)
        if not refs:
            raise SupervisorError("references is empty: give at least one sea state")
        for i, r in enumerate(refs):
            if not isinstance(r, SeaStateReference):
                raise SupervisorError(f"references[{i}] = {r!r} must be a SeaStateReference")
        ids = [r.sea_state for r in refs]
        dup = sorted({s for s in ids if ids.count(s) > 1})
        if dup:
            raise SupervisorError(f"references has duplicate sea state(s) {dup}")
        self.references = refs
        self._ref = {r.sea_state: r for r in refs}
        if isinstance(features, str):
            features = (features,)
        feats = tuple(features)
        bad = [f for f in feats if f not in FEATURES]
        if bad or not feats:
            raise SupervisorError(f"features = {list(feats)!r} must be a non-empty subset of {list(FEATURES)}")
        self.used_features = tuple(f for f in FEATURES if f in feats)
        self._use_wf = "amplitude" in self.used_features or "period" in self.used_features
        sc = dict(DEFAULT_SCALES)
        if scales is not None:
            if not isinstance(scales, Mapping):
                raise SupervisorError(f"scales = {scales!r} must be a mapping feature -> scale")
            unknown = sorted(set(scales) - set(FEATURES))
            if unknown:
                raise SupervisorError(f"scales has unknown feature(s) {unknown}; features are {list(FEATURES)}")
            for k, v in scales.items():
                sc[k] = _pos(f"scales[{k!r}]", v)
        self.scales = sc
        self.wave = WaveMotionStatistics(dt=dt, window=window, band=band)
        self.dt, self.window, self.band = self.wave.dt, self.wave.window, self.wave.band
        self.settle = self.wave.settle
        self.warm_up = self.settle + self.window if warm_up is None else _pos("warm_up", warm_up, allow_zero=True)
        self.dwell = _pos("dwell", dwell, allow_zero=True)
        self.margin = _pos("margin", margin, allow_zero=True)
        self.heading_step = _pos("heading_step", heading_step)
        if initial is None:
            initial = ids[0]
        if initial not in self._ref:
            raise SupervisorError(f"initial = {initial!r} is not one of the sea states {ids}")
        self.initial = str(initial)
        self._load = _Window(self.window, 3)  # |tau_xy|, cos psi, sin psi
        self._cache: dict[tuple[str, int], SeaStateFeatures] = {}
        self.reset()

    # -- state -----------------------------------------------------------------------------
    def reset(self) -> None:
        """Forget the samples and the switches: back to the initial sea state."""
        self.wave.reset()
        self._load.reset()
        self._active = self.initial
        self._t0: float | None = None
        self._t: float | None = None
        self._t_switch: float | None = None
        self._decided = False
        self._features: SeaStateFeatures | None = None
        self._psi = 0.0
        self._dist: dict[str, float] = {}
        self.events: list[dict] = []

    @property
    def sea_state(self) -> str:
        """The active sea state id."""
        return self._active

    @property
    def sea_class(self) -> str:
        """The class of the active sea state."""
        return self._ref[self._active].sea_class

    @property
    def sea_states(self) -> tuple[str, ...]:
        return tuple(self._ref)

    def class_of(self, sea_state: str) -> str:
        """Class of one of the supervisor's sea states."""
        try:
            return self._ref[sea_state].sea_class
        except KeyError:
            raise SupervisorError(f"sea_state = {sea_state!r} is not one of {list(self._ref)}") from None

    @property
    def features(self) -> SeaStateFeatures | None:
        """The latest measured features (None before the first usable sample)."""
        return self._features

    @property
    def heading(self) -> float:
        """Mean heading of the window [rad] (the heading of the expected features)."""
        return self._psi

    @property
    def distances(self) -> dict[str, float]:
        """Normalised distance of the latest features to each sea state's expected ones."""
        return dict(self._dist)

    @property
    def switches(self) -> int:
        """Number of sea-state switches so far."""
        return len(self.events)

    def log(self) -> list[dict]:
        """The switch events, oldest first (the :class:`~tapm_opt.interfaces.Logged` method)."""
        return [dict(e) for e in self.events]

    # -- expected features and distance ----------------------------------------------------
    def expected(self, sea_state: str, psi: float = 0.0) -> SeaStateFeatures:
        """Expected features of ``sea_state`` at heading ``psi`` [rad] (cached per
        ``heading_step``)."""
        ref = self._ref.get(sea_state)
        if ref is None:
            raise SupervisorError(f"sea_state = {sea_state!r} is not one of {list(self._ref)}")
        k = int(round(ssa(float(psi)) / self.heading_step))
        key = (sea_state, k)
        if key not in self._cache:
            self._cache[key] = ref.expected(k * self.heading_step)
        return self._cache[key]

    def distance(self, features: SeaStateFeatures, sea_state: str, psi: float = 0.0) -> float:
        """Normalised distance ``sqrt(sum_j ((ln f_j - ln e_j) / s_j)^2)`` over the used
        features, e = the expected features of ``sea_state`` at ``psi``."""
        e = self.expected(sea_state, psi)
        d2 = 0.0
        for f in self.used_features:
            a, b = features.get(f), e.get(f)
            if math.isnan(a) or math.isnan(b):
                continue
            fl = _FLOORS[f]
            d2 += ((math.log(max(a, fl)) - math.log(max(b, fl))) / self.scales[f]) ** 2
        return math.sqrt(d2)

    # -- the update ------------------------------------------------------------------------
    def update(self, t: float, estimate: Estimate) -> str:
        """Feed one estimate; returns the active sea state id.

        Parameters
        ----------
        t : float
            Time [s], every ``dt`` (a repeated time is ignored).
        estimate : Estimate
            Uses ``eta_wf`` (x, y) [m] in {E} (when the WF features are used), ``tau_env``
            (X, Y) [N] in {B} and ``eta[2]`` [rad].

        Raises
        ------
        SupervisorError
            Non-finite or missing input, time running backwards, or a sample interval other than
            ``dt``.
        """
        try:
            t = float(t)
        except (TypeError, ValueError):
            raise SupervisorError(f"t = {t!r} must be a number [s]") from None
        if not math.isfinite(t):
            raise SupervisorError(f"t = {t!r} must be finite [s]")
        if self._t is not None and t < self._t:
            raise SupervisorError(f"t = {t!r} s is before the previous update at {self._t!r} s; call reset()")
        if self._t is not None and t == self._t:
            return self._active
        tau = _finite_vec("estimate.tau_env", getattr(estimate, "tau_env", None), 3)
        eta = _finite_vec("estimate.eta", getattr(estimate, "eta", None), 3)
        use_wf = self._use_wf
        if use_wf:
            wf = getattr(estimate, "eta_wf", None)
            if wf is None:
                raise SupervisorError("estimate.eta_wf = None: the WF features need the estimator's wave-frequency "
                                      "motion (LowPassEstimator gives it); use features=('load',) otherwise")
            wf = _finite_vec("estimate.eta_wf", wf, 3)
            self.wave.update(t, float(wf[0]), float(wf[1]))
        elif self._t is not None and abs((t - self._t) - self.dt) > 0.01 * self.dt:
            raise SupervisorError(f"sample interval {t - self._t:g} s (t = {t:g} s) is not dt = {self.dt:g} s")
        if self._t0 is None:
            self._t0 = t
        self._t = t
        if t - self._t0 < self.settle:
            return self._active
        psi = float(eta[2])
        self._load.push(t, (math.hypot(tau[0], tau[1]), math.cos(psi), math.sin(psi)))
        L, c, s = self._load.mean()
        self._psi = math.atan2(s, c)
        A, T = self.wave.features if use_wf else (math.nan, math.nan)
        self._features = SeaStateFeatures(A, T, L)
        if t - self._t0 < self.warm_up:
            return self._active
        self._dist = {sid: self.distance(self._features, sid, self._psi) for sid in self._ref}
        best = min(self._dist, key=self._dist.get)
        if not self._decided:
            self._decided = True
            if best != self._active:
                self._switch(t, best, "first decision")
            else:
                self._t_switch = t
            return self._active
        if (best != self._active and t - self._t_switch >= self.dwell
                and self._dist[best] < self._dist[self._active] - self.margin):
            self._switch(t, best, "hysteresis")
        return self._active

    def _switch(self, t: float, to: str, reason: str) -> None:
        ev = {"t": t, "event": "sea state", "from": self._active, "to": to,
              "from_class": self.class_of(self._active), "to_class": self.class_of(to),
              "features": {**self._features.as_dict(), "heading_rad": self._psi},
              "expected": self.expected(to, self._psi).as_dict(),
              "distances": {k: float(v) for k, v in self._dist.items()}, "reason": reason}
        self.events.append(ev)
        self._active = to
        self._t_switch = t


# --- the switched controller ----------------------------------------------------------------

def class_mode_sets(modes: Mapping[str, Any] | None = None) -> dict[str, tuple[str, ...]]:
    """Mode set per class: ``modes`` (class -> mode set name or modes) over the defaults
    :data:`~tapm_opt.control.pid.CLASS_MODE_SETS` ([S] Table 3).

    Raises
    ------
    SupervisorError
        ``modes`` not a mapping, an unknown class or mode set.
    """
    out = {c: MODE_SETS[CLASS_MODE_SETS[c]] for c in SEA_CLASSES}
    if modes is None:
        return out
    if not isinstance(modes, Mapping):
        raise SupervisorError(f"modes = {modes!r} must be a mapping class -> mode set ({list(SEA_CLASSES)})")
    for c, m in modes.items():
        if c not in SEA_CLASSES:
            raise SupervisorError(f"modes has unknown class {c!r}; classes are {list(SEA_CLASSES)}")
        try:
            out[c] = _resolve_modes(m)
        except ControlError as exc:
            raise SupervisorError(f"modes[{c!r}] = {m!r}: {exc}") from None
    return out


def _mode_set_name(modes: tuple[str, ...]) -> str:
    for name, ms in MODE_SETS.items():
        if ms == modes:
            return name
    return "+".join(modes)


def _row_label(cond: Any) -> dict:
    return {"sea_state": cond.sea_state, "sea_class": cond.sea_class, "broken": cond.broken,
            "heading_rad": float(cond.heading), "weathervane": bool(cond.weathervane),
            "mode_set": cond.mode_set}


class SupervisedController:
    """A controller switched by a :class:`SeaStateSupervisor` ([S] §4.5, Fig. 9).

    Each :meth:`update` feeds the supervisor, then

    * for a :class:`~tapm_opt.control.scheduled.GainScheduledPID`: ``select(sea_state=<the
      supervisor's>, broken=<estimate.broken_lines, one line>, heading=<see heading>)``; a row
      the table lacks (an untabled line, two broken lines, a sea state it does not hold) is
      replaced by the nearest available one — same sea state with the active mooring state,
      then intact; other sea states of the same class, then the nearest by the supervisor's
      distance — and logged (``"event": "missing row"``, once per request);
    * for a :class:`~tapm_opt.control.pid.TAPMPID`: ``set_modes`` to the mode set of the
      supervisor's class (``modes``, default ``control.pid.CLASS_MODE_SETS``, [S] Table 3);

    and returns the inner controller's command. A line break reaches a TAPMPID as before, through
    ``estimate.broken_lines`` (its fault-tolerant feed-forward).

    Parameters
    ----------
    controller : GainScheduledPID or TAPMPID
    supervisor : SeaStateSupervisor
    modes : mapping class -> mode set, optional
        For a TAPMPID only (a gain table's rows carry their mode sets).
    heading : "auto", "setpoint" or "weathervane"
        Heading of the requested row: the setpoint heading ``eta_d[2]`` [rad], the table's
        weathervane row, or (``"auto"``) the setpoint heading when the table has fixed-heading
        rows, else weathervane.

    Raises
    ------
    SupervisorError
        A controller of another type, a supervisor that is not a SeaStateSupervisor, bad
        ``modes`` or ``heading``.
    """

    def __init__(self, controller: Any, supervisor: SeaStateSupervisor, *, modes: Mapping[str, Any] | None = None,
                 heading: str = "auto"):
        if not isinstance(supervisor, SeaStateSupervisor):
            raise SupervisorError(f"supervisor must be a SeaStateSupervisor, got {type(supervisor).__name__}")
        if isinstance(controller, GainScheduledPID):
            self._scheduled = True
            if modes is not None:
                raise SupervisorError("modes is for a TAPMPID: a gain table's rows carry their own mode sets")
        elif isinstance(controller, TAPMPID):
            self._scheduled = False
        else:
            raise SupervisorError(f"controller must be a GainScheduledPID or a TAPMPID, got "
                                  f"{type(controller).__name__}")
        if heading not in ("auto", "setpoint", "weathervane"):
            raise SupervisorError(f"heading = {heading!r} must be 'auto', 'setpoint' or 'weathervane'")
        self.controller = controller
        self.supervisor = supervisor
        self.heading = heading
        # the table never changes: whether it holds only weathervane rows is decided once
        self._all_weathervane = self._scheduled and all(c.weathervane for c in controller.conditions)
        self._modes = None if self._scheduled else class_mode_sets(modes)
        self.period = controller.period
        self._events: list[dict] = []
        self._missing: set = set()
        self._request: tuple | None = None
        self._apply_initial()

    def _apply_initial(self) -> None:
        if not self._scheduled:
            self.controller.set_modes(self._modes[self.supervisor.sea_class])

    # -- Controller protocol ---------------------------------------------------------------
    def reset(self) -> None:
        """Reset the supervisor (back to its initial sea state), the controller and the log."""
        self.supervisor.reset()
        self.controller.reset()
        self._events = []
        self._missing = set()
        self._request = None
        self._apply_initial()

    def last_step(self) -> ControllerStep | None:
        """The inner controller's diagnostics of the latest update."""
        return self.controller.last_step()

    def set_failed_thrusters(self, failed: frozenset[str]) -> None:
        """Pass the thruster feedback on to the inner controller (if it is fault-aware)."""
        if isinstance(self.controller, FaultAware):
            self.controller.set_failed_thrusters(failed)

    def update(self, t: float, estimate: Estimate, setpoint: Setpoint) -> np.ndarray:
        """Supervise, switch, then the inner controller's command ``tau`` (3,) in {B}
        [N, N, N m].

        Raises
        ------
        SupervisorError, ControlError
            Bad estimate or setpoint (see :meth:`SeaStateSupervisor.update`,
            :meth:`TAPMPID.update`).
        """
        sea_state = self.supervisor.update(t, estimate)
        if self._scheduled:
            self._select(float(t), sea_state, estimate, setpoint)
        else:
            want = self._modes[self.supervisor.class_of(sea_state)]
            have = self.controller.modes
            if want != have:
                self.controller.set_modes(want)
                self._events.append({"t": float(t), "event": "mode switch", "from": _mode_set_name(have),
                                     "to": _mode_set_name(want), "from_modes": list(have), "to_modes": list(want),
                                     "sea_state": sea_state, "sea_class": self.supervisor.class_of(sea_state)})
        return self.controller.update(t, estimate, setpoint)

    # -- gain table ------------------------------------------------------------------------
    def _heading_request(self, setpoint: Setpoint) -> float | str:
        if self.heading == "weathervane":
            return "weathervane"
        if self.heading == "auto" and self._all_weathervane:
            return "weathervane"
        eta_d = getattr(setpoint, "eta_d", None)
        psi = _finite_vec("setpoint.eta_d", eta_d, 3)[2]
        return float(psi)

    def _candidates(self, sea_state: str, broken: tuple[str, ...], heading: float | str) -> list[tuple]:
        conds = self.controller.conditions
        active = self.controller.active
        table_states = list(dict.fromkeys(c.sea_state for c in conds))
        sup = self.supervisor
        cls = sup.class_of(sea_state)
        dist = sup.distances

        def rank(s: str) -> tuple:
            same = any(c.sea_state == s and c.sea_class == cls for c in conds)
            return (not same, dist.get(s, math.inf), table_states.index(s))

        states = [sea_state] + sorted((s for s in table_states if s != sea_state), key=rank)
        b_opts = list(broken) if broken else ["intact"]
        b_opts += [b for b in (active.broken, "intact") if b not in b_opts]
        h_opts = [heading]
        if heading == "weathervane":
            h_opts.append(float(active.heading))
        return [(s, b, h) for s in states for b in b_opts for h in h_opts]

    def _select(self, t: float, sea_state: str, estimate: Estimate, setpoint: Setpoint) -> None:
        broken = tuple(sorted(estimate.broken_lines))
        heading = self._heading_request(setpoint)
        request = (sea_state, broken, heading)
        if request == self._request:
            return
        before = self.controller.active
        used = None
        for s, b, h in self._candidates(sea_state, broken, heading):
            try:
                self.controller.select(sea_state=s, broken=b, heading=h)
            except ControlError:
                continue
            used = (s, b, h)
            break
        self._request = request
        exact = (sea_state, broken[0] if len(broken) == 1 else "intact" if not broken else None, heading)
        # once per (sea state, broken lines, row used): a chased heading changes every update
        key = (sea_state, broken, None if used is None else used[:2])
        if used != exact and key not in self._missing:
            self._missing.add(key)
            self._events.append({"t": t, "event": "missing row",
                                 "requested": {"sea_state": sea_state, "broken": list(broken) or ["intact"],
                                               "heading": heading},
                                 "used": _row_label(self.controller.active)})
        after = self.controller.active
        if after != before:
            self._events.append({"t": t, "event": "mode switch", "from": _row_label(before),
                                 "to": _row_label(after), "from_modes": list(MODE_SETS[before.mode_set]),
                                 "to_modes": list(MODE_SETS[after.mode_set])})

    # -- Logged ----------------------------------------------------------------------------
    def log(self) -> list[dict]:
        """The supervisor's sea-state switches and the controller's mode switches (and missing
        rows), JSON-ready, in time order."""
        return sorted(self.supervisor.log() + [dict(e) for e in self._events], key=lambda e: e["t"])

    @property
    def mode_switches(self) -> int:
        """Number of mode-set (or gain-table row) switches so far."""
        return sum(e["event"] == "mode switch" for e in self._events)

    @property
    def sea_state(self) -> str:
        """The supervisor's active sea state."""
        return self.supervisor.sea_state

    @property
    def modes(self) -> tuple[str, ...]:
        """The inner controller's enabled modes."""
        return self.controller.modes
