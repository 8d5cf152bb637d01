"""Quasi-static top-tensioned riser: a tensioned beam in a sheared current, and its end angles.

The riser low-frequency model of [R] §2.1, ``M(r) r'' + C(r) r' + K(r) r = F_vesselLF + F_current``,
with inertia and damping dropped and the riser velocity neglected in the drag (the quasi-static
tensioned beam of survey §4.3.1, which finds "a less accurate FEM with a maximum of 10 elements"
sufficient for the top and bottom angles). ``[R]`` = seed reliability-setpoint-riser-mooring §2.1,
``[S]`` = the TAPM survey §4.3.1 and eq. (37).

Geometry and equation
---------------------
The riser hangs from the hang-off (``riser.hangoff`` in {B}, at depth ``z_top = water_depth -
length``) straight down to the wellhead (``riser.wellhead`` in {E}, on the seabed at z = water
depth); its stretch is ignored. With ``s`` the height above the wellhead (s = 0 at the wellhead,
s = L at the hang-off, depth z = water_depth - s), each horizontal component w(s) of the riser's
position in {E} (x and y, independent) satisfies

    EI w'''' - (T_e(s) w')' = q(s),                                                   (1)

    T_e = T_top - w_s (z - z_top) = T_bottom + w_s s,    T_bottom = T_top - w_s L > 0,
    q = 1/2 rho C_d D |v_c(z)| v_c(z)                     (the current drag per unit length),
    EI = E pi/64 (D^4 - (D - 2 t)^4)                      (``config.schema.Riser.EI``),

with the ends pinned (flex joints without rotational stiffness: zero moment, EI w'' = 0) at
``w(0) = wellhead`` and ``w(L) = hang-off``. With EI = 0 (``wall_thickness = 0``) it is a
tensioned string, ``-(T_e w')' = q``.

Discretisation
--------------
``n_elements`` equal cubic Hermite beam elements (nodal deflection w and slope w' = dw/ds), the
Galerkin form of (1): ``K u = f`` with

    K_e = int_e (EI N'' N''^T + T_e N' N'^T) ds,      f_e = int_e q N ds,

the bending stiffness plus the consistent geometric stiffness of the linearly varying tension
(Gauss-Legendre with 4 points: exact, the integrands are polynomials of degree <= 5). The load is
integrated exactly for the scenario's current profiles (split at the profile's break points, so
each piece is a polynomial). The end deflections are prescribed, the end slopes free (the zero
moment is the natural boundary condition). K is symmetric positive definite for T_e > 0, also for
EI = 0, and does not depend on the hang-off position or the current: the solve is linear in the
end deflections and in q. Hence the end angles are exactly affine,

    theta_top = c_t (p_top - p_wellhead) + h_t g(v_c),
    theta_bottom = c_b (p_top - p_wellhead) + h_b g(v_c),                               (2)

with four scalars (``c_t``, ``c_b`` [1/m], ``h_t``, ``h_b`` [s^2/m^2]) computed once from the
factorised stiffness, and ``g(v) = |v| v`` the quadratic drag velocity of the surface current
``v`` (the profile's shape phi(z) is inside f). (2) is the seed's influence relation
``theta = theta_o + c Delta r_v`` of [R] §2.2, exact here because q does not depend on the
deflection; :meth:`RiserModel.angles` evaluates it (microseconds), :meth:`RiserModel.deflection`
does the full solve.

Sign convention
---------------
The angles are *vectors* in {E}, shape (2,) [rad]: the horizontal components of the riser's
inclination from the vertical at each end, ``theta = dw/ds`` with s pointing up, from the
wellhead toward the hang-off. A straight riser whose top is offset by +Delta in x has both angles
about (+Delta/L, 0); with the ends fixed, a current going to +x bows the riser to +x: the bottom
angle is positive, the top angle negative. The magnitudes ``|theta|`` are the riser angles that
limits refer to; the components are [S] eq. (37)'s ``alpha_x, alpha_y``.

Assumptions
-----------
* No riser dynamics (no inertia, damping, wave-frequency loads or vortex-induced vibration); the
  riser follows the vessel quasi-statically and does not load it ([R] §2.1).
* Small angles: the drag is that of the full horizontal current, taken normal to the riser
  (cos theta = 1), and the tension acts along the vertical.
* Pinned ends: flex joints without rotational stiffness at both ends.
* The effective tension varies only with the submerged weight (stretch, internal pressure
  changes and the current's drag on the tension ignored).
* The smooth speed: ``|v|`` in the drag is ``sqrt(v.v + eps^2)`` with ``eps = 1e-6 m/s``
  (``SPEED_EPS``), so the CasADi function is differentiable at v = 0; the drag is then
  ``|v| v`` to a relative 5e-13 at 1 m/s (eps^2 / 2v^2). The numpy path uses the same
  smoothing.
"""

