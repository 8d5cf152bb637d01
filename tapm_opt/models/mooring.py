"""Quasi-static mooring restoring model: elastic catenary lines on a turret (survey eq. 17–29).

Sign conventions
----------------
* ``tau_moor = (X, Y, N)`` is the load of the mooring on the vessel in {B} [N, N, N m].
* Line i pulls its fairlead toward its anchor with the horizontal fairlead tension ``H_i``:
  the force on the vessel in {E} is ``-H_i (cos beta_i, sin beta_i)`` with ``beta_i`` the
  direction from anchor to fairlead (eq. 17–18).
* The stiffness ``K = -d tau_moor / d eta`` (3 x 3) is positive for a restoring mooring.
* Turret ``locked``: the fairleads turn with the hull (alpha_t fixed) and every line's moment about
  the body origin reaches the hull (eq. 19–23). Turret ``free``: an ideal bearing; the turret keeps
  its heading psi_t = alpha_t(0) in {E} (alpha_t = psi_t - psi) and passes only the net line force
  through the centre of turret, so the hull feels the moment of that force about CO
  (weathervaning).
* The 3-DOF model keeps the fairlead depth fixed: ``ZF = z_A - fairlead depth``, the fairlead's
  height above the anchor, with the anchor depth ``z_A`` (z down) on the seabed (``z_A`` = water
  depth) or above it (an anchor on a slope, a clump weight, a buoy), at
  ``h_A = water depth - z_A`` above the seabed; the catenary of each line takes its ``h_A``.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Any, Iterable, Literal

import casadi as ca
import numpy as np

from .. import _backend as bk
from .._io import readonly
from ..errors import ModelError
from ..geometry import fairleads_E, rot2_apply, rot_z
from . import catenary, composite as _composite
from .statics import EquilibriumError, solve_equilibrium

__all__ = ["MooringModel", "LinearMooring", "tension_depth_sensitivity"]

_SOLUTION_ARRAYS = ("HF", "VF", "HA", "VA", "TF", "TA", "LBot", "regime", "dHF_dXF", "dHF_dZF", "dVF_dXF", "dVF_dZF")
"""The per-configuration arrays of a CatenarySolution."""


def tension_depth_sensitivity(sol: catenary.CatenarySolution) -> np.ndarray:
    """``dTF/dz`` [N/m]: the change of the fairlead tension magnitude per metre its fairlead sinks
    (z down, the horizontal span held: ``ZF`` shrinks), ``-(HF dHF/dZF + VF dVF/dZF) / TF`` from the
    line's exact vertical stiffness (0 where ``TF`` is 0). Negative for a hanging line: a deeper
    fairlead slackens it."""
    return -(sol.HF * sol.dHF_dZF + sol.VF * sol.dVF_dZF) / np.maximum(sol.TF, 1e-300)


def _own_solver(sec: dict) -> bool:
    """A line of :attr:`Scenario.line_sections <tapm_opt.config.Scenario.line_sections>` that
    :func:`tapm_opt.models.composite.solve` solves: sections and points, or a tension-strain table
    (nonlinear EA; a homogeneous one is the one-section composite line)."""
    return sec["L"].size > 1 or any(t is not None for t in sec.get("EA_table", ()))


@dataclass(frozen=True, eq=False)
class MooringModel:
    """Quasi-static catenary mooring of a turret-moored vessel.

    Build with :meth:`from_scenario`. Arrays are per line, shape (n,).

    Attributes
    ----------
    line_ids : tuple of str
        Ids of the lines in the model (broken lines excluded).
    anchors : ndarray, shape (n, 2)
        Anchor (x, y) in {E} [m].
    p_T : ndarray, shape (n, 2)
        Fairleads in the turret frame {T} [m] (eq. 2).
    p_cot_B : ndarray, shape (2,)
        Centre of turret in {B} [m].
    turret_angle : float
        alpha_t at the field zero point [rad] (locked: always; free: psi_t = this angle in {E}).
    turret_mode : {"locked", "free"}
    ZF, L, EA, w, CB, MBS : ndarray, shape (n,)
        Fairlead height above anchor [m], unstretched length [m], axial stiffness [N], submerged
        weight [N/m], seabed friction [-], minimum breaking strength [N].
    MBS_std : ndarray, shape (n,)
        Standard deviation of the breaking strength [N] (sigma_b of the reliability index, survey
        eq. 32; 0: the line has no index).
    h_A : ndarray, shape (n,)
        Height of each anchor (the line's lower end) above the seabed [m], >= 0 (0: on the seabed).
        Seabed friction is not applied to a line whose anchor is above the seabed (see
        :mod:`tapm_opt.models.catenary`).
    composite : tuple of CompositeLine or None
        Per line, its sections and points (:class:`~tapm_opt.models.composite.CompositeLine`) for
        a composite line, None for a homogeneous one; empty: every line homogeneous. A composite
        line's L, EA, w are its equivalents (total length, series stiffness, mean weight, see
        ``Scenario.line_arrays``), read only where a rough scale is wanted; every tension comes
        from :meth:`line_solver`. A homogeneous line of a tension-strain table (nonlinear EA) is
        here too, as the one-section composite line with its table (its EA the table's secant).
    lost_points : tuple of (str, int)
        Points lost from composite lines, (line id, joint index from the anchor up), in the order
        they were lost (:meth:`with_points_lost`): their net weight ``W`` is 0 in ``composite``.
    """

    line_ids: tuple[str, ...]
    anchors: np.ndarray
    p_T: np.ndarray
    p_cot_B: np.ndarray
    turret_angle: float
    turret_mode: Literal["locked", "free"]
    ZF: np.ndarray
    L: np.ndarray
    EA: np.ndarray
    w: np.ndarray
    CB: np.ndarray
    MBS: np.ndarray
    h_A: np.ndarray
    MBS_std: np.ndarray = field(default_factory=lambda: readonly(np.zeros(0)))
    composite: tuple = ()
    lost_points: tuple = ()
    _cache: dict = field(default_factory=dict, repr=False, compare=False)

    # -- construction ---------------------------------------------------------------------
    @classmethod
    def from_scenario(cls, scenario: Any, *, broken: Iterable[str | int] = (),
                      lost_points: Iterable[tuple[str, int]] = ()) -> "MooringModel":
        """Mooring model of a :class:`~tapm_opt.config.Scenario`.

        Parameters
        ----------
        scenario : Scenario
        broken : iterable of line ids
            Lines left out (broken). Unknown ids raise :class:`ModelError`.
        lost_points : iterable of (line id, joint)
            Points of composite lines gone (:meth:`with_points_lost`); those on broken lines are
            ignored.

        Raises
        ------
        ModelError
            Unknown broken ids, every line broken, or an anchor depth ``z`` (third anchor
            coordinate) that is not finite, lies below the seabed or not below the fairleads.
        """
        ids = [ln.id for ln in scenario.lines]
        broken = {str(b) for b in broken}
        unknown = sorted(broken - set(ids))
        if unknown:
            raise ModelError(f"broken line id(s) {unknown} not in the scenario; lines are {ids}")
        keep = np.array([i not in broken for i in ids])
        if not keep.any():
            raise ModelError("every line is broken: there is no mooring left to model")
        la = scenario.line_arrays
        env = scenario.environment
        h_A = np.asarray(la["h_A"], dtype=float)
        zf = env.water_depth - h_A - scenario.turret.fairlead_depth
        for i, ln in enumerate(scenario.lines):
            z = env.water_depth - h_A[i]
            where = f"lines[{i}] (id {ln.id!r}): anchor z = {z:g} m"
            if not np.isfinite(h_A[i]):
                raise ModelError(f"{where} must be finite")
            if h_A[i] < 0:
                raise ModelError(f"{where} puts the anchor below the seabed (water depth {env.water_depth:g} m, "
                                 f"z down); z must be <= the water depth")
            if not zf[i] > 0:
                raise ModelError(f"{where} is not below the fairleads (fairlead depth "
                                 f"{scenario.turret.fairlead_depth:g} m, z down); z must be deeper than the fairleads")
        lost_points = [(str(lid), j) for lid, j in lost_points]
        unknown = sorted({lid for lid, _ in lost_points} - set(ids))
        if unknown:
            raise ModelError(f"lost point(s) on line(s) {unknown}, which are not in the scenario; lines are {ids}")
        return cls(
            line_ids=tuple(i for i, k in zip(ids, keep) if k),
            anchors=readonly(scenario.anchors[keep, :2]),
            p_T=readonly(scenario.fairleads_T[keep]),
            p_cot_B=readonly(scenario.turret.position),
            turret_angle=float(scenario.turret.angle),
            turret_mode=scenario.turret.mode,
            ZF=readonly(zf[keep]),
            L=readonly(la["L"][keep]),
            EA=readonly(la["EA"][keep]),
            w=readonly(la["w"][keep]),
            CB=readonly(la["CB"][keep]),
            MBS=readonly(la["MBS"][keep]),
            h_A=readonly(h_A[keep]),
            MBS_std=readonly(np.asarray(la["MBS_std"], float)[keep]),
            composite=tuple(_composite.CompositeLine.from_arrays(sec) if _own_solver(sec) else None
                            for sec, k in zip(scenario.line_sections, keep) if k)
            if any(_own_solver(sec) for sec in scenario.line_sections) else (),
        ).with_points_lost([(lid, j) for lid, j in lost_points if lid not in broken])

    def without(self, broken: Iterable[str]) -> "MooringModel":
        """The model with the lines ``broken`` (ids) left out; ids not in the model (already left
        out) are ignored. Leaving no line raises :class:`ModelError`."""
        broken = {str(b) for b in broken}
        keep = np.array([i not in broken for i in self.line_ids])
        if keep.all():
            return self
        if not keep.any():
            raise ModelError("every line is broken: there is no mooring left to model")
        arrays = {name: readonly(np.asarray(getattr(self, name))[keep])
                  for name in ("anchors", "p_T", "ZF", "L", "EA", "w", "CB", "MBS", "h_A", "MBS_std")}
        comp = tuple(c for c, k in zip(self.composite, keep) if k) if self.composite else ()
        ids = tuple(i for i, k in zip(self.line_ids, keep) if k)
        return MooringModel(line_ids=ids, p_cot_B=self.p_cot_B,
                            turret_angle=self.turret_angle, turret_mode=self.turret_mode,
                            composite=comp if any(c is not None for c in comp) else (),
                            lost_points=tuple(p for p in self.lost_points if p[0] in ids), **arrays)

    # -- lost points (a buoy or clump come off a composite line) ---------------------------
    @property
    def points(self) -> tuple[tuple[str, int, float], ...]:
        """Every point still on the model's composite lines: (line id, joint index from the anchor
        up, net weight W [N], positive down), lines in order, joints from the anchor up."""
        out = []
        for lid, c in zip(self.line_ids, self.composite or (None,) * self.n_lines):
            if c is not None:
                out += [(lid, j, float(W)) for j, W in enumerate(c.W) if W != 0.0]
        return tuple(out)

    @property
    def buoys(self) -> tuple[tuple[str, int], ...]:
        """The buoys still on the model's lines, (line id, joint): the points of net weight W < 0."""
        return tuple((lid, j) for lid, j, W in self.points if W < 0.0)

    def with_point_lost(self, line_id: str, joint: int) -> "MooringModel":
        """The model with the point (a buoy or a clump) at joint ``joint`` (index from the anchor
        up, 0 joining sections 0 and 1) of composite line ``line_id`` gone: the quasi-static line is
        :func:`tapm_opt.models.composite.solve` with that point's ``W`` set to 0, the line's mean
        weight ``w`` drops the point's. Raises :class:`ModelError` naming the line or joint when the
        line is not in the model or homogeneous, the joint out of range or without a point."""
        return self.with_points_lost([(line_id, joint)])

    def with_points_lost(self, points: Iterable[tuple[str, int]]) -> "MooringModel":
        """:meth:`with_point_lost` for every (line id, joint) of ``points``; a point already lost
        (:attr:`lost_points`) is ignored, so is an empty ``points`` (the model itself)."""
        comp = list(self.composite) if self.composite else [None] * self.n_lines
        w = np.array(self.w, dtype=float)
        lost = list(self.lost_points)
        for item in points:
            try:
                lid, joint = item
            except (TypeError, ValueError):
                raise ModelError(f"lost point {item!r} must be a pair (line id, joint index)") from None
            lid = str(lid)
            if (lid, joint) in lost:
                continue
            if lid not in self.line_ids:
                raise ModelError(f"lost point on line {lid!r}: no such line in the model; lines are {list(self.line_ids)}")
            i = self.line_ids.index(lid)
            c = comp[i]
            if c is None or c.W.size == 0:
                raise ModelError(f"lost point on line {lid!r}: a homogeneous line has no joints, so no point to lose")
            if isinstance(joint, (bool, np.bool_)) or not isinstance(joint, (int, np.integer)) \
                    or not 0 <= joint < c.W.size:
                raise ModelError(f"lost point at joint {joint!r} of line {lid!r}: the joint must be a whole number from "
                                 f"0 to {c.W.size - 1} (the line's {c.n_sections} sections from the anchor up)")
            joint = int(joint)
            if c.W[joint] == 0.0:
                at = [j for j, W in enumerate(c.W) if W != 0.0]
                raise ModelError(f"lost point at joint {joint} of line {lid!r}: that joint carries no point (W = 0); "
                                 f"the line's points are at joints {at}")
            W = np.array(c.W, dtype=float)
            w[i] -= W[joint] / c.length
            W[joint] = 0.0
            comp[i] = dataclasses.replace(c, W=readonly(W))
            lost.append((lid, joint))
        if len(lost) == len(self.lost_points):
            return self
        return dataclasses.replace(self, composite=tuple(comp), w=readonly(w), lost_points=tuple(lost),
                                   _cache={})

    def damaged(self, broken: Iterable[str] = (), lost_points: Iterable[tuple[str, int]] = ()) -> "MooringModel":
        """The model with the points ``lost_points`` (line id, joint) gone (:meth:`with_points_lost`)
        and the lines ``broken`` left out (:meth:`without`): the line system after these faults.
        Points on lines that are broken or not in the model are ignored, as :meth:`without` ignores
        such lines."""
        broken = {str(b) for b in broken}
        lost = [(str(lid), j) for lid, j in lost_points if str(lid) not in broken and str(lid) in self.line_ids]
        return self.with_points_lost(lost).without(broken)

    # -- the lines' quasi-static solution (one definition for every caller) ---------------
    @property
    def has_composite(self) -> bool:
        """True when any line is composite (sections and points)."""
        return any(c is not None for c in self.composite)

    def line_solver(self, i: int, ZF: float | None = None, *, L: float | None = None):
        """Quasi-static solution of line ``i`` at horizontal anchor-fairlead distances ``XF`` (any
        shape) [m]: a function ``XF -> CatenarySolution`` (:func:`tapm_opt.models.catenary.solve`
        for a homogeneous line, :func:`tapm_opt.models.composite.solve` for a composite one), at the
        line's fairlead height ``ZF`` unless another is given, and with the unstretched length ``L``
        [m] (a winch's) if given: a composite line's change of length is its fairlead section's
        (:meth:`CompositeLine.with_length <tapm_opt.models.composite.CompositeLine.with_length>`)."""
        zf = float(self.ZF[i]) if ZF is None else ZF
        hA = float(self.h_A[i])
        c = self.composite[i] if self.composite else None
        if c is None:
            EA, w, CB = (float(a[i]) for a in (self.EA, self.w, self.CB))
            Li = float(self.L[i]) if L is None else float(L)
            return lambda XF: catenary.solve(XF, zf, Li, EA, w, CB=CB, h_A=hA)
        if L is not None:
            c = c.with_length(L)
        warm = None
        starts = self._cache.get("warm_starts")   # inside equilibrium(): each line starts from its last solve
        if starts is not None:
            warm = starts.setdefault((self.line_key(i), None if L is None else float(L), zf), _composite.WarmStart())
        return lambda XF: _composite.solve(XF, zf, c, h_A=hA, warm=warm)

    def line_key(self, i: int) -> tuple:
        """Hashable description of line ``i``'s quasi-static physics (lines with equal keys share
        tables): (ZF, L, EA, w, CB, h_A) and, for a composite line, its sections and points."""
        base = tuple(float(a[i]) for a in (self.ZF, self.L, self.EA, self.w, self.CB, self.h_A))
        c = self.composite[i] if self.composite else None
        return base if c is None else base + (c.key(),)

    def solve_xf(self, XF, *, L=None) -> catenary.CatenarySolution:
        """Quasi-static solution of every line at horizontal distances ``XF`` [m] of shape
        (..., n) (lines on the last axis); ``L`` (n,) [m] replaces the lines' unstretched lengths
        (a winch's; a composite line's change is its fairlead section's, :meth:`line_solver`)."""
        XF = np.asarray(XF, dtype=float)
        Ls = self.L if L is None else np.asarray(L, dtype=float)
        if not self.has_composite:
            return catenary.solve(XF, self.ZF, Ls, self.EA, self.w, CB=self.CB, h_A=self.h_A)
        XF = np.broadcast_to(XF, XF.shape[:-1] + (self.n_lines,)) if XF.ndim else np.full(self.n_lines, XF)
        idx = np.broadcast_to(np.arange(self.n_lines), XF.shape)
        homo = np.array([c is None for c in self.composite])
        if L is None:
            return self.solve_at(XF, idx)
        # winch lengths: the homogeneous lines' catenary directly, each composite line at its length
        # (lines of equal physics and length in one call)
        if homo.any():
            sol = catenary.solve(XF, self.ZF, Ls, self.EA, self.w, CB=self.CB, h_A=self.h_A)
            out = {k: np.array(getattr(sol, k)) for k in _SOLUTION_ARRAYS}
            it = sol.iterations
        else:
            out = {k: np.zeros(XF.shape, dtype=np.int64 if k == "regime" else float) for k in _SOLUTION_ARRAYS}
            it = 0
        groups: dict = {}
        for i in np.flatnonzero(~homo):
            groups.setdefault((self.line_key(int(i)), float(Ls[i])), []).append(int(i))
        for (_, Li), members in groups.items():
            si = self.line_solver(members[0], L=Li)(XF[..., members])
            it = max(it, si.iterations)
            for k in _SOLUTION_ARRAYS:
                out[k][..., members] = getattr(si, k)
        return catenary.CatenarySolution(iterations=it, **out)

    def solve_at(self, XF, line) -> catenary.CatenarySolution:
        """Quasi-static solution at horizontal distances ``XF`` [m] of the lines ``line`` (indices,
        the same shape as ``XF``): each element solved with its line's physics, lines with equal
        :meth:`line_key` in one vectorised call."""
        XF = np.asarray(XF, dtype=float)
        line = np.broadcast_to(np.asarray(line, dtype=np.int64), XF.shape)
        Xf, lf = XF.ravel(), line.ravel()
        groups: dict = {}
        for i in range(self.n_lines):
            groups.setdefault(self.line_key(i), []).append(i)
        out = {k: np.zeros(Xf.size, dtype=np.int64 if k == "regime" else float) for k in _SOLUTION_ARRAYS}
        it = 0
        for members in groups.values():
            m = np.isin(lf, members)
            if not m.any():
                continue
            sol = self.line_solver(members[0])(Xf[m])
            it = max(it, sol.iterations)
            for k in _SOLUTION_ARRAYS:
                out[k][m] = getattr(sol, k)
        return catenary.CatenarySolution(iterations=it, **{k: v.reshape(XF.shape) for k, v in out.items()})

    @property
    def n_lines(self) -> int:
        return len(self.line_ids)

    # -- geometry (one definition, numpy or CasADi) ---------------------------------------
    def _alpha_t(self, psi):
        return self.turret_angle if self.turret_mode == "locked" else self.turret_angle - psi

    def fairleads(self, eta):
        """Fairlead positions (x, y) in {E} [m] for vessel pose ``eta`` (eq. 5)."""
        return fairleads_E(eta, self.p_cot_B, self.p_T, self._alpha_t(eta[2]))

    def spans(self, eta):
        """Horizontal anchor->fairlead vectors (dx, dy) and distances XF [m], each shape (n,)."""
        fx, fy = self.fairleads(eta)
        dx = fx - self.anchors[:, 0]
        dy = fy - self.anchors[:, 1]
        return dx, dy, bk.hypot(dx, dy)

    def tau_from_H(self, eta, H):
        """Mooring load in {B} from the horizontal fairlead tensions ``H`` (n,) [N] (eq. 18–23).

        Each line pulls its fairlead horizontally toward its anchor with ``H_i``.
        """
        fx, fy = self.fairleads(eta)
        dx = fx - self.anchors[:, 0]
        dy = fy - self.anchors[:, 1]
        XF = bk.hypot(dx, dy)
        XFs = bk.where(XF > 0, XF, 1.0)
        return self.tau_from_forces(eta, -H * dx / XFs, -H * dy / XFs, fairleads=(fx, fy))

    def tau_from_forces(self, eta, f_x, f_y, *, fairleads=None):
        """Load in {B} on the vessel from horizontal line forces at the fairleads (eq. 21–23).

        Parameters
        ----------
        eta : array_like (3,) or CasADi
            Vessel pose [m, m, rad].
        f_x, f_y : array_like (n,) or CasADi
            Force of each line on its fairlead in {E} [N] (north, east).
        fairleads : tuple, optional
            Fairlead positions (x, y) in {E} if already computed.

        Returns
        -------
        tau : (3,) in {B} [N, N, N m]. With a locked turret every line's moment about the body
        origin counts; with a free turret only the net force acting at the centre of turret.
        """
        fx, fy = self.fairleads(eta) if fairleads is None else fairleads
        Fx, Fy = bk.sum_(f_x), bk.sum_(f_y)
        x, y, psi = eta[0], eta[1], eta[2]
        if self.turret_mode == "locked":
            Nz = bk.sum_((fx - x) * f_y - (fy - y) * f_x)
        else:
            cx, cy = rot2_apply(psi, self.p_cot_B[0], self.p_cot_B[1])   # R2(psi) p_cot^B (eq. 5)
            Nz = cx * Fy - cy * Fx
        if bk.is_symbolic(eta, f_x, f_y):
            return ca.mtimes(rot_z(psi).T, ca.vertcat(Fx, Fy, Nz))
        return rot_z(psi).T @ np.array([Fx, Fy, Nz])

    # -- numeric ---------------------------------------------------------------------------
    def solve_lines(self, eta) -> catenary.CatenarySolution:
        """Catenary solution of every line at pose ``eta`` (x [m], y [m], psi [rad])."""
        eta = self._check_eta(eta)
        _, _, XF = self.spans(eta)
        return self.solve_xf(XF)

    def force(self, eta) -> np.ndarray:
        """Restoring load tau_moor in {B}, shape (3,) [N, N, N m] (eq. 23, 28)."""
        eta = self._check_eta(eta)
        return self.tau_from_H(eta, self.solve_lines(eta).HF)

    def load_evaluator(self, *, max_offset: float | None = None, rtol: float = 1e-9,
                       kernel: Literal["auto", "numba", "numpy"] = "auto"):
        """Fast evaluator of :meth:`force`: ``load_evaluator()(eta) -> tau_moor`` (3,) in {B}
        [N, N, N m], a few microseconds per call instead of a catenary solve per line.

        The same catenary physics, tabulated: each distinct line configuration's horizontal
        tension against its anchor–fairlead distance as a cubic Hermite table checked against
        :func:`~tapm_opt.models.catenary.solve` to ``rtol`` (each line's ``HF`` within
        ``rtol * max(HF, H_0)``), the geometry exact; poses beyond the tables (body origin more
        than ``max_offset`` [m] from the field zero point, default 30 % of the water depth below
        the fairleads) go to :meth:`force`. See
        :class:`~tapm_opt.models.characteristics.TabulatedMooringLoad`.

        Built on first request and kept with the model for the same arguments: ~50 ms of catenary
        solves for the tables; the first evaluator of a process also imports numba and loads its
        compiled kernel from the disk cache (~1.3 s; ~1 s more to compile when the cache is empty).
        """
        from .characteristics import TabulatedMooringLoad

        key = ("load_evaluator", max_offset, rtol, kernel)
        try:
            ev = self._cache.get(key)
        except TypeError:  # an unhashable argument: the evaluator rejects it by name
            return TabulatedMooringLoad(self, max_offset=max_offset, rtol=rtol, kernel=kernel)
        if ev is None or ev.model is not self:  # (a dataclasses.replace copy shares the dict)
            ev = TabulatedMooringLoad(self, max_offset=max_offset, rtol=rtol, kernel=kernel)
            self._cache[key] = ev
        return ev

    def force_fast(self, eta) -> np.ndarray:
        """:meth:`force` from the tabulated characteristics of :meth:`load_evaluator` (default
        settings): tau_moor in {B}, shape (3,) [N, N, N m], each line's horizontal tension within
        1e-9 of the catenary's (relative to its tension or pretension); exact :meth:`force` beyond
        the tables. Bad ``eta`` raises :class:`ModelError` as :meth:`force` does."""
        ev = self._cache.get("force_fast")
        if ev is None or ev.model is not self:
            ev = self._cache["force_fast"] = self.load_evaluator()
        return ev(eta)

    def tensions(self, eta) -> np.ndarray:
        """Fairlead tension magnitude TF of every line [N], shape (n,)."""
        return self.solve_lines(eta).TF

    def depth_sensitivity(self, eta) -> np.ndarray:
        """``dTF/dz`` of every line [N/m], shape (n,), at pose ``eta``: the change of its fairlead
        tension per metre its fairlead sinks with its horizontal position held
        (:func:`tension_depth_sensitivity`; the hull's heave, roll and pitch move the fairleads
        vertically, the 3-DOF model holds them at their depth)."""
        return tension_depth_sensitivity(self.solve_lines(self._check_eta(eta)))

    def stiffness(self, eta) -> np.ndarray:
        """Exact stiffness K = -d tau_moor / d eta, shape (3, 3), at pose ``eta``.

        Chain rule of CasADi derivatives of the geometry and the catenary's analytic sensitivity
        dH/dXF (implicit function theorem); no finite differences.
        """
        eta = self._check_eta(eta)
        sol = self.solve_lines(eta)
        f = self._geometry_jacobians()
        J_eta, J_H, J_XF = (np.asarray(m) for m in f(eta, sol.HF))
        return -(J_eta + J_H @ (sol.dHF_dXF[:, None] * J_XF))

    def _geometry_jacobians(self) -> ca.Function:
        if "geo" not in self._cache:
            eta = ca.SX.sym("eta", 3)
            H = ca.SX.sym("H", self.n_lines)
            tau = self.tau_from_H(eta, H)
            _, _, XF = self.spans(eta)
            self._cache["geo"] = ca.Function(
                "mooring_geometry_jac", [eta, H],
                [ca.jacobian(tau, eta), ca.jacobian(tau, H), ca.jacobian(XF, eta)])
        return self._cache["geo"]

    def _check_eta(self, eta) -> np.ndarray:
        eta = np.asarray(eta, dtype=float)
        if eta.shape != (3,):
            raise ModelError(f"eta must have shape (3,) = (x [m], y [m], psi [rad]), got shape {eta.shape}")
        if not np.all(np.isfinite(eta)):
            raise ModelError(f"eta = {eta.tolist()} must be finite")
        return eta

    # -- symbolic --------------------------------------------------------------------------
    def force_function(self, kind: Literal["catenary", "linear", "characteristic"] = "catenary",
                       *, eta0=(0.0, 0.0, 0.0), closure_tol: float = 1e-6,
                       with_closure_error: bool = False) -> ca.Function:
        """CasADi Function ``tau_moor(eta) -> tau`` for control design.

        Parameters
        ----------
        kind : {"catenary", "linear", "characteristic"}
            ``"catenary"``: every line through the elastic catenary root (exact derivatives);
            ``"characteristic"``: per-line characteristics linearised about ``eta0`` (eq. 27–28);
            ``"linear"``: the linear spring ``g(eta0) - R(psi)^T G_mo (eta - eta0)`` (eq. 29).
        eta0 : array_like, shape (3,)
            Working point [m, m, rad] for the linearised kinds and the Newton initial guess.
        closure_tol : float
            ``"catenary"`` only: if any line's root misses its spans by more than this [m], the
            load is NaN instead of a wrong number (an NLP solver treats NaN as an evaluation error
            and shortens its step).
        with_closure_error : bool
            ``"catenary"`` only: add a second output ``closure_error`` [m], the largest over lines.
        """
        key = ("force", kind, tuple(np.asarray(eta0, dtype=float)), closure_tol, with_closure_error)
        if key in self._cache:
            return self._cache[key]
        eta = ca.MX.sym("eta", 3)
        outs, names = [], ["tau_moor"]
        if kind == "catenary":
            HF, _, err = self._symbolic_lines(eta, np.asarray(eta0, dtype=float))
            worst = ca.mmax(err)
            tau = self.tau_from_H(eta, HF)
            tau = ca.if_else(worst <= closure_tol, tau, ca.DM.nan(3, 1))
            outs = [tau]
            if with_closure_error:
                outs.append(worst)
                names.append("closure_error")
        elif kind in ("linear", "characteristic"):
            outs = [self.linearised(eta0).force(eta, kind=kind)]
        else:
            raise ModelError(f"kind = {kind!r} is not one of 'catenary', 'linear', 'characteristic'")
        fn = ca.Function(f"tau_moor_{kind}", [eta], outs, ["eta"], names)
        self._cache[key] = fn
        return fn

    def tension_function(self, kind: Literal["catenary", "characteristic"] = "characteristic",
                         *, eta0=(0.0, 0.0, 0.0), closure_tol: float = 1e-6) -> ca.Function:
        """CasADi Function ``T_fairlead(eta) -> T`` (n,) [N], fairlead tension of every line.

        ``"catenary"``: exact, ``sqrt(HF^2 + VF^2)`` from the symbolic catenary (NaN if a root fails,
        as in :meth:`force_function`); ``"characteristic"``: each line's tension linearised in its
        horizontal distance about ``eta0``, ``T0 + (dT/dXF) (XF(eta) - XF0)`` with the exact geometry.
        """
        key = ("tension", kind, tuple(np.asarray(eta0, dtype=float)), closure_tol)
        if key in self._cache:
            return self._cache[key]
        eta0 = self._check_eta(eta0)
        eta = ca.MX.sym("eta", 3)
        if kind == "characteristic":
            T = self.characteristic_load(eta, self.characteristics(eta0))[1]
        elif kind == "catenary":
            HF, VF, err = self._symbolic_lines(eta, eta0)
            T = ca.sqrt(HF ** 2 + VF ** 2)
            T = ca.if_else(ca.mmax(err) <= closure_tol, T, ca.DM.nan(self.n_lines, 1))
        else:
            raise ModelError(f"kind = {kind!r} is not one of 'catenary', 'characteristic'")
        fn = ca.Function(f"T_fairlead_{kind}", [eta], [T], ["eta"], ["T"])
        self._cache[key] = fn
        return fn

    def _symbolic_lines(self, eta, eta0: np.ndarray):
        """Symbolic fairlead tensions (HF, VF) and closure errors of every line at the pose
        ``eta`` (CasADi), column vectors (n, 1): a homogeneous line through the catenary root
        started from the numeric solution at ``eta0`` extrapolated to first order; a line the root
        does not cover (composite, or with a tension-strain table) through the cubic-spline
        interpolant of its exact solve (:mod:`tapm_opt.models.line_interpolant`), whose closure
        error is its distance beyond the sampled range."""
        sol0 = self.solve_lines(eta0)
        _, _, XF0 = self.spans(eta0)
        _, _, XF = self.spans(eta)
        dX = XF - XF0
        DM = ca.DM
        HF0 = ca.fmax(DM(sol0.HF) + DM(sol0.dHF_dXF) * dX, DM(0.1 * sol0.HF + 1.0))
        VF0 = ca.fmax(DM(sol0.VF) + DM(sol0.dVF_dXF) * dX, DM(0.1 * sol0.VF + 1.0))
        if not self.has_composite:
            cat = catenary.symbolic_function().map(self.n_lines)
            HF, VF, err = cat(XF.T, self.ZF[None, :], self.L[None, :], self.EA[None, :], self.w[None, :],
                              self.CB[None, :], self.h_A[None, :], HF0.T, VF0.T)
            return HF.T, VF.T, err.T
        cat = catenary.symbolic_function()
        outs = []
        for i in range(self.n_lines):
            if self.composite[i] is None:
                outs.append(cat(XF[i], self.ZF[i], self.L[i], self.EA[i], self.w[i], self.CB[i], self.h_A[i],
                                HF0[i], VF0[i]))
            else:
                outs.append(self.line_interpolant(i).function(XF[i]))
        return tuple(ca.vertcat(*(o[k] for o in outs)) for k in range(3))

    def line_interpolant(self, i: int, *, max_offset: float | None = None):
        """Cubic-spline interpolant of line ``i``'s exact ``HF(XF)``, ``VF(XF)``
        (:func:`tapm_opt.models.line_interpolant.line_interpolant`) over the distances the line
        takes with the body origin up to ``max_offset`` [m] from the field zero point at any
        heading (default: 30 % of the deepest seabed below the fairleads, the load tables' range);
        kept with the model per line physics."""
        from .line_interpolant import line_interpolant

        if max_offset is None:
            max_offset = 0.3 * float(np.max(self.ZF + self.h_A))
        key = ("interpolant", self.line_key(i), float(max_offset))
        hit = self._cache.get(key)
        if hit is not None:
            return hit
        _, _, XF0 = self.spans(np.zeros(3))
        reach = max_offset + 2.0 * float(np.hypot(*self.p_cot_B)) + 2.0 * float(np.hypot(*self.p_T[i]))
        lo, hi = max(float(XF0[i]) - reach, 0.0), float(XF0[i]) + reach
        solve = self.line_solver(i)
        T_ref = float(solve(np.array([XF0[i]])).TF[0]) or 1.0
        li = line_interpolant(solve, lo, hi, T_ref=T_ref, name=f"line_{self.line_ids[i]}")
        self._cache[key] = li
        return li

    def characteristics(self, eta0) -> np.ndarray:
        """Every line's characteristic about the pose ``eta0`` (survey eq. 26–28), from the elastic
        catenary there: rows H0 [N] (horizontal fairlead tension), dH/dXF [N/m], XF0 [m]
        (horizontal anchor–fairlead distance), T0 [N] (fairlead tension) and dT/dXF [N/m]; shape
        (5, n). :meth:`characteristic_load` evaluates them at a pose."""
        eta0 = self._check_eta(eta0)
        sol = self.solve_lines(eta0)
        _, _, XF0 = self.spans(eta0)
        return np.stack([sol.HF, sol.dHF_dXF, XF0, sol.TF, sol.dTF_dXF])

    def characteristic_load(self, eta, coeffs):
        """Mooring load in {B} and fairlead tensions of the characteristics ``coeffs`` (the rows of
        :meth:`characteristics`, numbers or CasADi symbols) at the pose ``eta`` (numpy or CasADi):
        ``H_i = H0_i + (dH/dXF)_i (XF_i(eta) - XF0_i)``, ``T_i = T0_i + (dT/dXF)_i (XF_i - XF0_i)``
        with the exact geometry (eq. 27–28). Returns ``(tau (3,), T (n,))``."""
        H0, k, XF0, T0, dT = (coeffs[i] for i in range(5))
        _, _, XF = self.spans(eta)
        return self.tau_from_H(eta, H0 + k * (XF - XF0)), T0 + dT * (XF - XF0)

    def linearised(self, eta0=(0.0, 0.0, 0.0), *, D_mo=None) -> "LinearMooring":
        """Linear spring model about the working point ``eta0`` (survey eq. 26–30)."""
        eta0 = self._check_eta(eta0)
        sol = self.solve_lines(eta0)
        K = self.stiffness(eta0)
        _, _, XF0 = self.spans(eta0)
        return LinearMooring(
            model=self,
            eta0=readonly(eta0),
            g0=readonly(self.tau_from_H(eta0, sol.HF)),
            G_mo=readonly(rot_z(eta0[2]) @ K),
            H0=readonly(sol.HF),
            k=readonly(sol.dHF_dXF),
            XF0=readonly(XF0),
            D_mo=readonly(np.zeros((3, 3)) if D_mo is None else D_mo),
        )

    # -- static equilibrium ------------------------------------------------------------------
    def equilibrium(self, tau_env, *, psi: float | None = None, eta_guess=(0.0, 0.0, 0.0),
                    tol: float = 1e-9) -> np.ndarray:
        """Pose where the mooring balances a constant load in {B}: ``tau_moor(eta) + tau_env = 0``.

        ``psi=None``: x, y and psi all balance (the vessel at rest without thrust). ``psi``
        given: the heading is held there (by the heading controller) and x, y balance X and Y;
        the yaw moment ``tau_moor[N] + tau_env[N]`` at that pose is left to the thrusters.
        Solved by :func:`~tapm_opt.models.statics.solve_equilibrium` (Powell, exact
        :meth:`stiffness` as Jacobian, load continuation if the direct solve fails) on the
        residual scaled by ``max(|tau_env|, sum of the lines' horizontal tensions at the start, 1 kN)``
        over the balanced components.

        Parameters
        ----------
        tau_env : array_like, shape (3,)
            Load on the vessel in {B} besides the mooring (X [N], Y [N], N [N m]).
        psi : float, optional
            Heading held [rad]; None: free.
        eta_guess : array_like, shape (3,)
            Start point (x [m], y [m], psi [rad]); with ``psi`` given only x, y are used.
        tol : float
            Largest accepted scaled residual [-].

        Returns
        -------
        ndarray, shape (3,)
            (x [m], y [m], psi [rad]) in {E}.

        Raises
        ------
        EquilibriumError
            No equilibrium (the load exceeds what the lines hold, or, free turret with ``psi``
            free, a body-fixed yaw moment other than ``x_cot Y`` that makes the hull weathervane).
        """
        tau_env = np.asarray(tau_env, dtype=float)
        if tau_env.shape != (3,) or not np.all(np.isfinite(tau_env)):
            raise ModelError(f"tau_env = {np.ravel(tau_env).tolist()} must be 3 finite numbers "
                             f"(X [N], Y [N], N [N m])")
        guess = self._check_eta(eta_guess)
        # the residual's scale: the load, or the lines' own pull where it is larger (their tensions
        # round at 1e-16 of themselves, so a residual relative to 1 kN alone cannot reach tol on
        # a mooring of MN lines that is not balanced at the start), at least 1 kN
        pull = float(np.sum(np.abs(self.solve_lines(guess if psi is None else np.r_[guess[:2], float(psi)]).HF)))
        if psi is None:
            scale = max(float(np.max(np.abs(tau_env))), pull, 1.0e3)

            def residual(eta, s):
                return (self.force(eta) + s * tau_env) / scale

            def jacobian(eta, s):
                return -self.stiffness(eta) / scale

            start = guess
        else:
            psi = float(psi)
            scale = max(float(np.max(np.abs(tau_env[:2]))), pull, 1.0e3)

            def residual(xy, s):
                return (self.force(np.r_[xy, psi])[:2] + s * tau_env[:2]) / scale

            def jacobian(xy, s):
                return -self.stiffness(np.r_[xy, psi])[:2, :2] / scale

            start = guess[:2]
        # the composite lines' solves of this search start from their last (composite.WarmStart),
        # kept for this call only, so the answer depends on the inputs alone
        self._cache["warm_starts"] = {}
        try:
            root = solve_equilibrium(residual, jacobian, start, tol=tol)
        except EquilibriumError as exc:
            held = "free" if psi is None else f"held at {np.degrees(psi):g} deg"
            hint = ""
            if psi is None and self.turret_mode == "free":
                hint = (f"; with a free turret the hull can balance a body-fixed load only if "
                        f"N = x_cot Y (x_cot = {self.p_cot_B[0]:g} m), else it weathervanes")
            raise EquilibriumError(
                f"no mooring equilibrium for tau_env = {tau_env.tolist()} (heading {held}) with "
                f"lines {list(self.line_ids)}: {exc.reason}{hint}",
                residual=exc.residual, reason=exc.reason) from None
        finally:
            self._cache.pop("warm_starts", None)
        return root if psi is None else np.r_[root, psi]


