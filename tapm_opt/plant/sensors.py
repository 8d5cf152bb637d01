"""Sensors of the plant: GNSS position, gyro-compass heading, fairlead tension cells and, when
the scenario has a riser, inclinometers at the riser's top and bottom flex joints.

Each sensor samples at its own rate with sample-and-hold: at the first call, and whenever t
reaches the next sample instant k / rate, it takes a new noisy sample of the true value at t
(additive zero-mean Gaussian white noise); between instants it returns the held value. The heading
is wrapped with ``ssa``. Noise is drawn from four independent generators spawned from one seed
(GNSS, heading, tensions, riser angles), so e.g. changing the number of lines does not change the
GNSS noise, and a riser leaves the other sensors' noise as it was.

A vessel with low-frequency roll and pitch (``vessel.roll_pitch``) carries a motion reference
unit (MRU): roll, pitch and their rates (4,) [rad, rad, rad/s, rad/s], sampled at ``mru_rate``
with the noise ``mru_angle_std`` on the angles and ``mru_rate_std`` on the rates, from a sixth
generator of the same seed (the other five draw as without it).

Two gyro-compasses measure the heading at ``heading_rate`` with the same noise, each from its own
generator (the second from a fifth stream, so the first four streams are those of a plant with one
gyro): ``Measurement.heading`` is gyro 1's, ``Measurement.heading2`` gyro 2's. ASSUMPTION: two
gyro-compasses, as the DP class notations ask of a vessel whose position keeping must survive a
single sensor failure (a third vote comes from the GNSS and the tension cells:
:mod:`tapm_opt.estimation.redundancy`).

Sensor faults (:data:`tapm_opt.config.schema.SENSOR_FAULT_KINDS`, injected by the plant with
:meth:`Sensors.inject`) act on the samples taken from the fault's ``time`` until its ``end_time``:

* ``gnss_dropout`` -- no fix: ``position`` is (nan, nan) and ``position_valid`` False (the receiver
  still reports, at its rate, that it has none: ``t_position`` advances);
* ``gnss_drift`` -- the fix drifts silently: ``+ speed (t - time) (cos direction, sin direction)``;
* ``cell_stuck`` -- the line's tension cell repeats the reading it held when the fault began;
* ``cell_drift`` -- the cell reads ``+ rate (t - time)`` (``rate_rel`` x MBS per second);
* ``cell_noisy`` -- the cell's noise is ``factor`` times its standard deviation (the same draws);
* ``gyro_stuck`` / ``gyro_drift`` -- gyro-compass ``gyro`` (1 or 2) repeats its last heading, or
  reads ``+ heading_rate (t - time)`` (wrapped).

None of them is flagged in the measurement except the dropout: a real sensor does not say it has
drifted or stuck.

The riser angles (top_x, top_y, bottom_x, bottom_y) [rad] in {E} are sampled at
``riser_angle_rate`` (default 1 Hz, the tension cells' rate: the bottom angle reaches the surface
by acoustic telemetry at about that rate) with the noise ``riser_angle_std`` on each component.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from .._io import readonly
from ..config import schema
from ..geometry import ssa
from ..interfaces import Measurement, _frozen
from .environment import PlantError, _num

__all__ = ["SensorSpec", "Measurement", "Sensors"]

_GNSS, _HEADING, _TENSION, _RISER, _HEADING2, _MRU = 0, 1, 2, 3, 4, 5
_NAN2 = np.array([math.nan, math.nan])


#: The sensor specification is the scenario's ``[sensors]`` section (one definition of the fields,
#: units and defaults: :class:`tapm_opt.config.schema.Sensors`; ``heading_std`` and
#: ``riser_angle_std`` are in rad in code).
SensorSpec = schema.Sensors


def _check_spec(spec: SensorSpec) -> None:
    for name in ("gnss_std", "heading_std", "tension_std_rel", "riser_angle_std", "mru_angle_std", "mru_rate_std"):
        _num(f"sensors.{name}", getattr(spec, name), lo=0.0)
    for name in ("gnss_rate", "heading_rate", "tension_rate", "riser_angle_rate", "mru_rate"):
        _num(f"sensors.{name}", getattr(spec, name), lo=0.0, strict=True, unit="Hz")


class Sensors:
    """Sample-and-hold noisy sensors (see the module docstring).

    Parameters
    ----------
    spec : SensorSpec
    n_lines : int
        Number of tension cells (one per mooring line).
    seed : int, SeedSequence or None
        Seed of the noise; the same seed gives the same noise sequence.
    MBS : array_like, shape (n_lines,), optional
        Minimum breaking strengths [N]; the tension noise is ``spec.tension_std_rel * MBS``.
        Required unless n_lines = 0.
    """

    def __init__(self, spec: SensorSpec, n_lines: int, seed: Any = None, *, MBS: Any = None):
        if not isinstance(n_lines, (int, np.integer)) or n_lines < 0:
            raise PlantError(f"n_lines={n_lines!r} must be an integer >= 0")
        _check_spec(spec)
        self.spec, self.n_lines = spec, int(n_lines)
        if MBS is not None:
            mbs = np.asarray(MBS, dtype=float)
            if mbs.shape != (self.n_lines,) or not np.all(np.isfinite(mbs) & (mbs > 0)):
                raise PlantError(f"MBS={mbs.tolist()} must be {self.n_lines} finite values > 0 [N]")
            std = spec.tension_std_rel * mbs
        elif self.n_lines == 0:
            std = np.zeros(0)
        else:
            raise PlantError("give MBS: the tension noise is sensors.tension_std_rel times each line's MBS")
        self.tension_std = readonly(std)
        self._rates = (spec.gnss_rate, spec.heading_rate, spec.tension_rate, spec.riser_angle_rate, spec.heading_rate,
                       spec.mru_rate)
        # spawn(6): the first three streams are those of the sensors without the riser's, the fifth
        # the second gyro's, the sixth the MRU's (a SeedSequence's i-th child does not depend on
        # how many are spawned: each sensor draws as without the ones after it)
        self._rngs = [np.random.default_rng(s) for s in np.random.SeedSequence(seed).spawn(6)]
        self.MBS = None if MBS is None else readonly(np.asarray(MBS, dtype=float))
        #: The sensor faults injected so far (:meth:`inject`), as dicts; ended ones stay listed.
        self.faults: list[dict] = []
        # next sample index k per sensor (the second gyro samples with the first: its entry unused)
        self._next: list[float] = [-math.inf] * 6
        self._held: list[Any] = [None] * 6
        self._t_held = [math.nan] * 6
        self._t_last = -math.inf
        self._gnss_ok = True

    @classmethod
    def from_scenario(cls, scenario: schema.Scenario, spec: SensorSpec | None = None, seed: Any = None) -> Sensors:
        """Sensors for all lines of a scenario: its ``[sensors]`` section unless ``spec`` is given."""
        return cls(spec or scenario.sensors, len(scenario.lines), seed, MBS=scenario.line_arrays["MBS"])

    def inject(self, fault: Any, line: int | None = None) -> None:
        """Start a sensor fault (:class:`~tapm_opt.config.schema.Fault` of a kind in
        :data:`~tapm_opt.config.schema.SENSOR_FAULT_KINDS`): it acts on the samples taken from
        ``fault.time`` until ``fault.end_time`` (module docstring). ``line`` is the index of the
        failing tension cell (cell faults). A stuck sensor repeats the value it holds now (its
        next sample when it has taken none). Raises :class:`PlantError` naming the field of a bad
        fault."""
        issues = schema.sensor_fault_issues(fault, range(self.n_lines)) if line is not None else \
            schema.sensor_fault_issues(fault, [])
        kind = getattr(fault, "kind", None)
        if kind not in schema.SENSOR_FAULT_KINDS:
            raise PlantError(f"fault kind = {kind!r} is not a sensor fault; sensor faults are "
                             f"{', '.join(schema.SENSOR_FAULT_KINDS)}")
        issues = [(f, m) for f, m in issues if f != "line"]   # the line is the index given
        if kind.startswith("cell_"):
            if not isinstance(line, (int, np.integer)) or not 0 <= line < self.n_lines:
                issues.append(("line", f"index {line!r} is not a tension cell 0..{self.n_lines - 1}"))
        if issues:
            f, msg = issues[0]
            raise PlantError(f"fault {kind} at t = {fault.time!r} s: {f} {msg}")
        end = math.inf if fault.end_time is None else float(fault.end_time)
        rec = {"kind": kind, "t0": float(fault.time), "t1": end, "line": None if line is None else int(line)}
        if kind == "gnss_drift":
            rec["v"] = float(fault.speed) * np.array([math.cos(fault.direction), math.sin(fault.direction)])
        elif kind == "cell_drift":
            rec["rate"] = float(fault.rate) if fault.rate is not None else float(fault.rate_rel) * float(
                self.MBS[line] if self.MBS is not None else 0.0)
        elif kind == "cell_noisy":
            rec["factor"] = float(fault.factor)
        elif kind.startswith("gyro_"):
            rec["gyro"] = int(fault.gyro or 1)
            if kind == "gyro_drift":
                rec["rate"] = float(fault.heading_rate)
        if kind == "cell_stuck":
            held = self._held[_TENSION]
            rec["value"] = None if held is None else float(held[line])
        elif kind == "gyro_stuck":
            rec["value"] = self._held[_HEADING if rec["gyro"] == 1 else _HEADING2]
        self.faults.append(rec)

    def _faulty(self, i: int, t: float, value: Any, std: Any = None, z: Any = None) -> tuple[Any, bool]:
        """Sensor i's new sample ``value`` at t [s] after the active faults (module docstring),
        and False when it is no fix (GNSS dropout). ``std`` and ``z``: the tension cells' noise
        standard deviations and standard normal draws (a noisy cell's extra noise)."""
        ok = True
        for f in self.faults:
            if not f["t0"] - 1e-9 <= t < f["t1"] - 1e-9:
                continue
            k = f["kind"]
            if i == _GNSS and k == "gnss_dropout":
                value, ok = _NAN2.copy(), False
            elif i == _GNSS and k == "gnss_drift":
                value = value + f["v"] * (t - f["t0"])
            elif i == _TENSION and k.startswith("cell_"):
                j = f["line"]
                if k == "cell_stuck":
                    if f["value"] is None:
                        f["value"] = float(value[j])
                    value[j] = f["value"]
                elif k == "cell_drift":
                    value[j] += f["rate"] * (t - f["t0"])
                else:
                    value[j] += (f["factor"] - 1.0) * std[j] * z[j]
            elif i in (_HEADING, _HEADING2) and k.startswith("gyro_") and f["gyro"] == (1 if i == _HEADING else 2):
                if k == "gyro_stuck":
                    if f["value"] is None:
                        f["value"] = float(value)
                    value = f["value"]
                else:
                    value = float(ssa(value + f["rate"] * (t - f["t0"])))
        return value, ok

    def _due(self, i: int, t: float) -> bool:
        """True (and schedule the next instant) when sensor i takes a new sample at t."""
        k = t * self._rates[i]
        if k < self._next[i] - 1e-9:
            return False
        self._next[i] = math.floor(k + 1e-9) + 1.0
        self._t_held[i] = t
        return True

    def sample(self, t: float, eta_total: Any, tensions: Any, riser_angles: Any = None,
               attitude: Any = None) -> Measurement:
        """Measurement at time t [s] of the true pose ``eta_total`` (3,) = (x [m], y [m], psi [rad])
        in {E} (LF + WF), the true fairlead tensions (n_lines,) [N] and, for a vessel with a riser,
        the true riser angles (4,) = (top_x, top_y, bottom_x, bottom_y) [rad] in {E} (None: no
        riser, and ``Measurement.riser_angles`` is None), and for a vessel with roll and pitch the
        true attitude (4,) = (roll [rad], pitch [rad], roll rate [rad/s], pitch rate [rad/s]) the
        MRU reads (None: no MRU, ``Measurement.attitude`` is None). Times must not decrease."""
        return Measurement(**self._fields(t, eta_total, tensions, riser_angles, attitude))

    def _fields(self, t: float, eta_total: Any, tensions: Any, riser_angles: Any = None, attitude: Any = None) -> dict:
        """The fields of :meth:`sample`'s Measurement (:meth:`Plant.measure` adds the thruster
        feedback and builds it once). The held arrays are new, read-only and held by nobody else
        (the Measurement takes them without a copy)."""
        if type(t) is not float or not math.isfinite(t):   # a finite float needs no conversion
            t = _num("t", t, unit="s")
        if t < self._t_last:
            raise PlantError(f"t={t!r} s is before the previous sample time {self._t_last!r} s")
        self._t_last = t
        eta = eta_total if type(eta_total) is np.ndarray and eta_total.dtype == np.float64 \
            else np.asarray(eta_total, dtype=float)
        T = tensions if type(tensions) is np.ndarray and tensions.dtype == np.float64 \
            else np.asarray(tensions, dtype=float)
        # a finite sum means every value is finite; only a non-finite one needs the element check
        if eta.shape != (3,) or not (math.isfinite(eta[0] + eta[1] + eta[2]) or np.isfinite(eta).all()):
            raise PlantError(f"eta_total={eta.tolist()} must be 3 finite numbers (x, y, psi)")
        n = self.n_lines
        if T.shape != (n,) or not (math.isfinite(float(T.sum())) or np.isfinite(T).all()):
            bad = [] if T.shape != (n,) else np.flatnonzero(~np.isfinite(T)).tolist()
            raise PlantError(f"tensions (shape {T.shape}) must be {n} finite values [N]; "
                             f"bad lines {bad}")
        if riser_angles is not None:
            theta = np.asarray(riser_angles, dtype=float)
            if theta.shape != (4,) or not (math.isfinite(float(theta.sum())) or np.isfinite(theta).all()):
                raise PlantError(f"riser_angles={theta.tolist()} must be 4 finite angles (top_x, top_y, bottom_x, "
                                 "bottom_y) [rad]")
        s = self.spec
        held, t_held, nxt, rates, rngs = self._held, self._t_held, self._next, self._rates, self._rngs
        # _due inlined: sensor i samples when t reaches its next instant k / rate
        faults = self.faults
        k = t * rates[_GNSS]
        if k >= nxt[_GNSS] - 1e-9:
            nxt[_GNSS] = math.floor(k + 1e-9) + 1.0
            t_held[_GNSS] = t
            p = eta[:2] + s.gnss_std * rngs[_GNSS].standard_normal(2)
            if faults:
                p, self._gnss_ok = self._faulty(_GNSS, t, p)
            held[_GNSS] = _frozen(p)
        k = t * rates[_HEADING]
        if k >= nxt[_HEADING] - 1e-9:
            nxt[_HEADING] = math.floor(k + 1e-9) + 1.0
            t_held[_HEADING] = t
            h1 = float(ssa(eta[2] + s.heading_std * rngs[_HEADING].standard_normal()))
            h2 = float(ssa(eta[2] + s.heading_std * rngs[_HEADING2].standard_normal()))
            if faults:
                h1 = self._faulty(_HEADING, t, h1)[0]
                h2 = self._faulty(_HEADING2, t, h2)[0]
            held[_HEADING], held[_HEADING2] = h1, h2
        k = t * rates[_TENSION]
        if k >= nxt[_TENSION] - 1e-9:
            nxt[_TENSION] = math.floor(k + 1e-9) + 1.0
            t_held[_TENSION] = t
            z = rngs[_TENSION].standard_normal(n)
            v = T + self.tension_std * z
            if faults:
                v = self._faulty(_TENSION, t, v, self.tension_std, z)[0]
            held[_TENSION] = _frozen(v)
        if riser_angles is None:
            riser, t_riser = None, None
        else:
            if self._due(_RISER, t):
                held[_RISER] = _frozen(theta + s.riser_angle_std * rngs[_RISER].standard_normal(4))
            riser, t_riser = held[_RISER], t_held[_RISER]
        out = dict(t=t, position=held[_GNSS], heading=held[_HEADING], heading2=held[_HEADING2],
                   position_valid=self._gnss_ok,
                   tensions=held[_TENSION], t_position=t_held[_GNSS],
                   t_heading=t_held[_HEADING], t_tensions=t_held[_TENSION],
                   riser_angles=riser, t_riser_angles=t_riser)
        if attitude is not None:   # the MRU: (roll, pitch, roll rate, pitch rate)
            att = np.asarray(attitude, dtype=float)
            if att.shape != (4,) or not np.isfinite(att).all():
                raise PlantError(f"attitude={att.tolist()} must be 4 finite numbers (roll [rad], pitch [rad], "
                                 "roll rate [rad/s], pitch rate [rad/s])")
            if self._due(_MRU, t):
                std = np.array([s.mru_angle_std, s.mru_angle_std, s.mru_rate_std, s.mru_rate_std])
                held[_MRU] = _frozen(att + std * rngs[_MRU].standard_normal(4))
            out["attitude"], out["t_attitude"] = held[_MRU], t_held[_MRU]
        return out

