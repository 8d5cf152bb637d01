"""FEM mooring lines of a scenario, attached to the vessel's fairleads.

Connects :class:`~tapm_opt.plant.fem.FEMLines` to a scenario: line properties (a composite
line's sections and points), catenary initialisation (a composite line on its quasi-static
shape), settling, fairlead kinematics and the load on the vessel. The turret and
fairlead geometry and the assembly of the load in {B} are those of
:class:`~tapm_opt.models.mooring.MooringModel` (one definition for the design model and the plant).
"""

from __future__ import annotations

import dataclasses
import math
import time
from dataclasses import dataclass
from typing import Any, Callable

import numpy as np

from ..errors import CatenaryError, ModelError, TapmError
from ..geometry import rot2_apply
from ..models import catenary, composite
from ..models.mooring import MooringModel
from .fem import MAX_NODE_SPEED, POINT_KEYS, SECTION_KEYS, FEMLines, LineSet, _as_f64

__all__ = ["MooringFEM", "SettleInfo", "SettlingNotConverged", "line_set_from_scenario"]


def _section_segments(line: Any, segments: int | None) -> tuple[int, ...]:
    """FEM segments of each section of a composite line: its own (``Line.section_segments``), or,
    with a total ``segments`` for every line, that total shared by length (at least 1 each)."""
    if segments is None:
        return line.section_segments()
    return dataclasses.replace(line, sections=tuple(dataclasses.replace(s, segments=None) for s in line.sections),
                               segments=int(segments)).section_segments()


def line_set_from_scenario(scenario: Any, *, segments: int | None = None) -> LineSet:
    """Per-line FEM properties of a scenario; ``segments`` overrides every line's count (a
    composite line's shared among its sections by length). Composite lines carry their sections
    and points (:attr:`LineSet.sections`), and so does a homogeneous line of a tension-strain
    table (nonlinear EA), as one section with its table."""
    if segments is not None and (not isinstance(segments, (int, np.integer)) or segments < 2):
        raise ModelError(f"segments = {segments!r} must be a whole number >= 2")
    la = scenario.line_arrays
    types = [scenario.line_type(ln) for ln in scenario.lines]
    n = len(types)
    sections = None
    tabled = [any(t is not None for t in sec["EA_table"]) for sec in scenario.line_sections]
    if any(ln.composite for ln in scenario.lines) or any(tabled):
        sections = []
        for ln, sec, tb in zip(scenario.lines, scenario.line_sections, tabled):
            if not ln.composite and not tb:
                sections.append(None)
                continue
            d = {k: np.array(sec[k], dtype=float) for k in SECTION_KEYS + POINT_KEYS if k not in ("mu", "segments")}
            d["mu"] = np.array(sec["CB"], dtype=float)
            d["segments"] = np.array(_section_segments(ln, segments) if ln.composite
                                     else [segments or ln.segments], dtype=int)
            d["EA_table"] = tuple(sec["EA_table"])
            sections.append(d)
        sections = tuple(sections)
    nseg = np.array([int(s["segments"].sum()) if s is not None else (segments or la["segments"][i])
                     for i, s in enumerate(sections)], dtype=int) if sections is not None else None
    return LineSet(
        ids=tuple(ln.id for ln in scenario.lines),
        L=np.array(la["L"], dtype=float),
        EA=np.array(la["EA"], dtype=float),
        w=np.array(la["w"], dtype=float),
        mass=np.array([t.mass_per_length for t in types]),
        d=np.array([t.diameter for t in types]),
        Cdn=np.array([t.Cd_normal for t in types]),
        Cdt=np.array([t.Cd_tangential for t in types]),
        Can=np.array([t.Ca_normal for t in types]),
        Cat=np.array([t.Ca_tangential for t in types]),
        segments=(nseg if nseg is not None else np.full(n, segments, dtype=int) if segments is not None
                  else np.array(la["segments"], dtype=int)),
        damping_ratio=np.array([getattr(t, "axial_damping_ratio", 0.0) for t in types]),
        mu=np.array([t.seabed_friction for t in types]),
        sections=sections,
    )


