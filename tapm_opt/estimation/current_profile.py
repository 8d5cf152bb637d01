"""On-line estimation of the current profile from the fairlead tension cells and the riser
inclinometers (survey §4.7: the monitoring functions built on the tension cells; method, equations,
observability and measured errors in ``docs/current_estimation.md``).

Frames and units: NED {E}, SI (m, N, rad, s); degrees only at the edge (study files, reports).

Profile family (eq. CP1)
------------------------
The current the estimator fits is ``v_c(z) = V phi(z; f_b) (cos beta, sin beta, 0)`` in {E} with

    phi(z; f_b) = 1 - (1 - f_b) w(z),                                                   (CP1)

``V`` the surface speed [m/s], ``beta`` the direction (going to) [rad], ``f_b`` the seabed factor
[-] (phi at the seabed) and ``w(z)`` a fixed shape from 0 at the surface to 1 at the seabed: the
scenario's nominal profile's deficit ``(1 - phi_0(z)) / (1 - phi_0(h))`` when ``phi_0`` (the sea
state's :class:`~tapm_opt.models.environment.CurrentProfile`) has one at the seabed, else ``z/h``
(the 'linear' profile of ``current_profile = "linear"``). ASSUMPTION: the profile keeps the
scenario's shape; only its amplitude (``f_b``), speed and direction are unknown.

Line model with current drag (eq. CP2)
--------------------------------------
Morison drag per unit length is ``q = 1/2 rho C_d D |v_n| v_n``, quadratic in the current. With
``phi >= 0`` (``f_b >= 0``), ``phi^2 = 1 - 2 d w + d^2 w^2`` with ``d = 1 - f_b``, so the drag
load is ``V^2 (q_1 - 2 d q_w + d^2 q_ww)``: the loads of the profiles ``1``, ``sqrt(w)`` and ``w``
at unit speed. With the tension response linear in the drag load (ASSUMPTION: small drag share;
the cross-check against the FEM is in ``tests/test_current_profile.py``) each line's tension share
of the current is

    Delta T_i(V, beta, f_b) = V^2 (A_i(beta) - 2 d B_i(beta) + d^2 C_i(beta)),          (CP2)

with ``A, B, C`` the fairlead tension shares of the plant's FEM (:class:`~tapm_opt.plant.
mooring_fem.MooringFEM`, the lines held at the reference pose and settled by dynamic relaxation)
under the three basis profiles at speed ``v_ref``, divided by ``v_ref^2``, on ``n_directions``
directions, and a least-squares Fourier series of order ``harmonics`` in ``beta`` between them.

Riser (eq. CP3)
---------------
The quasi-static riser (:class:`~tapm_opt.models.riser.RiserModel`, eq. 2 there) is affine in
``g = |v| v``: ``theta = c (p_top - p_wh) + h(phi) g``, with ``h`` linear in ``phi |phi|``, so

    theta(eta) - theta_0(eta) = h_1 g - 2 d h_w g + d^2 h_ww g,                         (CP3)

the riser's angle shares under the three basis profiles (exact, no linearisation): the top and
bottom angles weigh the profile differently, which is what makes ``f_b`` observable.

Estimator (eq. CP4)
-------------------
Residuals are averaged over blocks of ``block`` seconds (the wave-frequency tension and angle
swings average out): ``r_T = mean(T_meas - T_cat(eta_hat)) - b(eta_blk)`` with ``T_cat`` the
design catenary (no drag) at the estimator's pose and ``b = T_FEM,0 - T_cat`` the FEM's static
difference from the catenary without current at the block's mean pose ``eta_blk`` (one settle per
block), and ``r_theta = mean(theta_meas -
theta_0(eta_hat))``. Each block is an iterated-EKF (Gauss-Newton MAP) update of ``x = (u_x, u_y,
f_b)`` (``u = V (cos beta, sin beta)`` the surface current in {E}), a random walk between blocks:

    x_k = argmin ||R^-1/2 (r - h(x))||^2 + ||P^-1/2 (x - x_k^-)||^2,
    P_k = (J^T R^-1 J + P^-1)^-1,   P_{k+1}^- = P_k + Q block,                         (CP4)

``R`` the block mean's variance: the within-block sample variance over ``block / t_corr``
independent samples (ASSUMPTION: ``t_corr`` the residual's correlation time, default 10 s) plus the
model floor (``tension_floor``, ``angle_floor``). The first block is solved from several starting
directions (the drag is odd in ``u``: the direction is unique, but Gauss-Newton from zero is not).

Pieces: :class:`CurrentResponseModel` (CP1-CP3), :class:`CurrentProfileEstimator` (CP4),
:class:`CurrentEstimate`, :class:`CurrentEstimating` (an estimator that runs another and feeds
this one, for the closed loop; ``estimation.current = "estimated"`` in a study).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from .._checks import finite
from ..errors import TapmError

__all__ = ["CurrentEstimationError", "CurrentResponseModel", "CurrentProfileEstimator", "CurrentEstimate",
           "CurrentEstimating", "profile_shape", "CURRENT_MODES"]

#: ``current`` of a study or ``ClosedLoopSettings``: the layers take the sea state's profile
#: ("known"), or this module's estimate from the tension cells and the riser inclinometers
#: ("estimated"; the tensions alone without a riser), or from the tension cells alone
#: ("estimated_tensions": the seabed factor is then held at the profile's nominal one).
CURRENT_MODES = ("known", "estimated", "estimated_tensions")


class CurrentEstimationError(TapmError, ValueError):
    """Bad settings or measurements of the current-profile estimator (the message names the field)."""


def _num(name: str, value: Any, *, lo: float | None = None, strict: bool = False, unit: str = "") -> float:
    return finite(name, value, lo=lo, strict=strict, unit=unit, error=CurrentEstimationError, eq="=")


def profile_shape(sea_state: Any, water_depth: float) -> tuple[Any, float]:
    """The shape ``w(z)`` of eq. (CP1) and the sea state's seabed factor ``f_b``.

    ``w(z) = (1 - phi_0(z)) / (1 - phi_0(h))`` of the sea state's profile ``phi_0`` when it has a
    deficit at the seabed (``phi_0(h) < 1``), else ``z / h``; ``f_b = phi_0(h)`` (1 for a uniform
    profile). ``sea_state`` None: still water, a uniform profile. Returns ``(w, f_b)``, ``w`` a
    function of depths [m] (array) -> [-] in [0, 1]."""
    from ..models.environment import CurrentProfile

    h = _num("environment.water_depth", water_depth, lo=0.0, strict=True, unit="m")
    phi0 = None
    if sea_state is not None:
        try:
            phi0 = CurrentProfile(sea_state, h)
        except TapmError as exc:
            raise CurrentEstimationError(str(exc)) from None
    f_b = 1.0 if phi0 is None else float(phi0.factor(np.array([h]))[0])
    if phi0 is not None and f_b < 1.0 - 1e-9:
        deficit = 1.0 - f_b

        def w(z: Any) -> np.ndarray:
            return np.clip((1.0 - phi0.factor(np.asarray(z, float))) / deficit, 0.0, 1.0)
    else:
        def w(z: Any) -> np.ndarray:
            return np.clip(np.asarray(z, float) / h, 0.0, 1.0)
    return w, f_b


@dataclass(frozen=True)
class CurrentEstimate:
    """One estimate of the current profile.

    Attributes
    ----------
    t : time [s]; speed : surface speed V [m/s]; direction : beta (going to) [rad] in (-pi, pi];
    seabed_factor : f_b [-]; std : 1-sigma of (speed [m/s], direction [rad], seabed_factor [-])
    from the filter's covariance (linearised).
    """

    t: float
    speed: float
    direction: float
    seabed_factor: float
    std: tuple[float, float, float]

    @property
    def surface(self) -> np.ndarray:
        """Surface current (2,) in {E} [m/s]."""
        return np.array([self.speed * math.cos(self.direction), self.speed * math.sin(self.direction)])


class CurrentResponseModel:
    """The fairlead tensions' and the riser angles' response to the current (eq. CP1-CP3).

    Parameters
    ----------
    scenario : tapm_opt.config.Scenario
    settle : callable
        ``settle(eta, current) -> (M,)``: the static fairlead tensions [N] of the scenario's lines
        with the vessel held at ``eta`` under ``current`` (a function of node depths (n,) [m] ->
        velocities (n, 3) [m/s] in {E}, or None for still water) — the plant's FEM settled by
        dynamic relaxation (:func:`tapm_opt.studies.closed_loop.fem_static_tensions`), passed in
        from above the plant's layer.
    sea_state : SeaState or None
        Gives the profile's shape ``w(z)`` (:func:`profile_shape`) and the default ``v_ref``; its
        speed and direction are not used (None: the linear shape).
    eta_ref : (3,)
        Pose at which the lines are settled (x [m], y [m], psi [rad]; default the field zero point).
        ASSUMPTION: the drag shares at the vessel's pose are those at ``eta_ref``.
    n_directions : int
        Directions of the FEM basis, >= 4 (every ``360/n`` deg).
    harmonics : int or None
        Order of the Fourier series in beta (default ``(n_directions - 1) // 2 - 1``, a smoothing fit).
    v_ref : float or None
        Speed of the basis settles [m/s] (default the sea state's speed, at least 0.5 m/s).
    """

    def __init__(self, scenario: Any, settle: Any, sea_state: Any = None, *, eta_ref: Any = (0.0, 0.0, 0.0),
                 n_directions: int = 12, harmonics: int | None = None, v_ref: float | None = None):
        from ..models.mooring import MooringModel
        from ..models.riser import RiserModel

        self.scenario = scenario
        h = float(scenario.environment.water_depth)
        eta_ref = np.asarray(eta_ref, float)
        if eta_ref.shape != (3,) or not np.all(np.isfinite(eta_ref)):
            raise CurrentEstimationError(f"eta_ref = {np.asarray(eta_ref).tolist()} must be 3 finite numbers "
                                         "(x [m], y [m], psi [rad])")
        if not (isinstance(n_directions, (int, np.integer)) and n_directions >= 4):
            raise CurrentEstimationError(f"n_directions = {n_directions!r} must be an integer >= 4")
        n_h = (n_directions - 1) // 2 - 1 if harmonics is None else harmonics
        if not (isinstance(n_h, (int, np.integer)) and 0 <= 2 * n_h + 1 <= n_directions):
            raise CurrentEstimationError(f"harmonics = {harmonics!r} must be an integer with 2 harmonics + 1 <= "
                                         f"n_directions = {n_directions}")
        if v_ref is None:
            v_ref = max(float(getattr(sea_state, "current_speed", 0.0) or 0.0), 0.5)
        self.v_ref = _num("v_ref", v_ref, lo=0.0, strict=True, unit="m/s")
        self.eta_ref = eta_ref
        self.shape, self.nominal_seabed_factor = profile_shape(sea_state, h)
        self.lines = MooringModel.from_scenario(scenario)
        self.n_lines = len(scenario.lines)
        self.line_ids = tuple(ln.id for ln in scenario.lines)
        w = self.shape
        bases = (lambda z: np.ones_like(np.asarray(z, float)), lambda z: np.sqrt(w(z)), w)

        if not callable(settle):
            raise CurrentEstimationError(f"settle = {settle!r} must be a function (eta, current) -> tensions (M,) [N]")

        def tensions(fn: Any) -> np.ndarray:
            T = np.array(settle(eta_ref, fn), dtype=float)
            if T.shape != (self.n_lines,) or not np.all(np.isfinite(T)):
                raise CurrentEstimationError(f"settle returned {T.tolist()}: need {self.n_lines} finite tensions [N]")
            return T

        self._settle = settle
        #: FEM fairlead tensions without current at ``eta_ref`` [N] (M,).
        self.T_fem0 = tensions(None)
        #: The FEM's static tension less the design catenary's at ``eta_ref`` [N] (M,): eq. CP4's ``b``.
        self.bias = self.T_fem0 - np.asarray(self.lines.tensions(eta_ref), float)
        betas = 2.0 * math.pi * np.arange(n_directions) / n_directions
        shares = np.zeros((3, n_directions, self.n_lines))
        for k, phi in enumerate(bases):
            for j, b in enumerate(betas):
                surf = self.v_ref * np.array([math.cos(b), math.sin(b), 0.0])
                shares[k, j] = (tensions(lambda z, phi=phi, surf=surf: np.multiply.outer(phi(z), surf))
                                - self.T_fem0) / self.v_ref ** 2
        self.betas, self.basis_shares, self.harmonics = betas, shares, int(n_h)
        F = self._fourier(betas)
        #: Fourier coefficients (3 bases, 2 n_h + 1, M) of A, B, C [N s^2/m^2].
        self.coef = np.stack([np.linalg.lstsq(F, shares[k], rcond=None)[0] for k in range(3)])
        # riser: the same three bases as CurrentProfiles (piecewise through 201 depths)
        self.risers: tuple | None = None
        if scenario.riser is not None:
            zz = np.linspace(0.0, h, 201)
            ss0 = sea_state if sea_state is not None else scenario.sea_states[0]
            rs = []
            for phi in bases:
                ss = replace(ss0, current_speed=1.0, current_direction=0.0, current_profile="piecewise",
                             current_profile_depths=tuple(zz.tolist()), current_profile_factors=tuple(phi(zz).tolist()))
                rs.append(RiserModel.from_scenario(scenario, ss))
            self.risers = tuple(rs)

    def _fourier(self, beta: Any) -> np.ndarray:
        beta = np.atleast_1d(np.asarray(beta, float))
        cols = [np.ones_like(beta)]
        for n in range(1, self.harmonics + 1):
            cols += [np.cos(n * beta), np.sin(n * beta)]
        return np.column_stack(cols)

    def tension_share(self, u: Any, seabed_factor: float) -> np.ndarray:
        """Eq. (CP2): each line's fairlead tension share of the current [N] (M,), ``u`` the surface
        current (2,) in {E} [m/s], ``seabed_factor`` f_b [-]."""
        ux, uy = float(u[0]), float(u[1])
        V2 = ux * ux + uy * uy
        if V2 == 0.0:
            return np.zeros(self.n_lines)
        F = self._fourier(math.atan2(uy, ux))[0]
        d = 1.0 - float(seabed_factor)
        A, B, C = (F @ self.coef[k] for k in range(3))
        return V2 * (A - 2.0 * d * B + d * d * C)

    def riser_share(self, eta: Any, u: Any, seabed_factor: float) -> np.ndarray | None:
        """Eq. (CP3): the riser angles' share of the current (top_x, top_y, bottom_x, bottom_y)
        [rad] at pose ``eta``; None without a riser."""
        if self.risers is None:
            return None
        eta = np.asarray(eta, float)
        v = np.array([float(u[0]), float(u[1])])
        d = 1.0 - float(seabed_factor)
        s = [r.angles_at(eta, v) - r.angles_at(eta, np.zeros(2)) for r in self.risers]
        return s[0] - 2.0 * d * s[1] + d * d * s[2]

    def riser_still(self, eta: Any) -> np.ndarray | None:
        """Riser angles at pose ``eta`` in still water [rad] (4,); None without a riser."""
        return None if self.risers is None else self.risers[0].angles_at(np.asarray(eta, float), np.zeros(2))

    def static_bias(self, eta: Any) -> np.ndarray:
        """Eq. (CP4)'s ``b`` at pose ``eta``: the FEM's static fairlead tensions without current less
        the design catenary's [N] (M,) (one settle)."""
        eta = np.asarray(eta, float)
        T = np.array(self._settle(eta, None), dtype=float)
        if T.shape != (self.n_lines,) or not np.all(np.isfinite(T)):
            raise CurrentEstimationError(f"settle at eta = {eta.tolist()} returned {T.tolist()}: need "
                                         f"{self.n_lines} finite tensions [N]")
        return T - np.asarray(self.lines.tensions(eta), float)


class CurrentProfileEstimator:
    """Eq. (CP4): block-averaged iterated-EKF of ``x = (u_x, u_y, f_b)`` from the fairlead tensions
    (and the riser angles where measured) at the estimator's low-frequency pose.

    Parameters
    ----------
    model : CurrentResponseModel
    tension_noise : (M,) or float
        Standard deviation of one tension-cell sample [N] (the scenario's ``tension_std_rel`` x MBS).
    angle_noise : float
        Standard deviation of one riser-angle sample [rad] (``sensors.riser_angle_std``).
    block : float
        Averaging block [s], > 0.
    t_corr : float
        Correlation time of the residuals [s], > 0 (ASSUMPTION: the wave-frequency swings decorrelate in
        about a peak period).
    q_speed, q_factor : float
        Random-walk intensities of the surface current components [m/s/sqrt(s)] and of f_b [1/sqrt(s)].
    tension_floor, angle_floor : float
        Model-error floors of a block mean [N], [rad].
    use_riser : bool
        Use the riser angles when measured.
    warmup : float
        Samples of the first ``warmup`` seconds are not used [s], >= 0 (the start-up transient of
        the lines and the vessel).
    rebias : bool
        Take eq. (CP4)'s ``b`` at each block's mean pose (one FEM settle per block,
        :meth:`CurrentResponseModel.static_bias`), else at the model's reference pose. On fpso the
        FEM's difference from the design catenary changes by 20-30 kN over 10-15 m of offset, a
        tension pattern the estimator would read as 0.5-1 m/s of current.
    fit_seabed_factor : bool or None
        Estimate ``f_b`` (default: when the riser angles are used). From the tensions alone ``f_b``
        is not observable (its tension pattern is that of the speed's, ``docs/current_estimation.md``):
        it is then held at its prior ``x0[2]`` and ``V`` is the speed of that profile.
    x0 : (3,) or None
        Prior (u_x, u_y, f_b) (None: no current, the shape's nominal f_b, searched on the first block).
    """

    def __init__(self, model: CurrentResponseModel, *, tension_noise: Any = 0.0, angle_noise: float = 0.0,
                 block: float = 30.0, t_corr: float = 10.0, q_speed: float = 2e-3, q_factor: float = 2e-3,
                 tension_floor: float = 5e3, angle_floor: float = 2e-4, use_riser: bool = True, x0: Any = None,
                 fit_seabed_factor: bool | None = None, rebias: bool = True, warmup: float = 60.0):
        if not isinstance(model, CurrentResponseModel):
            raise CurrentEstimationError(f"model must be a CurrentResponseModel, got {type(model).__name__}")
        self.model = model
        M = model.n_lines
        tn = np.broadcast_to(np.asarray(tension_noise, float), (M,)).copy() if np.ndim(tension_noise) <= 1 else None
        if tn is None or tn.shape != (M,) or not np.all(np.isfinite(tn)) or np.any(tn < 0):
            raise CurrentEstimationError(f"tension_noise = {np.asarray(tension_noise).tolist()} N must be one "
                                         f"finite number >= 0 or {M} of them")
        self.tension_noise = tn
        self.angle_noise = _num("angle_noise", angle_noise, lo=0.0, unit="rad")
        self.block = _num("block", block, lo=0.0, strict=True, unit="s")
        self.t_corr = _num("t_corr", t_corr, lo=0.0, strict=True, unit="s")
        self.q = np.array([_num("q_speed", q_speed, lo=0.0, unit="m/s/sqrt(s)")] * 2
                          + [_num("q_factor", q_factor, lo=0.0, unit="1/sqrt(s)")])
        self.tension_floor = _num("tension_floor", tension_floor, lo=0.0, strict=True, unit="N")
        self.angle_floor = _num("angle_floor", angle_floor, lo=0.0, strict=True, unit="rad")
        self.use_riser = bool(use_riser) and model.risers is not None
        self.rebias = bool(rebias)
        self.warmup = _num("warmup", warmup, lo=0.0, unit="s")
        self.fit_seabed_factor = self.use_riser if fit_seabed_factor is None else bool(fit_seabed_factor)
        #: The estimated components of x (u_x, u_y and, when fitted, f_b).
        self.free = np.array([0, 1, 2] if self.fit_seabed_factor else [0, 1])
        if x0 is None:
            x0 = (0.0, 0.0, model.nominal_seabed_factor)
        x0 = np.asarray(x0, float)
        if x0.shape != (3,) or not np.all(np.isfinite(x0)):
            raise CurrentEstimationError(f"x0 = {np.asarray(x0).tolist()} must be 3 finite numbers (u_x [m/s], "
                                         "u_y [m/s], seabed factor [-])")
        self.x0 = x0
        self.reset()

    def reset(self) -> None:
        self.x = self.x0.copy()
        self.P = np.diag([1.0, 1.0, 0.5 ** 2 if self.fit_seabed_factor else 0.0])
        self.started = False
        self._t0: float | None = None
        self._t_first: float | None = None
        self._last_t_T: float | None = None
        self._last_t_a: float | None = None
        self._sT = np.zeros(self.model.n_lines)
        self._sT2 = np.zeros(self.model.n_lines)
        self._nT = 0
        self._sa = np.zeros(4)
        self._sa2 = np.zeros(4)
        self._na = 0
        self._eta_sum = np.zeros(3)
        self._n_eta = 0
        self.latest: CurrentEstimate | None = None
        self.history: list[CurrentEstimate] = []

    # -- measurement model ---------------------------------------------------------------------
    def predict(self, x: Any, eta: Any, broken: Any = ()) -> np.ndarray:
        """h(x): the tension shares of the intact lines (and the riser shares) at ``eta``."""
        keep = self._keep(broken)
        T = self.model.tension_share(x[:2], x[2])[keep]
        if self.use_riser:
            return np.concatenate([T, self.model.riser_share(eta, x[:2], x[2])])
        return T

    def _keep(self, broken: Any) -> np.ndarray:
        return np.array([i not in broken for i in self.model.line_ids])

    def jacobian(self, x: Any, eta: Any, broken: Any = (), step: tuple = (1e-3, 1e-3, 1e-3)) -> np.ndarray:
        """dh/dx by central differences (rows as :meth:`predict`, columns u_x, u_y, f_b)."""
        x = np.asarray(x, float)
        cols = []
        for k in range(3):
            dx = np.zeros(3)
            dx[k] = step[k]
            cols.append((self.predict(x + dx, eta, broken) - self.predict(x - dx, eta, broken)) / (2 * step[k]))
        return np.column_stack(cols)

    # -- filter --------------------------------------------------------------------------------
    def update(self, t: float, eta: Any, tensions: Any, riser_angles: Any = None, *, t_tensions: float | None = None,
               t_riser: float | None = None, broken: Any = frozenset()) -> CurrentEstimate | None:
        """Take one sample (a tension sample counts once, by its time ``t_tensions``); at the end of
        each block, update the estimate. Returns the latest estimate (None before the first block)."""
        t = _num("t", t, unit="s")
        eta = np.asarray(eta, float)
        if eta.shape != (3,) or not np.all(np.isfinite(eta)):
            raise CurrentEstimationError(f"eta at t = {t:g} s = {np.asarray(eta).tolist()} must be 3 finite numbers")
        T = np.asarray(tensions, float)
        if T.shape != (self.model.n_lines,) or not np.all(np.isfinite(T)):
            raise CurrentEstimationError(f"tensions at t = {t:g} s = {np.asarray(tensions).tolist()} must be "
                                         f"{self.model.n_lines} finite numbers [N]")
        a = None
        if self.use_riser and riser_angles is not None:
            a = np.asarray(riser_angles, float)
            if a.shape != (4,) or not np.all(np.isfinite(a)):
                raise CurrentEstimationError(f"riser_angles at t = {t:g} s = {a.tolist()} must be 4 finite "
                                             "numbers [rad]")
        if self._t_first is None:
            self._t_first = t
        if t < self._t_first + self.warmup - 1e-9:
            return self.latest
        if self._t0 is None:
            self._t0 = t
        tT = t if t_tensions is None else float(t_tensions)
        if tT != self._last_t_T:
            self._last_t_T = tT
            r = T - np.asarray(self.model.lines.tensions(eta), float)
            self._sT += r
            self._sT2 += r * r
            self._nT += 1
        if a is not None:
            ta = t if t_riser is None else float(t_riser)
            if ta != self._last_t_a:
                self._last_t_a = ta
                r = a - self.model.riser_still(eta)
                self._sa += r
                self._sa2 += r * r
                self._na += 1
        self._eta_sum += eta
        self._n_eta += 1
        if t - self._t0 >= self.block - 1e-9 and self._nT >= 2:
            self._block_update(t, frozenset(broken))
            self._t0 = t
            self._sT[:] = self._sT2[:] = self._sa[:] = self._sa2[:] = 0.0
            self._nT = self._na = self._n_eta = 0
            self._eta_sum[:] = 0.0
        return self.latest

    def _block_update(self, t: float, broken: frozenset) -> None:
        from scipy.optimize import least_squares

        keep = self._keep(broken)
        n = self._nT
        mT = self._sT / n
        vT = np.maximum(self._sT2 / n - mT * mT, 0.0)
        eta = self._eta_sum / max(self._n_eta, 1)
        mT = mT - (self.model.static_bias(eta) if self.rebias else self.model.bias)
        n_eff = max(self.block / self.t_corr, 1.0)
        RT = np.maximum(vT, self.tension_noise ** 2) / min(n_eff, n) + self.tension_floor ** 2
        z, R = mT[keep], RT[keep]
        use_a = self.use_riser and self._na >= 2
        if use_a:
            ma = self._sa / self._na
            va = np.maximum(self._sa2 / self._na - ma * ma, 0.0)
            Ra = np.maximum(va, self.angle_noise ** 2) / min(n_eff, self._na) + self.angle_floor ** 2
            z, R = np.concatenate([z, ma]), np.concatenate([R, Ra])
        riser = self.use_riser
        self.use_riser = use_a   # predict() without the riser rows when no angle came this block
        try:
            fr = self.free
            if self.started:
                self.P[np.ix_(fr, fr)] += np.diag(self.q[fr] ** 2) * self.block
            Pinv = np.linalg.inv(self.P[np.ix_(fr, fr)])
            L = np.linalg.cholesky(Pinv).T
            sR = np.sqrt(R)
            xp = self.x.copy()

            def full(xf: np.ndarray) -> np.ndarray:
                x = xp.copy()
                x[fr] = xf
                return x

            def res(xf: np.ndarray) -> np.ndarray:
                return np.concatenate([(z - self.predict(full(xf), eta, broken)) / sR, L @ (xf - xp[fr])])

            starts = [xp[fr]]
            if not self.started:
                for b in np.linspace(0.0, 2 * math.pi, 8, endpoint=False):
                    for V in (0.3, 1.0):
                        starts.append(np.array([V * math.cos(b), V * math.sin(b), xp[2]])[fr])
            lo, hi = np.array([-5.0, -5.0, 0.0])[fr], np.array([5.0, 5.0, 2.0])[fr]
            best = None
            for x_s in starts:
                sol = least_squares(res, np.clip(x_s, lo, hi), bounds=(lo, hi), method="trf", x_scale=0.1)
                if best is None or sol.cost < best.cost:
                    best = sol
            self.x = full(best.x)
            J = self.jacobian(self.x, eta, broken)[:, fr]
            Pf = np.linalg.inv(J.T @ (J / R[:, None]) + Pinv)
            self.P[np.ix_(fr, fr)] = 0.5 * (Pf + Pf.T)
        finally:
            self.use_riser = riser
        self.started = True
        ux, uy, fb = self.x
        V = math.hypot(ux, uy)
        # std of speed and direction from the covariance of (u_x, u_y)
        g_V = np.array([ux, uy]) / V if V > 0 else np.array([1.0, 0.0])
        g_b = np.array([-uy, ux]) / V ** 2 if V > 0 else np.array([0.0, 0.0])
        Puu = self.P[:2, :2]
        std = (float(math.sqrt(max(g_V @ Puu @ g_V, 0.0))),
               float(math.sqrt(max(g_b @ Puu @ g_b, 0.0))) if V > 0 else math.pi,
               float(math.sqrt(max(self.P[2, 2], 0.0))))
        self.latest = CurrentEstimate(t=float(t), speed=V, direction=math.atan2(uy, ux), seabed_factor=float(fb),
                                      std=std)
        self.history.append(self.latest)

    def surface(self) -> np.ndarray | None:
        """The estimated surface current (2,) in {E} [m/s]; None before the first block."""
        return None if self.latest is None else self.latest.surface


class CurrentEstimating:
    """An :class:`~tapm_opt.interfaces.Estimator` that runs ``inner`` and feeds its pose, the
    measured tensions and riser angles and its known broken lines to a
    :class:`CurrentProfileEstimator` (``current``). The estimate handed on is ``inner``'s; the
    layers that take the current read :meth:`surface_current`. Its log is ``inner``'s (if any)
    plus one ``{"event": "current estimate", "t", "speed", "direction", "seabed_factor", "std"}``
    per block."""

    def __init__(self, inner: Any, current: CurrentProfileEstimator):
        if not isinstance(current, CurrentProfileEstimator):
            raise CurrentEstimationError(f"current must be a CurrentProfileEstimator, got {type(current).__name__}")
        self.inner, self.current = inner, current

    def reset(self) -> None:
        self.inner.reset()
        self.current.reset()

    def update(self, t: float, m: Any) -> Any:
        est = self.inner.update(t, m)
        if m.tensions is not None:
            self.current.update(t, est.eta, m.tensions, m.riser_angles, t_tensions=m.t_tensions,
                                t_riser=m.t_riser_angles, broken=est.broken_lines)
        return est

    def surface_current(self) -> np.ndarray | None:
        """The estimated surface current (2,) in {E} [m/s] (None before the first block)."""
        return self.current.surface()

    def log(self) -> list[dict]:
        inner = list(self.inner.log()) if hasattr(self.inner, "log") else []
        return inner + [{"t": e.t, "event": "current estimate", "speed": e.speed, "direction": e.direction,
                         "seabed_factor": e.seabed_factor, "std": list(e.std)} for e in self.current.history]
