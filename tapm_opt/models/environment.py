"""Environment of the models: the current over depth (survey eq. 7) and the wind load on the hull
(Fossen 2011 §8.1).

:class:`CurrentProfile` is the one definition of the current over depth: the plant's environment
(:class:`tapm_opt.plant.environment.Environment`, the FEM lines' drag) and the quasi-static riser
(:class:`tapm_opt.models.riser.RiserModel`) both evaluate it.

One definition of the wind-load formula. The plant's gusty wind
(:meth:`tapm_opt.plant.environment.Wind.tau_wind`, with the vessel velocity) and the mean load of
the gain design (:func:`tapm_opt.design.loads.mean_environmental_load`, mean speed, vessel at
rest) both evaluate :meth:`HullWindLoad.tau`.

With the wind speed V going to ``beta_w`` in {E} and the vessel velocity (u, v) in {B}, the
velocity of the vessel relative to the air in {B} is

    (u_rw, v_rw) = (u, v) - V (cos(beta_w - psi), sin(beta_w - psi)),

``V_rw = |(u_rw, v_rw)|`` and ``gamma = atan2(v_rw, u_rw)`` is the angle the relative wind comes
FROM, relative to the bow, + to starboard. The load in {B} is

    (X, Y, N) = -1/2 rho_a V_rw^2 (c_x cos(gamma) A_F, c_y sin(gamma) A_L,
                                   c_n sin(2 gamma) A_L L_pp)
              = k * (V_rw u_rw, V_rw v_rw, u_rw v_rw),

with ``k = -1/2 rho_a (c_x A_F, c_y A_L, 2 c_n A_L L_pp)``.
This is Fossen's ``C_X = -c_x cos g``, ``C_Y = c_y sin g``, ``C_N = c_n sin 2g`` with ``g = -gamma``
(positive for wind from port). The moment turns the bow away from the wind (broadside).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from .._checks import finite
from .._io import readonly
from ..config import schema
from ..errors import ModelError

__all__ = ["CurrentProfile", "HullWindLoad"]


def _nonneg(name: str, value: Any, *, strict: bool = False) -> float:
    return finite(name, value, lo=0.0, strict=strict, error=ModelError, eq="=")


def finite_number(name: str, value: Any, *, lo: float = -math.inf, strict: bool = False, unit: str = "",
                  error: type[Exception] = ModelError) -> float:
    """``value`` as a float, finite and >= ``lo`` (> with ``strict``), else ``error`` naming
    ``name``, the value and its unit (:func:`tapm_opt._checks.finite`)."""
    return finite(name, value, lo=None if lo == -math.inf else lo, strict=strict, unit=unit, error=error, eq="=")


def finite_array(name: str, x: Any, unit: str, lo: float = 0.0, *, error: type[Exception] = ModelError) -> np.ndarray:
    """``x`` as a float array, every element finite and >= ``lo`` (no bound for ``-inf``), else
    ``error`` naming the first bad element."""
    x = np.asarray(x, dtype=float)
    ok = np.isfinite(x) if lo == -math.inf else np.isfinite(x) & (x >= lo)
    if not ok.all():
        i = int(np.flatnonzero(~ok.ravel())[0])
        raise error(f"{name}[{i}]={float(x.ravel()[i])!r} {unit} must be finite and >= {lo:g}")
    return x


_num, _array = finite_number, finite_array


class CurrentProfile:
    """Current over depth: ``v_c(z) = V_c phi(z) (cos beta_c, sin beta_c, 0)`` in {E} (eq. 7).

    ``phi = 1`` ('uniform'); linear from 1 at z = 0 to ``current_profile_factors[0]`` at the
    seabed ('linear'); linear through ``(current_profile_depths, current_profile_factors)``,
    constant beyond the ends ('piecewise'). Depths are clamped to [0, water_depth]. The direction
    does not change with depth.

    Parameters
    ----------
    sea_state : tapm_opt.config.SeaState
    water_depth : float
        Seabed depth [m], > 0.

    Raises
    ------
    ModelError
        A speed, direction, depth or factor that is not finite or out of range, or an
        inconsistent profile (the message names the field and its value).
    """

    def __init__(self, sea_state: schema.SeaState, water_depth: float):
        self.water_depth = _num("environment.water_depth", water_depth, lo=0.0, strict=True, unit="m")
        V = _num("sea_state.current_speed", sea_state.current_speed, lo=0.0, unit="m/s")
        beta = _num("sea_state.current_direction", sea_state.current_direction, unit="rad")
        self.kind = kind = sea_state.current_profile
        d = _array("sea_state.current_profile_depths", sea_state.current_profile_depths, "m")
        fac = _array("sea_state.current_profile_factors", sea_state.current_profile_factors, "")
        if (kind not in ("uniform", "linear", "piecewise") or (kind == "linear" and fac.size != 1) or (
                kind == "piecewise" and (d.size < 1 or d.size != fac.size or np.any(np.diff(d) <= 0)))):
            raise ModelError(f"sea_state.current_profile={kind!r}, depths {d.tolist()}, factors {fac.tolist()}: "
                             "need 'uniform', 'linear' (1 factor) or 'piecewise' (increasing depths, 1 factor each)")
        self._depths, self._factors = d, fac
        # np.interp holds the end factors beyond the end depths: with every depth in [0,
        # water_depth] (depths are >= 0) it clamps z as phi does, and the clamp can be skipped
        self._interp_clamps = kind == "piecewise" and bool(d[-1] <= self.water_depth)
        self.surface = np.array([V * math.cos(beta), V * math.sin(beta), 0.0])
        self.surface.flags.writeable = False

    @property
    def breakpoints(self) -> np.ndarray:
        """Depths [m] inside (0, water_depth) where phi(z) changes slope (the 'piecewise' depths;
        none for 'uniform' and 'linear'): phi is linear between them."""
        if self.kind != "piecewise":
            return readonly(np.zeros(0))
        d = self._depths
        return readonly(d[(d > 0.0) & (d < self.water_depth)])

    def factor(self, z: Any) -> np.ndarray:
        """Speed factor phi(z) [-] at depths z [m] (positive down), shape of ``z``."""
        if self.kind == "piecewise" and self._interp_clamps:
            return np.interp(z, self._depths, self._factors)
        z = np.minimum(np.maximum(z, 0.0), self.water_depth)
        if self.kind == "uniform":
            return np.ones_like(z)
        if self.kind == "linear":
            return 1.0 + (self._factors[0] - 1.0) * (z / self.water_depth)
        return np.interp(z, self._depths, self._factors)

    def velocity(self, z: Any) -> np.ndarray:
        """Current velocity in {E} at depths ``z`` [m], shape ``z.shape + (3,)`` [m/s]; v_z = 0."""
        return self.velocity_unchecked(_array("z", z, "m", -math.inf))

    def velocity_unchecked(self, z: np.ndarray) -> np.ndarray:
        """:meth:`velocity` for depths the caller has checked (a float array of finite depths [m]):
        the FEM plant's every step, which checks its nodes' health itself."""
        return np.multiply.outer(self.factor(z), self.surface)


@dataclass(frozen=True, kw_only=True, eq=False)
class HullWindLoad:
    """Wind-load model of a hull (module docstring).

    Parameters
    ----------
    c_x, c_y, c_n : float
        Wind-load coefficients [-], >= 0 (a large tanker/FPSO: 0.7-0.9, 0.8-0.95, 0.08-0.1).
    A_F, A_L : float
        Frontal and lateral projected wind areas [m^2], >= 0.
    L_pp : float
        Length between perpendiculars [m], >= 0.
    rho_a : float
        Air density [kg/m^3], > 0.
    """

    c_x: float
    c_y: float
    c_n: float
    A_F: float
    A_L: float
    L_pp: float
    rho_a: float

    def __post_init__(self) -> None:
        for name in ("c_x", "c_y", "c_n", "A_F", "A_L", "L_pp"):
            object.__setattr__(self, name, _nonneg(name, getattr(self, name)))
        object.__setattr__(self, "rho_a", _nonneg("rho_a", self.rho_a, strict=True))
        object.__setattr__(self, "_k", readonly(-0.5 * self.rho_a * np.array(
            [self.c_x * self.A_F, self.c_y * self.A_L, 2.0 * self.c_n * self.A_L * self.L_pp])))

    @property
    def k(self) -> np.ndarray:
        """``-1/2 rho_a (c_x A_F, c_y A_L, 2 c_n A_L L_pp)`` [kg/m, kg/m, kg], shape (3,)."""
        return self._k

    def tau(self, V: Any, beta_w: Any, psi: Any, u: Any = 0.0, v: Any = 0.0) -> np.ndarray:
        """Wind load on the hull in {B} (module docstring); arguments broadcast together.

        Parameters
        ----------
        V : float or array_like
            Wind speed [m/s], >= 0.
        beta_w : float or array_like
            Direction the wind is going to, in {E} from north [rad].
        psi : float or array_like
            Vessel heading [rad].
        u, v : float or array_like
            Vessel surge and sway velocity in {B} [m/s] (0: at rest).

        Returns
        -------
        ndarray, shape broadcast + (3,)
            (X [N], Y [N], N [N m]) in {B}.
        """
        if type(V) is type(beta_w) is type(psi) is type(u) is type(v) is float:
            # one load of floats (the plant's per-step call): math.cos/sin, the C library's (numpy's own bits except where it has AVX-512 sin/cos), faster
            b = beta_w - psi
            cb, sb = math.cos(b), math.sin(b)
        else:
            b = np.subtract(beta_w, psi)
            cb, sb = np.cos(b), np.sin(b)
        u_rw = u - V * cb
        v_rw = v - V * sb
        V_rw = np.hypot(u_rw, v_rw)
        parts = (V_rw * u_rw, V_rw * v_rw, u_rw * v_rw)
        # np.array for one load: a control-loop call, several times faster than np.stack
        return self._k * (np.array(parts) if np.ndim(V_rw) == 0 else np.stack(parts, axis=-1))