@dataclass(frozen=True)
class SettleInfo:
    """How the lines were settled: simulated time [s] until convergence (or until settling
    stopped), final largest node speed [m/s], the largest relative change of the fairlead
    tensions over the last check interval, whether both met their tolerances, and the wall
    time spent [s]."""

    time: float
    max_speed: float
    tension_change: float
    converged: bool
    wall_time: float = 0.0


#: Fastest node speed [m/s] below which lines that have not settled are taken to be still creeping
#: toward rest (a slow drift in a strong current) rather than an unstable FEM step, in the message.
SETTLE_UNSTABLE_SPEED = 1.0


class SettlingNotConverged(TapmError, RuntimeError):
    """The lines did not come to rest within the settling time; ``info`` is the :class:`SettleInfo`."""

    def __init__(self, message: str, info: SettleInfo):
        self.info = info
        super().__init__(message)


def vertical_offset(hz, ph, th, dx, dy, z_fl, c, s):
    """Displacement (x, y, z) in {E} [m] of fairleads by the hull's heave ``hz`` [m, down], roll
    ``ph`` [rad, starboard down] and pitch ``th`` [rad, bow up], small rotations about the body
    origin on the water line: ``(th z, -ph z, hz + ph y - th x)`` in {B} for a fairlead at
    ``(x, y, z)`` in {B} — ``(dx, dy)`` its horizontal offset from the body origin in {E}, ``z =
    z_fl`` its depth [m] — turned to {E} by the heading (``c, s`` its cosine and sine). Linear in
    ``(hz, ph, th)``: their rates and accelerations give the fairleads' velocities and
    accelerations (the change of the levers, second order, is left out). Arrays broadcast; the
    compiled plant's twin is ``fem_kernel._vertical_offset`` (the same operations)."""
    bx = c * dx + s * dy
    by = c * dy - s * dx
    ox = th * z_fl
    oy = -(ph * z_fl)
    oz = (hz + ph * by) - th * bx
    return c * ox - s * oy, s * ox + c * oy, oz


