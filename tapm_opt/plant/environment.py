"""Plant environment: current profile, irregular waves (WF motion, 2nd-order drift), wind.

The current over depth is the models' :class:`tapm_opt.models.environment.CurrentProfile` (one
definition, also used by the riser model), imported here so ``plant.environment.CurrentProfile``
keeps working; it raises :class:`~tapm_opt.errors.ModelError` for bad input, which
:class:`Environment` reports as a :class:`PlantError`.

Directions (survey eq. 7): where a current, wave or wind is *going to*, in {E} from north (x)
toward east (y). Loads in {B}, motions in {E}. Current loads act through ``nu_r`` in the vessel
model (eq. 8-15). Randomness is drawn once at construction (``numpy.random.default_rng(seed)``).
Models, constants, assumptions and references: ``docs/plant_environment.md``."""

from __future__ import annotations

import contextlib
import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..config import schema
from ..errors import ModelError, TapmError
from ..models.environment import CurrentProfile, HullWindLoad, finite_array, finite_number

__all__ = ["PlantError", "jonswap", "npd_spectrum", "CurrentProfile", "WaveParams", "WaveField",
           "WindParams", "Wind", "Environment", "hull_rao", "heading_interp", "N_HEADINGS", "Development",
           "DevelopingWaveField", "DevelopingWind", "spreading_directions", "hull_drift"]


class PlantError(TapmError, ValueError):
    """The plant was given an invalid parameter or input (message names the field and value)."""


def _num(name: str, value: Any, *, lo: float = -math.inf, strict: bool = False, unit: str = "") -> float:
    return finite_number(name, value, lo=lo, strict=strict, unit=unit, error=PlantError)


def _array(name: str, x: Any, unit: str, lo: float = 0.0) -> np.ndarray:
    return finite_array(name, x, unit, lo, error=PlantError)


def _time(t: Any) -> float | np.ndarray:
    if isinstance(t, (float, int)) and math.isfinite(t):
        return float(t)
    return _array("t", t, "s", -math.inf) if np.ndim(t) else _num("t", t, unit="s")


#: Most outer-step times of one block of precomputed wave and wind sums (:meth:`WaveField.block`,
#: :meth:`Wind.block`): 512 steps of 0.1 s are 51.2 s of simulated time, (512, 200) work arrays.
BLOCK_MAX = 512


#: Relative wave headings of the six-degree-of-freedom motion's sums (:meth:`WaveField.vertical_block`):
#: every 5 degrees, interpolated linearly between them (:func:`heading_interp`).
N_HEADINGS = 72

#: Singular values of the heading grid's weights kept in :meth:`WaveField.vertical_block`, relative
#: to the largest.
SVD_RTOL = 1e-12


_BLAS: Any = None


def _one_blas_thread() -> Any:
    """A context in which the BLAS runs on one thread (threadpoolctl; none without it): the drift
    sums' block product, (512, 200) by (200, 216), is large enough for OpenBLAS to wake its other
    threads, which then spin on the cores the compiled plant steps run on (fpso's storm with a
    full-rank table on 2 cores: 1.4x the plant's time without a table, 1.03x on one thread)."""
    global _BLAS
    if _BLAS is None:
        try:
            from threadpoolctl import ThreadpoolController
            _BLAS = tuple(ThreadpoolController().select(user_api="blas").lib_controllers)
        except Exception:   # threadpoolctl missing or failing: the BLAS as it is
            _BLAS = ()
    return _OneBlasThread(_BLAS) if _BLAS else contextlib.nullcontext()


class _OneBlasThread:
    """The context of :func:`_one_blas_thread`: each BLAS library's thread count set to 1 on entry
    and restored on exit, by the libraries' own calls (``threadpoolctl.ThreadpoolController.limit``
    lists the loaded libraries at every entry, ~140 us; this is ~2 us)."""

    __slots__ = ("_libs", "_old")

    def __init__(self, libs: tuple) -> None:
        self._libs = libs
        self._old: list[int] = []

    def __enter__(self) -> None:
        self._old = [lib.get_num_threads() for lib in self._libs]
        for lib, n in zip(self._libs, self._old):
            if n != 1:
                lib.set_num_threads(1)

    def __exit__(self, *exc: Any) -> None:
        for lib, n in zip(self._libs, self._old):
            if n != 1:
                lib.set_num_threads(n)


def spreading_directions(s: float, rng: np.random.Generator, n: int) -> np.ndarray:
    """n directions off the mean [rad] drawn from the cos-2s spreading function ``D(theta) =
    Gamma(s + 1) / (2 sqrt(pi) Gamma(s + 1/2)) cos^(2s)(theta / 2)`` on (-pi, pi] (DNV-RP-C205
    §3.5.8.4), one per wave component (the single-direction-per-frequency method: each component
    keeps its amplitude, so the spectrum's energy is the long-crested one's), stratified: the
    i-th of n equal-probability slices of D, a uniform draw inside it, by inverting D's
    cumulative distribution (tabulated on 4001 points), then shuffled over the frequencies."""
    theta = np.linspace(-math.pi, math.pi, 4001)
    log_c = math.lgamma(s + 1.0) - math.lgamma(s + 0.5) - math.log(2.0 * math.sqrt(math.pi))
    dens = np.exp(log_c + 2.0 * s * np.log(np.maximum(np.cos(theta / 2.0), 1e-300)))
    cdf = np.concatenate([[0.0], np.cumsum(0.5 * (dens[1:] + dens[:-1]) * np.diff(theta))])
    cdf /= cdf[-1]
    u = (np.arange(n) + rng.random(n)) / n
    return rng.permutation(np.interp(u, cdf, theta))


def heading_bracket(direction: float, psi: float) -> tuple[int, int, float]:
    """The grid headings g0, g1 = g0 + 1 (mod G) about ``beta = direction - psi`` [rad] taken
    into [0, 2 pi) and the fraction f [-] of the way from g0 to g1 (G = :data:`N_HEADINGS`).
    Plain float arithmetic, the compiled plant's ``fem_kernel._heading_bracket`` the same."""
    G = N_HEADINGS
    b = direction - psi
    b = b - 2.0 * math.pi * math.floor(b / (2.0 * math.pi))
    x = b * (G / (2.0 * math.pi))
    g0 = min(int(x), G - 1)
    f = x - g0
    g1 = 0 if g0 == G - 1 else g0 + 1
    return g0, g1, f


def heading_interp(grid: Any, direction: float, psi: float) -> np.ndarray:
    """Linear interpolation (K,) of sums on the heading grid ``grid`` (K G,) (column ``K g + d`` at
    the relative heading ``beta_g = 2 pi g / G``, G = :data:`N_HEADINGS`) at ``beta = direction -
    psi`` [rad] taken into [0, 2 pi); rows of sums (n, K G) give (n, K). Plain float arithmetic, the same operations as the compiled plant's
    (:func:`tapm_opt.plant.fem_kernel.plant_pre_step`)."""
    K = np.shape(grid)[-1] // N_HEADINGS
    g0, g1, f = heading_bracket(direction, psi)
    if np.ndim(grid) > 1:   # rows of sums (a time series): the same operations, elementwise
        v0 = grid[..., K * g0:K * g0 + K]
        return v0 + f * (grid[..., K * g1:K * g1 + K] - v0)
    out = np.empty(K)
    for d in range(K):
        v0 = float(grid[K * g0 + d])
        out[d] = v0 + f * (float(grid[K * g1 + d]) - v0)
    return out


def _rotations(omega: np.ndarray, h: float, n: int, cache: dict) -> tuple[np.ndarray, np.ndarray]:
    """``cos(omega j h)`` and ``sin(omega j h)`` for j = 0 .. n-1, each (n, N): the rotation of
    every component over j steps of h [s]; cached per step length (the same for every block).
    The first 16 rows are evaluated directly, later ones by doubling: rows ``[m, 2m)`` are rows
    ``[0, m)`` turned by ``omega m h`` (a rounding per doubling, 1e-15 at 512 rows)."""
    tab = cache.get(h)
    if tab is None:
        if len(cache) >= 4:
            cache.clear()
        b = np.multiply.outer(np.arange(16) * h, omega)
        tab = cache[h] = (np.cos(b), np.sin(b))
    while tab[0].shape[0] < n:
        c, s = tab
        m = c.shape[0]
        cm, sm = np.cos(omega * (m * h)), np.sin(omega * (m * h))
        tab = cache[h] = (np.concatenate([c, c * cm - s * sm]), np.concatenate([s, s * cm + c * sm]))
    return tab[0][:n], tab[1][:n]