from __future__ import annotations

import math
from typing import Any

import casadi as ca
import numpy as np
from scipy.linalg import cho_factor, cho_solve

from .._checks import finite, vector
from .. import _backend as bk
from .._io import readonly
from ..errors import ModelError
from ..geometry import turret_position
from .environment import CurrentProfile

__all__ = ["RiserModel", "SPEED_EPS"]

#: Smoothing speed [m/s] of ``|v| = sqrt(v.v + eps^2)`` in the drag (module docstring).
SPEED_EPS = 1e-6

#: Relative tolerance on ``length <= water_depth`` (a riser reaching the surface).
_LENGTH_TOL = 1e-9

_GAUSS_X, _GAUSS_W = np.polynomial.legendre.leggauss(4)


def _drag_velocity(vx: Any, vy: Any) -> tuple[Any, Any]:
    """g(v) = |v| v with the smooth speed ``sqrt(v.v + eps^2)`` [m^2/s^2]; floats or CasADi."""
    speed = bk.sqrt(vx * vx + vy * vy + SPEED_EPS**2) if bk.is_symbolic(vx) else math.sqrt(
        vx * vx + vy * vy + SPEED_EPS**2)
    return speed * vx, speed * vy


def _finite(name: str, value: Any, *, lo: float | None = None, strict: bool = False, unit: str = "") -> float:
    return finite(name, value, lo=lo, strict=strict, unit=unit, error=ModelError, eq="=")


def _vec2(name: str, value: Any, unit: str) -> np.ndarray:
    return vector(name, value, 2, what="(x, y) in {E}", unit=unit, error=ModelError, eq="=")


