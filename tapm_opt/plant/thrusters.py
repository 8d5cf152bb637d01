"""Thruster bank of the plant: first-order thrust response, rate limits, saturation, power, failures.

Each thruster i has a thrust f_i [N] along its direction alpha_i [rad] (measured in {B} from x^B
toward y^B). Azimuth thrusters turn (rate-limited, shortest way) and have f_i >= 0; tunnel and
fixed thrusters keep their scenario angle and may reverse (f_i in [-max_reverse, max]).

Thrust dynamics per step dt (exact for the first-order lag ``T df/dt = f_sat - f``, then the
rate limit)::

    f_sat  = clip(f_cmd, f_min, f_max)
    f_lag  = f_sat + (f - f_sat) exp(-dt/T)
    f_new  = f + clip(f_lag - f, -max_thrust_rate dt, +max_thrust_rate dt)

Power (ideal actuator-disk momentum theory, P = T^(3/2) / sqrt(2 rho A), with an overall
efficiency; e.g. Carlton, *Marine propellers and propulsion*)::

    P_i = k_i |f_i|^(3/2),   k_i = 1 / (eta sqrt(2 rho_w A_i)),   A_i = max_thrust_i / q

where the disk area A_i follows from an assumed bollard thrust loading ``q`` because the scenario
gives no propeller diameter. Defaults: ``q = 5.0e4 N/m^2`` (a 3.5 m ducted propeller producing
480 kN) and ``eta = 0.7``; together they give a specific bollard thrust at full load of
``eta sqrt(2 rho_w / q) = 0.142 N/W`` (0.14 kN/kW), typical of ducted DP thrusters.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from ._kernels import fem_kernel as _fem_kernel
from ..config import schema
from ..geometry import ssa
from ..models.thrust import configuration_matrix
from .environment import PlantError, _num

__all__ = ["ThrusterBank", "THRUST_LOADING", "EFFICIENCY"]

#: Assumed bollard thrust loading max_thrust / A_disk [N/m^2] (sets the disk area).
THRUST_LOADING = 5.0e4
#: Assumed overall efficiency eta of the ideal actuator-disk power P = |f|^1.5 / (eta sqrt(2 rho A)) [-].
EFFICIENCY = 0.7


@dataclass(frozen=True, eq=False)
class _Limits:
    """Per-thruster constant arrays, shape (n,)."""

    x: np.ndarray
    y: np.ndarray
    azimuth: np.ndarray  # bool: rotatable
    f_min: np.ndarray
    f_max: np.ndarray
    rate: np.ndarray
    alpha_rate: np.ndarray  # inf: instantaneous
    T: np.ndarray
    k_power: np.ndarray


class ThrusterBank:
    """All thrusters of a vessel: state (f, alpha), response, generalised force and power.

    Parameters
    ----------
    thrusters : sequence of tapm_opt.config.Thruster
        kind, position (x, y) in {B} [m], angle [rad], max_thrust, max_reverse_thrust [N],
        max_thrust_rate [N/s], max_azimuth_rate [rad/s] or None (instantaneous), time_constant [s].
        ``forbidden_sectors`` are an allocation constraint and are not enforced here.
    water_density : float
        rho_w [kg/m^3] for the power constant.
    thrust_loading, efficiency : float
        q [N/m^2] and eta [-] of the power model (module docstring).

    Attributes
    ----------
    ids : tuple of str
        Thruster ids, in order.
    limits : read-only arrays (n,)
        ``x, y`` [m], ``azimuth`` (bool), ``f_min, f_max`` [N], ``rate`` [N/s], ``alpha_rate``
        [rad/s] (inf: instantaneous), ``T`` [s], ``k_power`` [W/N^1.5].
    """

    def __init__(self, thrusters: Sequence[schema.Thruster], water_density: float, *, thrust_loading: float = THRUST_LOADING,
                 efficiency: float = EFFICIENCY):
        self.ids = tuple(str(th.id) for th in thrusters)
        n = len(self.ids)
        rho = _pos("water_density", water_density)
        q, eta = _pos("thrust_loading", thrust_loading), _pos("efficiency", efficiency)
        if eta > 1.0:
            raise PlantError(f"efficiency={efficiency!r} must be in (0, 1]")
        cols: dict[str, list[float]] = {k: [] for k in _Limits.__dataclass_fields__}
        alpha0 = []
        for i, th in enumerate(thrusters):
            p = f"thrusters[{i}]"
            if th.kind not in ("azimuth", "tunnel", "fixed"):
                raise PlantError(f"{p}.kind={th.kind!r} must be 'azimuth', 'tunnel' or 'fixed'")
            az = th.kind == "azimuth"
            x, y = (_num(f"{p}.position[{j}]", th.position[j], unit="m") for j in range(2))
            f_max = _pos(f"{p}.max_thrust", th.max_thrust)
            rev = 0.0 if az else _num(f"{p}.max_reverse_thrust", th.max_reverse_thrust, lo=0.0, unit="N")
            a_rate = th.max_azimuth_rate if az and th.max_azimuth_rate is not None else math.inf
            if az and th.max_azimuth_rate is not None:
                _pos(f"{p}.max_azimuth_rate", a_rate)
            vals = dict(x=x, y=y, azimuth=az, f_min=-rev, f_max=f_max,
                        rate=_pos(f"{p}.max_thrust_rate", th.max_thrust_rate), alpha_rate=a_rate,
                        T=_pos(f"{p}.time_constant", th.time_constant),
                        k_power=1.0 / (eta * math.sqrt(2.0 * rho * f_max / q)))
            for k, v in vals.items():
                cols[k].append(v)
            alpha0.append(_num(f"{p}.angle", th.angle, unit="rad"))
        arrs = {k: np.array(v, dtype=bool if k == "azimuth" else float).reshape(n) for k, v in cols.items()}
        for a in arrs.values():
            a.flags.writeable = False
        self.limits = _Limits(**arrs)
        self._alpha0 = ssa(np.array(alpha0, dtype=float).reshape(n))
        self._f = np.zeros(n)
        self._alpha = self._alpha0.copy()
        self._failed = np.zeros(n, dtype=bool)
        self._dt_decay = math.nan  # step of the cached lag factors (_advance)

    @classmethod
    def from_scenario(cls, scenario: schema.Scenario, **kw: Any) -> ThrusterBank:
        """Build from ``scenario.thrusters`` and ``scenario.environment.water_density``."""
        return cls(scenario.thrusters, scenario.environment.water_density, **kw)

    # -- state -------------------------------------------------------------------------------
    @property
    def n(self) -> int:
        """Number of thrusters."""
        return len(self.ids)

    @property
    def f(self) -> np.ndarray:
        """Actual thrusts, shape (n,) [N] (a copy)."""
        return self._f.copy()

    @property
    def alpha(self) -> np.ndarray:
        """Actual thrust directions in {B}, shape (n,) [rad] in [-pi, pi) (a copy)."""
        return self._alpha.copy()

    @property
    def failed(self) -> np.ndarray:
        """Failed thrusters, shape (n,) bool (a copy)."""
        return self._failed.copy()

    def index(self, thruster: int | str) -> int:
        """Index of a thruster given by index or id; PlantError if there is none."""
        if isinstance(thruster, (int, np.integer)) and not isinstance(thruster, bool):
            if 0 <= thruster < self.n:
                return int(thruster)
        elif str(thruster) in self.ids:
            return self.ids.index(str(thruster))
        raise PlantError(f"thruster={thruster!r}: no such thruster (ids {list(self.ids)})")

    def reset(self, f: Any = None, alpha: Any = None) -> None:
        """Set the state (default: zero thrust, scenario angles); failures stay. f clipped to limits."""
        f = np.zeros(self.n) if f is None else self._vector("f", f)
        self._f = np.where(self._failed, 0.0, np.clip(f, self.limits.f_min, self.limits.f_max))
        a = self._alpha0 if alpha is None else self._vector("alpha", alpha)
        self._alpha = ssa(np.where(self.limits.azimuth, a, self._alpha0))

    def fail(self, thruster: int | str) -> None:
        """Fail a thruster (index or id): it produces zero thrust from now on."""
        i = self.index(thruster)
        self._failed[i] = True
        self._f[i] = 0.0

    # -- dynamics ----------------------------------------------------------------------------
    def _vector(self, name: str, v: Any) -> np.ndarray:
        try:
            a = np.asarray(v, dtype=float)
        except (TypeError, ValueError):
            raise PlantError(f"{name}={v!r} is not numeric") from None
        if a.shape != (self.n,):
            raise PlantError(f"{name} has shape {a.shape}, expected ({self.n},) (one per thruster)")
        bad = np.flatnonzero(~np.isfinite(a))
        if bad.size:
            i = int(bad[0])
            raise PlantError(f"{name}[{i}]={float(a[i])!r} for thruster {self.ids[i]!r} is not finite")
        return a

    def step(self, dt: float, f_cmd: Any, alpha_cmd: Any = None) -> None:
        """Advance the thrusters by dt toward the commands.

        Parameters
        ----------
        dt : float
            Time step [s], > 0.
        f_cmd : array_like, shape (n,)
            Commanded thrusts [N]; saturated to [-max_reverse_thrust, max_thrust] ([0, max] for
            azimuths). Non-finite values raise PlantError.
        alpha_cmd : array_like, shape (n,), optional
            Commanded azimuths [rad] (used by azimuth thrusters only; None: keep). Each azimuth
            turns the shortest way (ssa) at most ``max_azimuth_rate dt``.
        """
        dt = _pos("dt", dt)
        f_cmd = self._vector("f_cmd", f_cmd)
        a_cmd = None if alpha_cmd is None else self._vector("alpha_cmd", alpha_cmd)  # all checked first
        self._advance(dt, f_cmd, a_cmd)

    def _advance(self, dt: float, f_cmd: np.ndarray, alpha_cmd: np.ndarray | None, *,
                 compiled: bool = False) -> np.ndarray:
        """:meth:`step` on checked commands (dt [s] > 0, float arrays (n,) [N], [rad]).

        ``compiled``: run the compiled kernel (:func:`tapm_opt.plant.fem_kernel.thruster_step`,
        the same operations in the same order), else the numpy path; either way returns the new
        :meth:`tau` (3,) [N, N, N m]. The caller checks that numba is available.
        """
        lim = self.limits
        if self._dt_decay != dt:
            self._lag(dt)
        if compiled:
            fem_kernel = _fem_kernel()
            return fem_kernel.thruster_step(self._f, self._alpha, self._failed, f_cmd,
                                            self._f if alpha_cmd is None else alpha_cmd, alpha_cmd is not None,
                                            lim.f_min, lim.f_max, self._decay, self._rate_dt, self._alpha_rate_dt,
                                            lim.azimuth, lim.x, lim.y)
        f_sat = np.clip(f_cmd, lim.f_min, lim.f_max)
        f_lag = f_sat + (self._f - f_sat) * self._decay
        f = self._f + np.clip(f_lag - self._f, -self._rate_dt, self._rate_dt)
        self._f = np.where(self._failed, 0.0, f)
        if alpha_cmd is not None:
            da = np.clip(ssa(alpha_cmd - self._alpha), -self._alpha_rate_dt, self._alpha_rate_dt)
            self._alpha = np.where(lim.azimuth, ssa(self._alpha + da), self._alpha)
        return self.tau()

    def _lag(self, dt: float) -> None:
        """The factors of a step of ``dt`` [s]: ``exp(-dt / T)`` of the first-order lag, the thrust
        and azimuth changes allowed in it [N, rad] (kept until the step length changes)."""
        lim = self.limits
        self._dt_decay, self._decay = dt, np.exp(-dt / lim.T)
        self._rate_dt, self._alpha_rate_dt = lim.rate * dt, lim.alpha_rate * dt

    # -- outputs -----------------------------------------------------------------------------
    def T_alloc(self, alpha: Any = None) -> np.ndarray:
        """Thrust configuration matrix T(alpha), shape (3, n): column i = (cos a_i, sin a_i, x_i sin a_i - y_i cos a_i).

        ``tau = T(alpha) f``; default alpha: the actual azimuths.
        """
        a = self._alpha if alpha is None else self._vector("alpha", alpha)
        return configuration_matrix(a, self.limits.x, self.limits.y)

    def tau(self) -> np.ndarray:
        """Generalised thruster force tau_thr = sum_i f_i (cos a_i, sin a_i, x_i sin a_i - y_i cos a_i)
        in {B}, shape (3,) [N, N, N m]."""
        return self.T_alloc() @ self._f

    def power(self) -> np.ndarray:
        """Shaft power of each thruster, ``k_i |f_i|^1.5``, shape (n,) [W] (module docstring)."""
        return self.limits.k_power * np.abs(self._f) ** 1.5


def _pos(name: str, v: Any) -> float:
    return _num(name, v, lo=0.0, strict=True)
