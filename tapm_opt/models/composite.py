"""Composite mooring line: sections in series joined by points that may carry a clump or a buoy.

A composite line runs from its anchor A (section 0) to its fairlead (section n-1) through sections
``k = 0..n-1`` of unstretched length ``L_k`` [m], axial stiffness ``EA_k`` [N], submerged weight
``w_k`` [N/m] and seabed friction ``CB_k``, joined by points ``j = 1..n-1`` (point j between
sections j-1 and j) with net submerged weight ``W_j`` [N] (positive down: a clump weight; negative:
a buoy's net buoyancy; 0: a plain joint).

Quasi-static solve (the formulation MoorPy and MoorDyn use for free points): each section is the
elastic catenary of :mod:`tapm_opt.models.catenary` between its two end points, with its own seabed
contact (its lower end's height above the seabed is the catenary's ``h_A``), and every point is in
equilibrium in the line's vertical plane::

    R_j = F_j^(below) + F_j^(above) + (0, -W_j) = 0,        j = 1..n-1

where ``F_j^(below)`` is the force of section j-1 on its upper end and ``F_j^(above)`` that of
section j on its lower end, each from the section's catenary solution (a section pulls its upper
end toward its lower end with ``(HF, VF)`` and its lower end with ``(HA, VA)``). A section may also
run downward (its upper end in the line order lies lower, e.g. the part of a line below a buoy):
the catenary then takes its ends the other way round. A point that reaches the seabed with a net
downward load rests on it (the seabed's reaction balances it vertically; no friction on a point).

The unknowns, the points' horizontal and vertical positions (x along the anchor-fairlead
direction from the anchor, z above the seabed), are found by damped Newton with the analytic
Jacobian of the section forces (the catenary's exact stiffness, and the derivative with respect to
the height of an elevated lower end for a section touching the seabed); the line's stiffness at
the fairlead then follows exactly by the implicit function theorem. Vectorised over any number of
configurations at once.

Buoyant sections (``w_k < 0``: distributed buoyancy modules, a lazy wave's arch) are the same
elastic catenary upside down: with heights measured down from the sea surface, ``z' = S - z``
(``S`` the surface's height above the seabed, :attr:`CompositeLine.surface`), the section is the
catenary of weight ``|w_k|`` between the same ends, its real upper end the lower one; its forces
on its ends and their derivatives come back with the vertical components and the derivatives
with respect to heights negated. A buoyant section arches up from its ends (its lowest points
are its ends), so it never reaches the seabed; where the flipped catenary would reach its
"seabed", the surface (it touches down, lies slack, or an end is above the surface), the section
would float there, which the model does not describe: :func:`solve` and :func:`points` raise
:class:`CatenaryError` naming the section, the configuration and the height, and a line that
floats as a whole (its weight in water with the points not positive) is refused. Where buoyant
sections may be in a scenario is the loader's rule
(:func:`tapm_opt.config.loader.buoyant_line_problem`: between weighted sections).

The one-section line is :func:`tapm_opt.models.catenary.solve` itself (the same numbers). The
solution has the fields of :class:`~tapm_opt.models.catenary.CatenarySolution` with the fairlead
(HF, VF), the anchor (HA, VA) and, for regime, one code per combination of section regimes (it
changes wherever any section's regime changes).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from .._io import readonly
from ..errors import CatenaryError
from . import catenary
from .catenary import SEABED, SLACK, SUSPENDED, TOUCHDOWN, CatenarySolution

__all__ = ["CompositeLine", "profile", "solve"]

_BIG_STIFFNESS = 1e12
"""Finite stand-in [N/m] for the infinite vertical stiffness of a section lying straight on the
seabed (catenary regime 'seabed'); only its sign matters to the Newton step, which locks such a
point on the seabed anyway."""

_REST_FORCE = 1e-5
"""Net upward load on a point at the seabed, relative to the line's force scale, below which the
point still rests there. A point without weight (a plain joint, a buoy lost) at the place where
the line lifts off the seabed would rise by ``V^2 / (2 w H)``, 1e-11 m for fpso's chain, while its
section's vertical force there is the catenary's to a few newton only (a suspended length of
1e-4 m left by the catenary's own tolerance): Newton cannot resolve that equilibrium and stalls
at its residual. Held on the seabed within this band (30 N on fpso as chain-wire-chain, the lift
below 1e-7 m), it converges."""

_REST_HEIGHT = 1e-9
"""Height above the seabed [m] below which a Newton step down puts a point on it (see _REST_FORCE)."""


@dataclass(frozen=True)
class CompositeLine:
    """Sections and points of one composite line (arrays from the anchor up).

    Attributes
    ----------
    L, EA, w, CB : ndarray, shape (n,)
        Per section: unstretched length [m], axial stiffness [N], submerged weight [N/m]
        (negative: a buoyant section, the module docstring), seabed friction [-].
    W : ndarray, shape (n - 1,)
        Net submerged weight of each point [N], positive down (clump), negative (buoy).
    tables : tuple
        Per section, its tension-strain table (:class:`~tapm_opt.strain_table.StrainTable`, a
        nonlinear axial law; its ``EA`` is then the table's secant) or None; empty (default):
        every section of constant EA. A homogeneous line with a table is the one-section line.
    surface : float or None
        Height of the sea surface above the seabed [m] (the water depth), which a buoyant section
        must stay below; None (default): not known, and the fairlead's height is taken instead
        (a fairlead is at most at the waterline, so no buoyant section is let above the surface,
        but one that would rise above its fairlead is refused). Lines without a buoyant section
        do not read it.
    """

    L: np.ndarray
    EA: np.ndarray
    w: np.ndarray
    CB: np.ndarray
    W: np.ndarray
    tables: tuple = ()
    surface: float | None = None

    @classmethod
    def from_arrays(cls, sec: dict) -> CompositeLine:
        """From one entry of :attr:`Scenario.line_sections <tapm_opt.config.Scenario.line_sections>`."""
        tabs = tuple(sec.get("EA_table", ()))
        tabs = tuple(None if t is None else catenary.as_table(t) for t in tabs) if any(
            t is not None for t in tabs) else ()
        surface = sec.get("surface")
        return cls(*(readonly(np.asarray(sec[k], dtype=float)) for k in ("L", "EA", "w", "CB", "W")), tables=tabs,
                   surface=None if surface is None else float(surface))

    def table(self, k: int):
        """Section ``k``'s tension-strain table, or None (constant EA)."""
        return self.tables[k] if self.tables else None

    @property
    def has_tables(self) -> bool:
        """True when a section has a tension-strain table (nonlinear EA)."""
        return any(t is not None for t in self.tables)

    @property
    def buoyant(self) -> np.ndarray:
        """Per section, True where it is buoyant (``w < 0``)."""
        return np.asarray(self.w) < 0

    @property
    def n_sections(self) -> int:
        return int(self.L.size)

    @property
    def length(self) -> float:
        """Total unstretched length [m]."""
        return float(np.sum(self.L))

    def key(self) -> tuple:
        """Hashable description (equal lines share tables)."""
        base = tuple(tuple(np.asarray(a, float).tolist()) for a in (self.L, self.EA, self.w, self.CB, self.W))
        if self.surface is not None and np.any(self.buoyant):
            base = base + (("surface", float(self.surface)),)
        if not self.has_tables:
            return base
        return base + (tuple(None if t is None else t.key() for t in self.tables),)

    def _table_ids(self, m: int):
        """Per section of ``m`` configurations (flat, section-major per configuration), the index of
        its table in :attr:`tables` (-1: constant EA); None when no section has one."""
        if not self.has_tables:
            return None
        ids = np.array([-1 if t is None else k for k, t in enumerate(self.tables)], dtype=np.int64)
        return np.broadcast_to(ids, (m, self.n_sections)).ravel()

    def with_length(self, length: float) -> CompositeLine:
        """The line with a total unstretched length of ``length`` [m] by its fairlead section's: a
        winch pays that section out (``length`` longer) or hauls it in; the other sections and the
        points keep theirs."""
        top = float(self.L[-1]) + (float(length) - self.length)
        if not (math.isfinite(top) and top > 0.0):
            raise CatenaryError(f"length = {length!r} m leaves the fairlead section of this composite line (sections "
                                f"L = {self.L.tolist()} m) {top:g} m: it must stay longer than the other sections")
        if top == float(self.L[-1]):
            return self
        L = np.array(self.L, dtype=float)
        L[-1] = top
        return dataclasses.replace(self, L=readonly(L))

    def force_scale(self) -> float:
        """A force scale [N] of the line: its weights (and buoyancies) in water, for tolerances."""
        return float(np.sum(np.abs(self.w) * self.L) + np.sum(np.abs(self.W))) or 1.0


# ------------------------------------------------------------------------------------------
# one section between two free ends: forces and their derivatives
# ------------------------------------------------------------------------------------------


def _solve_sections(X, Z, L, EA, w, CB, h, guess, tab_id, tables) -> CatenarySolution:
    """:func:`catenary.solve` of sections (flat arrays), those of each tension-strain table
    (``tables[tab_id]``; ``tab_id`` -1 or None: constant EA) in one call of their own."""
    if tab_id is None:
        return catenary.solve(X, Z, L, EA, w, CB=CB, h_A=h, guess=guess)
    X, Z, L, EA, w, CB, h = np.broadcast_arrays(*(np.asarray(a, dtype=float) for a in (X, Z, L, EA, w, CB, h)))
    out: dict = {}
    it = 0
    for t in np.unique(tab_id):
        m = tab_id == t
        g = None if guess is None else tuple(np.broadcast_to(np.asarray(a, float), X.shape)[m] for a in guess)
        sol = catenary.solve(X[m], Z[m], L[m], EA[m], w[m], CB=CB[m], h_A=h[m], guess=g,
                             table=None if t < 0 else tables[t])
        it = max(it, sol.iterations)
        for k in _SOL_FIELDS:
            v = getattr(sol, k)
            if k not in out:
                out[k] = np.zeros(X.shape, dtype=v.dtype)
            out[k][m] = v
    return CatenarySolution(iterations=it, **out)


_SOL_FIELDS = ("HF", "VF", "HA", "VA", "TF", "TA", "LBot", "regime", "dHF_dXF", "dHF_dZF", "dVF_dXF", "dVF_dZF")


def _section(xlo, zlo, xhi, zhi, L, EA, w, CB, guess=None, tab_id=None, tables=(), top=None):
    """Forces of sections on their ends and their derivatives, vectorised (flat arrays), as
    :func:`_hanging`; a buoyant section (``w < 0``) is the same catenary with the vertical axis
    flipped (module docstring, "Buoyant sections"): its heights measured down from ``top`` [m]
    (the sea surface above the seabed, per section), its weight ``|w|``, no friction; its forces
    and their derivatives flipped back. Its entries of the returned solution are the flipped
    catenary's (``HF``, ``VF`` >= 0; ``LBot`` its length along the surface, the regime its)."""
    b = np.asarray(w) < 0
    if not np.any(b):
        return _hanging(xlo, zlo, xhi, zhi, L, EA, w, CB, guess, tab_id, tables)
    top = np.broadcast_to(np.asarray(top, dtype=float), np.shape(xlo))
    F_lo, F_hi, J_lo, J_hi, sol = _hanging(xlo, np.where(b, top - zlo, zlo), xhi, np.where(b, top - zhi, zhi), L, EA,
                                           np.abs(w), np.where(b, 0.0, CB), guess, tab_id, tables)
    # z = top - z': the vertical force and every derivative with respect to a height change sign
    flip = np.where(b, -1.0, 1.0)
    for F in (F_lo, F_hi):
        F[:, 1] *= flip
    for J in (J_lo, J_hi):
        J[:, 1, :] *= flip[:, None]
        J[:, :, 1::2] *= flip[:, None, None]
    return F_lo, F_hi, J_lo, J_hi, sol


def _hanging(xlo, zlo, xhi, zhi, L, EA, w, CB, guess=None, tab_id=None, tables=()):
    """Forces of sections (``w >= 0``) on their ends and their derivatives, vectorised (flat arrays).

    Returns F_lo, F_hi (m, 2) — the section's force on its lower-index and upper-index end, (x, z)
    with z up — their Jacobians (m, 2, 4) with respect to (x_lo, z_lo, x_hi, z_hi), and the
    catenary solution (whose ends are the physically lower end A and the upper end U). ``tab_id``
    (m,) picks each section's tension-strain table in ``tables`` (-1: constant EA)."""
    up = zhi >= zlo
    xA, zA = np.where(up, xlo, xhi), np.where(up, zlo, zhi)
    xU, zU = np.where(up, xhi, xlo), np.where(up, zhi, zlo)
    dx = xU - xA
    s = np.where(dx >= 0, 1.0, -1.0)
    X, Z = np.abs(dx), zU - zA
    h = np.maximum(zA, 0.0)
    sol = _solve_sections(X, Z, L, EA, w, CB, h, guess, tab_id, tables)
    HF, VF, HA, VA = sol.HF, sol.VF, sol.HA, sol.VA
    dHX, dHZ, dVX = sol.dHF_dXF, sol.dHF_dZF, sol.dVF_dXF
    dVZ = np.where(np.isfinite(sol.dVF_dZF), sol.dVF_dZF, _BIG_STIFFNESS)
    reg = sol.regime
    zero = np.zeros_like(HF)
    dHh, dVh = zero.copy(), zero.copy()
    # lower-end force derivatives, suspended-like by default (HA = HF, VA = VF - w L)
    dHAX, dHAZ, dHAh = dHX.copy(), dHZ.copy(), zero.copy()
    dVAX, dVAZ, dVAh = dVX.copy(), dVZ.copy(), zero.copy()
    with np.errstate(divide="ignore", invalid="ignore"):
        # touching down from an elevated lower end: VA = -V1(HF, h)
        m = (reg == TOUCHDOWN) & (h > 0) & (VA < 0)
        if np.any(m):
            V1 = -VA[m]
            H = HF[m]
            h1 = np.hypot(H, V1)
            ea = EA[m] if np.ndim(EA) else np.full(V1.shape, EA)
            ww = w[m] if np.ndim(w) else np.full(V1.shape, w)
            dV1dH = V1 / ((h1 + H) * (1.0 + h1 / ea))
            dV1dh = ww * h1 / (V1 * (1.0 + h1 / ea))
            dXdh = -(V1 * V1 / (h1 + H)) / (ww * h1) * dV1dh
            if tab_id is not None:  # sections of a tension-strain table: its V1(HF, h) and span
                tm = tab_id[m]
                for t in np.unique(tm[tm >= 0]):
                    q = tm == t
                    a1, a2, a3 = catenary._reach_terms_table(H[q], V1[q], ww[q], tables[t])
                    dV1dH[q], dV1dh[q], dXdh[q] = a1, a2, a3 * a2
            dHh[m] = -dHX[m] * dXdh + dHZ[m]
            dVh[m] = -dVX[m] * dXdh + dVZ[m]
            dHAh[m] = dHh[m]
            dVAX[m] = -dV1dH * dHX[m]
            dVAZ[m] = -dV1dH * dHZ[m]
            dVAh[m] = -(dV1dH * dHh[m] + dV1dh)
        # touching down from a lower end on the seabed: VA = 0, HA = max(HF - CB w LB, 0)
        m = (reg == TOUCHDOWN) & ~((h > 0) & (VA < 0))
        if np.any(m):
            cb = (CB[m] if np.ndim(CB) else np.full(int(m.sum()), CB))
            act = HA[m] > 0
            dHAX[m] = np.where(act, dHX[m] + cb * dVX[m], 0.0)
            dHAZ[m] = np.where(act, dHZ[m] + cb * dVZ[m], 0.0)
            dVAX[m] = 0.0
            dVAZ[m] = 0.0
        # slack: VF = w L2(Z + h), VA = -w L1(h), no horizontal tension
        m = reg == SLACK
        if np.any(m):
            ww = w[m] if np.ndim(w) else np.full(int(m.sum()), w)
            ea = EA[m] if np.ndim(EA) else np.full(int(m.sum()), EA)
            L1 = -VA[m] / ww
            dVh[m] = dVZ[m]
            dHAX[m] = dHAZ[m] = 0.0
            dVAX[m] = dVAZ[m] = 0.0
            dVAh[m] = np.where(h[m] > 0, -ww / (1.0 + ww * L1 / ea), 0.0)
            if tab_id is not None:  # d(w L1)/dh = w / (1 + eps(w L1)) of a table
                tm = tab_id[m]
                for t in np.unique(tm[tm >= 0]):
                    q = np.flatnonzero(m)[tm == t]
                    wq = ww[tm == t]
                    dVAh[q] = np.where(h[q] > 0, -wq / (1.0 + tables[t].strain_at(-VA[q])), 0.0)
        # both ends on the seabed: VF = VA = 0
        m = reg == SEABED
        if np.any(m):
            dHAX[m] = np.where(HA[m] > 0, dHX[m], 0.0)
            dHAZ[m] = 0.0
            dVAX[m] = 0.0
            dVAZ[m] = 0.0
    # forces on U and A, and derivatives w.r.t. (xA, zA, xU, zU)
    FU = np.stack([-s * HF, -VF], axis=-1)
    FA = np.stack([s * HA, VA], axis=-1)
    JU = np.empty(HF.shape + (2, 4))
    JA = np.empty(HF.shape + (2, 4))
    JU[..., 0, :] = np.stack([dHX, s * (dHZ - dHh), -dHX, -s * dHZ], axis=-1)
    JU[..., 1, :] = np.stack([s * dVX, dVZ - dVh, -s * dVX, -dVZ], axis=-1)
    JA[..., 0, :] = np.stack([-dHAX, s * (-dHAZ + dHAh), dHAX, s * dHAZ], axis=-1)
    JA[..., 1, :] = np.stack([-s * dVAX, -dVAZ + dVAh, s * dVAX, dVAZ], axis=-1)
    # map (A, U) back to (lo, hi)
    u = up[..., None]
    F_lo = np.where(u, FA, FU)
    F_hi = np.where(u, FU, FA)
    # columns: (A cols 0,1; U cols 2,3) -> (lo cols 0,1; hi cols 2,3): swap column pairs where down
    swap = np.array([2, 3, 0, 1])
    uu = up[..., None, None]
    JA_l = np.where(uu, JA, JA[..., swap])
    JU_l = np.where(uu, JU, JU[..., swap])
    J_lo = np.where(uu, JA_l, JU_l)
    J_hi = np.where(uu, JU_l, JA_l)
    return F_lo, F_hi, J_lo, J_hi, sol


# ------------------------------------------------------------------------------------------
# the composite solve
# ------------------------------------------------------------------------------------------


def _nodes(y, XF, D, hA):
    """Node coordinates (m, n+1) x and z from the unknowns y (m, 2 (n-1))."""
    m = y.shape[0]
    x = np.concatenate([np.zeros((m, 1)), y[:, 0::2], XF[:, None]], axis=1)
    z = np.concatenate([hA[:, None], y[:, 1::2], D[:, None]], axis=1)
    return x, z


def _evaluate(y, XF, D, hA, line: CompositeLine, guess=None):
    """Residuals (m, 2 np), Jacobian (m, 2 np, 2 np), section solutions and end forces; ``guess``
    (HF, VF) of the sections (m n,) starts their catenary solves (e.g. the previous iterate's)."""
    m = y.shape[0]
    n = line.n_sections
    x, z = _nodes(y, XF, D, hA)
    rep = (lambda a: np.broadcast_to(a, (m, n)).ravel())
    F_lo, F_hi, J_lo, J_hi, sol = _section(x[:, :-1].ravel(), z[:, :-1].ravel(), x[:, 1:].ravel(), z[:, 1:].ravel(),
                                           rep(line.L), rep(line.EA), rep(line.w), rep(line.CB), guess=guess,
                                           tab_id=line._table_ids(m), tables=line.tables,
                                           top=rep(_surface(D, line)[:, None]))
    F_lo = F_lo.reshape(m, n, 2)
    F_hi = F_hi.reshape(m, n, 2)
    J_lo = J_lo.reshape(m, n, 2, 4)
    J_hi = J_hi.reshape(m, n, 2, 4)
    npt = n - 1
    R = F_hi[:, :-1] + F_lo[:, 1:]  # (m, np, 2): point j+1 is section j's upper and section j+1's lower end
    R[..., 1] -= line.W[None, :]
    J = np.zeros((m, 2 * npt, 2 * npt))
    for j in range(npt):  # point j (0-based) is node j + 1
        r = slice(2 * j, 2 * j + 2)
        # section j (below): lo = node j, hi = node j+1
        J[:, r, 2 * j:2 * j + 2] += J_hi[:, j, :, 2:4]
        if j > 0:
            J[:, r, 2 * (j - 1):2 * j] += J_hi[:, j, :, 0:2]
        # section j + 1 (above): lo = node j+1, hi = node j+2
        J[:, r, 2 * j:2 * j + 2] += J_lo[:, j + 1, :, 0:2]
        if j + 1 < npt:
            J[:, r, 2 * (j + 1):2 * (j + 2)] += J_lo[:, j + 1, :, 2:4]
    return R.reshape(m, 2 * npt), J, sol, F_lo, F_hi, J_lo, J_hi


def _surface(D, line: CompositeLine) -> np.ndarray:
    """Height of the sea surface above the seabed [m] per configuration: the line's
    :attr:`~CompositeLine.surface`, or the fairlead's height ``D`` where it has none."""
    D = np.asarray(D, dtype=float)
    return D if line.surface is None else np.full(D.shape, float(line.surface))


def _check_surface(y, XF, D, hA, line: CompositeLine, sol) -> None:
    """Raise :class:`CatenaryError` where a buoyant section of a solved configuration reaches the
    sea surface: its flipped catenary lies along the surface (the surface would carry it) or one
    of its ends is above it. The message names the line, the section, the configuration and the
    height."""
    b = line.buoyant
    if not np.any(b):
        return
    m, n = y.shape[0], line.n_sections
    _, z = _nodes(y, XF, D, hA)
    top = _surface(D, line)
    reg = sol.regime.reshape(m, n)
    along = sol.LBot.reshape(m, n)
    zmax = np.maximum(z[:, :-1], z[:, 1:])
    slack = 1e-9 * np.maximum(top, 1.0)
    over = b[None, :] & ((zmax > top[:, None] + slack[:, None]) | (along > 0.0)
                         | np.isin(reg, (TOUCHDOWN, SLACK, SEABED)))
    if not np.any(over):
        return
    i, k = (int(a[0]) for a in np.nonzero(over))
    where = (f"the sea surface {top[i]:g} m above the seabed" if line.surface is not None else
             f"the sea surface, taken at the fairlead's height {top[i]:g} m above the seabed (the line is not given "
             "the water depth, CompositeLine.surface, and a fairlead is at most at the waterline)")
    if zmax[i, k] > top[i] + slack[i]:
        what = f"its upper end would be {zmax[i, k]:g} m above the seabed, above {where}"
    else:
        what = (f"it rises to {where}, where {max(float(along[i, k]), 0.0):.4g} m of it would float; its ends are "
                f"{z[i, k]:g} m and {z[i, k + 1]:g} m above the seabed")
    raise CatenaryError(
        f"composite line (sections L = {line.L.tolist()} m, w = {line.w.tolist()} N/m, point weights W = "
        f"{line.W.tolist()} N) at XF = {XF[i]:g} m, ZF = {D[i] - hA[i]:g} m, h_A = {hA[i]:g} m: buoyant section {k} "
        f"({line.L[k]:g} m, w = {line.w[k]:g} N/m) reaches the sea surface: {what}. A buoyant section must stay "
        "submerged (the model has no floating line); a shorter or less buoyant section, or a longer line below it, "
        "keeps it down")


def _guess(XF, D, hA, line: CompositeLine):
    """Start: the points where the equivalent homogeneous line (same length, series stiffness,
    mean weight with the points') puts them, clamped to the seabed; the chord if that fails."""
    Ltot = line.length
    EAe = Ltot / float(np.sum(line.L / line.EA))
    we = max((float(np.sum(line.w * line.L)) + float(np.sum(line.W))) / Ltot, 1e-3 * float(np.max(line.w)) + 1e-9)
    s_pts = np.cumsum(line.L)[:-1]  # arc length of each point from the anchor
    frac = s_pts / Ltot
    x0 = XF[:, None] * frac[None, :]
    z0 = hA[:, None] + (D - hA)[:, None] * frac[None, :]
    try:
        sol = catenary.solve(XF, D - hA, Ltot, EAe, we, h_A=hA)
    except CatenaryError:
        sol = None
    if sol is not None:
        HF, VF, LB = sol.HF, sol.VF, sol.LBot
        grounded = (sol.regime == TOUCHDOWN) & (hA <= 0)
        susp = sol.regime == SUSPENDED
        # grounded stretch from the anchor, then the hanging part from its end
        sig = np.maximum(s_pts[None, :] - np.where(grounded, LB, 0.0)[:, None], 0.0)
        V0 = np.where(grounded, 0.0, np.where(susp, VF - we * Ltot, 0.0))
        with np.errstate(all="ignore"):
            dxh, dzh, _ = catenary._hanging_piece(HF[:, None], V0[:, None], sig, we, EAe)
        xg = np.where(grounded[:, None], np.minimum(s_pts[None, :], LB[:, None]) + dxh, dxh)
        zg = hA[:, None] + dzh
        use = (grounded | susp) & (HF > 0)
        ok = use[:, None] & np.isfinite(xg) & np.isfinite(zg)
        x0 = np.where(ok, xg, x0)
        z0 = np.where(ok, zg, z0)
    z0 = np.maximum(z0, 0.0)
    y = np.empty((XF.size, 2 * s_pts.size))
    y[:, 0::2] = x0
    y[:, 1::2] = z0
    return y


def _seabed_contact(y, R, J, rest: float):
    """Residuals and Jacobian with the points that rest on the seabed held there: a point at
    ``z <= 0`` with a net downward load (or an upward one up to ``rest`` [N]) keeps ``z = 0``, its
    vertical equation replaced by ``dz = 0`` and its z left out of the other equations. Returns
    the masked residuals, the masked Jacobian and the (m, n_points) contact mask."""
    zc = np.arange(1, y.shape[1], 2)
    on = (y[:, zc] <= 0.0) & (R[:, zc] <= rest)
    Rm = R.copy()
    Jm = J.copy()
    if np.any(on):
        Rm[:, zc] = np.where(on, 0.0, R[:, zc])
        rows = np.zeros(y.shape, bool)
        rows[:, zc] = on
        Jm[rows] = 0.0
        Jm.transpose(0, 2, 1)[rows] = 0.0  # no other equation moves it either
        ii = np.nonzero(rows)
        Jm[ii[0], ii[1], ii[1]] = 1.0
    return Rm, Jm, on


def _newton(XF, D, hA, line: CompositeLine, *, rtol: float, max_iter: int, y0=None):
    """Damped Newton with the seabed as a one-sided contact for the points."""
    y = _guess(XF, D, hA, line) if y0 is None else y0.copy()
    scale = line.force_scale()
    tol = rtol * scale
    m, nv = y.shape
    zc = np.arange(1, nv, 2)
    rest = _REST_FORCE * scale

    def contact_masked(y, R, J):
        Rm, Jm, _ = _seabed_contact(y, R, J, rest)
        return Rm, Jm

    n = line.n_sections
    R, J, sol, *_ = _evaluate(y, XF, D, hA, line)
    gH, gV = sol.HF.reshape(m, n).copy(), sol.VF.reshape(m, n).copy()  # warm starts of the sections
    Rm, Jm = contact_masked(y, R, J)
    err = np.max(np.abs(Rm), axis=1)
    it = 0
    for it in range(1, max_iter + 1):
        active = err > tol
        if not np.any(active):
            it -= 1
            break
        a = np.flatnonzero(active)
        Ja, Ra = Jm[a], Rm[a]
        # Levenberg-style safeguard: a tiny diagonal shift for singular (slack) Jacobians
        diag = np.abs(np.diagonal(Ja, axis1=1, axis2=2))
        shift = 1e-12 * (np.max(diag, axis=1, keepdims=True) + 1e-300)
        Jr = Ja + shift[..., None] * np.eye(nv)[None]
        try:
            dy = -np.linalg.solve(Jr, Ra[..., None])[..., 0]
        except np.linalg.LinAlgError:
            dy = np.zeros_like(Ra)
            for k in range(a.size):
                dy[k] = -np.linalg.lstsq(Jr[k], Ra[k], rcond=None)[0]
        dy = np.where(np.isfinite(dy), dy, 0.0)
        # limit a step to a fraction of the line's length
        big = np.max(np.abs(dy), axis=1, keepdims=True)
        dy *= np.minimum(1.0, 0.25 * line.length / np.maximum(big, 1e-300))
        step = np.ones((a.size, 1))
        ya = y[a]
        for _ in range(12):
            yn = ya + step * dy
            yn[:, zc] = np.where((yn[:, zc] <= 0.0) | ((yn[:, zc] <= _REST_HEIGHT) & (dy[:, zc] < 0.0)), 0.0,
                                 yn[:, zc])
            Rn, Jn, sn, *_ = _evaluate(yn, XF[a], D[a], hA[a], line, guess=(gH[a].ravel(), gV[a].ravel()))
            Rnm, Jnm = contact_masked(yn, Rn, Jn)
            en = np.max(np.abs(Rnm), axis=1)
            ok = (en < err[a] * (1.0 - 1e-4 * step[:, 0]) + 1e-300) | (en <= tol)  # decrease, or converged
            if np.all(ok):
                break
            step = np.where(ok[:, None], step, 0.5 * step)
        take = ok | (step[:, 0] <= 2.0 ** -11)  # a tiny step is taken anyway (leaves a stall)
        idx = a[take]
        y[idx] = yn[take]
        gH[idx] = sn.HF.reshape(-1, n)[take]
        gV[idx] = sn.VF.reshape(-1, n)[take]
        Rm[idx], Jm[idx], err[idx] = Rnm[take], Jnm[take], en[take]
    return y, err, tol, it


def _continuation_start(XF, ZF, hA, line: CompositeLine, *, rtol: float, max_iter: int, every: int = 16):
    """Start for many configurations that differ only in XF (a table, a sweep): solve every
    ``every``-th distance (sorted) and interpolate the points' positions between them; None when
    there are few configurations or they differ in ZF or h_A."""
    m = XF.size
    if m < 2 * every or np.ptp(ZF) > 0 or np.ptp(hA) > 0:
        return None
    order = np.argsort(XF)
    sub = order[np.unique(np.r_[np.arange(0, m, every), m - 1])]
    try:
        ys, err, tol, _ = _newton(XF[sub], hA[sub] + ZF[sub], hA[sub], line, rtol=rtol, max_iter=max_iter)
    except (np.linalg.LinAlgError, FloatingPointError):  # pragma: no cover - the full solve decides
        return None
    if not np.all(err <= tol):
        return None
    xs = XF[sub]
    y0 = np.empty((m, ys.shape[1]))
    for c in range(ys.shape[1]):
        y0[:, c] = np.interp(XF, xs, ys[:, c])
    return y0


_WARM_REACH = 0.01
"""A warm start is used for distances within this fraction of the line's length of the last ones."""
_WARM_ITERATIONS = 8
"""Newton iterations allowed from a warm start before the configuration is solved from the usual one."""


class WarmStart:
    """The points of a line's last solution, kept to start the next solve of the same line
    (:func:`solve`'s ``warm``): each new distance starts from the nearest kept configuration's
    points moved by their exact sensitivity to the distance (a first-order predictor), for the same
    fairlead and anchor height only. A solve from such a start converges to the same tolerance as
    one from the equivalent line's shape, so the two differ by at most that tolerance; it is
    cheaper where calls move the fairlead a little (an equilibrium search, a stiffness by
    differences, a gain table's rows)."""

    __slots__ = ("XF", "ZF", "dy", "h_A", "y")

    def __init__(self) -> None:
        self.ZF = self.h_A = None
        self.XF = self.y = self.dy = None

    def start(self, XF: np.ndarray, ZF: np.ndarray, hA: np.ndarray, reach: float) -> np.ndarray | None:
        """The start at distances ``XF`` [m]; None when some distance is farther than ``reach``
        [m] from every kept one, or there is no last solution at these heights."""
        if self.y is None or np.ptp(ZF) > 0 or np.ptp(hA) > 0 or ZF[0] != self.ZF or hA[0] != self.h_A:
            return None
        j = np.clip(np.searchsorted(self.XF, XF), 1, self.XF.size - 1) if self.XF.size > 1 else np.zeros(XF.size, int)
        if self.XF.size > 1:
            j = np.where(np.abs(XF - self.XF[j - 1]) < np.abs(XF - self.XF[j]), j - 1, j)
        d = XF - self.XF[j]
        if np.max(np.abs(d)) > reach:
            return None
        return self.y[j] + self.dy[j] * d[:, None]

    def keep(self, XF: np.ndarray, ZF: np.ndarray, hA: np.ndarray, y: np.ndarray, dy: np.ndarray) -> None:
        """Keep a converged solution: points ``y`` and their derivative ``dy`` with respect to the
        distance (configurations at one fairlead and anchor height only)."""
        if XF.size == 0 or np.ptp(ZF) > 0 or np.ptp(hA) > 0 or not np.all(np.isfinite(dy)):
            return
        xs, keep = np.unique(XF, return_index=True)
        self.XF, self.y, self.dy = xs, y[keep].copy(), dy[keep].copy()
        self.ZF, self.h_A = float(ZF[0]), float(hA[0])


def _check_line(line: CompositeLine, D) -> None:
    """Refuse, naming the numbers, a line the solve cannot take: a buoyant line whose weight in
    water (sections and points) is not positive (it floats: nothing hangs from the fairlead), or a
    fairlead above the given sea surface."""
    if not np.any(line.buoyant):
        return
    total = float(np.sum(line.w * line.L) + np.sum(line.W))
    if not total > 0.0:
        raise CatenaryError(
            f"composite line (sections L = {line.L.tolist()} m, w = {line.w.tolist()} N/m, point weights W = "
            f"{line.W.tolist()} N) weighs {total:g} N in water with its buoyant sections: a line must weigh (its "
            "sections' and points' weights summed positive) to hang from its fairlead; a line that floats as a "
            "whole is not a mooring line")
    if line.surface is not None and np.any(np.asarray(D) > line.surface * (1.0 + 1e-12)):
        raise CatenaryError(f"the fairlead, {float(np.max(D)):g} m above the seabed, is above the sea surface "
                            f"(CompositeLine.surface = {line.surface:g} m)")


def solve(XF, ZF, line: CompositeLine, *, h_A=0.0, rtol: float = 1e-10, max_iter: int = 80,
          continuation: bool = True, warm: WarmStart | None = None) -> CatenarySolution:
    """Quasi-static solution of a composite line for arrays of fairlead positions.

    Parameters
    ----------
    XF, ZF : array_like
        Horizontal distance anchor -> fairlead [m] (>= 0) and height of the fairlead above the
        anchor [m] (> 0), broadcast together.
    line : CompositeLine
    h_A : array_like
        Height of the anchor above the seabed [m], >= 0.
    rtol : float
        Point equilibrium tolerance relative to the line's weight in water.
    continuation : bool
        For many configurations that differ only in XF: start from every 16th solved and the
        points interpolated between them (the same answer to the tolerance; about 3 times fewer
        section solves on a table of 257 distances).
    warm : WarmStart, optional
        The line's last solution: the start when it has one at these heights (configurations that
        do not converge from it are solved again from the usual start); updated with this one.

    Returns
    -------
    CatenarySolution
        Fairlead tensions (HF, VF) and their exact sensitivities to (XF, ZF), anchor tensions
        (HA, VA), ``LBot`` the length on the seabed summed over the sections, ``regime`` a code of
        the section regimes, ``iterations`` the Newton iterations of the point equilibrium.

    Raises
    ------
    CatenaryError
        On invalid input or a configuration whose points do not reach equilibrium (the message
        names it and the residual).
    """
    XF, ZF, hA = (np.asarray(a, dtype=float) for a in (XF, ZF, h_A))
    shape = np.broadcast_shapes(XF.shape, ZF.shape, hA.shape)
    if line.n_sections == 1:
        _check_line(line, np.ravel(hA + ZF))
        return catenary.solve(XF, ZF, line.L[0], line.EA[0], line.w[0], CB=line.CB[0], h_A=hA, table=line.table(0))
    XF, ZF, hA = (np.broadcast_to(a, shape).ravel().copy() for a in (XF, ZF, hA))
    for name, a, lo in (("XF", XF, 0.0), ("ZF", ZF, 0.0), ("h_A", hA, 0.0)):
        bad = ~np.isfinite(a) | (a < lo)
        if np.any(bad):
            i = int(np.argmax(bad))
            raise CatenaryError(f"{name} = {a[i]!r} at index {i} must be finite and >= {lo:g} (composite line)")
    D = hA + ZF
    _check_line(line, D)
    y0 = warm.start(XF, ZF, hA, _WARM_REACH * line.length) if warm is not None else None
    started = y0 is not None
    if y0 is None and continuation:
        y0 = _continuation_start(XF, ZF, hA, line, rtol=rtol, max_iter=max_iter)
    y, err, tol, it = _newton(XF, D, hA, line, rtol=rtol, max_iter=_WARM_ITERATIONS if started else max_iter, y0=y0)
    if started and not np.all(err <= tol):   # the last solution was not a good start: the usual one
        again = np.flatnonzero(~(err <= tol))
        ya, ea, _, ita = _newton(XF[again], D[again], hA[again], line, rtol=rtol, max_iter=max_iter)
        y[again], err[again], it = ya, ea, max(it, ita)
    bad = ~(err <= max(tol, 1e-7 * line.force_scale()))
    if np.any(bad):
        i = int(np.argmax(bad))
        raise CatenaryError(
            f"composite line (sections L = {line.L.tolist()} m, point weights W = {line.W.tolist()} N) did not reach "
            f"equilibrium at XF = {XF[i]:g} m, ZF = {ZF[i]:g} m, h_A = {hA[i]:g} m (index {i}): residual force "
            f"{err[i]:.3g} N")
    R, J, sol, F_lo, F_hi, J_lo, J_hi = _evaluate(y, XF, D, hA, line)
    _check_surface(y, XF, D, hA, line, sol)
    m = XF.size
    n = line.n_sections
    # fairlead: section n-1's force on its upper end; anchor: section 0's on its lower end
    Ff = F_hi[:, -1]
    Fa = F_lo[:, 0]
    HF, VF = -Ff[:, 0], -Ff[:, 1]
    HA, VA = Fa[:, 0], Fa[:, 1]
    # sensitivities: dFf/d(XF, D) = dFf/dq - dFf/dy J^-1 dR/dq, q = (XF, D) (only the last point's
    # residual and the fairlead force depend on q and the last point)
    _, Jm, on = _seabed_contact(y, R, J, _REST_FORCE * line.force_scale())
    rows = np.zeros(J.shape[:2], bool)
    rows[:, 1::2] = on
    Jf_q = J_hi[:, -1, :, 2:4]  # fairlead force w.r.t. the fairlead node (x, z)
    Jf_y = np.zeros((m, 2, J.shape[1]))
    Jf_y[:, :, -2:] = J_hi[:, -1, :, 0:2]  # ... w.r.t. the last point
    dR_q = np.zeros((m, J.shape[1], 2))
    dR_q[:, -2:, :] = J_lo[:, -1, :, 2:4]  # the last point's residual: section n-1's force on its lower end
    dR_q[rows] = 0.0
    with np.errstate(all="ignore"):
        try:
            sens = np.linalg.solve(Jm, dR_q)  # (m, nv, 2)
        except np.linalg.LinAlgError:  # a slack joint (no stiffness along the line): least squares
            sens = np.stack([np.linalg.lstsq(Jm[k], dR_q[k], rcond=None)[0] for k in range(m)])
    if warm is not None:
        warm.keep(XF, ZF, hA, y, -sens[:, :, 0])   # dy/dXF = -J^-1 dR/dXF
    dFf = Jf_q - np.einsum("mij,mjk->mik", Jf_y, sens)  # (m, 2, 2): d(Fx, Fz)/d(XF, D)
    dHX, dHZ = -dFf[:, 0, 0], -dFf[:, 0, 1]
    dVX, dVZ = -dFf[:, 1, 0], -dFf[:, 1, 1]
    reg_s = sol.regime.reshape(m, n).astype(np.int64)
    code = np.zeros(m, dtype=np.int64)
    for k in range(n):
        code = code * 6 + reg_s[:, k]
    code = code * 2 ** (n - 1) + (on.astype(np.int64) * (2 ** np.arange(n - 1))).sum(axis=1)
    LBot = np.where(line.buoyant[None, :], 0.0, sol.LBot.reshape(m, n)).sum(axis=1)  # a buoyant one's is the surface's
    res = {"HF": HF, "VF": VF, "HA": HA, "VA": VA, "TF": np.hypot(HF, VF), "TA": np.hypot(HA, VA), "LBot": LBot,
           "dHF_dXF": dHX, "dHF_dZF": dHZ, "dVF_dXF": dVX, "dVF_dZF": dVZ}
    for k, v in res.items():
        if not np.all(np.isfinite(v)):
            i = int(np.argmax(~np.isfinite(v)))
            raise CatenaryError(f"non-finite {k} of the composite line at XF = {XF[i]:g} m, ZF = {ZF[i]:g} m")
    shaped = {k: v.reshape(shape) for k, v in res.items()}
    return CatenarySolution(regime=code.reshape(shape), iterations=int(it), **shaped)


def points(XF, ZF, line: CompositeLine, *, h_A=0.0, rtol: float = 1e-10, max_iter: int = 80):
    """Equilibrium positions of the points: ``(x, z)`` arrays of shape (..., n - 1) [m], x from the
    anchor toward the fairlead, z height above the seabed."""
    XF, ZF, hA = (np.asarray(a, dtype=float) for a in (XF, ZF, h_A))
    shape = np.broadcast_shapes(XF.shape, ZF.shape, hA.shape)
    if line.n_sections == 1:  # no point (a homogeneous line of a tension-strain table)
        _check_line(line, np.ravel(hA + ZF))
        return np.zeros(shape + (0,)), np.zeros(shape + (0,))
    XF, ZF, hA = (np.broadcast_to(a, shape).ravel().copy() for a in (XF, ZF, hA))
    D = hA + ZF
    _check_line(line, D)
    y, *_ = _newton(XF, D, hA, line, rtol=rtol, max_iter=max_iter)
    if np.any(line.buoyant):
        _check_surface(y, XF, D, hA, line, _evaluate(y, XF, D, hA, line)[2])
    return y[:, 0::2].reshape(shape + (-1,)), y[:, 1::2].reshape(shape + (-1,))


def profile(XF: float, ZF: float, line: CompositeLine, *, h_A: float = 0.0, n: int = 101):
    """Shape and tension along a composite line from the anchor (s = 0) to the fairlead: ``s``,
    ``x`` (from the anchor), ``z`` (height above the anchor; the seabed at ``-h_A``), ``T``, each
    of about ``n`` points (every section sampled in proportion to its length, both ends kept), and
    ``points`` (x, z) of the joints, as :func:`tapm_opt.models.catenary.line_profile`."""
    if line.n_sections == 1:
        _check_line(line, np.ravel(h_A + ZF))
        return catenary.line_profile(XF, ZF, line.L[0], line.EA[0], line.w[0], CB=line.CB[0], h_A=h_A, n=n,
                                     table=line.table(0))
    px, pz = points(XF, ZF, line, h_A=h_A)
    x = np.r_[0.0, px.ravel(), XF]
    z = np.r_[h_A, pz.ravel(), h_A + ZF]
    S, X, Zs, T = [], [], [], []
    s0 = 0.0
    for k in range(line.n_sections):
        up = z[k + 1] >= z[k]
        a, b = (k, k + 1) if up else (k + 1, k)
        sgn = 1.0 if x[b] >= x[a] else -1.0
        nk = max(int(np.rint(n * line.L[k] / line.length)), 2)
        pr = catenary.line_profile(abs(x[b] - x[a]), z[b] - z[a], line.L[k], line.EA[k], line.w[k],
                                   CB=line.CB[k], h_A=max(z[a], 0.0), n=nk, table=line.table(k))
        xs, zs, Ts, ss = x[a] + sgn * pr["x"], z[a] + pr["z"], pr["T"], pr["s"]
        if not up:
            xs, zs, Ts, ss = xs[::-1], zs[::-1], Ts[::-1], line.L[k] - ss[::-1]
        S.append(s0 + ss)
        X.append(xs)
        Zs.append(zs - h_A)
        T.append(Ts)
        s0 += line.L[k]
    sol = solve(XF, ZF, line, h_A=h_A)
    return {"s": np.concatenate(S), "x": np.concatenate(X), "z": np.concatenate(Zs), "T": np.concatenate(T),
            "points": (px.ravel(), pz.ravel() - h_A), "solution": sol}
