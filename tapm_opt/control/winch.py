"""Passivity-based winch (line-tension) control of a thruster-assisted mooring.

Seed: O. M. Aamo, T. I. Fossen, "Controlling line tension in thruster assisted mooring systems"
(IEEE CCA 1999), §III-IV, referred to as [AF].

The map from the winding velocity ``u`` of a line to its top tension ``y`` is passive ([AF]
Proposition 1, storage function (12)), so a passive tension controller (P, PI) keeps the moored
system stable. The DP controller commands a generalised force ``tau_c``; the winches drive the
mooring's horizontal force ``tau_m`` towards it and the thrusters supply the rest,

    tau_thr = tau_c - tau_m                                           ([AF] §III, Fig. 2)

so the vessel feels exactly the DP command and "the performance of the thruster assisted mooring
system is exactly that of the DP system alone". The tension controller of [AF] §IV is

    u = -k_c B (tau_c - tau_m),   B = [p_1 ... p_m]^T,   p_j = I* r_0^j / |I* r_0^j|      (AF-P)

with ``p_j`` the horizontal unit vector from the fairlead to the anchor of line j: hauling line j
in (u_j < 0) raises its pull along ``p_j``. Here it is extended by an integral term with
anti-windup (PI, passive as well: [AF] §V names P, PI and PID):

    u_j = -k_c s_j - k_i zeta_j,   s_j = p_j . (tau_c - tau_m),   zeta_j' = s_j      (AF-PI)

Conventions (SI): ``u`` [m/s] is the winch speed, + pays out (dL/dt = u / (1 + e), [AF] eq. 11),
as :meth:`tapm_opt.plant.simulator.Plant.step`; ``tau_c`` comes from the DP controller in {B}
[N, N, N m] and is rotated into {E} by the estimated heading before (AF-P) — ``p_j`` and ``B``
are in {E}; ``tau_m`` is the measured mooring force: each line's measured fairlead tension
times its horizontal share ``H/T`` from the elastic catenary at the estimated pose and the line's
current length, summed along the ``p_j``. Only the horizontal force is regulated (the third
column of ``B`` is zero, [AF]: ``I*`` removes it); the mooring's yaw moment is left to the
thrusters through ``tau_thr = tau_c - tau_m`` in all three components.

Limits, applied in this order to every line with a winch (``lines[].winch_max_rate > 0``):

1. tension guard: at or above ``T_max`` the line is not hauled in, it pays out at
   ``k_c (T - T_max)``; at or below ``T_min`` it is not paid out, it hauls in at
   ``k_c (T_min - T)``;
2. rate: ``|u| <= winch_max_rate``;
3. length: the length after one control period stays in ``[min_length, max_length]``.

Anti-windup: a line's integrator ``zeta_j`` is frozen while its command is limited and the
integral would push it further into the limit (conditional integration).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np

from .._checks import finite, vector
from .._io import readonly
from ..errors import TapmError
from ..geometry import rot_z
from ..models import catenary

__all__ = ["WinchError", "WinchSettings", "WinchTensionController", "configuration_matrix", "horizontal_force",
           "AF_KC", "CEILING_MARGIN", "LENGTH_GRID"]

#: Gain k_c of [AF] Table I [(m/s)/N].
AF_KC = 2.5e-7

#: Default tension ceiling of the winch guard as a fraction of ``limits.tension_utilisation`` [-].
CEILING_MARGIN = 0.95

#: Step [m] of the length grid of a composite line's tension tables in the controller's model
#: (``models.characteristics.LengthTables``: linear in length between grid lengths). On the
#: chain-wire-chain fpso the horizontal share H/T is then within 3e-4 of the exact solve's (1e-3
#: of the pretension in T); a table costs about a second, built when the length first needs it.
LENGTH_GRID = 5.0


class WinchError(TapmError, ValueError):
    """Bad winch-controller input: a gain, limit, tension or command that is not usable (the
    message names the field and its value)."""


def _finite(name: str, v: Any, *, lo: float | None = None, strict: bool = False, unit: str = "") -> float:
    return finite(name, v, lo=lo, strict=strict, unit=unit, error=WinchError)


def _vec(name: str, v: Any, n: int, unit: str) -> np.ndarray:
    return vector(name, v, n, unit=unit, error=WinchError)


def configuration_matrix(model: Any, eta: Any = None) -> np.ndarray:
    """The configuration matrix ``B`` (m, 3) of [AF] §IV: row j is ``p_j^T``, the horizontal unit
    vector in {E} from line j's fairlead to its anchor, third component 0 ([AF]: ``I*``).

    Parameters
    ----------
    model : MooringModel
        The lines (anchors, fairlead geometry), e.g. ``System.lines``.
    eta : array_like (3,), optional
        Vessel pose (x [m], y [m], psi [rad]) of the fairleads; default the field zero point, where
        for fairleads at the turret centre (aamo4) ``p_j = I* r_0^j / |I* r_0^j|`` exactly as [AF].

    ``B^T H`` is the horizontal mooring force in {E} [N] of the horizontal line tensions ``H``
    [N] (third entry 0): :func:`horizontal_force`.
    """
    eta = np.zeros(3) if eta is None else np.asarray(eta, dtype=float)
    if eta.shape != (3,) or not np.all(np.isfinite(eta)):
        raise WinchError(f"eta = {eta!r} must be 3 finite numbers (x [m], y [m], psi [rad])")
    dx, dy, XF = model.spans(eta)          # anchor -> fairlead
    dx, dy, XF = (np.asarray(a, dtype=float) for a in (dx, dy, XF))
    if np.any(XF <= 0):
        j = int(np.flatnonzero(XF <= 0)[0])
        raise WinchError(f"line {model.line_ids[j]!r}: the fairlead is right above its anchor (horizontal span "
                         f"{XF[j]:g} m); its pull has no horizontal direction")
    return np.column_stack([-dx / XF, -dy / XF, np.zeros_like(XF)])


def horizontal_force(B: np.ndarray, H: Any) -> np.ndarray:
    """Horizontal mooring force (3,) in {E} [N, N, 0] from horizontal line tensions ``H`` (m,) [N]:
    ``B^T H`` ([AF] §IV)."""
    H = np.asarray(H, dtype=float)
    if H.shape != (B.shape[0],):
        raise WinchError(f"H has shape {H.shape}, expected ({B.shape[0]},) (one tension per line)")
    return B.T @ H


@dataclass(frozen=True, kw_only=True)
class WinchSettings:
    """Options of :class:`WinchTensionController`.

    Attributes
    ----------
    kc : float
        Proportional gain k_c [(m/s)/N], >= 0 (default 2.5e-7, [AF] Table I).
    ki : float
        Integral gain k_i [(m/s)/(N s)], >= 0 (default 0: the P controller of [AF]).
    T_max_fraction : float or None
        Tension ceiling as a fraction of MBS (default: :data:`CEILING_MARGIN` = 0.95 of the
        scenario's ``limits.tension_utilisation``: the guard holds a line at its ceiling, with the
        dynamic tension about it; at the limit itself aamo4's beam line overshot by 1 %).
    T_min_fraction : float
        Tension floor: ``T_min = w ZF + T_min_fraction (T_0 - w ZF)``, with ``w ZF`` the weight of a
        line hanging straight down the fairlead height (no horizontal pull left) and ``T_0`` the
        pretension at the field zero point (default 0.1).
    geometry : {"pose", "fixed"}
        ``B`` from the fairleads at the estimated pose (default) or fixed at the field zero point
        (the anchors' directions of [AF]).
    """

    kc: float = AF_KC
    ki: float = 0.0
    T_max_fraction: float | None = None
    T_min_fraction: float = 0.1
    geometry: Literal["pose", "fixed"] = "pose"

    def __post_init__(self) -> None:
        _finite("winch_options.kc", self.kc, lo=0.0, unit="(m/s)/N")
        _finite("winch_options.ki", self.ki, lo=0.0, unit="(m/s)/(N s)")
        if self.T_max_fraction is not None:
            v = _finite("winch_options.T_max_fraction", self.T_max_fraction, lo=0.0, strict=True)
            if v > 1.0:
                raise WinchError(f"winch_options.T_max_fraction = {v!r} must be in (0, 1] (a fraction of MBS)")
        v = _finite("winch_options.T_min_fraction", self.T_min_fraction, lo=0.0)
        if v >= 1.0:
            raise WinchError(f"winch_options.T_min_fraction = {v!r} must be in [0, 1) (0: the hanging weight, "
                             "1: the pretension)")
        if self.geometry not in ("pose", "fixed"):
            raise WinchError(f"winch_options.geometry = {self.geometry!r} is not one of 'pose', 'fixed'")

    @classmethod
    def from_mapping(cls, options: Any) -> "WinchSettings":
        """Settings from a table of options (study file, ``--winch-option``); unknown keys raise."""
        if options is None:
            return cls()
        if isinstance(options, WinchSettings):
            return options
        if not hasattr(options, "items"):
            raise WinchError(f"winch_options = {options!r} must be a table of options")
        allowed = {"kc", "ki", "T_max_fraction", "T_min_fraction", "geometry"}
        for k in options:
            if k not in allowed:
                raise WinchError(f"winch_options.{k}: unknown option; allowed: {', '.join(sorted(allowed))}")
        return cls(**dict(options))


class WinchTensionController:
    """The P / PI line-tension controller of [AF] §IV with rate, length and tension limits.

    Parameters
    ----------
    system : System or Scenario
        The moored system (its ``lines`` model and scenario: winch rates, length limits, MBS).
    settings : WinchSettings or mapping, optional

    Implements :class:`tapm_opt.interfaces.WinchController`: :meth:`update` returns the winch
    speeds [m/s] (+ pays out) for the plant, :meth:`mooring_load` the measured mooring force the
    thrusters are relieved of (``tau_thr = tau_c - tau_m``).
    """

    def __init__(self, system: Any, settings: Any = None):
        from ..models.system import System

        system = system if isinstance(system, System) else System.from_scenario(system)
        self.system = system
        self.settings = s = WinchSettings.from_mapping(settings)
        sc = system.scenario
        self.model = model = system.lines
        self.line_ids = tuple(ln.id for ln in sc.lines)
        if tuple(model.line_ids) != self.line_ids:
            raise WinchError(f"the system's line model has lines {list(model.line_ids)}, the scenario "
                             f"{list(self.line_ids)}: build the winch controller on an intact system")
        self.rate_max = readonly(np.array([ln.winch_max_rate for ln in sc.lines], dtype=float))
        self._no_rate = self.rate_max == 0   # lines without a winch
        if not np.any(self.rate_max > 0):
            raise WinchError(f"scenario {sc.name!r} has no winch: every lines[].winch_max_rate is 0; give the lines "
                             "winches (winch_max_rate, min_length, max_length) to use winch control")
        self.L_limits = readonly(np.array([ln.length_limits for ln in sc.lines], dtype=float))
        self.L0 = readonly(np.array([ln.length for ln in sc.lines], dtype=float))
        mbs = np.asarray(model.MBS, dtype=float)
        frac = CEILING_MARGIN * sc.limits.tension_utilisation if s.T_max_fraction is None else s.T_max_fraction
        #: Tension ceiling of each line [N].
        self.T_max = readonly(frac * mbs)
        T0 = np.asarray(model.solve_lines(np.zeros(3)).TF, dtype=float)
        hang = np.asarray(model.w, dtype=float) * np.asarray(model.ZF, dtype=float)
        #: Tension floor of each line [N].
        self.T_min = readonly(hang + s.T_min_fraction * np.maximum(T0 - hang, 0.0))
        self._B_fixed = configuration_matrix(model)
        # composite lines (and lines of a tension-strain table): their solve costs ~13 ms, so the
        # horizontal share comes from tables in distance and length (models.characteristics.LengthTables)
        self._tables: dict[int, Any] = {}
        comp = [i for i, c in enumerate(model.composite or ()) if c is not None and self.rate_max[i] > 0]
        if comp:
            from ..models.characteristics import LengthTables

            _, _, XF0 = model.spans(np.zeros(3))
            reach = (0.3 * float(np.max(np.asarray(model.ZF) + np.asarray(model.h_A)))
                     + 2.0 * float(np.hypot(*model.p_cot_B)) + 2.0 * np.hypot(model.p_T[:, 0], model.p_T[:, 1]))
            H_ref = float(np.max(T0[comp]))   # one scale and one range per line key: equal lines share tables
            rng: dict = {}
            for i in comp:
                lo, hi = rng.get(model.line_key(i), (math.inf, -math.inf))
                rng[model.line_key(i)] = (min(lo, float(XF0[i] - reach[i])), max(hi, float(XF0[i] + reach[i])))
            for i in comp:
                lo, hi = rng[model.line_key(i)]
                self._tables[i] = LengthTables(model, i, max(lo, 0.0), hi, L0=float(self.L0[i]), dL=LENGTH_GRID,
                                               H_ref=H_ref)
        self._simple = np.array([i not in self._tables for i in range(len(self.line_ids))])
        self.reset()

    # -- state -----------------------------------------------------------------------------
    def reset(self) -> None:
        n = len(self.line_ids)
        self._L = np.array(self.L0, dtype=float)
        self._zeta = np.zeros(n)
        self._u = np.zeros(n)
        self._t_prev: float | None = None
        self._tau_m_B = np.zeros(3)
        self._tau_m_E = np.zeros(3)
        self._limited = np.zeros(n, dtype=bool)
        self._cut = np.zeros(n)        # sign(u_raw - u): +1 where a limit cut the command from above
        self._B = self._B_fixed

    @property
    def lengths(self) -> np.ndarray:
        """Unstretched line lengths [m] as the controller tracks them (winch encoders: the integral
        of the speeds it commanded, which the plant applies)."""
        return readonly(self._L)

    @property
    def B(self) -> np.ndarray:
        """Configuration matrix (m, 3) of the latest update (:func:`configuration_matrix`)."""
        return readonly(self._B)

    @property
    def limited(self) -> np.ndarray:
        """Lines whose command the latest update limited (tension, rate or length), bool (m,)."""
        return readonly(self._limited)

    def force_capacity(self, directions: int = 72) -> float:
        """Horizontal force [N] the winches can make the mooring deliver in every direction at the
        field zero point: ``min_d sum_j max(H_max,j p_j.d, H_min,j p_j.d)`` over ``directions``
        horizontal unit vectors d, with each line's horizontal tension between its floor and
        ceiling, ``H = T - w ZF`` (the catenary with a grounded part: top tension = horizontal
        tension + the weight of the fairlead height, exact for the inextensible line; 1.9 % above the
        elastic catenary's H on aamo4 at the pretension) and lines
        without a winch at their pretension. The DP command with winch control may ask this much
        more than the thrusters can give (:func:`tapm_opt.studies.controllers.build_controller`):
        the mooring carries it ([AF] §III)."""
        m = self.model
        hang = np.asarray(m.w, dtype=float) * np.asarray(m.ZF, dtype=float)
        H0 = np.asarray(m.solve_lines(np.zeros(3)).HF, dtype=float)
        hi = np.where(self._no_rate, H0, np.maximum(self.T_max - hang, 0.0))
        lo = np.where(self._no_rate, H0, np.maximum(self.T_min - hang, 0.0))
        ang = np.linspace(0.0, 2.0 * math.pi, int(directions), endpoint=False)
        proj = self._B_fixed[:, :2] @ np.vstack([np.cos(ang), np.sin(ang)])   # (m, n) p_j . d
        return float(np.min(np.sum(np.maximum(hi[:, None] * proj, lo[:, None] * proj), axis=0)))

    def mooring_load(self) -> np.ndarray:
        """Measured mooring load ``tau_m`` (3,) in {B} [N, N, N m] of the latest update."""
        return readonly(self._tau_m_B)

    def mooring_force_E(self) -> np.ndarray:
        """Measured horizontal mooring force (3,) in {E} [N, N, 0] of the latest update."""
        return readonly(self._tau_m_E)

    # -- the law ---------------------------------------------------------------------------
    def measured_horizontal_tensions(self, eta: Any, tensions: Any,
                                     broken: frozenset = frozenset()) -> tuple[np.ndarray, np.ndarray]:
        """``(H, T)`` (m,) [N]: each line's fairlead tension T (the measured one; the elastic
        catenary's at pose ``eta`` and the tracked length when ``tensions`` is None) and its
        horizontal part ``H = T HF/TF`` with ``HF/TF`` of that catenary; H = 0 for a line reported
        broken."""
        m = self.model
        eta = _vec("eta", eta, 3, "m, m, rad")
        _, _, XF = m.spans(eta)
        XF = np.asarray(XF, float)
        if not self._tables:
            sol = m.solve_xf(XF, L=self._L)
            HF, TF = np.asarray(sol.HF, float), np.asarray(sol.TF, float)
        else:   # homogeneous lines by their catenary at the tracked lengths, the others from tables
            HF, TF = np.zeros(XF.size), np.zeros(XF.size)
            simple = self._simple
            if simple.any():
                sol = catenary.solve(XF[simple], np.asarray(m.ZF)[simple], self._L[simple], np.asarray(m.EA)[simple],
                                     np.asarray(m.w)[simple], CB=np.asarray(m.CB)[simple],
                                     h_A=np.asarray(m.h_A)[simple])
                HF[simple], TF[simple] = sol.HF, sol.TF
            for i, tab in self._tables.items():
                HF[i], TF[i] = tab(XF[i], self._L[i])
        T = TF.copy() if tensions is None else _vec("estimate.tensions", tensions, len(self.line_ids), "N")
        H = np.maximum(T, 0.0) * np.where(TF > 0, HF / np.where(TF > 0, TF, 1.0), 0.0)
        H[[lid in broken for lid in self.line_ids]] = 0.0
        return H, T

    def update(self, t: float, estimate: Any, tau_cmd: Any) -> np.ndarray:
        """Winch speeds u (m,) [m/s] (+ pays out) from the DP command and the measured tensions.

        Parameters
        ----------
        t : float
            Time [s] (non-decreasing).
        estimate : Estimate
            ``eta`` (3,) the estimated LF pose in {E}; ``tensions`` (m,) the measured fairlead
            tensions [N] (None: the catenary's at the tracked lengths); ``broken_lines``.
        tau_cmd : array_like (3,)
            The DP controller's commanded generalised force ``tau_c`` in {B} [N, N, N m].
        """
        t = _finite("t", t, unit="s")
        tau_c = _vec("tau_cmd", tau_cmd, 3, "N, N, N m")
        eta = _vec("estimate.eta", getattr(estimate, "eta", None), 3, "m, m, rad")
        s = self.settings
        # lengths: the speeds held since the last update (the plant applies them as commanded)
        dt = 0.0 if self._t_prev is None else t - self._t_prev
        if dt < 0:
            raise WinchError(f"t = {t!r} s is before the previous update at {self._t_prev!r} s")
        if dt > 0:
            self._L = np.clip(self._L + dt * self._u, self.L_limits[:, 0], self.L_limits[:, 1])
        broken = frozenset(getattr(estimate, "broken_lines", frozenset()) or ())
        tensions = getattr(estimate, "tensions", None)
        H, T = self.measured_horizontal_tensions(eta, tensions, broken)
        self._B = configuration_matrix(self.model, eta) if s.geometry == "pose" else self._B_fixed  # read only
        self._tau_m_E = horizontal_force(self._B, H)
        self._tau_m_B = np.asarray(self.model.tau_from_H(eta, H), dtype=float)
        tau_c_E = np.zeros(3)
        tau_c_E[:2] = rot_z(eta[2])[:2, :2] @ tau_c[:2]
        e = tau_c_E - self._tau_m_E                       # horizontal force error in {E} [N]
        sj = self._B @ e                                  # p_j . e
        # integrator update with the held speeds' limits (conditional integration), then the law
        if dt > 0 and s.ki > 0:
            push = -s.ki * sj                             # the direction the integral moves u_j
            frozen = self._limited & (np.sign(push) == self._cut) & (push != 0)
            self._zeta += np.where(frozen, 0.0, dt * sj)
        u_raw = -s.kc * sj - s.ki * self._zeta
        u = u_raw.copy()
        # 1. tension guard
        hi, lo = T >= self.T_max, T <= self.T_min
        u = np.where(hi, np.maximum(u, s.kc * (T - self.T_max)), u)
        u = np.where(lo, np.minimum(u, -s.kc * (self.T_min - T)), u)
        # 2. rate
        u = np.clip(u, -self.rate_max, self.rate_max)
        # 3. length after one period (the last one, else 1 s)
        h = dt if dt > 0 else 1.0
        u = np.clip(u, (self.L_limits[:, 0] - self._L) / h, (self.L_limits[:, 1] - self._L) / h)
        no_winch = self._no_rate | np.array([lid in broken for lid in self.line_ids])
        u = np.where(no_winch, 0.0, u)
        self._limited = np.abs(u - u_raw) > 1e-12 * np.maximum(1.0, np.abs(u_raw))
        self._cut = np.sign(u_raw - u)
        self._u = u
        self._t_prev = t
        return u.copy()

    def integrator(self) -> np.ndarray:
        """The integral states zeta_j [N s] (m,) of (AF-PI)."""
        return readonly(self._zeta)
