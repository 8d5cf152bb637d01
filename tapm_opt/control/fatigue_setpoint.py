"""Fatigue-aware setpoint chasing (survey §4.2.4: "the fatigue effect is improved by changing the
setpoint"): the setpoint is moved to spread the tension cycles over the lines.

Two parts:

* **On-line damage** (:class:`LineDamageMonitor`): every measured fairlead tension (the tension
  cells, ``Estimate.tensions``) is rainflow-counted as it arrives and summed by Miner's rule with
  its line type's T-N curve (:class:`~tapm_opt.models.fatigue.StreamingDamage`,
  :func:`~tapm_opt.models.fatigue.line_curves`): ``D_i(t)`` equals the offline
  :func:`~tapm_opt.models.fatigue.miner_damage` of the record so far, the open ranges (the residue)
  counted as half cycles as the standard counts them at the end of a record.
* **The setpoint** (:class:`FatigueAwareSetpoint`): setpoint chasing (survey eq. 38,
  :class:`~tapm_opt.control.setpoint.SetpointChasing`) gives ``p_c``; every ``period`` seconds the
  layer picks the turret offset ``p*`` on a grid within ``search_radius`` of ``p_c`` (and inside the
  safe circle the chasing is kept in) that minimises

  ``J(p) = K_T F_T(p)^2 + K_D sum_i w_i Ddot_i(p) / sum_i w_i Ddot_i(p_c)``

  - ``F_T(p)^2 = || (tau_env + tau_moor(p)) / tau_max ||^2``: the thrust holding ``p`` needs against
    the estimated mean environmental load, each DOF over the thrusters' capacity on it (as
    :mod:`tapm_opt.control.setpoint_opt` defines it), the mooring load from the catenary model
    (:meth:`MooringModel.solve_lines <tapm_opt.models.mooring.MooringModel.solve_lines>`);
  - ``Ddot_i(p)``: the predicted damage rate of line ``i``, narrow band
    (:func:`~tapm_opt.models.fatigue.narrow_band_damage_rate`) of the tension standard deviation
    ``sigma_i(p) = sigma_i,meas k_i(p) / k_i(p_m)``: ``sigma_i,meas`` each line's measured tension
    standard deviation (exponentially weighted over ``stats_time``), measured about the turret's
    mean position ``p_m`` (``Estimate.eta`` plus ``Estimate.eta_wf``, weighted alike), scaled by the
    line's local tension stiffness ``k_i = |dT_F/dX_F|`` (the catenary's exact sensitivity,
    :class:`~tapm_opt.models.catenary.CatenarySolution`) at the candidate over the one where it was
    measured: the turret's motion is the sea's, the tension it drives is the line's stiffness times
    it. The up-crossing rate is the same for every line and cancels in the ratio.
    Why measured sigma and not ``k_i sigma_motion``: on fpso in the ``normal`` sea (chasing, PID,
    600 s) the quasi-static ``sqrt(g_i^T Sigma g_i)`` of the measured turret motion gives 38 kN on
    the weather bundle (measured 52 kN) but 9-13 kN on the other eight lines (measured 64-70 kN): their
    cycles come from the hull's heave, roll and pitch at the fairleads and from line dynamics, which
    the horizontal motion does not see. The measured sigma carries them; the model gives the change;
  - ``w_i = (1 + damage_weight D_i / mean_j D_j) / (1 + damage_weight)``: the lines that have
    taken more damage count more (``damage_weight = 0``: every line alike, the total damage rate).

  The setpoint is ``p_c + delta``: its offset ``delta`` from the chased point moves toward
  ``p* - p_c`` at no more than ``max_rate`` (a step limit), so the setpoint goes to ``p*`` and stays
  there until the next optimisation while ``p_c`` follows the vessel; it is kept inside the circle of
  the chasing. Before the first optimisation (``warmup``) ``delta = 0``: plain chasing. Heading:
  ``psi_d`` (or the weather-optimal heading layer on top).

ASSUMPTIONS: a line's tension cycles scale with its horizontal tension stiffness ``dT_F/dX_F`` when
the setpoint moves (the vertical and dynamic parts are taken to scale alike); the narrow-band rate is
used only as a ratio between lines and setpoints; the statistics measured about ``p_m`` hold, scaled,
at the candidates (the sea is stationary over ``stats_time``). After a line break is detected
(``Estimate.broken_lines``) the layer falls back to plain chasing (the intact model is then wrong).
Source: survey §4.2.4 (setpoint chasing and fatigue); the formula is this project's
(``docs/fatigue_setpoint.md``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Mapping

import numpy as np

from .._checks import finite
from ..errors import TapmError
from ..geometry import body_from_turret, turret_offset
from ..interfaces import Estimate, Setpoint
from ..models.fatigue import LineCurve, StreamingDamage, narrow_band_damage_rate
from .setpoint import SetpointChasing

__all__ = ["FatigueOptions", "FatigueSetpointError", "LineDamageMonitor", "FatigueAwareSetpoint"]


class FatigueSetpointError(TapmError, ValueError):
    """Bad settings or inputs of the fatigue-aware setpoint layer."""


@dataclass(frozen=True, kw_only=True)
class FatigueOptions:
    """Settings of :class:`FatigueAwareSetpoint` (``setpoint_options`` of ``setpoint = "fatigue"``
    in study files). Every one is optional.

    Attributes
    ----------
    K_T : float
        Weight of the squared normalised thrust ``F_T^2`` [-] (>= 0).
    K_D : float
        Weight of the weighted damage rate relative to the chased point's [-] (>= 0).
    damage_weight : float
        How much the accumulated damage weights a line (``w_i`` in the module docstring) [-] (>= 0).
    period : float
        Time between optimisations [s] (> 0).
    warmup : float
        Time before the first optimisation, while the motion statistics fill [s] (>= 0).
    max_rate : float
        Largest speed of the setpoint toward the optimum [m/s] (> 0).
    search_radius : float
        The candidates lie within this distance of the chased point [m] (> 0).
    grid : int
        Candidates per axis of the search grid (odd, 3 to 31).
    stats_time : float
        Time constant of the motion's exponentially weighted mean and covariance [s] (> 0).
    """

    K_T: float = 1.0
    K_D: float = 1.0
    damage_weight: float = 1.0
    period: float = 60.0
    warmup: float = 120.0
    max_rate: float = 0.05
    search_radius: float = 25.0
    grid: int = 11
    stats_time: float = 300.0

    def __post_init__(self) -> None:
        for name in ("K_T", "K_D", "damage_weight", "warmup"):
            finite(f"setpoint_options.{name}", getattr(self, name), lo=0.0, error=FatigueSetpointError,
                   numbers_only=True)
        for name in ("period", "max_rate", "search_radius", "stats_time"):
            finite(f"setpoint_options.{name}", getattr(self, name), lo=0.0, strict=True, error=FatigueSetpointError,
                   numbers_only=True)
        g = self.grid
        if isinstance(g, bool) or not isinstance(g, (int, np.integer)) or not (3 <= g <= 31) or g % 2 == 0:
            raise FatigueSetpointError(f"setpoint_options.grid = {g!r} must be an odd whole number from 3 to 31")
        if self.K_T == 0 and self.K_D == 0:
            raise FatigueSetpointError("setpoint_options.K_T = 0 and K_D = 0: give at least one a positive weight")

    @classmethod
    def from_mapping(cls, options: Mapping[str, Any] | None, where: str = "setpoint_options") -> "FatigueOptions":
        """Options from a study file's table, unknown keys named with ``where``."""
        if options is not None and not isinstance(options, Mapping):
            raise FatigueSetpointError(f"{where} = {options!r} must be a table of options")
        options = dict(options or {})
        known = set(cls.__dataclass_fields__)
        unknown = sorted(set(options) - known)
        if unknown:
            raise FatigueSetpointError(f"{where}: unknown option(s) {unknown} of setpoint = 'fatigue'; "
                                       f"known: {', '.join(sorted(known))}")
        try:
            return cls(**options)
        except FatigueSetpointError as exc:
            raise FatigueSetpointError(str(exc).replace("setpoint_options.", f"{where}.", 1)) from None