class MooringFEM:
    """All mooring lines of a scenario as lumped-mass FEM lines, moved by the vessel.

    Parameters
    ----------
    scenario : Scenario
    segments : int, optional
        FEM segments per line (default: each line's ``segments``).
    current : callable, optional
        ``current(z) -> (n, 3)`` current velocity in {E} at depths z [m]; default none.
    safety : float
        Fraction of the stability limit used as time step (see ``FEMLines.stable_dt``).
    geometry : MooringModel, optional
        The scenario's intact line system for the turret and fairlead geometry (default: built
        from the scenario).
    """

    def __init__(self, scenario: Any, *, segments: int | None = None,
                 current: Callable[[np.ndarray], np.ndarray] | None = None, safety: float = 0.9,
                 geometry: MooringModel | None = None):
        if not (0.0 < safety <= 1.0):
            raise ModelError(f"safety = {safety!r} must be in (0, 1]")
        self.scenario = scenario
        if geometry is not None and geometry.n_lines != len(scenario.lines):
            raise ModelError(f"geometry has {geometry.n_lines} lines, the scenario {len(scenario.lines)}: the "
                             f"FEM plant needs the intact line system")
        self.geometry = geometry if geometry is not None else MooringModel.from_scenario(scenario)
        self._p_cot = np.array(self.geometry.p_cot_B, dtype=float)  # the compiled step's geometry arrays
        self._p_T = np.array(self.geometry.p_T, dtype=float, order="C")
        env = scenario.environment
        self.fem = FEMLines(line_set_from_scenario(scenario, segments=segments), np.array(scenario.anchors),
                            water_depth=env.water_depth, rho_w=env.water_density)
        self.fairlead_z = float(scenario.turret.fairlead_depth)
        self.current = current
        self.safety = float(safety)
        self.dt = self.fem.stable_dt(safety)
        self._vc = np.zeros((self.fem.n_nodes, 3))

    @property
    def line_ids(self) -> tuple[str, ...]:
        return self.fem.lines.ids

    # -- kinematics ------------------------------------------------------------------------
    def _levers(self, eta, fx, fy):
        """Lever arm (x, y) in {E} about which the fairleads turn with the heading rate [m]: from
        the body origin to each fairlead (locked turret) or to the centre of turret, R2(psi)
        p_cot^B (free turret, eq. 5). ``eta`` may carry trailing axes (a pose sequence)."""
        g = self.geometry
        if g.turret_mode == "locked":
            return fx - eta[0], fy - eta[1]
        return rot2_apply(eta[2], g.p_cot_B[0], g.p_cot_B[1])

    def fairlead_state(self, eta: np.ndarray, eta_dot: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Fairlead positions and velocities in {E}, each (n_lines, 3), for the vessel pose and rate.

        Rigid-body kinematics of eq. (5): ``v = p_dot + psi_dot k x (p_f - p)`` (locked turret) or
        ``v = p_dot + psi_dot k x R2(psi) p_cot`` plus no turret rotation (free turret). A pose
        of six, ``(x, y, psi, heave, roll, pitch)`` [m, m, rad, m, rad, rad] (and its rate), adds
        the hull's wave-frequency heave, roll and pitch (:func:`vertical_offset`).
        """
        r, v = self.fairlead_states(np.asarray(eta, float)[None, :], np.asarray(eta_dot, float)[None, :])
        return r[0], v[0]

    def _update_current(self) -> np.ndarray:
        """The current at the nodes [m/s] (n_nodes, 3) for their present depths. Nodes that are no
        longer finite have no depth: the FEM is reported as diverged (not the current profile's
        input as bad)."""
        if self.current is not None:
            z = self.fem.r[:, 2]
            if not np.isfinite(z).all():
                self.fem.check_health()
            self._vc = self.current(z)
        return self._vc

    # -- set-up ----------------------------------------------------------------------------
    def initialise(self, eta: np.ndarray) -> None:
        """Place every line's nodes on its elastic catenary for the vessel at ``eta``.

        An anchor above the seabed (height ``h_A`` of the geometry's lines) is held at depth
        ``water depth - h_A``, and its line's catenary starts there (a sag that reaches the seabed
        puts the middle nodes on it). A composite line's nodes lie on its quasi-static shape
        (:meth:`_composite_nodes`): the joint nodes exactly at its points' equilibrium, each
        section's nodes on its own catenary between them."""
        fem = self.fem
        eta = np.asarray(eta, float)
        r_fl, _ = self.fairlead_state(eta, np.zeros_like(eta))
        depth = fem.depth
        h_A = np.asarray(self.geometry.h_A, dtype=float)
        for j in range(fem.n_lines):  # set-up only, not in the time step
            fem.anchors[j, 2] = depth - h_A[j]  # where the FEM holds the anchor node
            a = fem.anchors[j]
            d = r_fl[j, :2] - a[:2]
            XF = float(np.hypot(*d))
            u = d / XF if XF > 0 else np.array([1.0, 0.0])
            ns = int(fem.lines.segments[j])
            L, EA, w, mu = fem.L[j], fem.lines.EA[j], fem.lines.w[j], fem.lines.mu[j]
            table = None
            if fem.composite[j] and len(fem.lines.sections[j]["L"]) == 1:  # one section: the homogeneous line
                sec = fem.lines.sections[j]
                L, EA, w, mu = (float(np.ravel(sec[k])[0]) for k in ("L", "EA", "w", "mu"))
                table = (tuple(sec.get("EA_table", ())) or (None,))[0]
            elif fem.composite[j]:
                x, z = self._composite_nodes(j, XF, a[2] - r_fl[j, 2], float(h_A[j]))
                sl = slice(fem.node_start[j], fem.node_start[j] + ns + 1)
                fem.r[sl, :2] = a[:2] + x[:, None] * u
                fem.r[sl, 2] = depth - z
                continue
            prof = catenary.line_profile(XF, a[2] - r_fl[j, 2], L, EA, w, CB=mu, h_A=h_A[j], n=ns + 1,
                                         table=table)
            sl = slice(fem.node_start[j], fem.node_start[j] + ns + 1)
            fem.r[sl, :2] = a[:2] + prof["x"][:, None] * u
            fem.r[sl, 2] = a[2] - prof["z"]
            # a slack line's seabed part: put the nodes just on the seabed
        fem.r[fem.fairlead_idx] = r_fl
        fem.v[:] = 0.0
        self._r_fl = r_fl

    def _composite_nodes(self, j: int, XF: float, ZF: float, h_A: float) -> tuple[np.ndarray, np.ndarray]:
        """Node positions of composite line ``j`` on its quasi-static shape: horizontal distance
        from the anchor ``x`` and height above the seabed ``z`` [m], each (segments + 1,).

        The points' equilibrium (:func:`tapm_opt.models.composite.points`) places the joint nodes;
        each section's nodes are its elastic catenary between its two ends at equal steps of
        unstretched arc length (:func:`tapm_opt.models.catenary.line_profile`, taken from the
        physically lower end, so a section hanging down from a buoy is sampled as it hangs). Where
        a catenary cannot be solved (a configuration out of its reach) the nodes are spread on the
        chord instead, and settling does the rest."""
        sec = self.fem.lines.sections[j]
        tabs = tuple(sec.get("EA_table", ()))
        line = composite.CompositeLine(L=np.asarray(sec["L"], float), EA=np.asarray(sec["EA"], float),
                                       w=np.asarray(sec["w"], float), CB=np.asarray(sec["mu"], float),
                                       W=np.asarray(sec["W"], float),
                                       tables=tabs if any(t is not None for t in tabs) else ())
        seg = np.asarray(sec["segments"], dtype=int)
        try:
            px, pz = composite.points(XF, ZF, line, h_A=h_A)
            px, pz = np.ravel(px), np.ravel(pz)
        except CatenaryError:  # the points on the straight line, by arc length
            frac = np.cumsum(line.L)[:-1] / line.length
            px, pz = XF * frac, h_A + ZF * frac
        xe = np.r_[0.0, px, XF]  # the ends of the sections
        ze = np.r_[h_A, pz, h_A + ZF]
        xs, zs = [np.array([0.0])], [np.array([h_A])]
        for k in range(line.n_sections):
            up = ze[k + 1] >= ze[k]
            lo, hi = (k, k + 1) if up else (k + 1, k)
            sgn = 1.0 if xe[hi] >= xe[lo] else -1.0
            try:
                pr = catenary.line_profile(abs(xe[hi] - xe[lo]), ze[hi] - ze[lo], line.L[k], line.EA[k], line.w[k],
                                           CB=line.CB[k], h_A=max(ze[lo], 0.0), n=int(seg[k]) + 1,
                                           table=line.table(k))
                x, z = xe[lo] + sgn * pr["x"], ze[lo] + pr["z"]
                if not up:
                    x, z = x[::-1], z[::-1]
                ok = bool(np.all(np.isfinite(x)) and np.all(np.isfinite(z)))
            except CatenaryError:
                ok = False
            if not ok:
                f = np.linspace(0.0, 1.0, int(seg[k]) + 1)
                x, z = xe[k] + f * (xe[k + 1] - xe[k]), ze[k] + f * (ze[k + 1] - ze[k])
            x, z = x.copy(), z.copy()
            x[-1], z[-1] = xe[k + 1], ze[k + 1]  # the joints exactly at the points
            xs.append(x[1:])
            zs.append(z[1:])
        return np.concatenate(xs), np.maximum(np.concatenate(zs), 0.0)

    def settle(self, eta: np.ndarray, *, max_time: float = 1200.0, check_every: float = 5.0,
               tol: float = 1e-6, speed_tol: float = 0.01, damping: float = 0.5,
               strict: bool = True) -> SettleInfo:
        """Let the lines come to rest with the vessel held at ``eta`` (dynamic relaxation).

        Runs with mass-proportional damping ``damping`` [1/s] until, over ``check_every`` seconds,
        every fairlead tension changes by less than ``tol`` (relative) and the fastest node moves
        slower than ``speed_tol`` [m/s]; at most ``max_time`` seconds. Not converged by then:
        :class:`SettlingNotConverged` (``strict``) or a :class:`SettleInfo` with
        ``converged=False``. Lines that never settle usually mean an unstable FEM step (a
        ``safety`` factor too close to 1 for the damping) or lines still oscillating after
        ``max_time``.
        """
        w0 = time.perf_counter()
        eta = np.asarray(eta, float)
        r_fl, v_fl = self.fairlead_state(eta, np.zeros_like(eta))
        fem = self.fem
        dt = min(self.dt, fem.stable_dt(self.safety, extra_damping=damping))
        n_check = max(1, int(round(check_every / dt)))
        T_prev = fem.fairlead_tension()
        t = 0.0
        change, speed = np.inf, np.inf
        converged = False
        r_seq = np.broadcast_to(r_fl, (n_check,) + r_fl.shape)
        v_seq = np.broadcast_to(v_fl, (n_check,) + v_fl.shape)
        for _ in range(max(1, int(round(max_time / (n_check * dt))))):
            # the current is evaluated at the nodes' depths once per check interval
            fem.advance(dt, r_seq, v_seq, self._update_current(), extra_damping=damping)
            t += n_check * dt
            fem.check_health()
            T = fem.fairlead_tension()
            change = float(np.max(np.abs(T - T_prev) / np.maximum(np.abs(T), 1.0)))
            speed = float(np.sqrt(np.max(np.einsum("ij,ij->i", fem.v, fem.v))))
            T_prev = T
            if change < tol and speed < speed_tol:
                converged = True
                break
        info = SettleInfo(time=t, max_speed=speed, tension_change=change, converged=converged,
                          wall_time=time.perf_counter() - w0)
        if not converged and strict:
            i = int(np.argmax(np.einsum("ij,ij->i", fem.v, fem.v)))
            j = int(fem.line_of_node[i])
            head = (f"the mooring lines did not settle within {max_time:g} s: the fastest node (line "
                    f"{fem.lines.ids[j]!r}, node {i - int(fem.node_start[j])}) still moves at {speed:.3g} m/s "
                    f"(tolerance {speed_tol:g}) and the fairlead tensions change by {change:.2g} per "
                    f"{n_check * dt:.3g} s (tolerance {tol:g})")
            vc = float(np.sqrt(np.max(np.einsum("ij,ij->i", self._vc, self._vc)))) if self.current is not None else 0.0
            if speed < SETTLE_UNSTABLE_SPEED:
                flow = f" in a current of up to {vc:.3g} m/s at the nodes" if vc > 0 else ""
                advice = (f"; the lines are still creeping toward rest{flow}, not unstable (no node faster than "
                          f"{SETTLE_UNSTABLE_SPEED:g} m/s): they need longer than the plant's settling time. From the "
                          "command line, a weaker current (the sea state's current_speed or current_profile) or "
                          "another sea state (--sea-state) settles sooner; from Python, settle(max_time=...) of "
                          "tapm_opt.plant.mooring_fem.MooringFEM gives it longer")
            else:
                advice = (f"; a node this fast means the explicit FEM step is unstable for these lines (step "
                          f"{dt:.3g} s, {self.safety:g} of the stability limit). From the command line, other "
                          "segment counts (--segments, or the scenario's lines[].segments) change the step; from "
                          "Python, a smaller safety factor (tapm_opt.plant.Plant(..., safety=0.5)) shortens it")
            raise SettlingNotConverged(head + advice, info)
        fem.v[:] = 0.0
        fem.t = 0.0
        return info

    # -- time stepping ---------------------------------------------------------------------
    def step(self, eta: np.ndarray, eta_dot: np.ndarray) -> np.ndarray:
        """One FEM step of length ``self.dt`` with the fairleads at pose ``eta`` moving at ``eta_dot``.

        Returns the segment tensions at the start of the step [N].
        """
        r_fl, v_fl = self.fairlead_state(eta, eta_dot)
        self._r_fl = r_fl
        return self.fem.step(self.dt, r_fl, v_fl, self._update_current())

    def fairlead_states(self, eta_seq: np.ndarray, eta_dot_seq: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`fairlead_state` for a sequence of poses and rates, each (n, 3), vectorised:
        fairlead positions and velocities in {E}, each (n, n_lines, 3)."""
        eta_seq = np.asarray(eta_seq, dtype=float)
        eta_dot_seq = np.asarray(eta_dot_seq, dtype=float)
        if eta_seq.ndim != 2 or eta_seq.shape[1] not in (3, 6) or eta_dot_seq.shape != eta_seq.shape:
            raise ModelError(f"eta_seq and eta_dot_seq have shapes {eta_seq.shape} and {eta_dot_seq.shape}, "
                             "expected (n, 3) or (n, 6) each")
        g = self.geometry
        e = eta_seq.T[:, :, None]  # (3 or 6, n, 1): broadcasts against the fairleads
        fx, fy = g.fairleads(e[:3])    # (n, n_lines)
        n, nl = fx.shape
        r = np.empty((n, nl, 3))
        r[:, :, 0] = fx
        r[:, :, 1] = fy
        r[:, :, 2] = self.fairlead_z
        rx, ry = self._levers(e, fx, fy)
        ed = eta_dot_seq.T[:, :, None]
        v = np.zeros_like(r)
        v[:, :, 0] = ed[0] - ed[2] * ry
        v[:, :, 1] = ed[1] + ed[2] * rx
        if e.shape[0] == 6 and (np.any(e[3:]) or np.any(ed[3:])):
            c, s = np.cos(e[2]), np.sin(e[2])
            dx, dy = fx - e[0], fy - e[1]
            for out, q in ((r, e), (v, ed)):
                ox, oy, oz = vertical_offset(q[3], q[4], q[5], dx, dy, self.fairlead_z, c, s)
                out[:, :, 0] += ox
                out[:, :, 1] += oy
                out[:, :, 2] += oz
        return r, v

    def advance(self, eta_seq: np.ndarray, eta_dot_seq: np.ndarray,
                fairlead_force_out: np.ndarray | None = None) -> np.ndarray:
        """``n`` FEM steps of length ``self.dt``, step i ending with the fairleads at pose
        ``eta_seq[i]`` moving at ``eta_dot_seq[i]`` (each (n, 3)), in one call of
        :meth:`FEMLines.advance`.

        The same as n calls of :meth:`step`, except that the current is evaluated once, on the
        node depths at the start, and held over the n steps (:meth:`step` re-evaluates it every
        step; the current depends on the node depths only, so over a short batch the difference is
        tiny; identical in still water). Returns the segment tensions at the start of the last step [N].
        ``fairlead_force_out`` (n, n_lines, 3), when given, receives the fairlead forces at the
        start of every step (:meth:`FEMLines.advance`).
        """
        r_seq, v_seq = self.fairlead_states(eta_seq, eta_dot_seq)
        T = self.fem.advance(self.dt, r_seq, v_seq, self._update_current(), fairlead_force_out=fairlead_force_out)
        self._r_fl = r_seq[-1]
        return T

    def outer_step_compiled(self, pose0: np.ndarray, pose1: np.ndarray, rate_prev: np.ndarray, h: float,
                            n_sub: int, near_tension: np.ndarray):
        """A plant outer step of the lines in one compiled call (:func:`tapm_opt.plant.fem_kernel.mooring_step`;
        the FEM kernel must be "numba"): the same as :meth:`advance` over ``n_sub`` steps of
        ``self.dt = h / n_sub`` along the poses from ``pose0`` to ``pose1`` [m, m, rad] at the
        rate ``(pose1 - pose0) / h``, then :meth:`fairlead_acceleration` at ``pose1`` from the
        change of rate since ``rate_prev`` over ``h`` [s], and :meth:`tau` at ``pose1``.

        Returns the bond tensions at the start of the last step [N], the rate (3,), the fairlead
        accelerations (n_lines, 3) [m/s^2], the load on the vessel (3,) [N, N, N m] in {B} and the
        flags ``near`` (an intact line's tension bound at or above its ``near_tension`` [N]) and
        ``suspect`` (a node state non-finite or faster than :data:`~tapm_opt.plant.fem.MAX_NODE_SPEED`,
        for :meth:`FEMLines.check_health` to report).
        """
        from . import fem_kernel

        fem, g = self.fem, self.geometry
        self.dt = h / n_sub
        shape = (fem.n_nodes, 3)
        pose0, pose1 = np.asarray(pose0, dtype=float), np.asarray(pose1, dtype=float)
        v0, v1 = (np.ascontiguousarray(p[3:6]) if p.size == 6 else np.zeros(3) for p in (pose0, pose1))
        rate_prev = np.asarray(rate_prev, dtype=float)
        if rate_prev.size == 3:
            rate_prev = np.concatenate([rate_prev, np.zeros(3)])
        r, v, T, self._r_fl, rate, a_fl, tau, near, suspect = fem_kernel.mooring_step(
            np.ascontiguousarray(pose0[:3]), np.ascontiguousarray(pose1[:3]), v0, v1, rate_prev, float(h), int(n_sub), self._p_cot, self._p_T, float(g.turret_angle),
            g.turret_mode == "locked", self.fairlead_z,
            _as_f64(fem.r, shape, "r"), _as_f64(fem.v, shape, "v"), _as_f64(self._update_current(), shape, "v_current"),
            *fem._kernel_constants(), fem.fairlead_seg, fem.anchor_seg, fem.active, near_tension, MAX_NODE_SPEED)
        fem.r, fem.v = r, v
        dt = self.dt
        for _ in range(n_sub):  # the same sum as n single steps (FEMLines._advance_compiled)
            fem.t += dt
        return T, rate, a_fl, tau, near, suspect

    def fairlead_acceleration(self, eta: np.ndarray, eta_dot: np.ndarray, eta_ddot: np.ndarray) -> np.ndarray:
        """Fairlead accelerations in {E} (n_lines, 3) [m/s^2] for the vessel pose, rate and
        acceleration (rigid body, the time derivative of :meth:`fairlead_state`'s velocity; poses
        of six add the heave, roll and pitch accelerations, :func:`vertical_offset`)."""
        g = self.geometry
        fx, fy = g.fairleads(eta[:3])
        rx, ry = self._levers(eta, fx, fy)
        rd, rdd = eta_dot[2], eta_ddot[2]
        a = np.zeros((fx.shape[0], 3))
        a[:, 0] = eta_ddot[0] - rdd * ry - rd * rd * rx
        a[:, 1] = eta_ddot[1] + rdd * rx - rd * rd * ry
        if len(eta) == 6 and (np.any(eta[3:]) or np.any(eta_dot[3:]) or np.any(eta_ddot[3:])):
            c, s = math.cos(eta[2]), math.sin(eta[2])
            ax, ay, az = vertical_offset(eta_ddot[3], eta_ddot[4], eta_ddot[5], fx - eta[0], fy - eta[1],
                                         self.fairlead_z, c, s)
            a[:, 0] += ax
            a[:, 1] += ay
            a[:, 2] += az
        return a

    def tau(self, eta: np.ndarray, a_fairlead: np.ndarray | None = None) -> np.ndarray:
        """Load of all lines on the vessel in {B} [N, N, N m] (horizontal fairlead forces).

        The fairlead nodes' tension, weight, drag and, with ``a_fairlead`` (n_lines, 3) [m/s^2]
        (see :meth:`fairlead_acceleration`), inertia (:meth:`FEMLines.fairlead_forces`).
        ``eta`` must be the pose of the last :meth:`step` (the fairlead positions are reused).
        """
        fem = self.fem
        vc = self._vc[fem.fairlead_idx] if self.current is not None else None
        f = fem.fairlead_forces(vc, a_fairlead)
        r = self._r_fl
        return self.geometry.tau_from_forces(eta[:3], f[:, 0], f[:, 1], fairleads=(r[:, 0], r[:, 1]))

    def fairlead_tension(self) -> np.ndarray:
        """Fairlead tension of every line [N] (0 for a broken line)."""
        return self.fem.fairlead_tension()

    def anchor_tension(self) -> np.ndarray:
        """Anchor tension of every line [N]."""
        return self.fem.anchor_tension()

    def lose_point(self, line_id: str, joint: int) -> None:
        """The point (buoy or clump) at joint ``joint`` (from the anchor up) of composite line
        ``line_id`` comes off (:meth:`FEMLines.lose_point`); the FEM step is the new stable step."""
        try:
            j = self.line_ids.index(str(line_id))
        except ValueError:
            raise ModelError(f"cannot take a point off line {line_id!r}: no such line; lines are "
                             f"{list(self.line_ids)}") from None
        self.fem.lose_point(j, joint)
        self.dt = min(self.dt, self.fem.stable_dt(self.safety))

    def break_line(self, line_id: str) -> None:
        """Break line ``line_id`` at its fairlead."""
        try:
            j = self.line_ids.index(str(line_id))
        except ValueError:
            raise ModelError(f"cannot break line {line_id!r}: no such line; lines are {list(self.line_ids)}") from None
        self.fem.break_line(j)