def _block_trig(t0: float, h: float, n: int, omega: np.ndarray, phase: np.ndarray,
                cache: dict) -> tuple[np.ndarray, np.ndarray]:
    """``sin theta`` and ``cos theta``, each (n, N), of ``theta = omega t + phase`` at the times
    ``t0 + j h`` [s], j < n, by the angle sums: ``theta_0 = omega t0 + phase`` (the scalar path's
    phase) plus ``omega j h`` (:func:`_rotations`). As accurate as the direct sines (a few units in
    the last place of the phase, which the direct ``omega t`` has too), without n N of them."""
    th0 = t0 * omega + phase
    s0, c0 = np.sin(th0), np.cos(th0)
    cb, sb = _rotations(omega, h, n, cache)
    return s0 * cb + c0 * sb, c0 * cb - s0 * sb


def jonswap(omega: Any, Hs: float, Tp: float, gamma: float = 3.3) -> np.ndarray:
    """JONSWAP wave spectrum S(w) [m^2 s/rad], shape of ``omega``; DNV-RP-C205 §3.5.5.

    ``S = A_g S_PM gamma^exp(-(w - wp)^2 / (2 sigma^2 wp^2))``, ``S_PM = 5/16 Hs^2 wp^4 w^-5
    exp(-5/4 (w/wp)^-4)``, ``wp = 2 pi/Tp``, ``A_g = 1 - 0.287 ln gamma``, ``sigma = 0.07`` (w <=
    wp) or 0.09; ``gamma = 1``: Pierson-Moskowitz. Area Hs^2/16 within 2 % for gamma <= 7.

    Parameters
    ----------
    omega : array_like
        Angular frequencies [rad/s], >= 0 (S(0) = 0).
    Hs, Tp, gamma : float
        Significant wave height [m] >= 0, peak period [s] > 0, peak enhancement [-] in [1, 10].
    """
    Hs = _num("Hs", Hs, lo=0.0, unit="m")
    Tp = _num("Tp", Tp, lo=0.0, strict=True, unit="s")
    if not 1.0 <= _num("gamma", gamma) <= 10.0:
        raise PlantError(f"gamma={gamma!r} must be in [1, 10]")
    return _jonswap(_array("omega", omega, "rad/s"), Hs, Tp, gamma)


def _jonswap(w: np.ndarray, Hs: Any, Tp: Any, gamma: float) -> np.ndarray:
    """:func:`jonswap` on checked input; ``Hs`` and ``Tp`` may be arrays that broadcast with ``w``
    (a developing sea's spectrum at many times)."""
    wp = 2.0 * math.pi / Tp
    x = np.where(w > 0, w, wp) / wp
    with np.errstate(over="ignore"):
        S_pm = 5.0 / 16.0 * Hs**2 / wp * np.exp(-5.0 * np.log(x) - 1.25 * x**-4)
    sigma = np.where(x <= 1.0, 0.07, 0.09)
    S = (1.0 - 0.287 * math.log(gamma)) * S_pm * gamma ** np.exp(-0.5 * ((x - 1.0) / sigma) ** 2)
    return np.where(w > 0, S, 0.0)


def npd_spectrum(f: Any, U10: float, z: float = 10.0) -> np.ndarray:
    """NPD (Frøya) gust spectrum S(f) [m^2/s^2 per Hz], DNV-RP-C205 §2.3.4, ISO 19901-1.

    ``S = 320 (U10/10)^2 (z/10)^0.45 / (1 + x^n)^(5/(3n))``, ``x = 172 f (z/10)^(2/3)
    (U10/10)^(-3/4)``, ``n = 0.468``.

    Parameters
    ----------
    f : array_like
        Frequencies [Hz], >= 0.
    U10, z : float
        1-hour mean wind speed at 10 m [m/s] >= 0 (0: zero spectrum); height [m] > 0.
    """
    U10 = _num("U10", U10, lo=0.0, unit="m/s")
    z = _num("z", z, lo=0.0, strict=True, unit="m")
    f = _array("f", f, "Hz")
    if U10 == 0.0:
        return np.zeros_like(f)
    return _npd(f, U10, z)


def _npd(f: np.ndarray, U10: Any, z: float) -> np.ndarray:
    """:func:`npd_spectrum` on checked input, ``U10`` > 0 possibly an array broadcasting with ``f``
    (zero where ``U10`` is 0)."""
    if np.ndim(U10):
        U10 = np.asarray(U10, dtype=float)
        Ub = np.where(U10 > 0, U10, 1.0)
        return np.where(U10 > 0, _npd_formula(f, Ub, z), 0.0)
    return _npd_formula(f, U10, z)


def _npd_formula(f: np.ndarray, U10: Any, z: float) -> np.ndarray:
    n = 0.468
    x = 172.0 * f * (z / 10.0) ** (2.0 / 3.0) * (U10 / 10.0) ** -0.75
    return 320.0 * (U10 / 10.0) ** 2 * (z / 10.0) ** 0.45 / (1.0 + x**n) ** (5.0 / (3.0 * n))


def _check_params(p: Any, band: tuple[str, str], nonneg: tuple[str, ...]) -> None:
    cls = type(p).__name__
    if not isinstance(p.n_components, (int, np.integer)) or p.n_components < 1:
        raise PlantError(f"{cls}.n_components={p.n_components!r} must be an integer >= 1")
    for name in nonneg:
        _num(f"{cls}.{name}", getattr(p, name), lo=0.0)
    lo = _num(f"{cls}.{band[0]}", getattr(p, band[0]), lo=0.0, strict=True)
    _num(f"{cls}.{band[1]} (> {band[0]})", getattr(p, band[1]), lo=lo, strict=True)


@dataclass(frozen=True, kw_only=True)
class WaveParams:
    """Discretisation and coefficients of :class:`WaveField`: ``n_components`` N (one per equal
    frequency bin); band ``[omega_min, omega_max]`` as multiples of w_p [-] (99.5 % of the variance);
    ``yaw_rao`` c_psi of the yaw RAO ``c_psi k h_L sin 2beta`` [rad per rad of wave slope k a];
    ``drift_yaw`` c_N of the yaw drift coefficient ``-1/2 rho g L^2 c_N R(w) sin 2beta`` [-]."""

    n_components: int = 200
    omega_min: float = 0.5
    omega_max: float = 4.0
    yaw_rao: float = 1.0
    drift_yaw: float = 0.05

    def __post_init__(self) -> None:
        _check_params(self, ("omega_min", "omega_max"), ("yaw_rao", "drift_yaw"))