class LineDamageMonitor:
    """Miner's damage of every line from its measured fairlead tension, counted on-line.

    Parameters
    ----------
    curves : mapping line id -> LineCurve
        The T-N curve and nominal area of each line, in the order of ``Estimate.tensions``
        (:func:`~tapm_opt.models.fatigue.line_curves`).
    """

    def __init__(self, curves: Mapping[str, LineCurve]):
        if not curves:
            raise FatigueSetpointError("curves: the damage monitor needs at least one line")
        self.ids = tuple(str(k) for k in curves)
        self.curves = dict(curves)
        self.counters = [StreamingDamage(c.a_D, c.m, c.area) for c in curves.values()]

    def reset(self) -> None:
        for c in self.counters:
            c.reset()

    def push(self, tensions: Any) -> None:
        """One sample of every line's measured tension [N], in the order of :attr:`ids`."""
        T = np.asarray(tensions, dtype=float).ravel()
        if T.size != len(self.counters):
            raise FatigueSetpointError(f"tensions: {T.size} values for {len(self.counters)} lines")
        for c, v in zip(self.counters, T):
            c.push(v)

    @property
    def damage(self) -> np.ndarray:
        """Accumulated damage of each line [-], shape (n,) (the residue as half cycles)."""
        return np.array([c.damage for c in self.counters])