@dataclass(frozen=True, eq=False)
class LinearMooring:
    """Linearised mooring about a working point ``eta0`` (survey eq. 26–30).

    Attributes
    ----------
    eta0 : ndarray (3,)
        Working point (the field zero point by default) [m, m, rad].
    g0 : ndarray (3,)
        Restoring load at eta0 in {B}, g_moor(eta0) [N, N, N m] (zero for a symmetric mooring).
    G_mo : ndarray (3, 3)
        Stiffness in {E} of eq. (29): tau ~ g0 - R(psi)^T G_mo (eta - eta0).
    H0, k, XF0 : ndarray (n,)
        Per-line horizontal tension [N], characteristic slope dH/dL_h [N/m] and horizontal
        anchor–fairlead distance [m] at eta0 (eq. 26–27).
    D_mo : ndarray (3, 3)
        Linear mooring damping of eq. (30) [N s/m, N s, N m s] (identified from the plant later).
    """

    model: MooringModel
    eta0: np.ndarray
    g0: np.ndarray
    G_mo: np.ndarray
    H0: np.ndarray
    k: np.ndarray
    XF0: np.ndarray
    D_mo: np.ndarray

    def force(self, eta, nu=None, *, kind: Literal["linear", "characteristic"] = "linear"):
        """Linearised mooring load in {B} (numpy or CasADi ``eta``).

        ``kind="linear"``: eq. (29) plus damping -D_mo nu (eq. 30) when ``nu`` is given.
        ``kind="characteristic"``: eq. (27)–(28), H_i = H0_i + k_i (|p_tp - p_a| - XF0_i), with
        the exact geometry.
        """
        if kind == "characteristic":
            tau = self.model.characteristic_load(eta, (self.H0, self.k, self.XF0, 0.0, 0.0))[0]
        elif kind == "linear":
            Rt = rot_z(eta[2]).T
            if bk.is_symbolic(eta):
                tau = self.g0 - ca.mtimes(Rt, ca.mtimes(self.G_mo, eta - self.eta0))
            else:
                tau = self.g0 - Rt @ (self.G_mo @ (np.asarray(eta, dtype=float) - self.eta0))
        else:
            raise ModelError(f"kind = {kind!r} is not one of 'linear', 'characteristic'")
        if nu is not None:
            tau = tau - (ca.mtimes(self.D_mo, nu) if bk.is_symbolic(nu) else self.D_mo @ np.asarray(nu))
        return tau