class WaveField:
    """Long-crested first-order irregular sea, its WF vessel motion and 2nd-order drift loads.

    ``zeta(t) = sum_k a_k cos theta_k``, ``theta_k = w_k t + phi_k``, ``a_k = sqrt(2 S(w_k) dw)``
    (a random frequency in each of N equal bins, random phases) at the field zero point. With
    ``beta = beta_wave - psi``, ``k = w^2/g``, hull filters ``h_l = 1/(1 + (w/w_l)^4)``, ``w_l =
    sqrt(pi g/l)`` for l = L_pp (h_L) or breadth (h_B):

    * WF motion in {B} (RAO superposition, Fossen 2011 §8.2; a short body follows the orbital
      displacement ``a sin theta``, Faltinsen 1990 ch. 2): surge ``cos beta sum a h_L sin theta``,
      sway ``sin beta sum a h_B sin theta``, yaw ``sin 2beta sum c_psi k h_L a cos theta``.
    * Drift in {B} (Newman 1974): ``F(t) = 2 c(beta) (sum a_k sqrt(R_k) cos theta_k)^2`` of mean
      ``sum D(w_k) a_k^2``, ``D = R(w) c(beta)``, ``c = 1/2 rho g (B cos|cos|, L sin|sin|, -c_N L^2
      sin 2beta)`` (wall-sided body, Faltinsen 1990 ch. 5), ``R(w) = 1 - exp(-2 k T)``; or, with
      the user's coefficients ``drift(omega, beta)`` (:meth:`_drift_weights`), ``F_i = 2 s_i
      (sum a_k sqrt|D_i(w_k, beta)| cos theta_k)^2``, ``s_i`` the sign of the mean ``sum a_k^2
      D_i(w_k, beta)``, on the heading grid.

    Parameters
    ----------
    sea_state, vessel, env : tapm_opt.config.SeaState, Vessel, Environment
        Hs, Tp, gamma, wave_direction; length_pp, breadth, draught; water_density, gravity.
    seed : int, SeedSequence or Generator
        Passed to ``numpy.random.default_rng``.
    params : WaveParams
    rao : callable, optional
        The hull's transfer functions ``rao(omega, beta)`` (:func:`hull_rao`; None: the horizontal
        model).
    drift : callable, optional
        The hull's mean drift coefficients ``drift(omega, beta)`` -> (..., 3) [N/m^2, N/m^2,
        N m/m^2] (:func:`hull_drift`; None: the wall-sided formula).
    """

    def __init__(self, sea_state: schema.SeaState, vessel: schema.Vessel, env: schema.Environment,
                 seed: Any = None, *, params: WaveParams = WaveParams(), rao: Any = None, drift: Any = None):
        self.Hs = _num("sea_state.Hs", sea_state.Hs, lo=0.0, unit="m")
        self.Tp = _num("sea_state.Tp", sea_state.Tp, lo=0.0, strict=True, unit="s")
        self.direction = _num("sea_state.wave_direction", sea_state.wave_direction, unit="rad")
        L, B, T = (_num(f"vessel.{n}", getattr(vessel, n), lo=0.0, strict=True, unit="m")
                   for n in ("length_pp", "breadth", "draught"))
        rho, g = (_num(f"environment.{n}", getattr(env, n), lo=0.0, strict=True)
                  for n in ("water_density", "gravity"))
        self.params = p = params
        self.gamma = float(sea_state.gamma)
        rng, N = np.random.default_rng(seed), int(p.n_components)
        wp_lo, wp_hi = self._peak_band(sea_state)
        # N equal bins over [omega_min, omega_max] times the peak frequency (a developing sea: from
        # its lowest to its highest peak frequency)
        dw = ((p.omega_max - p.omega_min) * wp_lo / N if wp_lo == wp_hi
              else (p.omega_max * wp_hi - p.omega_min * wp_lo) / N)
        self.omega = w = p.omega_min * wp_lo + dw * (np.arange(N) + rng.random(N))
        self.phase = 2.0 * math.pi * rng.random(N)
        self._dw = dw
        self.amplitude = a = np.sqrt(2.0 * jonswap(w, self.Hs, self.Tp, sea_state.gamma) * dw)
        self._g, self._L, self._B = g, L, B
        k = w**2 / g
        self.reflection = 1.0 - np.exp(-2.0 * k * T)
        # short-crested: each component's direction off the mean (one direction per frequency)
        s_spread = getattr(sea_state, "wave_spreading", None)
        self.spreading = None if s_spread is None else _num("sea_state.wave_spreading", s_spread, lo=0.0, strict=True)
        self.delta = np.zeros(N) if self.spreading is None else spreading_directions(self.spreading, rng, N)
        self._Ws, self._Wc = self._horizontal_weights(a)
        self._drift_c = 0.5 * rho * g * np.array([B, L, p.drift_yaw * L**2])
        # the drift factor of a short-crested sea on the heading grid: c(beta + delta_k) weighted by
        # each component's share a_k^2 R_k of the drift (none when long-crested)
        self._drift_grid = np.zeros(0)
        if self.spreading is not None:
            share = a**2 * self.reflection
            share = share / share.sum() if share.sum() > 0 else np.full(N, 1.0 / N)
            beta = 2.0 * math.pi / N_HEADINGS * np.arange(N_HEADINGS)[None, :] + self.delta[:, None]
            cb, sb = np.cos(beta), np.sin(beta)
            c = np.stack([cb * np.abs(cb), sb * np.abs(sb), -np.sin(2.0 * beta)], axis=-1) * self._drift_c
            self._drift_grid = np.ascontiguousarray(np.einsum("k,kgd->gd", share, c).reshape(-1))
        self._cache: tuple[float, np.ndarray, np.ndarray] | None = None
        self._dir_cache: tuple[float, Any] | None = None
        # work arrays of the scalar-time sums (theta, sin theta, cos theta), shape (N,)
        self._th, self._sin, self._cos = np.empty(N), np.empty(N), np.empty(N)
        self._rot_cache: dict = {}  # rotation tables of the block sums, per step length
        self._vertical_weights(rao, a)
        self._drift_weights(drift, a)

    def _peak_band(self, sea_state: Any) -> tuple[float, float]:
        """The lowest and highest peak frequency [rad/s] the components must cover (the sea
        state's own; a developing sea's over its time table)."""
        wp = 2.0 * math.pi / self.Tp
        return wp, wp

    def _horizontal_weights(self, a: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Weights of sin(theta) (surge, sway, -yaw rate) and of cos(theta) (yaw, drift, surge and
        sway rates), (3, N) and (4, N), for component amplitudes ``a`` [m] (ones: per metre)."""
        p, w, g = self.params, self.omega, self._g
        k = w**2 / g
        h_L = 1.0 / (1.0 + (w / math.sqrt(math.pi * g / self._L)) ** 4)
        h_B = 1.0 / (1.0 + (w / math.sqrt(math.pi * g / self._B)) ** 4)
        return (np.stack([a * h_L, a * h_B, p.yaw_rao * k * h_L * a * w]),
                np.stack([p.yaw_rao * k * h_L * a, a * np.sqrt(self.reflection), a * h_L * w, a * h_B * w]))

    def horizontal_rao(self, omega: Any, beta: Any) -> np.ndarray:
        """The parametric surge, sway and yaw transfer functions (..., 3) in {B} of the model above
        (complex per metre of wave amplitude; ``surge = cos beta a h_L sin theta`` is ``-i h_L cos
        beta``), for the heading grid of a short-crested sea."""
        p, g = self.params, self._g
        w = np.asarray(omega, dtype=float)
        k = w**2 / g
        h_L = 1.0 / (1.0 + (w / math.sqrt(math.pi * g / self._L)) ** 4)
        h_B = 1.0 / (1.0 + (w / math.sqrt(math.pi * g / self._B)) ** 4)
        return np.stack(np.broadcast_arrays(-1j * h_L * np.cos(beta), -1j * h_B * np.sin(beta),
                                            (p.yaw_rao * k * h_L) * np.sin(2.0 * beta) + 0j), axis=-1)

    def _vertical_weights(self, rao: Any, a: np.ndarray) -> None:
        """The weights of the motion sums on the relative-heading grid (:data:`N_HEADINGS` headings
        ``beta_g = 2 pi g / G``), rows ``[cos theta; sin theta]``, column ``K g + d``:
        ``x_d(t, beta_g) = sum_k a_k (Re H_kgd cos theta_k - Im H_kgd sin theta_k)`` with ``H =
        rao(omega (N,), beta (G,))`` complex per metre of wave amplitude: (N, G, 3) heave, roll and
        pitch (:func:`tapm_opt.models.rao.closed_form_rao`; K = 3), or (N, G, 6) all six degrees
        of freedom in the order surge, sway, heave, roll, pitch, yaw (a user's table,
        :class:`tapm_opt.models.rao.RAOTable`; K = 6, stored heave, roll, pitch, surge, sway, yaw:
        the hull's surge, sway and yaw then come from the table, :attr:`grid_horizontal`).
        None (``six_dof`` False) without ``rao``."""
        self.six_dof = rao is not None
        N, G = self.omega.size, N_HEADINGS
        self.grid_horizontal = False
        self._Wv_lr = None
        if rao is None and self.spreading is None:
            self._Wv = self._Wv_dot = np.zeros((2 * N, 0))
            return
        # each component at its own direction: beta_g + delta_k (delta 0 when long-crested)
        omega, beta = self.omega[:, None], 2.0 * math.pi / G * np.arange(G)[None, :] + self.delta[:, None]
        H = np.zeros((N, G, 3), complex) if rao is None else np.asarray(rao(omega, beta))
        if H.ndim != 3 or H.shape[:2] != (N, G) or H.shape[2] not in (3, 6) or not np.isfinite(H).all():
            raise PlantError(f"the hull's transfer functions have shape {H.shape} (expected {(N, G, 3)} or "
                             f"{(N, G, 6)}) or are not finite")
        if H.shape[2] == 3 and self.spreading is not None:   # short-crested: surge, sway, yaw on the grid too
            hr = self.horizontal_rao(omega, beta)
            H = np.concatenate([hr[:, :, :2], H, hr[:, :, 2:]], axis=2)   # surge, sway, heave, roll, pitch, yaw
        if H.shape[2] == 6:
            H = H[:, :, [2, 3, 4, 0, 1, 5]]
            self.grid_horizontal = True
        K = H.shape[2]
        aw = (a * self.omega)[:, None, None]
        a = a[:, None, None]
        self._Wv = np.concatenate([(a * H.real).reshape(N, K * G), (-a * H.imag).reshape(N, K * G)])
        self._Wv_dot = np.concatenate([(-aw * H.imag).reshape(N, K * G), (-aw * H.real).reshape(N, K * G)])
        # the block's product through the weights' leading singular vectors: the heading grid's
        # columns are smooth in the heading, so few carry them (49 of 216 for fpso's closed form
        # at 1e-12 of the largest): (n, 2N) @ (2N, r) @ (r, K G), several times cheaper
        U, sv, Vt = np.linalg.svd(self._Wv, full_matrices=False)
        r = int(np.count_nonzero(sv > SVD_RTOL * sv[0])) if sv.size and sv[0] > 0 else 0
        self._Wv_lr = (U[:, :r] * sv[:r], Vt[:r]) if 0 < r < K * G // 2 else None

    def _drift_weights(self, drift: Any, a: np.ndarray) -> None:
        """The weights of the drift sums of the user's mean drift coefficients on the heading grid
        (:data:`N_HEADINGS` headings ``beta_g = 2 pi g / G``, column ``3 g + i`` for surge, sway,
        yaw): ``q_i(t, beta_g) = sum_k a_k sqrt|D_i(w_k, beta_g + delta_k)| cos theta_k`` with ``D =
        drift(omega (N, 1), beta (N, G))`` (N, G, 3) (each component at its own direction, as the
        motion's grid takes it), for component amplitudes ``a`` [m] (ones: per metre); the sign
        ``s_i`` of the mean ``sum a_k^2 D_i`` and the mean ``s_i sum a_k^2 |D_i|`` of each column,
        of the amplitudes :attr:`amplitude`. None (``drift_table`` False, no columns) without
        ``drift``: the wall-sided formula (:meth:`drift_factor`)."""
        N, G = self.omega.size, N_HEADINGS
        self.drift_table = drift is not None
        self._Wd_lr = None
        if drift is None:
            self._Wd = np.zeros((N, 0))
            self._drift_D = np.zeros((N, 0))
            self._drift_sign = self._drift_mean = np.zeros(0)
            return
        beta = 2.0 * math.pi / G * np.arange(G)[None, :] + self.delta[:, None]
        D = np.asarray(drift(self.omega[:, None], beta), dtype=float)
        if D.shape != (N, G, 3) or not np.isfinite(D).all():
            raise PlantError(f"the hull's mean drift coefficients have shape {D.shape} (expected {(N, G, 3)}) "
                             "or are not finite")
        self._drift_D = D = D.reshape(N, 3 * G)
        root = np.sqrt(np.abs(D))
        self._Wd = a[:, None] * root
        a2 = self.amplitude**2
        self._drift_sign = np.sign(a2 @ D)
        self._drift_mean = self._drift_sign * (a2 @ np.abs(D))
        # the block's product through the weights' leading singular vectors, as vertical_block's
        U, sv, Vt = np.linalg.svd(self._Wd, full_matrices=False)
        r = int(np.count_nonzero(sv > SVD_RTOL * sv[0])) if sv.size and sv[0] > 0 else 0
        self._Wd_lr = (U[:, :r] * sv[:r], Vt[:r]) if 0 < r < 3 * G // 2 else None

    def _drift_sign_at(self, t: Any) -> np.ndarray:
        """The sign ``s_i`` of the mean drift on the heading grid (3 G,) at time(s) t (the
        stationary sea's: the same at every time)."""
        return self._drift_sign

    def _scale_cos(self, c: np.ndarray, t: Any) -> np.ndarray:
        """``cos theta`` (..., N) at the times t as the drift weights take them (the stationary
        field's weights carry the amplitudes: unchanged)."""
        return c

    def drift_block(self, t0: float, h: float, n: int) -> np.ndarray:
        """The drift sums ``q_i`` on the heading grid (:meth:`_drift_weights`) at the n times ``t0
        + j h`` [s], shape (n, 3 G); (n, 0) without the user's drift coefficients. The same angle
        sums as :meth:`block`, through the weights' leading singular vectors."""
        if not self._Wd.shape[1]:
            return np.zeros((int(n), 0))
        _, cos_th = _block_trig(float(t0), float(h), int(n), self.omega, self.phase, self._rot_cache)
        cos_th = self._scale_cos(cos_th, float(t0) + float(h) * np.arange(int(n)))
        with _one_blas_thread():
            return (cos_th @ self._Wd_lr[0]) @ self._Wd_lr[1] if self._Wd_lr is not None else cos_th @ self._Wd

    def drift_of(self, grid: Any, psi: float, t: float = 0.0) -> np.ndarray:
        """The drift load (3,) [N, N, N m] in {B} at the LF heading psi [rad] from the drift sums
        on the heading grid (3 G,) at time t [s] (:meth:`drift_block`): ``2 s q^2`` on the grid,
        interpolated linearly in the relative heading (:func:`heading_interp`) — the plant's
        compiled step does the same operations."""
        F = 2.0 * grid * grid * self._drift_sign_at(t)
        return heading_interp(F, self.direction, psi)

    def _sums(self, t: Any) -> tuple[np.ndarray, np.ndarray]:
        """(W_sin @ sin theta, W_cos @ cos theta), shapes (3, ...) and (4, ...); last t cached."""
        if type(t) is not float or not math.isfinite(t):  # a finite float needs no check
            t = _time(t)
        if isinstance(t, float):
            if self._cache is not None and self._cache[0] == t:
                return self._cache[1], self._cache[2]
            th = np.multiply(t, self.omega, out=self._th)
            th += self.phase
            S, C = self._Ws @ np.sin(th, out=self._sin), self._Wc @ np.cos(th, out=self._cos)
            self._cache = (t, S, C)
            return S, C
        th = t[..., None] * self.omega + self.phase
        return np.moveaxis(np.sin(th) @ self._Ws.T, -1, 0), np.moveaxis(np.cos(th) @ self._Wc.T, -1, 0)

    def block(self, t0: float, h: float, n: int) -> tuple[np.ndarray, np.ndarray]:
        """The sums of :meth:`_sums` at the n times ``t0 + j h`` [s] (j < n) at once: ``(S (n, 3),
        C (n, 4))`` — the plant's outer steps (:class:`tapm_opt.plant.simulator.Plant`), a block
        at a time. The same sums as the scalar path to a few units in the last place of the
        phases (:func:`_block_trig`; the sums in another order)."""
        sin_th, cos_th = _block_trig(float(t0), float(h), int(n), self.omega, self.phase, self._rot_cache)
        return sin_th @ self._Ws.T, cos_th @ self._Wc.T

    def _scale_trig(self, cs: np.ndarray, t: Any) -> np.ndarray:
        """The rows ``[cos theta, sin theta]`` (..., 2N) at the times t, as the weights take them
        (the stationary field's weights carry the amplitudes: unchanged)."""
        return cs

    def ramp(self, t: Any) -> tuple[Any, Any]:
        """The factor ``s(t)`` [-] that brings the heave, roll and pitch in over the first
        peak period (raised cosine ``(1 - cos(pi t / T_p)) / 2``, 1 after T_p, 0 before t = 0) and
        its rate ``s'(t)`` [1/s]. The lines settle with the hull at rest; a fairlead that starts
        at its full wave-frequency velocity sends a stress wave down its line (2.7 % of fpso's
        fairlead tension in the storm in the first 0.1 s with heave, roll and pitch)."""
        T = self.Tp
        x = np.clip(np.asarray(t, dtype=float) / T, 0.0, 1.0)
        return 0.5 * (1.0 - np.cos(math.pi * x)), np.where((x > 0) & (x < 1), 0.5 * math.pi / T * np.sin(math.pi * x),
                                                             0.0)

    def vertical_block(self, t0: float, h: float, n: int) -> np.ndarray:
        """The heave, roll and pitch sums on the heading grid at the n times ``t0 + j h`` [s],
        shape (n, K G) (column ``K g + d``, :meth:`_vertical_weights`); (n, 0) without the
        six-degree-of-freedom motion. The same angle sums as :meth:`block`, through the weights'
        leading singular vectors (those above :data:`SVD_RTOL` of the largest; the sums agree with
        the full product to about that fraction of the largest weight's sum)."""
        if not self._Wv.shape[1]:
            return np.zeros((int(n), 0))
        sin_th, cos_th = _block_trig(float(t0), float(h), int(n), self.omega, self.phase, self._rot_cache)
        cs = self._scale_trig(np.concatenate([cos_th, sin_th], axis=1), float(t0) + float(h) * np.arange(int(n)))
        with _one_blas_thread():
            out = (cs @ self._Wv_lr[0]) @ self._Wv_lr[1] if self._Wv_lr is not None else cs @ self._Wv
        if t0 < self.Tp:   # the first peak period: heave, roll and pitch brought in by the ramp
            m = min(int(n), int(math.ceil((self.Tp - t0) / h)) + 1)
            K = out.shape[1] // N_HEADINGS
            out[:m].reshape(m, N_HEADINGS, K)[:, :, :3] *= self.ramp(t0 + h * np.arange(m))[0][:, None, None]
        return out

    def vertical_of(self, grid: Any, psi: float) -> np.ndarray:
        """Heave [m, down], roll [rad, starboard down] and pitch [rad, bow up] (3,) at the LF heading
        psi [rad] from the sums on the heading grid (K G,) (:meth:`vertical_block`): linear
        interpolation in the relative heading ``beta = beta_wave - psi`` (:func:`heading_interp`)."""
        return heading_interp(grid, self.direction, float(psi))[:3]

    def horizontal_of(self, grid: Any, psi: float) -> np.ndarray:
        """With a user's table (:attr:`grid_horizontal`): the WF motion (x [m], y [m], psi [rad])
        in {E} at the LF heading psi [rad] from the sums on the heading grid (6 G,): the table's
        surge and sway turned by the heading, its yaw — the plant's compiled step does the same."""
        v = heading_interp(grid, self.direction, float(psi))
        c, s = math.cos(psi), math.sin(psi)
        return np.array([c * v[3] - s * v[4], s * v[3] + c * v[4], v[5]])

    def _vertical(self, t: Any, psi: float, rate: bool) -> np.ndarray:
        """The motion on the heading grid (``rate``: its time derivative) at time(s) t interpolated
        at the heading psi, heave, roll and pitch with the start-up :meth:`ramp`: (..., K) (a
        table's surge, sway and yaw start at once, as the horizontal model's do)."""
        t = _time(t)
        if not self._Wv.shape[1]:
            return np.zeros(np.shape(t) + (3,))
        th = np.multiply.outer(t, self.omega) + self.phase
        cs = self._scale_trig(np.concatenate([np.cos(th), np.sin(th)], axis=-1), t)
        psi = _num("psi", psi, unit="rad")
        s, ds = (np.asarray(x)[..., None] for x in self.ramp(t))
        v = heading_interp(cs @ self._Wv, self.direction, psi)
        if rate:
            v_dot = heading_interp(cs @ self._Wv_dot, self.direction, psi)
            v_dot[..., :3] = s * v_dot[..., :3] + ds * v[..., :3]
            return v_dot
        v[..., :3] *= s
        return v

    def vertical(self, t: Any, psi: float) -> np.ndarray:
        """Heave [m, down], roll [rad, starboard down] and pitch [rad, bow up] of the hull at time(s)
        t [s] and LF heading psi [rad], shape t.shape + (3,) (zeros without the six-degree-of-freedom
        motion)."""
        return self._vertical(t, psi, False)[..., :3]

    def vertical_dot(self, t: Any, psi: float) -> np.ndarray:
        """Time derivative of :meth:`vertical` at fixed LF heading [m/s, rad/s, rad/s]."""
        return self._vertical(t, psi, True)[..., :3]

    def _dirs(self, psi: float) -> tuple[float, float, float, np.ndarray]:
        """cos beta, sin beta, sin 2beta and the drift factor c(beta) (3,) at heading psi; cached."""
        if self._dir_cache is not None and self._dir_cache[0] == psi:
            return self._dir_cache[1]
        beta = self.direction - _num("psi", psi, unit="rad")
        cb, sb, s2b = math.cos(beta), math.sin(beta), math.sin(2.0 * beta)
        out = (cb, sb, s2b, self._drift_c * np.array([cb * abs(cb), sb * abs(sb), -s2b]))
        self._dir_cache = (psi, out)
        return out

    def elevation(self, t: Any) -> np.ndarray:
        """Wave elevation zeta(t) [m] at the field zero point (positive up), shape of ``t``."""
        return np.cos(np.multiply.outer(_time(t), self.omega) + self.phase) @ self.amplitude

    def _motion(self, t: Any, psi: float, rate: bool) -> np.ndarray:
        if self.grid_horizontal:   # the user's table: surge, sway and yaw on the heading grid
            v = self._vertical(t, psi, rate)
            c, s = math.cos(psi), math.sin(psi)
            return np.stack([c * v[..., 3] - s * v[..., 4], s * v[..., 3] + c * v[..., 4], v[..., 5]], axis=-1)
        cb, sb, s2b, _ = self._dirs(psi)
        S, C = self._sums(t)
        xb, yb, z = (cb * C[2], sb * C[3], -s2b * S[2]) if rate else (cb * S[0], sb * S[1], s2b * C[0])
        c, s = math.cos(psi), math.sin(psi)
        if np.ndim(xb) == 0:
            return np.array([c * xb - s * yb, s * xb + c * yb, z])
        return np.stack([c * xb - s * yb, s * xb + c * yb, z], axis=-1)

    def _motion_of(self, S0: float, S1: float, C0: float, psi: float) -> np.ndarray:
        """WF motion (3,) [m, m, rad] in {E} of :meth:`_motion` from its sums ``S[0], S[1], C[0]``
        (floats, e.g. of :meth:`block`) at the finite float heading psi [rad]."""
        cb, sb, s2b, _ = self._dirs(psi)
        xb, yb, z = cb * S0, sb * S1, s2b * C0
        c, s = math.cos(psi), math.sin(psi)
        return np.array([c * xb - s * yb, s * xb + c * yb, z])

    def eta_wf(self, t: Any, psi: float) -> np.ndarray:
        """WF motion (x [m], y [m], psi [rad]) in {E} at LF heading psi [rad]; shape t.shape + (3,)."""
        return self._motion(t, psi, rate=False)

    def eta_wf_dot(self, t: Any, psi: float) -> np.ndarray:
        """Time derivative of :meth:`eta_wf` at fixed LF heading [m/s, m/s, rad/s] in {E}."""
        return self._motion(t, psi, rate=True)

    def drift_factor(self, psi: float) -> np.ndarray:
        """The drift factor c(beta) (3,) [N/m^2, N/m^2, N/m] at the LF heading psi [rad]: the
        wall-sided body's of the mean direction (long-crested), or, short-crested, the mean of
        c(beta + delta_k) weighted by each component's share of the drift (``a_k^2 R_k``), on the
        heading grid (:func:`heading_interp`). The wall-sided formula's: not used with the user's
        drift coefficients (:attr:`drift_table`)."""
        if self._drift_grid.size:
            return heading_interp(self._drift_grid, self.direction, _num("psi", psi, unit="rad"))
        return self._dirs(psi)[3]

    def mean_drift(self, psi: float) -> np.ndarray:
        """Newman mean drift ``sum_k D(w_k, beta) a_k^2`` in {B}, shape (3,) [N, N, N m]: the time
        mean of :meth:`tau_drift`. With the user's coefficients ``s_i sum_k a_k^2 |D_i(w_k,
        beta)|`` on the heading grid, interpolated linearly at the heading (``sum a^2 D`` where
        ``D_i`` keeps one sign over the frequencies)."""
        if self.drift_table:
            return heading_interp(self._drift_mean, self.direction, _num("psi", psi, unit="rad"))
        return (self.amplitude**2 @ self.reflection) * self.drift_factor(psi)

    def tau_drift(self, t: Any, psi: float) -> np.ndarray:
        """Mean + slowly varying drift load in {B} [N, N, N m] (Newman), shape t.shape + (3,)."""
        if self.drift_table:
            t = _time(t)
            c = self._scale_cos(np.cos(np.multiply.outer(t, self.omega) + self.phase), t)
            return self.drift_of(c @ self._Wd, _num("psi", psi, unit="rad"), t)
        q = self._sums(t)[1][1]
        if np.ndim(q) == 0:
            return 2.0 * q * q * self.drift_factor(psi)
        return np.multiply.outer(2.0 * q * q, self.drift_factor(psi))


@dataclass(frozen=True, kw_only=True)
class WindParams:
    """Gusts and coefficients of :class:`Wind`: ``n_components`` (one per log-spaced bin); band
    ``[f_min, f_max]`` [Hz] (1/3600 Hz: the 1-hour mean of U10); ``height`` z [m] of the mean
    speed ``U10 (1 + C ln(z/10))``, ``C = 0.0573 sqrt(1 + 0.148 U10)``, and of the spectrum;
    ``c_x, c_y, c_n`` wind-load coefficients of a large tanker/FPSO [-] (Fossen 2011 §8.1:
    0.7-0.9, 0.8-0.95, 0.08-0.1)."""

    n_components: int = 100
    f_min: float = 1.0 / 3600.0
    f_max: float = 0.5
    height: float = 10.0
    c_x: float = 0.8
    c_y: float = 0.9
    c_n: float = 0.08

    def __post_init__(self) -> None:
        _check_params(self, ("f_min", "f_max"), ("c_x", "c_y", "c_n"))
        _num("WindParams.height", self.height, lo=0.0, strict=True, unit="m")


class Wind:
    """Mean wind plus NPD gusts (fixed direction), and the wind load (Fossen 2011 §8.1).

    ``V(t) = max(0, U(z) + sum_k b_k cos(2 pi f_k t + phi_k))``, ``b_k = sqrt(2 S_NPD(f_k) df_k)``.
    The load is :meth:`tapm_opt.models.environment.HullWindLoad.tau` (``hull``) of the relative
    wind: ``-1/2 rho_a V_rw^2 (c_x cos(gamma) A_F, c_y sin(gamma) A_L, c_n sin(2 gamma) A_L
    L_pp)``, gamma the angle the relative wind comes FROM, + to starboard.

    Parameters
    ----------
    sea_state, vessel, env : tapm_opt.config.SeaState, Vessel, Environment
        wind_speed U10 (1-hour mean at 10 m), wind_direction beta_w (going to); wind_area_frontal
        A_F, wind_area_lateral A_L, length_pp; air_density rho_a.
    seed : int, SeedSequence or Generator
    params : WindParams
    """

    def __init__(self, sea_state: schema.SeaState, vessel: schema.Vessel, env: schema.Environment,
                 seed: Any = None, *, params: WindParams = WindParams()):
        self.U10 = _num("sea_state.wind_speed", sea_state.wind_speed, lo=0.0, unit="m/s")
        self.direction = _num("sea_state.wind_direction", sea_state.wind_direction, unit="rad")
        self.params = p = params
        rho_a = _num("environment.air_density", env.air_density, lo=0.0, strict=True)
        A_F, A_L, L = (_num(f"vessel.{n}", getattr(vessel, n), lo=0.0)
                       for n in ("wind_area_frontal", "wind_area_lateral", "length_pp"))
        rng, edges = np.random.default_rng(seed), np.geomspace(p.f_min, p.f_max, int(p.n_components) + 1)
        df = np.diff(edges)
        self.freq = edges[:-1] + df * rng.random(df.size)
        self.phase = 2.0 * math.pi * rng.random(df.size)
        self.amplitude = np.sqrt(2.0 * npd_spectrum(self.freq, self.U10, p.height) * df)
        self._w = 2.0 * math.pi * self.freq
        self.mean_speed = self.U10 * (1.0 + 0.0573 * math.sqrt(1.0 + 0.148 * self.U10) * math.log(p.height / 10))
        self.hull = HullWindLoad(c_x=p.c_x, c_y=p.c_y, c_n=p.c_n, A_F=A_F, A_L=A_L, L_pp=L, rho_a=rho_a)
        self._th = np.empty(df.size)  # work array of the scalar-time speed (phase, then its cosine)
        self._rot_cache: dict = {}  # rotation tables of the block speeds, per step length

    def speed(self, t: Any) -> Any:
        """Wind speed V(t) at the reference height [m/s], float or shape of ``t``."""
        if type(t) is not float or not math.isfinite(t):  # a finite float needs no check
            t = _time(t)
        if isinstance(t, float):
            th = np.multiply(t, self._w, out=self._th)
            th += self.phase
            return max(self.mean_speed + float(self.amplitude @ np.cos(th, out=th)), 0.0)
        return np.maximum(self.mean_speed + np.cos(t[..., None] * self._w + self.phase) @ self.amplitude, 0.0)

    def block(self, t0: float, h: float, n: int) -> list[float]:
        """:meth:`speed` [m/s] at the n times ``t0 + j h`` [s] (j < n) at once, as floats: the
        plant's outer steps, a block at a time (the same speeds as the scalar path to a few units
        in the last place of the phases, :func:`_block_trig`, the sum in another order)."""
        _, cos_th = _block_trig(float(t0), float(h), int(n), self._w, self.phase, self._rot_cache)
        return np.maximum(self.mean_speed + cos_th @ self.amplitude, 0.0).tolist()

    def direction_at(self, t: float) -> float:
        """Direction the wind goes to at time t [s] [rad] (steady: ``wind_direction``)."""
        return self.direction

    def tau_wind(self, t: float, psi: float, nu: Any = None) -> np.ndarray:
        """Wind load (X [N], Y [N], N [N m]) in {B}, shape (3,), at time t [s], LF heading psi
        [rad] and vessel velocity nu = (u, v, r) in {B} [m/s, m/s, rad/s] (None: at rest)."""
        t = float(t)
        psi = _num("psi", psi, unit="rad")
        if nu is None:
            return self.hull.tau(self.speed(t), self.direction, psi)
        nu = np.asarray(nu, dtype=float)
        u_v_r = nu.tolist() if nu.shape == (3,) else None  # floats: the scalar path of HullWindLoad.tau
        if u_v_r is None or not all(map(math.isfinite, u_v_r)):
            raise PlantError(f"nu={nu.tolist()} must be 3 finite numbers (u, v, r) in {{B}}")
        return self.tau_wind_unchecked(t, psi, u_v_r[0], u_v_r[1])

    def tau_wind_unchecked(self, t: float, psi: float, u: float, v: float) -> np.ndarray:
        """:meth:`tau_wind` for a finite float time t [s], heading psi [rad] and surge and sway
        velocity u, v [m/s], without the checks of the arguments (the plant's outer step, on its
        own checked state)."""
        return self.hull.tau(self.speed(t), self.direction, psi, u, v)


class Development:
    """The time table of a developing sea state (``sea_state.development``): each field a row
    gives (:data:`tapm_opt.config.schema.DEVELOPING_FIELDS`) linear in time between the rows that
    give it, the sea state's own value at t = 0 when its first row comes later, held after its last.

    ``value(name, t)`` [SI; angles rad] at time(s) t [s]; ``varies(name)``: the field changes."""

    def __init__(self, sea_state: schema.SeaState):
        self.tables: dict[str, tuple[np.ndarray, np.ndarray]] = {}
        self._base = {f: float(getattr(sea_state, f)) for f in schema.DEVELOPING_FIELDS}
        for f in schema.DEVELOPING_FIELDS:
            rows = [(float(r.t), float(getattr(r, f))) for r in sea_state.development if getattr(r, f) is not None]
            if not rows:
                continue
            if rows[0][0] > 0.0:
                rows.insert(0, (0.0, self._base[f]))
            t, v = np.array([r[0] for r in rows]), np.array([r[1] for r in rows])
            if np.any(v != self._base[f]):
                self.tables[f] = (t, v)

    def varies(self, name: str) -> bool:
        return name in self.tables

    def value(self, name: str, t: Any) -> Any:
        if name not in self.tables:
            return self._base[name] if np.ndim(t) == 0 else np.full(np.shape(t), self._base[name])
        out = np.interp(t, *self.tables[name])
        return float(out) if np.ndim(out) == 0 else out

    def extremes(self, name: str) -> tuple[float, float]:
        """The smallest and largest value the field takes [SI]."""
        v = self.tables[name][1] if name in self.tables else np.array([self._base[name]])
        return float(v.min()), float(v.max())


class DevelopingWaveField(WaveField):
    """:class:`WaveField` of a sea state whose Hs and Tp follow a time table (:class:`Development`).

    The components' frequencies and phases are drawn once, over the band of the table's lowest to
    highest peak frequency ([omega_min, omega_max] times them, N equal bins); their amplitudes
    follow the spectrum of the moment, ``a_k(t) = sqrt(2 S(omega_k; Hs(t), Tp(t)) d omega)``, so
    the elevation ``sum a_k(t) cos theta_k`` is continuous (no jumps where the table turns) and
    its spectrum is the table's at every time. The weights of the sums are per metre of
    amplitude and the sums take ``a_k(t)`` at each time. Rates (``eta_wf_dot``,
    ``vertical_dot``) leave out ``da/dt``, of the order of a/(the table's time scale) against a
    omega. :attr:`amplitude` is a(0); ``mean_drift`` is the drift at t = 0; a short-crested sea's
    drift factor weights the components by their shares at t = 0. With the user's drift
    coefficients the sign of each heading's mean drift is that of the moment (``sum a_k(t)^2 D``)."""

    def __init__(self, sea_state: schema.SeaState, vessel: schema.Vessel, env: schema.Environment,
                 seed: Any = None, *, params: WaveParams = WaveParams(), rao: Any = None, drift: Any = None,
                 development: Development):
        self.development = development
        super().__init__(sea_state, vessel, env, seed, params=params, rao=rao, drift=drift)
        ones = np.ones_like(self.omega)
        self._Ws, self._Wc = self._horizontal_weights(ones)
        self._vertical_weights(rao, ones)
        self._drift_weights(drift, ones)
        self._cache = None

    def _peak_band(self, sea_state: Any) -> tuple[float, float]:
        lo, hi = self.development.extremes("Tp")
        return 2.0 * math.pi / hi, 2.0 * math.pi / lo

    def amplitudes(self, t: Any) -> np.ndarray:
        """Component amplitudes a_k(t) [m], shape t.shape + (N,)."""
        t = np.asarray(t, dtype=float)
        dev = self.development
        Hs, Tp = dev.value("Hs", t), dev.value("Tp", t)
        S = _jonswap(self.omega, np.asarray(Hs)[..., None], np.asarray(Tp)[..., None], self.gamma)
        return np.sqrt(2.0 * S * self._dw)

    def _scale_trig(self, cs: np.ndarray, t: Any) -> np.ndarray:
        A = self.amplitudes(t)
        return cs * np.concatenate([A, A], axis=-1)

    def _scale_cos(self, c: np.ndarray, t: Any) -> np.ndarray:
        return c * self.amplitudes(t)

    def _drift_sign_at(self, t: Any) -> np.ndarray:
        return np.sign(self.amplitudes(t) ** 2 @ self._drift_D)

    def _sums(self, t: Any) -> tuple[np.ndarray, np.ndarray]:
        t = _time(t)
        th = np.multiply.outer(t, self.omega) + self.phase
        A = self.amplitudes(t)
        S, C = (A * np.sin(th)) @ self._Ws.T, (A * np.cos(th)) @ self._Wc.T
        return np.moveaxis(S, -1, 0), np.moveaxis(C, -1, 0)

    def block(self, t0: float, h: float, n: int) -> tuple[np.ndarray, np.ndarray]:
        sin_th, cos_th = _block_trig(float(t0), float(h), int(n), self.omega, self.phase, self._rot_cache)
        A = self.amplitudes(float(t0) + float(h) * np.arange(int(n)))
        return (A * sin_th) @ self._Ws.T, (A * cos_th) @ self._Wc.T

    def elevation(self, t: Any) -> np.ndarray:
        t = _time(t)
        return np.sum(self.amplitudes(t) * np.cos(np.multiply.outer(t, self.omega) + self.phase), axis=-1)


class DevelopingWind(Wind):
    """:class:`Wind` whose 1-hour mean speed and direction follow a time table
    (:class:`Development`; a squall is its speed's time series): the mean ``U(z)`` of the speed
    of the moment and the NPD gusts of that speed (the components' frequencies and phases drawn
    once, their amplitudes ``sqrt(2 S_NPD(f_k; U10(t)) df_k)``); the load takes the direction of
    the moment (:meth:`direction_at`)."""

    def __init__(self, sea_state: schema.SeaState, vessel: schema.Vessel, env: schema.Environment,
                 seed: Any = None, *, params: WindParams = WindParams(), development: Development):
        self.development = development
        super().__init__(sea_state, vessel, env, seed, params=params)
        edges = np.geomspace(self.params.f_min, self.params.f_max, int(self.params.n_components) + 1)
        self._df = np.diff(edges)

    def direction_at(self, t: float) -> float:
        return float(self.development.value("wind_direction", float(t)))

    def _at(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Mean speed at the reference height (...) and gust amplitudes (..., M) at the times t."""
        p = self.params
        U10 = np.asarray(self.development.value("wind_speed", t), dtype=float)
        mean = U10 * (1.0 + 0.0573 * np.sqrt(1.0 + 0.148 * U10) * math.log(p.height / 10))
        amp = np.sqrt(2.0 * _npd(self.freq, U10[..., None], p.height) * self._df)
        return mean, amp

    def speed(self, t: Any) -> Any:
        t = _time(t)
        mean, amp = self._at(np.asarray(t, dtype=float))
        v = np.maximum(mean + np.sum(amp * np.cos(np.multiply.outer(t, self._w) + self.phase), axis=-1), 0.0)
        return float(v) if np.ndim(v) == 0 else v

    def block(self, t0: float, h: float, n: int) -> list[float]:
        _, cos_th = _block_trig(float(t0), float(h), int(n), self._w, self.phase, self._rot_cache)
        mean, amp = self._at(float(t0) + float(h) * np.arange(int(n)))
        return np.maximum(mean + np.sum(amp * cos_th, axis=1), 0.0).tolist()

    def tau_wind_unchecked(self, t: float, psi: float, u: float, v: float) -> np.ndarray:
        return self.hull.tau(self.speed(t), self.direction_at(t), psi, u, v)

    def tau_wind(self, t: float, psi: float, nu: Any = None) -> np.ndarray:
        t = float(t)
        psi = _num("psi", psi, unit="rad")
        if nu is None:
            return self.hull.tau(self.speed(t), self.direction_at(t), psi)
        nu = np.asarray(nu, dtype=float)
        if nu.shape != (3,) or not np.isfinite(nu).all():
            raise PlantError(f"nu={nu.tolist()} must be 3 finite numbers (u, v, r) in {{B}}")
        return self.tau_wind_unchecked(t, psi, float(nu[0]), float(nu[1]))


def hull_rao(vessel: schema.Vessel, env: schema.Environment) -> Any:
    """The transfer functions ``rao(omega, beta)`` of the hull (``vessel.wave_motion``; the
    arguments broadcast, e.g. frequencies (N, 1) and each component's headings (N, G)): heave,
    roll and pitch, complex (N, G, 3), of the closed form (:func:`tapm_opt.models.rao.closed_form_rao`,
    model "six_dof"), all six, complex (N, G, 6), of the user's table (model "table": a CSV of
    :func:`~tapm_opt.models.rao.read_rao_csv` or a WAMIT ``.4`` file, :func:`~tapm_opt.models.rao.read_wamit4`),
    or None for the horizontal model."""
    wm = vessel.wave_motion
    if wm.model == "horizontal":
        return None
    from ..models import rao as rao_mod

    if wm.model == "table":
        path = str(wm.rao_file)
        try:
            table = (rao_mod.read_wamit4(path, ulen=float(wm.rao_ulen)) if path.lower().endswith(".4")
                     else rao_mod.read_rao_csv(path))
        except (ModelError, OSError) as exc:
            raise PlantError(f"vessel.wave_motion.rao_file = {path!r}: {exc}") from None
        return table.evaluate

    cb = float(wm.block_coefficient)
    cwp = float(wm.waterplane_coefficient) if wm.waterplane_coefficient is not None else (1.0 + 2.0 * cb) / 3.0
    try:
        hull = rao_mod.HullMotionParams(
            length_pp=float(vessel.length_pp), breadth=float(vessel.breadth), draught=float(vessel.draught),
            block_coefficient=cb, waterplane_coefficient=cwp, GM_T=float(wm.GM_T),
            roll_period=float(wm.roll_period), roll_damping=float(wm.roll_damping))
    except ModelError as exc:
        raise PlantError(f"vessel.wave_motion: {exc}") from None
    g = float(env.gravity)
    return lambda omega, beta: rao_mod.closed_form_rao(omega, beta, hull, g=g)


def hull_drift(vessel: schema.Vessel, env: schema.Environment) -> Any:
    """The hull's mean drift coefficients ``drift(omega, beta)`` -> (..., 3) [N/m^2, N/m^2,
    N m/m^2] of the user's table ``vessel.wave_motion.drift_file`` (a CSV of
    :func:`~tapm_opt.models.rao.read_drift_csv`, or a WAMIT ``.8`` or ``.9`` file of
    :func:`~tapm_opt.models.rao.read_wamit_drift` with ``drift_ulen`` and the scenario's water
    density and gravity), or None (the wall-sided formula) without one."""
    wm = vessel.wave_motion
    path = getattr(wm, "drift_file", None)
    if path is None:
        return None
    from ..models import rao as rao_mod

    path = str(path)
    try:
        if path.lower().endswith((".8", ".9")):
            table = rao_mod.read_wamit_drift(path, ulen=float(wm.drift_ulen), rho=float(env.water_density),
                                             g=float(env.gravity))
        else:
            table = rao_mod.read_drift_csv(path)
    except (ModelError, OSError) as exc:
        raise PlantError(f"vessel.wave_motion.drift_file = {path!r}: {exc}") from None
    return table.evaluate


class Environment:
    """Current, waves and wind of one sea state of a scenario, with independent random streams.

    Waves and wind draw from ``SeedSequence(seed).spawn(2)``: changing one leaves the other.
    ``eta_wf(t, psi)``, ``eta_wf_dot(t, psi)`` (WF motion and rate in {E}, :class:`WaveField`)
    and ``current_at(z)`` (:meth:`CurrentProfile.velocity`) are the components' bound methods.

    Parameters
    ----------
    scenario : tapm_opt.config.Scenario
        Uses ``environment`` (water_depth, densities, gravity) and ``vessel``.
    sea_state : SeaState, str or None
        The sea state, its id, or None for the scenario's first one.
    seed : int
        Master seed.
    wave_params, wind_params : WaveParams, WindParams
    """

    def __init__(self, scenario: schema.Scenario, sea_state: schema.SeaState | str | None = None,
                 seed: int = 0, *, wave_params: WaveParams = WaveParams(),
                 wind_params: WindParams = WindParams()):
        if not isinstance(sea_state, schema.SeaState):
            try:
                sea_state = scenario.sea_state(sea_state)
            except KeyError as exc:
                raise PlantError(f"sea_state: {exc.args[0]}") from None
        self.sea_state = sea_state
        env, ves = scenario.environment, scenario.vessel
        s_wave, s_wind = np.random.SeedSequence(seed).spawn(2)
        try:
            self.current = CurrentProfile(sea_state, env.water_depth)
        except ModelError as exc:
            raise PlantError(str(exc)) from None
        #: The time table of a developing sea state (None: steady).
        self.development = dev = Development(sea_state) if sea_state.development else None
        if dev is not None and (dev.varies("Hs") or dev.varies("Tp")):
            self.waves: WaveField = DevelopingWaveField(sea_state, ves, env, s_wave, params=wave_params,
                                                        rao=hull_rao(ves, env), drift=hull_drift(ves, env),
                                                        development=dev)
        else:
            self.waves = WaveField(sea_state, ves, env, s_wave, params=wave_params, rao=hull_rao(ves, env),
                                   drift=hull_drift(ves, env))
        if dev is not None and (dev.varies("wind_speed") or dev.varies("wind_direction")):
            self.wind: Wind = DevelopingWind(sea_state, ves, env, s_wind, params=wind_params, development=dev)
        else:
            self.wind = Wind(sea_state, ves, env, s_wind, params=wind_params)
        self.eta_wf, self.eta_wf_dot = self.waves.eta_wf, self.waves.eta_wf_dot
        self.current_at = self.current.velocity
        #: Rate of turn of the current direction [rad/s] (``sea_state.current_turn_rate``; 0: steady).
        self.current_turn_rate = float(getattr(sea_state, "current_turn_rate", 0.0) or 0.0)
        if not math.isfinite(self.current_turn_rate):
            raise PlantError(f"sea_state.current_turn_rate = {self.current_turn_rate!r} rad/s must be finite")

    def current_surface(self, t: float) -> np.ndarray:
        """Surface current (3,) in {E} [m/s] at time t [s]: speed V_c in the direction
        beta_c(t) = beta_c + current_turn_rate t (the rotating tidal current of the line-tension
        seed's Table I, v_c(t) = (-cos(t/6875), sin(t/6875), 0) m/s, is beta_c = 180 deg and a
        rate of -1/6875 rad/s)."""
        dev = self.development
        developing = dev is not None and (dev.varies("current_speed") or dev.varies("current_direction"))
        if self.current_turn_rate == 0.0 and not developing:
            return np.asarray(self.current.surface, dtype=float).copy()
        if developing:
            V = float(dev.value("current_speed", float(t)))
            beta = float(dev.value("current_direction", float(t))) + self.current_turn_rate * float(t)
        else:
            V = float(np.hypot(self.current.surface[0], self.current.surface[1]))
            beta = self.sea_state.current_direction + self.current_turn_rate * float(t)
        return np.array([V * math.cos(beta), V * math.sin(beta), 0.0])

    def current_velocity(self, z: Any, t: float = 0.0) -> np.ndarray:
        """Current velocity in {E} at depths ``z`` [m] and time t [s], shape ``z.shape + (3,)``
        [m/s]: the profile factor phi(z) times :meth:`current_surface` (the direction turns with
        depth-independent rate, as the profile's does not change with depth)."""
        if not self.current_varies:
            return self.current.velocity(z)
        return np.multiply.outer(self.current.factor(np.asarray(z, dtype=float)), self.current_surface(t))

    @property
    def current_varies(self) -> bool:
        """The surface current changes in time (a turn rate, or a developing current)."""
        dev = self.development
        return self.current_turn_rate != 0.0 or (dev is not None and (dev.varies("current_speed")
                                                                       or dev.varies("current_direction")))

    @property
    def develops(self) -> bool:
        """Some field of the sea state follows a time table (:class:`Development`)."""
        return self.development is not None and bool(self.development.tables)

    def _loads_unchecked(self, t: float, psi: float, u: float, v: float) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`loads` (wind, drift) for a finite float time t [s], heading psi [rad] and surge and
        sway velocity u, v [m/s] in {B}, without the checks of the arguments (the plant's outer
        step, on its own checked state): the same operations, the same numbers."""
        return self.wind.tau_wind_unchecked(t, psi, u, v), self.waves.tau_drift(t, psi)

    def loads(self, t: float, eta: Any, nu: Any = None) -> dict[str, np.ndarray]:
        """Environmental loads in {B} (survey eq. 9) at time t [s], LF pose eta (3,) [m, m, rad]
        and velocity nu (3,) in {B}: ``{"tau_wind": (3,), "tau_drift": (3,)}`` [N, N, N m]."""
        psi = eta[2]
        return {"tau_wind": self.wind.tau_wind(t, psi, nu), "tau_drift": self.waves.tau_drift(t, psi)}