class FatigueAwareSetpoint:
    """Setpoint chasing moved to spread the tension cycles over the lines (module docstring).

    Parameters
    ----------
    lines : MooringModel
        The design model of the lines (``System.lines``).
    curves : mapping line id -> LineCurve
        Each line's T-N curve (:func:`~tapm_opt.models.fatigue.line_curves`), one per model line,
        in its order.
    tau_max : (3,)
        The thrusters' capacity on each DOF [N, N, N m] (:meth:`ThrusterSet.max_tau`).
    T : float
        Time constant of the chasing [s].
    R : float or None
        Radius of the circle the setpoint is kept in [m] (None: none).
    psi_d : float
        Heading setpoint [rad].
    p_cot_B : (2,)
        Centre of turret in {B} [m].
    options : FatigueOptions or mapping
    """

    def __init__(self, lines: Any, curves: Mapping[str, LineCurve], tau_max: Any, T: float, R: float | None,
                 psi_d: float = 0.0, p_cot_B: Any = (0.0, 0.0),
                 options: FatigueOptions | Mapping[str, Any] | None = None):
        self.opts = options if isinstance(options, FatigueOptions) else FatigueOptions.from_mapping(options)
        self.lines = lines
        if len(curves) != int(lines.n_lines):
            raise FatigueSetpointError(f"curves: {len(curves)} for {int(lines.n_lines)} model lines")
        self.monitor = LineDamageMonitor(curves)
        tm = np.asarray(tau_max, dtype=float)
        if tm.shape != (3,) or not np.all(np.isfinite(tm)) or np.any(tm <= 0):
            raise FatigueSetpointError(f"tau_max = {tm.tolist()} must be 3 positive numbers [N, N, N m]")
        self.tau_max = tm
        self.chase = SetpointChasing(T, R, psi_d, p_cot_B)
        self.R = self.chase.R
        self.p_cot_B = np.asarray(p_cot_B, dtype=float)
        self.reset()

    # -- state ---------------------------------------------------------------------------------
    def reset(self) -> None:
        self.chase.reset()
        self.monitor.reset()
        self.p: np.ndarray | None = None         # the present setpoint (turret offset) [m]
        self.delta = np.zeros(2)                 # the setpoint's offset from the chased point [m]
        self.target: np.ndarray | None = None    # the last optimum p* (turret offset) [m]; None: chase
        self._t: float | None = None
        self._t0: float | None = None
        self._t_opt = -math.inf
        self._p_mean: np.ndarray | None = None   # EW mean of the turret's measured position [m]
        self._T_mean: np.ndarray | None = None   # EW mean and variance of each measured tension [N, N²]
        self._T_var: np.ndarray | None = None
        self._log: list[dict] = []

    def log(self) -> list[dict]:
        """One entry per optimisation: ``t``, ``p_chase``, ``target``, ``J``, ``J_chase``,
        ``F_T``, ``F_T_chase``, ``sigma`` (each line's measured tension standard deviation [N]) and
        ``damage`` (per line, the on-line Miner sum so far)."""
        return list(self._log)

    @property
    def damage(self) -> dict[str, float]:
        """The on-line damage of each line so far [-]."""
        return dict(zip(self.monitor.ids, self.monitor.damage.tolist()))

    @property
    def sigma(self) -> np.ndarray | None:
        """Each line's measured tension standard deviation [N] (exponentially weighted over
        ``stats_time``), None before the first sample."""
        return None if self._T_var is None else np.sqrt(self._T_var)

    # -- the prediction ------------------------------------------------------------------------
    def _at(self, p: np.ndarray, psi: float) -> tuple[np.ndarray, np.ndarray]:
        """Each line's tension stiffness ``|dT_F/dX_F|`` (n,) [N/m] and the mooring load (3,) in {B}
        at turret offset ``p`` [m] and heading ``psi`` [rad]."""
        bx, by = body_from_turret(p, psi, self.p_cot_B)
        eta = np.array([bx, by, psi])
        sol = self.lines.solve_lines(eta)
        return np.abs(np.asarray(sol.dTF_dXF, float)), np.asarray(self.lines.tau_from_H(eta, sol.HF), float)

    def rates(self, p: Any, psi: float, sigma: Any, k_ref: Any) -> np.ndarray:
        """Predicted damage rate of each line at turret offset ``p`` [m], heading ``psi`` [rad], per
        unit up-crossing rate [1/s per Hz]: the narrow-band rate of ``sigma k(p) / k_ref``,
        ``sigma`` (n,) [N] each line's measured tension standard deviation where its stiffness was
        ``k_ref`` (n,) [N/m]."""
        k, _ = self._at(np.asarray(p, float), psi)
        return self._rates(k, sigma, k_ref)

    def _rates(self, k: np.ndarray, sigma: Any, k_ref: Any) -> np.ndarray:
        sig = np.asarray(sigma, float) * k / np.maximum(np.asarray(k_ref, float), 1e-12)
        return np.array([narrow_band_damage_rate(sg, 1.0, c.a_D, c.m, c.area)
                         for sg, c in zip(sig, self.monitor.curves.values())])

    def cost(self, p: Any, psi: float, tau_env: Any, sigma: Any, k_ref: Any, weights: Any,
             ref: float) -> tuple[float, float]:
        """``(J, F_T)`` at turret offset ``p`` (module docstring); ``ref`` the weighted damage rate
        of the chased point."""
        k, tau_moor = self._at(np.asarray(p, float), psi)
        FT2 = float(np.sum(((np.asarray(tau_env, float) + tau_moor) / self.tau_max) ** 2))
        fat = float(np.dot(weights, self._rates(k, sigma, k_ref))) / ref if ref > 0 else 0.0
        return self.opts.K_T * FT2 + self.opts.K_D * fat, math.sqrt(FT2)

    def weights(self) -> np.ndarray:
        """``w_i`` of the accumulated damage (module docstring)."""
        D = self.monitor.damage
        lam = self.opts.damage_weight
        mean = float(np.mean(D))
        if not mean > 0:
            return np.ones_like(D)
        return (1.0 + lam * D / mean) / (1.0 + lam)

    def _optimise(self, t: float, p_c: np.ndarray, psi: float, tau_env: np.ndarray) -> None:
        o = self.opts
        w = self.weights()
        sigma = self.sigma
        k_ref, _ = self._at(self._p_mean, psi)    # where the tensions' sigma was measured
        ref = float(np.dot(w, self.rates(p_c, psi, sigma, k_ref)))
        J_c, F_c = self.cost(p_c, psi, tau_env, sigma, k_ref, w, ref)
        best, J_best, F_best = p_c.copy(), J_c, F_c
        s = np.linspace(-o.search_radius, o.search_radius, int(o.grid))
        for dx in s:
            for dy in s:
                q = p_c + (dx, dy)
                if math.hypot(dx, dy) > o.search_radius * (1 + 1e-9) or (dx == 0 and dy == 0):
                    continue
                if self.R is not None and math.hypot(*q) > self.R:
                    continue
                J, F = self.cost(q, psi, tau_env, sigma, k_ref, w, ref)
                if J < J_best:
                    best, J_best, F_best = q, J, F
        self.target = best
        self._log.append({"t": float(t), "p_chase": p_c.tolist(), "target": best.tolist(), "J": J_best,
                          "J_chase": J_c, "F_T": F_best, "F_T_chase": F_c, "sigma": sigma.tolist(),
                          "damage": self.monitor.damage.tolist()})

    # -- the layer -----------------------------------------------------------------------------
    def update(self, t: float, estimate: Estimate) -> Setpoint:
        sp = self.chase.update(t, estimate)
        p_c = np.array(sp.eta_d[:2], dtype=float)
        psi = float(estimate.eta[2])
        if estimate.tensions is not None:
            self.monitor.push(estimate.tensions)
        # the statistics of the present setpoint: the turret's mean position (low- plus
        # wave-frequency) and each measured tension's mean and variance, exponentially weighted
        eta = np.asarray(estimate.eta, float)
        if estimate.eta_wf is not None:
            eta = eta + np.asarray(estimate.eta_wf, float)
        pm = np.asarray(turret_offset(eta, self.p_cot_B), dtype=float)
        dt = 0.0 if self._t is None else max(float(t) - self._t, 0.0)
        a = 1.0 - math.exp(-dt / self.opts.stats_time)
        if self._p_mean is None:
            self._p_mean, self._t0 = pm, float(t)
        else:
            self._p_mean = self._p_mean + a * (pm - self._p_mean)
        if estimate.tensions is not None:
            T = np.asarray(estimate.tensions, float)
            if self._T_mean is None:
                self._T_mean, self._T_var = T.copy(), np.zeros_like(T)
            else:
                d = T - self._T_mean
                self._T_mean = self._T_mean + a * d
                self._T_var = (1.0 - a) * (self._T_var + a * d * d)
        if estimate.broken_lines:                 # the intact model is wrong: back to plain chasing
            self.target = None
        elif (t - self._t0 >= self.opts.warmup and t - self._t_opt >= self.opts.period
              and self._T_var is not None):
            self._t_opt = float(t)
            self._optimise(t, p_c, psi, np.asarray(estimate.tau_env, float))
        goal = np.zeros(2) if self.target is None else self.target - p_c
        step = goal - self.delta                  # the offset moves at no more than max_rate
        dist = float(np.hypot(*step))
        lim = self.opts.max_rate * dt
        self.delta = goal if dist <= lim else self.delta + step * (lim / dist)
        self.p = p_c + self.delta
        if self.R is not None:
            r = float(np.hypot(*self.p))
            if r > self.R:
                self.p = self.p * (self.R / r)
        self._t = float(t)
        return Setpoint(eta_d=np.array([self.p[0], self.p[1], sp.eta_d[2]]))