def _shape_functions(xi: np.ndarray, l: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Cubic Hermite N, dN/ds, d2N/ds2 at xi in [0, 1] on an element of length l; each (4, len(xi))
    for the DOFs (w_1, w'_1, w_2, w'_2)."""
    x2, x3 = xi * xi, xi * xi * xi
    N = np.stack([1 - 3 * x2 + 2 * x3, l * (xi - 2 * x2 + x3), 3 * x2 - 2 * x3, l * (x3 - x2)])
    dN = np.stack([(-6 * xi + 6 * x2) / l, 1 - 4 * xi + 3 * x2, (6 * xi - 6 * x2) / l, 3 * x2 - 2 * xi])
    d2N = np.stack([(12 * xi - 6) / l**2, (6 * xi - 4) / l, (6 - 12 * xi) / l**2, (6 * xi - 2) / l])
    return N, dN, d2N


class RiserModel:
    """Quasi-static tensioned-beam riser and its end angles (module docstring).

    Parameters
    ----------
    length : float
        Riser length L [m], > 0 and at most ``water_depth``.
    water_depth : float
        Depth of the wellhead (the seabed) [m]; the hang-off is at depth ``water_depth - length``.
    top_tension : float
        Effective tension at the hang-off T_top [N], > 0.
    submerged_weight : float
        Submerged weight per unit length w_s [N/m], >= 0 (0: constant tension); the tension at the
        wellhead ``T_top - w_s L`` must be > 0.
    diameter : float
        Hydrodynamic diameter D [m], > 0.
    rho : float
        Water density [kg/m^3], > 0.
    Cd : float
        Drag coefficient on D [-], >= 0.
    EI : float
        Bending stiffness [N m^2], >= 0 (0: a tensioned string).
    wellhead : array_like, shape (2,)
        Wellhead (x, y) in {E} [m].
    hangoff_B : array_like, shape (2,)
        Hang-off point (x, y) in {B} [m].
    current : CurrentProfile, optional
        The current over depth: its shape phi(z) scales any surface current given to the methods,
        and its surface velocity is their default. None: still water, and a uniform shape for a
        surface current given to the methods.
    n_elements : int
        Number of beam elements, >= 10 (survey §4.3.1: 10 suffice for the end angles).
    names : dict, optional
        Field names used in error messages (``from_scenario`` names the scenario's fields).

    Raises
    ------
    ModelError
        A parameter out of range, a riser longer than the water depth, or a tension that is not
        positive down to the wellhead; the message names the field and its value.
    """

    def __init__(self, *, length: float, water_depth: float, top_tension: float, submerged_weight: float,
                 diameter: float, rho: float, Cd: float = 1.0, EI: float = 0.0, wellhead: Any = (0.0, 0.0),
                 hangoff_B: Any = (0.0, 0.0), current: CurrentProfile | None = None, n_elements: int = 20,
                 names: dict[str, str] | None = None):
        nm = {"length": "length", "water_depth": "water_depth", "top_tension": "top_tension",
              "submerged_weight": "submerged_weight", "diameter": "diameter", "rho": "rho", "Cd": "Cd",
              "EI": "EI", "wellhead": "wellhead", "hangoff_B": "hangoff_B", **(names or {})}
        self.length = L = _finite(nm["length"], length, lo=0.0, strict=True, unit="m")
        self.water_depth = d = _finite(nm["water_depth"], water_depth, lo=0.0, strict=True, unit="m")
        if L > d * (1.0 + _LENGTH_TOL):
            raise ModelError(f"{nm['length']}={length!r} m exceeds the water depth {d:g} m: the tensioned-beam "
                             "riser model needs a riser no longer than the water depth (a top-tensioned riser "
                             "straight up from the wellhead)")
        self.top_tension = _finite(nm["top_tension"], top_tension, lo=0.0, strict=True, unit="N")
        self.submerged_weight = _finite(nm["submerged_weight"], submerged_weight, lo=0.0, unit="N/m")
        self.diameter = _finite(nm["diameter"], diameter, lo=0.0, strict=True, unit="m")
        self.rho = _finite(nm["rho"], rho, lo=0.0, strict=True, unit="kg/m^3")
        self.Cd = _finite(nm["Cd"], Cd, lo=0.0)
        self.EI = _finite(nm["EI"], EI, lo=0.0, unit="N m^2")
        self.wellhead = readonly(_vec2(nm["wellhead"], wellhead, "m"))
        self.hangoff_B = readonly(_vec2(nm["hangoff_B"], hangoff_B, "m"))
        if not isinstance(n_elements, (int, np.integer)) or isinstance(n_elements, bool) or n_elements < 10:
            raise ModelError(f"n_elements={n_elements!r} must be an integer >= 10 (survey §4.3.1: 10 elements "
                             "give the end angles accurately enough)")
        self.n_elements = n = int(n_elements)
        #: Depth of the hang-off [m] (z down).
        self.z_top = max(d - L, 0.0)
        #: Effective tension at the wellhead [N].
        self.bottom_tension = self.top_tension - self.submerged_weight * L
        if not self.bottom_tension > 0.0:
            raise ModelError(
                f"{nm['top_tension']}={top_tension!r} N leaves the effective tension at the wellhead "
                f"T_top - w_s L = {self.bottom_tension:.4g} N not positive ({nm['submerged_weight']} = "
                f"{self.submerged_weight:g} N/m over {L:g} m): the riser would buckle; raise the top tension")
        if current is not None and not isinstance(current, CurrentProfile):
            raise ModelError(f"current must be a CurrentProfile or None, got {type(current).__name__}")
        if current is not None and not math.isclose(current.water_depth, d, rel_tol=1e-12):
            raise ModelError(f"current is a profile over {current.water_depth:g} m of water, the riser stands in "
                             f"{nm['water_depth']} = {d:g} m: build the CurrentProfile with the riser's water depth")
        self.current = current
        #: Default surface current (2,) in {E} [m/s]: the profile's, or zero.
        self.v_c = readonly(np.zeros(2) if current is None else np.asarray(current.surface[:2], dtype=float))
        #: 1/2 rho C_d D [kg/m^2]: the drag per unit length is this times phi|phi| g(v) [N/m].
        self.k_drag = 0.5 * self.rho * self.Cd * self.diameter
        #: Node heights above the wellhead s (n + 1,) [m], from the wellhead up.
        self.s = readonly(np.linspace(0.0, L, n + 1))
        self._assemble()
        self._fn: ca.Function | None = None
        self._jac_fn: ca.Function | None = None
        self._g_default = np.array(_drag_velocity(self.v_c[0], self.v_c[1]))
        # floats of the affine map for the per-step path (:meth:`_affine`)
        self._g_default_xy = tuple(self._g_default.tolist())
        self._wellhead_xy = tuple(self.wellhead.tolist())
        self._hangoff_xy = tuple(self.hangoff_B.tolist())
        self._cc, self._hh = tuple(self._c.tolist()), tuple(self._h.tolist())

    # -- construction ----------------------------------------------------------------------
    @classmethod
    def from_scenario(cls, scenario: Any, sea_state: Any = None, *, n_elements: int = 20) -> RiserModel:
        """The riser of a scenario (its ``[riser]``, ``environment.water_depth`` and
        ``water_density``) in a sea state's current.

        Parameters
        ----------
        scenario : tapm_opt.config.Scenario
        sea_state : SeaState, str or None
            The sea state (or its id) whose current and profile act on the riser; None: still water.
        n_elements : int
            Beam elements, >= 10.
        """
        rs = scenario.riser
        if rs is None:
            raise ModelError(f"scenario {scenario.name!r} has no [riser]")
        env = scenario.environment
        current = None
        if sea_state is not None:
            if isinstance(sea_state, str):
                try:
                    sea_state = scenario.sea_state(sea_state)
                except KeyError as exc:
                    raise ModelError(f"sea_state = {sea_state!r}: {str(exc).strip(chr(39) + chr(34))}") from None
            current = CurrentProfile(sea_state, env.water_depth)
        names = {k: f"riser.{k}" for k in ("length", "top_tension", "submerged_weight", "diameter", "Cd",
                                            "wellhead")}
        names.update(water_depth="environment.water_depth", rho="environment.water_density",
                     EI="riser.EI (youngs_modulus, wall_thickness)", hangoff_B="riser.hangoff")
        return cls(length=rs.length, water_depth=env.water_depth, top_tension=rs.top_tension,
                   submerged_weight=rs.submerged_weight, diameter=rs.diameter, rho=env.water_density, Cd=rs.Cd,
                   EI=rs.EI, wellhead=rs.wellhead, hangoff_B=rs.hangoff, current=current, n_elements=n_elements,
                   names=names)

    def _phi_abs_phi(self, s: np.ndarray) -> np.ndarray:
        """phi |phi| of the profile at heights s above the wellhead (1 without a profile)."""
        if self.current is None:
            return np.ones_like(s)
        phi = self.current.factor(self.water_depth - s)
        return phi * np.abs(phi)

    def _assemble(self) -> None:
        n, s, EI, ws, Tb = self.n_elements, self.s, self.EI, self.submerged_weight, self.bottom_tension
        ndof = 2 * (n + 1)
        K = np.zeros((ndof, ndof))
        f = np.zeros(ndof)
        xi = 0.5 * (_GAUSS_X + 1.0)
        wq = 0.5 * _GAUSS_W
        # heights of the profile's break points, where phi changes slope
        brk = np.zeros(0) if self.current is None else self.water_depth - np.asarray(self.current.breakpoints)
        for e in range(n):
            s0, s1 = s[e], s[e + 1]
            l = s1 - s0
            N, dN, d2N = _shape_functions(xi, l)
            T = Tb + ws * (s0 + xi * l)
            Ke = l * ((EI * d2N * wq) @ d2N.T + (T * wq * dN) @ dN.T)
            # load: exact on each piece between the profile's break points (phi linear on it)
            cuts = np.concatenate([[s0], np.sort(brk[(brk > s0) & (brk < s1)]), [s1]])
            fe = np.zeros(4)
            for a, b in zip(cuts[:-1], cuts[1:]):
                sq = a + (b - a) * xi
                Nq, _, _ = _shape_functions((sq - s0) / l, l)
                fe += (b - a) * (Nq * (wq * self._phi_abs_phi(sq))).sum(axis=1)
            idx = slice(2 * e, 2 * e + 4)
            K[idx, idx] += Ke
            f[idx] += self.k_drag * fe
        self._K, self._f = K, f
        top, bot = 2 * n, 0
        free = np.array([i for i in range(ndof) if i not in (bot, top)])
        self._free, self._i_top, self._i_bot = free, top, bot
        self._cho = cho_factor(K[np.ix_(free, free)])
        # The deflection is solved relative to the wellhead, w - w(0): a rigid translation has no
        # strain energy (K annihilates it), so only the offset p_top - wellhead enters, and a riser
        # straight above its wellhead in still water has angles exactly 0.
        # Columns: prescribed top offset, load shape -> free DOFs.
        X = cho_solve(self._cho, np.column_stack([-K[free, top], f[free]]))
        j_top = int(np.flatnonzero(free == top + 1)[0])  # slope at the hang-off
        j_bot = int(np.flatnonzero(free == bot + 1)[0])  # slope at the wellhead
        #: rows of K_ff^-1 giving the two end slopes (top, bottom) from the free right-hand side
        self._rows = cho_solve(self._cho, np.eye(free.size)[:, [j_top, j_bot]]).T
        # theta_end = c (p_top - wellhead) + h g(v), per component (module docstring, eq. 2)
        self._c = X[[j_top, j_bot], 0]
        self._h = X[[j_top, j_bot], 1]

    # -- properties ------------------------------------------------------------------------
    @property
    def z(self) -> np.ndarray:
        """Node depths (n_elements + 1,) [m], from the wellhead (z = water depth) up to the hang-off."""
        return readonly(self.water_depth - self.s)

    @property
    def coefficients(self) -> dict[str, float]:
        """The scalars of the affine map (eq. 2 of the module docstring): ``c_t``, ``c_b`` [1/m]
        (d theta / d p_top per component) and ``h_t``, ``h_b`` [s^2/m^2] (d theta / d g(v_c))."""
        return {"c_t": float(self._c[0]), "c_b": float(self._c[1]),
                "h_t": float(self._h[0]), "h_b": float(self._h[1])}

    def tension(self, z: Any) -> np.ndarray:
        """Effective tension T_e(z) = T_top - w_s (z - z_top) [N] at depths z [m] on the riser."""
        z = np.asarray(z, dtype=float)
        return self.top_tension - self.submerged_weight * (z - self.z_top)

    def drag(self, z: Any, v_c: Any = None) -> np.ndarray:
        """Current drag per unit length q(z) = 1/2 rho C_d D |v_c(z)| v_c(z) [N/m] in {E} at depths
        z [m], shape ``z.shape + (2,)``; ``v_c`` the surface current (2,) [m/s] (default the
        sea state's)."""
        g = self._g(v_c)
        s = self.water_depth - np.asarray(z, dtype=float)
        return self.k_drag * np.multiply.outer(self._phi_abs_phi(s), g)

    # -- numeric evaluation ----------------------------------------------------------------
    def _g(self, v_c: Any) -> np.ndarray:
        """g(v_c) = |v_c| v_c (2,) [m^2/s^2] of a surface current (default the sea state's)."""
        return self._g_default if v_c is None else np.array(self._g_xy(v_c))

    def _g_xy(self, v_c: Any) -> tuple[float, float]:
        if v_c is None:
            return self._g_default_xy
        vx, vy = _vec2("v_c", v_c, "m/s").tolist()
        return _drag_velocity(vx, vy)

    def angles(self, p_top_E: Any, v_c: Any = None) -> tuple[np.ndarray, np.ndarray]:
        """Top and bottom riser angles for a hang-off at ``p_top_E`` (eq. 2 of the module docstring).

        Parameters
        ----------
        p_top_E : array_like, shape (2,)
            Hang-off (x, y) in {E} [m].
        v_c : array_like, shape (2,), optional
            Surface current (x, y) in {E} [m/s] (the profile's shape is kept); default the sea
            state's.

        Returns
        -------
        theta_top, theta_bottom : ndarray, shape (2,)
            Angle vectors in {E} [rad]: dw/ds (s up) at the hang-off and at the wellhead.
        """
        px, py = _vec2("p_top_E", p_top_E, "m").tolist()
        a = self._affine(px, py, v_c)
        return np.array(a[:2]), np.array(a[2:])

    def angles_at(self, eta: Any, v_c: Any = None) -> np.ndarray:
        """Riser angles of the vessel at pose ``eta`` = (x [m], y [m], psi [rad]) in {E} (the
        hang-off of :meth:`hangoff_E`) as one vector (top_x, top_y, bottom_x, bottom_y), shape (4,)
        [rad] in {E}: the layout of ``Measurement.riser_angles``. The plant's per-step path."""
        try:
            x, y, psi = (eta.tolist() if type(eta) is np.ndarray and eta.shape == (3,) and eta.dtype == float
                         else (float(v) for v in eta))
        except (TypeError, ValueError):
            raise ModelError(f"eta={eta!r} must be 3 numbers (x [m], y [m], psi [rad])") from None
        if not (math.isfinite(x) and math.isfinite(y) and math.isfinite(psi)):
            raise ModelError(f"eta={eta!r} must be finite (x [m], y [m], psi [rad])")
        c, s_ = math.cos(psi), math.sin(psi)
        bx, by = self._hangoff_xy
        return np.array(self._affine(x + c * bx - s_ * by, y + s_ * bx + c * by, v_c))

    def _affine(self, px: float, py: float, v_c: Any) -> tuple[float, float, float, float]:
        """Eq. 2 of the module docstring on floats: (top_x, top_y, bottom_x, bottom_y) [rad]."""
        gx, gy = self._g_xy(v_c)
        (wx, wy), (c_t, c_b), (h_t, h_b) = self._wellhead_xy, self._cc, self._hh
        dx, dy = px - wx, py - wy
        return (c_t * dx + h_t * gx, c_t * dy + h_t * gy, c_b * dx + h_b * gx, c_b * dy + h_b * gy)

    def hangoff_E(self, eta: Any) -> np.ndarray:
        """Hang-off (x, y) in {E} [m] of the vessel at pose ``eta`` (3,) or (..., 3) = (x [m], y [m],
        psi [rad]): ``p + R2(psi) hangoff^B`` (:func:`tapm_opt.geometry.turret_position`, the same
        kinematics for any point of the hull); shape (2,) or (..., 2)."""
        e = np.asarray(eta, dtype=float)
        if e.ndim == 0 or e.shape[-1] != 3 or not np.all(np.isfinite(e)):
            raise ModelError(f"eta={eta!r} must be finite (x [m], y [m], psi [rad]) along its last axis")
        x, y = turret_position(e, self.hangoff_B)
        return np.stack([x, y], axis=-1)

    def influence(self, p_top_E: Any, v_c: Any = None) -> tuple[np.ndarray, np.ndarray]:
        """Influence coefficients ``(c_t, c_b)`` of [R] §2.2: the Jacobians d theta_top / d p_top and
        d theta_bottom / d p_top, each (2, 2) [rad/m], by automatic differentiation of
        :meth:`angle_function` (the model is affine in p_top, so they are ``c I`` with the
        :attr:`coefficients`, at every p_top and current)."""
        p = _vec2("p_top_E", p_top_E, "m")
        v = self.v_c if v_c is None else _vec2("v_c", v_c, "m/s")
        jt, jb = self.influence_function()(p, v)
        return np.asarray(jt.full()), np.asarray(jb.full())

    def deflection(self, p_top_E: Any, v_c: Any = None) -> tuple[np.ndarray, np.ndarray]:
        """The deflected riser by the full FE solve.

        Returns
        -------
        z : ndarray, shape (n_elements + 1,)
            Node depths [m], from the hang-off (z_top) down to the wellhead (water depth).
        w : ndarray, shape (n_elements + 1, 2)
            Horizontal (x, y) of the riser at those depths in {E} [m].
        """
        u = self._solve(p_top_E, v_c)
        return readonly(self.z[::-1]), readonly(u[0::2][::-1])

    def bending_moment(self, p_top_E: Any, v_c: Any = None) -> tuple[np.ndarray, np.ndarray]:
        """Bending moment EI w'' (x, y components) [N m] at the element ends, from the FE
        solution: ``(z (n_elements, 2) depths of each element's lower and upper end [m],
        M (n_elements, 2, 2) [element, end (lower, upper), component])``; the pinned ends have
        zero moment to within the discretisation error (natural boundary condition)."""
        u = self._solve(p_top_E, v_c)
        n, l = self.n_elements, self.length / self.n_elements
        _, _, d2N = _shape_functions(np.array([0.0, 1.0]), l)
        M = np.empty((n, 2, 2))
        for e in range(n):
            M[e] = self.EI * (d2N.T @ u[2 * e: 2 * e + 4])
        z = self.water_depth - np.column_stack([self.s[:-1], self.s[1:]])
        return readonly(z), readonly(M)

    def _solve(self, p_top_E: Any, v_c: Any) -> np.ndarray:
        """All DOFs (2 (n + 1), 2): deflection and slope of each node (from the wellhead up), x and y."""
        p = _vec2("p_top_E", p_top_E, "m")
        g = self._g(v_c)
        K, free, top = self._K, self._free, self._i_top
        u = np.zeros((K.shape[0], 2))  # relative to the wellhead (see _assemble)
        u[top] = p - self.wellhead
        u[free] = cho_solve(self._cho, np.outer(self._f[free], g) - np.outer(K[free, top], u[top]))
        u[0::2] += self.wellhead
        return u

    # -- symbolic --------------------------------------------------------------------------
    def angle_function(self) -> ca.Function:
        """CasADi Function ``riser_angles(p_top (2), v_c (2)) -> (theta_top (2), theta_bottom (2))``
        [m, m/s -> rad] in {E}: the FE solve for the two end slopes written over the symbols (the
        stiffness is numeric, the right-hand side symbolic in the prescribed top deflection and the
        drag), with the smooth speed of the module docstring; exact derivatives. Built once and
        cached."""
        if self._fn is None:
            p = ca.SX.sym("p_top", 2)
            v = ca.SX.sym("v_c", 2)
            g = _drag_velocity(v[0], v[1])
            K, free, top = self._K, self._free, self._i_top
            rows = ca.DM(self._rows)
            k_t, f = ca.DM(K[free, top]), ca.DM(self._f[free])
            ends = []
            for c in range(2):
                rhs = f * g[c] - k_t * (p[c] - float(self.wellhead[c]))  # relative to the wellhead
                ends.append(ca.mtimes(rows, rhs))  # (theta_top_c, theta_bottom_c)
            th_top = ca.vertcat(ends[0][0], ends[1][0])
            th_bot = ca.vertcat(ends[0][1], ends[1][1])
            self._fn = ca.Function("riser_angles", [p, v], [th_top, th_bot], ["p_top", "v_c"],
                                   ["theta_top", "theta_bottom"])
        return self._fn

    def influence_function(self) -> ca.Function:
        """CasADi Function ``riser_influence(p_top (2), v_c (2)) -> (c_t (2x2), c_b (2x2))``, the
        Jacobians of :meth:`angle_function` with respect to ``p_top`` [rad/m]; cached."""
        if self._jac_fn is None:
            fn = self.angle_function()
            p = ca.SX.sym("p_top", 2)
            v = ca.SX.sym("v_c", 2)
            th_t, th_b = fn(p, v)
            self._jac_fn = ca.Function("riser_influence", [p, v], [ca.jacobian(th_t, p), ca.jacobian(th_b, p)],
                                       ["p_top", "v_c"], ["c_t", "c_b"])
        return self._jac_fn

    def __repr__(self) -> str:
        return (f"RiserModel(L={self.length:g} m, T_top={self.top_tension:g} N, T_bottom={self.bottom_tension:g} N, "
                f"EI={self.EI:g} N m^2, n_elements={self.n_elements})")
