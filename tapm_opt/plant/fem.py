"""Lumped-mass finite-element model of all mooring lines, vectorised (seed [A] §II.C, [R] eq. 7).

Every line j is cut into ``n_j`` segments of unstretched length ``l_j = L_j / n_j``; nodes 0..n_j,
node 0 at the anchor, node n_j at the fairlead. All nodes of all lines live in one flat array, and
every force is computed for all of them at once with index gathers (no Python loop over lines or
nodes in a time step). A composite line (:attr:`LineSet.sections`) is cut section by section: the
segments of section k have its own ``l_k = L_k / n_k``, EA, weight, mass and damping, its nodes
its own drag and added-mass coefficients, and the node joining two sections (a *joint*) carries
half of each adjacent segment with that segment's own coefficients, plus the point there (a clump
weight or a buoy: its mass, net weight ``(m - rho V) g``, isotropic added mass ``Ca rho V`` and
drag ``1/2 rho CdA |v_r| v_r``, MoorDyn's point). See docs/plant.md, "Composite lines in the FEM".

Forces on node k (NED, z down):

* axial elasticity in tension only: segment tension ``T = EA max(e, 0) + c_int de/dt`` (clipped
  at 0), strain ``e = |l_k| / l - 1`` ([A] eq. 1, [R] eq. 7 f_r); a section with a tension-strain
  table (nonlinear EA) reads ``T(e)`` from it instead, linear between rows and beyond the last;
* submerged weight ``w (l_k + l_{k+1}) / 2`` downward ([A] eq. 2);
* Morison drag on the velocity relative to the current at the node's depth, each adjacent segment
  contributing half its length ([A] eq. 3–4, 'D_k'): normal ``-1/2 rho C_DN d eps |v_n| v_n`` and
  tangential ``-1/2 rho C_DT d eps |v_t| v_t``. **Both use the nominal diameter d** (as the seed),
  not pi d for the tangential term;
* added mass ``C_MN rho pi d^2/4`` per stretched length normal to the node tangent ([A] eq. 5); the
  node tangent is the normalised sum of the two adjacent segment tangents, so the 3 x 3 mass
  matrix ``m I + m_a (I - q q^T)`` inverts in closed form (equals the seed's M_k when the two
  segments are collinear);
* seabed contact for nodes below the seabed: a vertical spring-damper per unit length
  ``k_b d``, ``c_b d`` and optional Coulomb friction ``mu`` on the velocity relative to the
  seabed, applied implicitly in the step (stick or slide, :meth:`FEMLines._friction`).

Integration: semi-implicit (symplectic) Euler with a step chosen from the stiffest segment
(``dt <= safety * 2 / omega_max``, see :meth:`FEMLines.stable_dt`).

Two implementations of the step, chosen with ``FEMLines(..., kernel=...)``: ``"numba"`` (default)
runs :mod:`tapm_opt.plant.fem_kernel`, one compiled call per step or per batch of steps
(:meth:`FEMLines.advance`); ``"numpy"`` is the vectorised reference (:meth:`FEMLines.accelerations`),
a few dozen numpy calls per step. Both give the same results to round-off.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable

import numpy as np

from ..errors import ModelError, TapmError
from ..models.catenary import as_table

__all__ = ["LineSet", "FEMLines", "SimulationDiverged", "KERNELS", "set_default_kernel"]

KERNELS = ("numba", "numpy")
"""Implementations of the FEM step: the compiled kernel and the numpy reference."""

MAX_NODE_SPEED = 100.0
"""Node speed [m/s] above which the FEM state counts as diverged (:meth:`FEMLines.check_health`)."""

_default_kernel = "numba"


def set_default_kernel(kernel: str) -> str:
    """Set the kernel of the :class:`FEMLines` built without ``kernel=`` (also those built inside
    :class:`~tapm_opt.plant.mooring_fem.MooringFEM`, the plant and ``forced_motion``); returns the
    previous default. For comparisons and benchmarks of the two paths."""
    global _default_kernel
    if kernel not in KERNELS:
        raise ModelError(f"kernel = {kernel!r} must be one of {', '.join(map(repr, KERNELS))}")
    previous, _default_kernel = _default_kernel, kernel
    return previous


def _as_f64(x, shape: tuple[int, ...], name: str) -> np.ndarray:
    """``x`` as a writable, C-contiguous float64 array of ``shape`` (broadcast as numpy would),
    the one array layout the compiled kernel is built for; ``x`` itself when it already is one."""
    if type(x) is np.ndarray and x.shape == shape and x.dtype == np.float64:
        flags = x.flags
        if flags.c_contiguous and flags.writeable:
            return x
    try:
        return np.array(np.broadcast_to(np.asarray(x, dtype=float), shape), dtype=float, order="C")
    except ValueError:
        raise ModelError(f"{name} has shape {np.shape(x)}, expected {shape}") from None


class SimulationDiverged(TapmError, RuntimeError):
    """The simulation state became non-finite or unphysical.

    Attributes name the time [s], line id and node index where it was detected.
    """

    def __init__(self, message: str, *, time: float, line: str | None = None, node: int | None = None):
        self.time, self.line, self.node = time, line, node
        super().__init__(message)


@dataclass(frozen=True)
class LineSet:
    """Per-line properties, arrays of shape (n_lines,) (SI units).

    ``L`` unstretched length [m]; ``EA`` [N]; ``w`` submerged weight [N/m]; ``mass`` mass per
    length in air [kg/m]; ``d`` hydrodynamic diameter [m]; ``Cdn``, ``Cdt`` drag and ``Can``,
    ``Cat`` added-mass coefficients; ``segments`` (int); ``damping_ratio`` axial internal damping as
    a fraction of the critical damping of one segment's axial mode; ``mu`` seabed friction.

    ``sections`` (optional) makes lines composite: one entry per line, ``None`` for a homogeneous
    line (its properties are the per-line arrays) or a dict of per-section arrays from the anchor
    up (:data:`SECTION_KEYS`: ``L, EA, w, mass, d, Cdn, Cdt, Can, Cat, damping_ratio, mu`` and the
    int ``segments``, shape (n_sections,); optionally ``EA_table``, per section a tension-strain
    table (:class:`~tapm_opt.strain_table.StrainTable`, nonlinear EA) or None, whose ``EA`` is the
    table's secant, the stiffness of the damping ratio) and of per-point arrays (:data:`POINT_KEYS`: ``W`` net
    submerged weight [N] positive down, ``point_mass`` [kg], ``point_volume`` [m^3],
    ``point_CdA`` [m^2], ``point_Ca`` [-], shape (n_sections - 1,), point k joining section k to
    section k + 1). A composite line's ``segments`` is the sum of its sections' and its ``L`` their
    total length; its other per-line values are not used by the FEM.
    """

    ids: tuple[str, ...]
    L: np.ndarray
    EA: np.ndarray
    w: np.ndarray
    mass: np.ndarray
    d: np.ndarray
    Cdn: np.ndarray
    Cdt: np.ndarray
    Can: np.ndarray
    Cat: np.ndarray
    segments: np.ndarray
    damping_ratio: np.ndarray
    mu: np.ndarray
    sections: tuple[dict | None, ...] | None = None


SECTION_KEYS = ("L", "EA", "w", "mass", "d", "Cdn", "Cdt", "Can", "Cat", "damping_ratio", "mu", "segments")
"""Per-section arrays of a composite line in :attr:`LineSet.sections` (from the anchor up)."""

POINT_KEYS = ("W", "point_mass", "point_volume", "point_CdA", "point_Ca")
"""Per-point arrays of a composite line in :attr:`LineSet.sections` (point k joins sections k and k + 1)."""

JOINT_COLUMNS = ("cdn_lo", "cdn_hi", "cdt_lo", "cdt_hi", "can_lo", "can_hi", "cat_lo", "cat_hi", "cda", "m_add")
"""Columns of :attr:`FEMLines.joint_c`, one row per joint node: the normal and tangential drag
(``1/2 rho C d / 2`` per stretched length) and added-mass (``C rho pi d^2/4 / 2`` per stretched
length) factors of the segment below (``lo``) and above (``hi``) the node, applied to each
segment's own stretched length; the point's isotropic drag ``cda = 1/2 rho CdA`` [kg/m] on the
relative velocity and isotropic added mass ``m_add = Ca rho V`` [kg]."""


CurrentField = Callable[[np.ndarray], np.ndarray]
"""Current velocity at node positions: ``f(r) -> v_c``, both (n_nodes, 3) [m, m/s], {E}."""


class FEMLines:
    """State and dynamics of all lumped-mass lines (positions and velocities in {E}).

    Parameters
    ----------
    lines : LineSet
    anchors : ndarray, shape (n_lines, 3)
        Anchor positions in {E} [m] (z down).
    water_depth, rho_w, g : float
        Seabed depth [m], water density [kg/m^3], gravity [m/s^2] (g only enters through w).
    seabed_penetration : float
        Static penetration of a line lying on the seabed under its own weight [m]; sets the
        seabed stiffness ``k_b = w / (d * penetration)`` per unit area. Default 1 cm.
    seabed_damping_ratio : float
        Seabed contact damping as a fraction of critical (per node).
    kernel : {"numba", "numpy"}, optional
        Implementation of :meth:`step` and :meth:`advance`: the compiled kernel
        (:mod:`tapm_opt.plant.fem_kernel`) or the numpy reference; default "numba" (see
        :func:`set_default_kernel`). Without numba the numpy path is used (with a warning);
        :attr:`kernel` tells which one runs.
    """

    def __init__(self, lines: LineSet, anchors: np.ndarray, *, water_depth: float, rho_w: float,
                 seabed_penetration: float = 0.01, seabed_damping_ratio: float = 0.5,
                 kernel: str | None = None):
        self.kernel = _default_kernel if kernel is None else kernel
        self.lines = lines
        self.depth = float(water_depth)
        self.rho_w = float(rho_w)
        nl = len(lines.ids)
        nseg = np.asarray(lines.segments, dtype=int)
        self.n_lines = nl
        self._seg_per_line = nseg
        self.node_start = np.concatenate([[0], np.cumsum(nseg + 1)[:-1]])
        self.n_nodes = int(np.sum(nseg + 1))
        self.anchor_idx = self.node_start.copy()
        self.fairlead_idx = self.node_start + nseg
        self.line_of_node = np.repeat(np.arange(nl), nseg + 1)
        # "bonds": bond i joins node i to node i + 1; the bond from a fairlead to the next line's
        # anchor is not a segment (masked). Segment k of line j is bond node_start[j] + k.
        nb = self.n_nodes - 1
        self.bond_ok = np.ones(nb, dtype=bool)
        self.bond_ok[self.fairlead_idx[:-1]] = False
        self.line_of_bond = self.line_of_node[:-1]
        self.anchor_seg = self.node_start.copy()
        self.fairlead_seg = self.fairlead_idx - 1
        self.anchors = np.asarray(anchors, dtype=float).copy()
        self.L = np.asarray(lines.L, dtype=float).copy()
        self.active = np.ones(nl, dtype=bool)  # False once a line breaks
        self.fixed = np.zeros(self.n_nodes, dtype=bool)
        self.fixed[self.anchor_idx] = True
        self.fixed[self.fairlead_idx] = True
        ls = lines
        ok = self.bond_ok
        lb = self.line_of_bond
        self._EA = np.where(ok, ls.EA[lb], 0.0)
        self._EA_max = self._EA.copy()  # the stiffest slope of each bond (its table's largest)
        self._w = np.where(ok, ls.w[lb], 0.0)
        self._m = np.where(ok, ls.mass[lb], 0.0)
        self._zeta_int = np.where(ok, ls.damping_ratio[lb], 0.0)
        # drag 1/2 rho C d per stretched length, halved: applied to the sum of the two adjacent
        # segments' stretched lengths (twice the node's share)
        self._cdn_node = 0.5 * (0.5 * rho_w * ls.Cdn * ls.d)[self.line_of_node]
        self._cdt_node = 0.5 * (0.5 * rho_w * ls.Cdt * ls.d)[self.line_of_node]
        area = 0.25 * np.pi * ls.d**2
        self._can_half = 0.5 * (ls.Can * rho_w * area)[self.line_of_node]
        self._cat_half = 0.5 * (ls.Cat * rho_w * area)[self.line_of_node]
        self._d_node = ls.d[self.line_of_node]
        self._mu = np.asarray(ls.mu, dtype=float)[self.line_of_node]
        self._setup_sections(ls.sections)
        self._kb_pen = float(seabed_penetration)
        self._zeta_b = float(seabed_damping_ratio)
        self._attached = np.arange(nl)
        self._has_friction = bool(np.any(self._mu))
        # padded bond buffers: row i + 1 holds bond i, rows 0 and n_nodes are zero
        self._qp = np.zeros((self.n_nodes + 1, 3))
        self._no_force_out = np.zeros((0, nl, 3))  # advance without a fairlead-force output
        self._tvp = np.zeros((self.n_nodes + 1, 3))
        self._epsp = np.zeros(self.n_nodes + 1)
        self.r = np.zeros((self.n_nodes, 3))
        self.v = np.zeros((self.n_nodes, 3))
        self.t = 0.0
        self._kc: tuple | None = None  # _kernel_constants
        self._update_lengths()

    @property
    def kernel(self) -> str:
        """Implementation of :meth:`step` and :meth:`advance` in use: "numba" or "numpy"
        (assignable; "numba" falls back to "numpy" when numba is not installed)."""
        return self._kernel

    @kernel.setter
    def kernel(self, kernel: str) -> None:
        if kernel not in KERNELS:
            raise ModelError(f"kernel = {kernel!r} must be one of {', '.join(map(repr, KERNELS))}")
        self._kernel_fn = None
        if kernel == "numba":
            from . import fem_kernel  # imported here: numba loads only when a compiled FEM is built

            if fem_kernel.AVAILABLE:
                self._kernel_fn = fem_kernel.advance
            else:
                kernel = "numpy"
        self._kernel = kernel

    # -- composite lines -------------------------------------------------------------------
    def _setup_sections(self, sections) -> None:
        """Per-bond and per-node properties of the composite lines (:attr:`LineSet.sections`).

        Each section's bonds take its EA, w, mass, internal damping and ``l0 = L_k / n_k``; its
        nodes (the anchor node for the first section, the fairlead node for the last) its drag and
        added-mass factors. A node joining two sections is a *joint* (:attr:`joint_node`,
        :attr:`joint_c`): its drag and added mass are the sum of each adjacent half segment's with
        that segment's own factors and stretched length, plus the point's isotropic drag and added
        mass; its mass and weight gain the point's (:meth:`_update_lengths`). A joint between two
        sections with the same factors and no point is an ordinary node (a line cut into equal
        sections is the homogeneous line, to the bit)."""
        nl, nb = self.n_lines, self.n_nodes - 1
        self.composite = np.zeros(nl, dtype=bool)
        self._sec_bond = np.zeros(nb, dtype=bool)
        self._l0_sec = np.ones(nb)
        self._top_bond = np.zeros(nb, dtype=bool)   # bonds of a composite line's fairlead section
        self._top_L = np.zeros(nl)                  # its length [m] in the line's sections, and segments
        self._top_seg = np.ones(nl, dtype=np.int64)
        self._point_mass = np.zeros(self.n_nodes)  # point mass [kg] and net weight [N] at the joint nodes
        self._point_W = np.zeros(self.n_nodes)
        self._bond_table = np.full(nb, -1, dtype=np.int64)  # index into self.tables, -1: constant EA
        self.tables: list = []
        """The tension-strain tables of the lines' sections (:class:`~tapm_opt.strain_table.StrainTable`)."""
        rows: list[list[float]] = []
        nodes: list[int] = []
        if sections is not None:
            if len(sections) != nl:
                raise ModelError(f"LineSet.sections has {len(sections)} entries, expected one per line ({nl})")
            rho = self.rho_w
            for j, sec in enumerate(sections):
                if sec is None:
                    continue
                lid = self.lines.ids[j]
                missing = [k for k in SECTION_KEYS + POINT_KEYS if k not in sec]
                if missing:
                    raise ModelError(f"sections of line {lid!r} lack {', '.join(missing)}")
                a = {k: np.asarray(sec[k], dtype=float).ravel() for k in SECTION_KEYS + POINT_KEYS}
                ns = a["L"].size
                seg = np.asarray(sec["segments"]).ravel().astype(int)
                if ns < 1 or any(a[k].size != ns for k in SECTION_KEYS) or any(a[k].size != ns - 1 for k in POINT_KEYS):
                    raise ModelError(f"sections of line {lid!r}: every section array needs one value per section "
                                     f"({ns}) and every point array one per joint ({ns - 1})")
                if np.any(seg < 1) or int(seg.sum()) != int(self._seg_per_line[j]):
                    raise ModelError(f"sections of line {lid!r} have {seg.tolist()} segments, which must each be >= 1 "
                                     f"and add up to the line's {int(self._seg_per_line[j])}")
                if not (np.all(a["L"] > 0) and np.all(np.isfinite(a["L"]))):
                    raise ModelError(f"sections of line {lid!r} have lengths {a['L'].tolist()} m, which must be > 0")
                if not math.isclose(float(self.L[j]), float(a["L"].sum()), rel_tol=1e-12):
                    raise ModelError(f"line {lid!r} has L = {float(self.L[j]):g} m, its sections "
                                     f"{float(a['L'].sum()):g} m")
                self.composite[j] = True
                cum = np.concatenate([[0], np.cumsum(seg)])
                b0 = int(self.node_start[j])
                cdn = 0.5 * (0.5 * rho * a["Cdn"] * a["d"])  # the per-line formulas of __init__, per section
                cdt = 0.5 * (0.5 * rho * a["Cdt"] * a["d"])
                area = 0.25 * np.pi * a["d"] ** 2
                can = 0.5 * (a["Can"] * rho * area)
                cat = 0.5 * (a["Cat"] * rho * area)
                tabs = tuple(sec.get("EA_table", ())) or (None,) * ns
                if len(tabs) != ns:
                    raise ModelError(f"sections of line {lid!r}: EA_table has {len(tabs)} entries, expected {ns}")
                for k in range(ns):
                    bonds = slice(b0 + cum[k], b0 + cum[k + 1])
                    self._EA[bonds] = a["EA"][k]
                    self._EA_max[bonds] = a["EA"][k]
                    if tabs[k] is not None:
                        tk = as_table(tabs[k])
                        if tk not in self.tables:
                            self.tables.append(tk)
                        self._bond_table[bonds] = self.tables.index(tk)
                        self._EA_max[bonds] = tk.max_slope
                    self._w[bonds] = a["w"][k]
                    self._m[bonds] = a["mass"][k]
                    self._zeta_int[bonds] = a["damping_ratio"][k]
                    self._sec_bond[bonds] = True
                    self._l0_sec[bonds] = a["L"][k] / seg[k]
                    if k == ns - 1:   # the fairlead section: a winch pays it out and hauls it in
                        self._top_bond[bonds] = True
                        self._top_L[j], self._top_seg[j] = a["L"][k], seg[k]
                    inner = slice(b0 + cum[k] + (0 if k == 0 else 1), b0 + cum[k + 1] + (1 if k == ns - 1 else 0))
                    self._cdn_node[inner] = cdn[k]
                    self._cdt_node[inner] = cdt[k]
                    self._can_half[inner] = can[k]
                    self._cat_half[inner] = cat[k]
                    self._d_node[inner] = a["d"][k]
                    self._mu[inner] = a["mu"][k]
                for k in range(ns - 1):  # point k joins section k (below) and k + 1 (above)
                    i = b0 + int(cum[k + 1])
                    lo, hi = k, k + 1
                    share = np.abs([a["w"][lo] * a["L"][lo] / seg[lo], a["w"][hi] * a["L"][hi] / seg[hi]])
                    mus = np.array([a["mu"][lo], a["mu"][hi]])
                    self._mu[i] = float(share @ mus / share.sum()) if share.sum() > 0 else float(mus.mean())
                    self._d_node[i] = 0.5 * (a["d"][lo] + a["d"][hi])
                    m_add = a["point_Ca"][k] * rho * a["point_volume"][k]
                    cda = 0.5 * rho * a["point_CdA"][k]
                    self._point_mass[i] = a["point_mass"][k]
                    self._point_W[i] = a["W"][k]
                    row = [cdn[lo], cdn[hi], cdt[lo], cdt[hi], can[lo], can[hi], cat[lo], cat[hi], cda, m_add]
                    if row[0::2][:4] == row[1::2][:4] and cda == 0.0 and m_add == 0.0:
                        # the same factors both sides and no point's drag or added mass: an ordinary node
                        self._cdn_node[i], self._cdt_node[i] = cdn[lo], cdt[lo]
                        self._can_half[i], self._cat_half[i] = can[lo], cat[lo]
                        continue
                    self._cdn_node[i] = 0.5 * (cdn[lo] + cdn[hi])  # not used at a joint (joint_c is)
                    self._cdt_node[i] = 0.5 * (cdt[lo] + cdt[hi])
                    self._can_half[i] = 0.5 * (can[lo] + can[hi])
                    self._cat_half[i] = 0.5 * (cat[lo] + cat[hi])
                    nodes.append(i)
                    rows.append(row)
        self._L_composite = np.where(self.composite, self.L, np.nan)  # the lengths _update_lengths keeps
        self.joint_node = np.array(nodes, dtype=np.int64)
        """Nodes joining two sections of a composite line that differ or carry a point (n_joints,)."""
        self.joint_c = np.array(rows, dtype=float).reshape(len(rows), len(JOINT_COLUMNS))
        """Drag and added-mass factors of each joint node, columns :data:`JOINT_COLUMNS`."""
        self._joint_c4 = self.joint_c[:, :8].reshape(-1, 4, 2)  # (lo, hi) of cdn, cdt, can, cat
        self._joint_bonds = np.column_stack([self.joint_node, self.joint_node + 1])  # rows of epsp: below, above
        self._has_points = bool(np.any(self._point_mass) or np.any(self._point_W))
        # the tables packed for the compiled kernel: rows (strain, tension, slope of the segment from
        # the row; the last row's is the last segment's), each bond's rows [start, stop) or (-1, -1)
        packed, start = [], [0]
        for tk in self.tables:
            packed.append(np.column_stack([tk.strain, tk.tension, np.r_[tk.slope, tk.slope[-1]]]))
            start.append(start[-1] + tk.strain.size)
        self._tab = np.ascontiguousarray(np.concatenate(packed) if packed else np.zeros((0, 3)))
        self._tab_idx = np.full((nb, 2), -1, dtype=np.int64)
        on = self._bond_table >= 0
        self._tab_idx[on, 0] = np.asarray(start[:-1], dtype=np.int64)[self._bond_table[on]]
        self._tab_idx[on, 1] = np.asarray(start[1:], dtype=np.int64)[self._bond_table[on]]
        self._has_tables = bool(on.any())

    def _table_tension(self, T: np.ndarray, strain: np.ndarray, bonds: np.ndarray | None) -> None:
        """The tension of the bonds of tension-strain tables (in ``T``, in place) from their strain:
        ``T_j + s_j (e - e_j)`` on the row j at or below ``e`` (the first row below the table, the
        segment before the last row beyond it), in the compiled kernel's operations."""
        tid = self._bond_table if bonds is None else self._bond_table[bonds]
        for k, tk in enumerate(self.tables):
            m = tid == k
            if m.any():
                e = strain[m]
                j = np.clip(np.searchsorted(tk.strain, e, side="right") - 1, 0, tk.strain.size - 2)
                T[m] = tk.tension[j] + tk.slope[j] * (e - tk.strain[j])

    def _node_factors(self, epsp: np.ndarray) -> tuple[np.ndarray, ...]:
        """Per node, for the padded stretched bond lengths ``epsp`` (n_nodes + 1,): the normal and
        tangential drag factors on the node's stretched length (``1/2 rho C d`` times it, the
        squared relative speed still to come) and the node's mass normal and tangential to its
        tangent [kg] (structural, point and added mass), and twice the nodes' stretched lengths. At
        a joint each adjacent segment's own factors on its own stretched length (the kernel's
        ``_joints``, in its order)."""
        stretched = epsp[1:] + epsp[:-1]
        cn = self._cdn_node * stretched
        ct = self._cdt_node * stretched
        mn = self.node_mass + self._can_half * stretched
        mt = self.node_mass + self._cat_half * stretched
        jn = self.joint_node
        if jn.size:  # (n_joints, 4): lo * e_lo + hi * e_hi of the drag and added-mass factors
            f = (self._joint_c4 * epsp[self._joint_bonds][:, None, :]).sum(axis=2)
            cn[jn] = f[:, 0]
            ct[jn] = f[:, 1]
            mj, ma = self.node_mass[jn], self.joint_c[:, 9]
            mn[jn] = mj + f[:, 2] + ma
            mt[jn] = mj + f[:, 3] + ma
        return cn, ct, mn, mt, stretched

    # -- geometry and constants ------------------------------------------------------------
    def _update_lengths(self) -> None:
        """Recompute per-segment/per-node constants from the current unstretched lengths L (a
        composite line's change of ``L`` is its fairlead section's: a winch pays that section out
        and hauls it in, the other sections keep their lengths)."""
        ok = self.bond_ok
        self.l0 = np.where(ok, (self.L / self._seg_per_line)[self.line_of_bond], 1.0)  # (n_bonds,)
        if self.composite.any():
            # a composite line's winch pays out its fairlead section: the other sections keep theirs
            top_L = np.where(self.composite, self._top_L + (self.L - self._L_composite), 1.0)
            if not np.all(top_L > 0.0):
                j = int(np.argmax(~(top_L > 0.0)))
                raise ModelError(f"line {self.lines.ids[j]!r} is a composite line of {self._L_composite[j]:g} m whose "
                                 f"fairlead section is {self._top_L[j]:g} m: its length cannot change to "
                                 f"{self.L[j]:g} m (the winch would haul in more than that section)")
            l0_sec = self._l0_sec.copy()
            tb = self._top_bond
            lb = self.line_of_bond[tb]
            l0_sec[tb] = top_L[lb] / self._top_seg[lb]
            self.l0[self._sec_bond] = l0_sec[self._sec_bond]
        l0 = np.where(ok, self.l0, 0.0)
        self.node_len = 0.5 * (np.append(l0, 0.0) + np.insert(l0, 0, 0.0))  # unstretched length per node
        ml = self._m * l0
        wl = self._w * l0
        self.node_mass = 0.5 * (np.append(ml, 0.0) + np.insert(ml, 0, 0.0))
        self.node_weight = 0.5 * (np.append(wl, 0.0) + np.insert(wl, 0, 0.0))
        k_ax = self._EA / self.l0
        self._c_int = self._zeta_int * 2.0 * np.sqrt(k_ax * 0.5 * self._m * l0) * self.l0  # [N s] on strain rate
        self._has_int_damping = bool(np.any(self._c_int))
        # node spring [N/m]: static penetration = seabed_penetration under the node's weight; a
        # buoyant section's node (w < 0, it rises off the seabed) gets the spring its weight's
        # magnitude would, so the seabed stays as stiff under it if it is pushed down
        wl_abs = np.abs(wl)
        kb_w = 0.5 * (np.append(wl_abs, 0.0) + np.insert(wl_abs, 0, 0.0))
        if self._has_points:
            # a clump's weight presses its node into the seabed (the spring keeps the penetration);
            # a buoy's lift does not soften the seabed under the line's own weight
            self._kb = (kb_w + np.maximum(self._point_W, 0.0)) / self._kb_pen
            self.node_mass = self.node_mass + self._point_mass
            self.node_weight = self.node_weight + self._point_W
        else:
            self._kb = kb_w / self._kb_pen
        self._cb = self._zeta_b * 2.0 * np.sqrt(self._kb * self.node_mass)

    def stable_dt(self, safety: float = 0.8, extra_damping: float = 0.0) -> float:
        """Largest stable step of the symplectic Euler scheme [s], times ``safety``.

        Derivation (see docs/plant.md, "Time step"). For one mode ``x'' + 2 zeta w x' + w^2 x = 0``
        stepped as ``v+ = v + h (-w^2 x - 2 zeta w v)``, ``x+ = x + h v+`` (damping on the old
        velocity, as :meth:`step` does), the amplification matrix has trace ``2 - W^2 - 2 zeta W``
        and determinant ``1 - 2 zeta W`` with ``W = w h``; the Jury conditions give stability iff

            W <= 2 (sqrt(1 + zeta^2) - zeta).

        The internal damping is stiffness-proportional (segment damper ``c = beta k`` with
        ``beta = c_int / EA``), so a mode of frequency w is damped at ``zeta = beta w / 2``: the
        stiffest (zig-zag) axial mode carries more damping than the per-segment ratio (sqrt(2)
        times it on a uniform line). The mass-proportional settling damping ``extra_damping``
        [1/s] adds ``alpha / (2 w)``. Per free node, w and zeta of the axial modes are bounded by
        the Gershgorin row sums of the stiffness and damping matrices, ``w^2 <= 2 (k_below +
        k_above) / m`` and ``2 zeta w <= 2 (c_below + c_above) / m + alpha``, and the bound on W is
        evaluated at that w and zeta (W grows and the limit falls with w, so the bound is safe).
        The seabed contact mode (vertical spring-damper ``k_seabed``, ``c_seabed`` per node) is
        bounded the same way on its own: it acts across the grounded, horizontal segments, so it
        does not add to their axial modes. Added mass only lowers the transverse frequencies; drag
        (quadratic, explicit) is left out; seabed friction is implicit (:meth:`_friction`).
        On composite lines every bond has its own section's stiffness and damping and every node
        its own mass, a joint's with the point's mass: the bound is per node as on a homogeneous
        line (a joint is no stiffer than the interior nodes of its two sections, a point only adds
        mass).
        """
        free = ~self.fixed
        m_node = np.maximum(self.node_mass, 1e-300)[free]
        ok = self.bond_ok
        k_ax = np.where(ok, self._EA_max / self.l0, 0.0)  # a table's stiffest slope
        c_ax = np.where(ok, self._c_int / self.l0, 0.0)
        k_row = (2.0 * (np.append(k_ax, 0.0) + np.insert(k_ax, 0, 0.0)))[free]
        c_row = (2.0 * (np.append(c_ax, 0.0) + np.insert(c_ax, 0, 0.0)))[free]
        if not k_row.size:
            return float(safety)
        alpha = float(extra_damping)

        def limit(k, c):
            on = k > 0.0
            if not on.any():
                return math.inf
            m = m_node[on]
            omega = np.sqrt(k[on] / m)
            zeta = (c[on] / m + alpha) / (2.0 * omega)
            return float(np.min(2.0 * (np.sqrt(1.0 + zeta * zeta) - zeta) / omega))

        return float(safety * min(limit(k_row, c_row), limit(self._kb[free], self._cb[free])))

    # -- forces ----------------------------------------------------------------------------
    def segment_state(self, r: np.ndarray, v: np.ndarray, bonds: np.ndarray | None = None):
        """Bond vectors toward the upper node, stretched lengths [m] and tensions [N] (tension only,
        with internal damping; 0 on non-segments) of every bond, shape (n_nodes-1, 3) and
        (n_nodes-1,), or of the bonds ``bonds`` only.

        Segment k of line j is bond ``node_start[j] + k``.
        """
        if bonds is None:
            lv = r[1:] - r[:-1]
            l0, EA, c = self.l0, self._EA, self._c_int
        else:
            lv = r[bonds + 1] - r[bonds]
            l0, EA, c = self.l0[bonds], self._EA[bonds], self._c_int[bonds]
        eps = np.sqrt((lv * lv).sum(axis=1))
        strain = eps / l0 - 1.0
        T = EA * strain
        if self._has_tables:
            self._table_tension(T, strain, bonds)
        if self._has_int_damping:
            dv = v[1:] - v[:-1] if bonds is None else v[bonds + 1] - v[bonds]
            T += c * (dv * lv).sum(axis=1) / (eps * l0)
        np.maximum(T, 0.0, out=T)
        T[strain <= 0.0] = 0.0
        return lv, eps, T

    def accelerations(self, r: np.ndarray, v: np.ndarray, v_current: np.ndarray):
        """Node accelerations [m/s^2] (n_nodes, 3) and bond tensions [N] (n_nodes - 1,).

        Drag and added mass use the node tangent q (normalised sum of the adjacent segment
        tangents) and the node's share of stretched length (half of each adjacent segment).
        """
        lv, eps, T = self.segment_state(r, v)
        qp, tvp, epsp = self._qp, self._tvp, self._epsp
        inv = self.bond_ok / eps
        q = qp[1:-1]
        np.multiply(lv, inv[:, None], out=q)
        np.multiply(T[:, None], q, out=tvp[1:-1])
        np.multiply(eps, self.bond_ok, out=epsp[1:-1])
        F = tvp[1:] - tvp[:-1]
        F[:, 2] += self.node_weight
        qn = qp[1:] + qp[:-1]
        qn /= np.sqrt((qn * qn).sum(axis=1))[:, None]
        cn, ct, mn, mt, _ = self._node_factors(epsp)  # drag factors and masses (a joint: each half segment's)
        jn = self.joint_node
        # Morison drag on the relative velocity, normal and tangential to the node tangent
        vr = v - v_current
        vt = (vr * qn).sum(axis=1)
        vn = vr - vt[:, None] * qn
        vn_mag = np.sqrt((vn * vn).sum(axis=1))
        F -= (cn * vn_mag)[:, None] * vn
        F -= (ct * np.abs(vt) * vt)[:, None] * qn
        if jn.size:  # the points' isotropic drag 1/2 rho CdA |v_r| v_r
            vrj = vr[jn]
            F[jn] -= (self.joint_c[:, 8] * np.sqrt((vrj * vrj).sum(axis=1)))[:, None] * vrj
        # seabed contact
        pen = r[:, 2] - self.depth
        on = pen > 0.0
        if on.any():
            Fn = np.maximum(self._kb * pen + self._cb * v[:, 2], 0.0)
            Fn[~on] = 0.0
            F[:, 2] -= Fn
        # closed-form inverse of m I + m_an (I - q q^T) + m_at q q^T
        Ft = (F * qn).sum(axis=1)
        a = (F - Ft[:, None] * qn) * (1.0 / mn)[:, None]
        a += (Ft / mt)[:, None] * qn
        return a, T

    # -- integration -----------------------------------------------------------------------
    def step(self, dt: float, fairlead_r: np.ndarray, fairlead_v: np.ndarray, v_current: np.ndarray,
             extra_damping: float = 0.0):
        """Advance one symplectic-Euler step with prescribed fairlead motion.

        Parameters
        ----------
        dt : float
            Step [s] (at most :meth:`stable_dt`).
        fairlead_r, fairlead_v : ndarray, shape (n_lines, 3)
            Fairlead positions [m] and velocities [m/s] in {E} at the end of the step.
        v_current : ndarray, shape (n_nodes, 3)
            Current velocity at each node [m/s].
        extra_damping : float
            Mass-proportional damping rate [1/s] (used only to settle the lines).

        Returns
        -------
        T : ndarray (n_nodes - 1,)
            Bond tensions at the start of the step [N].

        :attr:`r` and :attr:`v` are replaced by new arrays (the old ones are left as they were).
        """
        if self._kernel_fn is not None:
            shape = (self.n_lines, 3)
            return self._advance_compiled(dt, _as_f64(fairlead_r, shape, "fairlead_r")[None],
                                          _as_f64(fairlead_v, shape, "fairlead_v")[None],
                                          v_current, extra_damping, 1, None)
        return self._step_numpy(dt, fairlead_r, fairlead_v, v_current, extra_damping)

    def advance(self, dt: float, fairlead_r_seq: np.ndarray, fairlead_v_seq: np.ndarray,
                v_current: np.ndarray, extra_damping: float = 0.0,
                fairlead_force_out: np.ndarray | None = None) -> np.ndarray:
        """``n`` steps of :meth:`step` with the fairleads on a prescribed path, in one call.

        Parameters
        ----------
        dt : float
            Step [s] (at most :meth:`stable_dt`).
        fairlead_r_seq, fairlead_v_seq : ndarray, shape (n, n_lines, 3)
            Fairlead positions [m] and velocities [m/s] in {E} at the end of each step, n >= 1.
        v_current : ndarray, shape (n_nodes, 3)
            Current velocity at each node [m/s], held over the n steps.
        extra_damping : float
            Mass-proportional damping rate [1/s].
        fairlead_force_out : ndarray (n, n_lines, 3), optional
            Filled with :meth:`fairlead_forces` (``v_current`` at the fairleads, no inertia) at the
            start of every step [N]: the load on the vessel along the path, for energy integrals.

        Returns
        -------
        T : ndarray (n_nodes - 1,)
            Bond tensions at the start of the last step [N].

        The same as n calls of :meth:`step` with the same ``v_current``; the compiled kernel runs
        all n steps in one call, the numpy path loops over :meth:`step`.
        """
        r_seq = np.asarray(fairlead_r_seq, dtype=float)
        v_seq = np.asarray(fairlead_v_seq, dtype=float)
        if r_seq.ndim != 3 or r_seq.shape[1:] != (self.n_lines, 3) or v_seq.shape != r_seq.shape:
            raise ModelError(f"fairlead_r_seq and fairlead_v_seq have shapes {r_seq.shape} and {v_seq.shape}, "
                             f"expected (n_steps, {self.n_lines}, 3)")
        n = r_seq.shape[0]
        if n < 1:
            raise ModelError("advance needs at least one step (fairlead sequences of length 0)")
        if fairlead_force_out is not None and (fairlead_force_out.shape != r_seq.shape
                                               or fairlead_force_out.dtype != np.float64):
            raise ModelError(f"fairlead_force_out has shape {fairlead_force_out.shape}, expected {r_seq.shape} (float64)")
        if self._kernel_fn is not None:
            return self._advance_compiled(dt, _as_f64(r_seq, r_seq.shape, "fairlead_r_seq"),
                                          _as_f64(v_seq, v_seq.shape, "fairlead_v_seq"), v_current, extra_damping, n,
                                          fairlead_force_out)
        vc_fl = np.broadcast_to(np.asarray(v_current, dtype=float), (self.n_nodes, 3))[self.fairlead_idx]
        for i in range(n):
            if fairlead_force_out is not None:
                fairlead_force_out[i] = self.fairlead_forces(vc_fl)
            T = self._step_numpy(dt, r_seq[i], v_seq[i], v_current, extra_damping)
        return T

    def _advance_compiled(self, dt, r_seq, v_seq, v_current, extra_damping, n: int,
                          force_out: np.ndarray | None) -> np.ndarray:
        """n steps in one call of the compiled kernel (fairlead sequences already checked)."""
        shape = (self.n_nodes, 3)
        if force_out is None:
            force_out = self._no_force_out
            if force_out.shape[1] != self.n_lines:
                force_out = self._no_force_out = np.zeros((0, self.n_lines, 3))
        self.r, self.v, T = self._kernel_fn(
            _as_f64(self.r, shape, "r"), _as_f64(self.v, shape, "v"), _as_f64(v_current, shape, "v_current"),
            float(dt), float(extra_damping), r_seq, v_seq, *self._kernel_constants(), force_out)
        if force_out.shape[0]:
            force_out[:, ~self.active] = 0.0
        for _ in range(n):  # the same sum as n single steps
            self.t += dt
        return T

    def _kernel_constants(self) -> tuple:
        """The line constants, in the order the compiled kernels take them
        (:func:`tapm_opt.plant.fem_kernel.advance`, from ``l0`` to ``attached``): one tuple, kept
        while the lengths (:meth:`_update_lengths`, a new ``l0``) and the attached lines
        (:meth:`break_line`, a new ``_attached``) stay."""
        c = self._kc
        if c is not None and c[0] is self.l0 and c[-1] is self._attached:
            return c
        c = self._kc = (self.l0, self._EA, self._tab_idx, self._tab, self._c_int, self.bond_ok, self.node_weight, self.node_mass,
                self._cdn_node, self._cdt_node, self._can_half, self._cat_half, self.joint_node, self.joint_c,
                self._kb, self._cb, self._mu,
                float(self.depth), bool(self._has_int_damping), bool(self._has_friction),
                self.anchor_idx, self.anchors, self.fairlead_idx, self._attached)
        return c

    def _friction(self, v_new: np.ndarray, dt: float) -> None:
        """Coulomb seabed friction on the new velocities ``v_new`` (in place), applied implicitly.

        A node on the seabed (state at the start of the step) with normal force ``F_n`` can lose
        at most ``dv = dt mu F_n / m_t`` of horizontal speed in the step (``m_t`` its mass with the
        tangential added mass): if its horizontal speed is below that it sticks (0), otherwise it
        slides with its speed reduced by ``dv``. Friction acts on the velocity relative to the
        seabed and cannot reverse a motion, so it sets no limit on the step.
        """
        pen = self.r[:, 2] - self.depth
        Fn = np.where(pen > 0.0, np.maximum(self._kb * pen + self._cb * self.v[:, 2], 0.0), 0.0)
        dv = dt * self._mu * Fn / self._node_factors(self._epsp)[3]
        vh = v_new[:, :2]
        sp = np.sqrt((vh * vh).sum(axis=1))
        act = dv > 0.0
        scale = np.where(act & (sp > dv), 1.0 - dv / np.where(sp > 0.0, sp, 1.0), 1.0)
        scale = np.where(act & (sp <= dv), 0.0, scale)
        vh *= scale[:, None]

    def _step_numpy(self, dt, fairlead_r, fairlead_v, v_current, extra_damping=0.0):
        """The numpy reference of :meth:`step`."""
        a, T = self.accelerations(self.r, self.v, v_current)
        if extra_damping:
            a -= extra_damping * self.v
        v = self.v + dt * a
        if self._has_friction:
            self._friction(v, dt)
        v[self.anchor_idx] = 0.0
        att = self._attached
        v[self.fairlead_idx[att]] = fairlead_v[att]
        r = self.r + dt * v
        r[self.anchor_idx] = self.anchors
        r[self.fairlead_idx[att]] = fairlead_r[att]
        self.r, self.v = r, v
        self.t += dt
        return T

    def joint_node_index(self, j: int, k: int) -> int:
        """The node of composite line ``j`` where its point ``k`` joins section k to section k + 1
        (flat node index). :class:`~tapm_opt.errors.ModelError` for a homogeneous line or a ``k``
        outside 0 .. n_sections - 2."""
        sec = self.lines.sections[j] if self.lines.sections is not None else None
        if sec is None or not self.composite[j]:
            raise ModelError(f"line {self.lines.ids[j]!r} is homogeneous: it has no joints")
        seg = np.asarray(sec["segments"]).ravel().astype(int)
        if not (isinstance(k, (int, np.integer)) and not isinstance(k, (bool, np.bool_)) and 0 <= k < seg.size - 1):
            raise ModelError(f"joint {k!r} of line {self.lines.ids[j]!r} must be a whole number from 0 to "
                             f"{seg.size - 2} (its {seg.size} sections from the anchor up)")
        return int(self.node_start[j] + np.sum(seg[:k + 1]))

    def lose_point(self, j: int, k: int) -> None:
        """The point at joint ``k`` of composite line ``j`` comes off (a buoy or clump lost): from
        now on its node carries no point mass, net weight, added mass or drag, only the half
        segments of its two sections (the seabed spring under it goes back to theirs). The stable
        step may shrink (the node is lighter): :meth:`stable_dt` tells the new one.
        :class:`~tapm_opt.errors.ModelError` when the joint carries no point."""
        i = self.joint_node_index(j, k)
        row = np.flatnonzero(self.joint_node == i)
        has = self._point_mass[i] != 0.0 or self._point_W[i] != 0.0 or (
            row.size and np.any(self.joint_c[row[0], 8:10] != 0.0))
        if not has:
            raise ModelError(f"joint {k} of line {self.lines.ids[j]!r} carries no point to lose")
        self._point_mass = self._point_mass.copy()
        self._point_W = self._point_W.copy()
        self._point_mass[i] = 0.0
        self._point_W[i] = 0.0
        if row.size:  # the point's isotropic drag and added mass (new arrays: a kernel may hold the old)
            jc = self.joint_c.copy()
            jc[row[0], 8:10] = 0.0
            self.joint_c = jc
        self._has_points = bool(np.any(self._point_mass) or np.any(self._point_W))
        self._update_lengths()   # node mass, weight and seabed spring without the point; a new l0

    def break_line(self, j: int) -> None:
        """Line j breaks at its fairlead: it no longer acts on the vessel and its upper end falls free.

        The line keeps its own internal tension as it falls; its reported fairlead tension is 0.
        """
        self.active[j] = False
        self.fixed[self.fairlead_idx[j]] = False
        self._attached = np.flatnonzero(self.active)

    # -- outputs ---------------------------------------------------------------------------
    def fairlead_forces(self, v_current: np.ndarray | None = None,
                        a_fairlead: np.ndarray | None = None) -> np.ndarray:
        """Force of each line on its fairlead point in {E} [N], shape (n_lines, 3).

        The vessel carries the fairlead's lumped node (half the top segment), so the load is the
        net force of the line and the water on that node, less its inertia:

        * the top segment's tension along the segment toward the anchor;
        * the node's submerged weight;
        * the Morison drag on the node's half segment (normal and tangential to the top segment,
          on the fairlead velocity relative to ``v_current`` at the fairlead, (n_lines, 3) [m/s];
          still water when None) — as on every other node;
        * ``- M a_fairlead``: the node's structural mass and its added mass (normal ``C_MN``,
          tangential ``C_MT``) times the fairlead acceleration (n_lines, 3) [m/s^2], when given.

        Zero for a broken line. See docs/plant.md, "Load on the vessel".
        """
        fl = self.fairlead_idx
        lv, eps, T = self.segment_state(self.r, self.v, self.fairlead_seg)
        q = lv / eps[:, None]
        f = -T[:, None] * q
        f[:, 2] += self.node_weight[fl]
        vr = self.v[fl] if v_current is None else self.v[fl] - v_current
        vt = (vr * q).sum(axis=1)
        vn = vr - vt[:, None] * q
        vn_mag = np.sqrt((vn * vn).sum(axis=1))
        f -= (self._cdn_node[fl] * eps * vn_mag)[:, None] * vn
        f -= (self._cdt_node[fl] * eps * np.abs(vt) * vt)[:, None] * q
        if a_fairlead is not None:
            a = np.asarray(a_fairlead, dtype=float)
            at = (a * q).sum(axis=1)
            an = a - at[:, None] * q
            f -= (self.node_mass[fl] + self._can_half[fl] * eps)[:, None] * an
            f -= ((self.node_mass[fl] + self._cat_half[fl] * eps) * at)[:, None] * q
        f[~self.active] = 0.0
        return f

    def fairlead_tension(self) -> np.ndarray:
        """Fairlead tension of each line [N]: magnitude of the top segment's tension vector plus
        the fairlead node's weight (the static part of :meth:`fairlead_forces`; no drag or
        inertia). 0 for a broken line."""
        if self._kernel_fn is not None:
            return self.end_tensions()[0]
        lv, eps, T = self.segment_state(self.r, self.v, self.fairlead_seg)
        f = -(T / eps)[:, None] * lv
        f[:, 2] += self.node_weight[self.fairlead_idx]
        out = np.sqrt((f * f).sum(axis=1))
        out[~self.active] = 0.0
        return out

    def anchor_tension(self, T: np.ndarray | None = None) -> np.ndarray:
        """Anchor tension of each line: tension of the segment at the anchor [N] (from the bond
        tensions ``T`` when given, else evaluated on the bottom segments only)."""
        if T is not None:
            return T[self.anchor_seg]
        if self._kernel_fn is not None:
            return self.end_tensions()[1]
        return self.segment_state(self.r, self.v, self.anchor_seg)[2]

    def section_top_bonds(self) -> tuple[tuple[int, int, int], ...]:
        """The sections below the fairlead section of every line of more than one section, each
        as ``(line j, section k, bond b)``: section k counted from the anchor up from 0 (the
        scenario's ``sections`` order), ``b`` its top segment (the bond just below joint k,
        :meth:`joint_node_index`). Lines in order, sections from the anchor up; empty without
        such lines."""
        out = []
        secs = self.lines.sections
        for j in range(self.n_lines):
            sec = secs[j] if secs is not None else None
            if sec is None:
                continue
            n = int(np.asarray(sec["segments"]).size)
            out += [(j, k, self.joint_node_index(j, k) - 1) for k in range(n - 1)]
        return tuple(out)

    def section_tension(self, bonds: np.ndarray, lines: np.ndarray) -> np.ndarray:
        """Tension at the upper end of sections [N], each given by its top segment ``bonds`` and
        its line ``lines`` (:meth:`section_top_bonds`): :meth:`fairlead_tension`'s definition one
        section down, the magnitude of the top segment's tension vector (tension only, with the
        internal damping) plus the submerged weight of its upper half ``w l0 / 2``, i.e. the
        tension at the section's top end, just below the joint (a point there is not included:
        it acts on the joint, above the section's end). 0 on a broken line (as its fairlead)."""
        bonds = np.asarray(bonds, dtype=np.int64)
        if bonds.size == 0:
            return np.zeros(0)
        if self._kernel_fn is not None:   # the compiled kernel: the same operations in one call
            from . import fem_kernel

            shape = (self.n_nodes, 3)
            return fem_kernel.section_tensions(_as_f64(self.r, shape, "r"), _as_f64(self.v, shape, "v"), self.l0,
                                               self._EA, self._tab_idx, self._tab, self._c_int,
                                               bool(self._has_int_damping), self._w, bonds,
                                               np.asarray(lines, dtype=np.int64), self.active)
        lv, eps, T = self.segment_state(self.r, self.v, bonds)
        f = -(T / eps)[:, None] * lv
        f[:, 2] += 0.5 * self._w[bonds] * self.l0[bonds]
        out = np.sqrt((f * f).sum(axis=1))
        out[~self.active[np.asarray(lines, dtype=np.int64)]] = 0.0
        return out

    def end_tensions(self) -> tuple[np.ndarray, np.ndarray]:
        """(:meth:`fairlead_tension`, :meth:`anchor_tension`) [N], each (n_lines,), in one pass: the
        compiled :func:`tapm_opt.plant.fem_kernel.end_tensions` with the "numba" kernel (the same
        operations in the same order), else the numpy path of each."""
        if self._kernel_fn is None:
            return self.fairlead_tension(), self.anchor_tension()
        from . import fem_kernel  # loaded with the compiled FEM already

        shape = (self.n_nodes, 3)
        return fem_kernel.end_tensions(_as_f64(self.r, shape, "r"), _as_f64(self.v, shape, "v"), self.l0, self._EA,
                                       self._tab_idx, self._tab,
                                       self._c_int, bool(self._has_int_damping), self.node_weight, self.fairlead_seg,
                                       self.fairlead_idx, self.anchor_seg, self.active)

    def energy(self) -> float:
        """Mechanical energy of the lines [J]: kinetic (structural mass) + elastic + gravitational.

        The gravitational part uses the submerged weight with z down (potential -w z). Excludes
        added mass; used for health checks and tests.
        """
        lv, eps, T = self.segment_state(self.r, self.v)
        strain = np.maximum(eps / self.l0 - 1.0, 0.0)
        if not self.tables:
            elastic = 0.5 * np.sum(self._EA * strain**2 * self.l0 * self.bond_ok)
        else:  # a table's bonds: its strain energy int_0^e T de
            density = 0.5 * self._EA * strain**2
            for k, tk in enumerate(self.tables):
                m = self._bond_table == k
                density[m] = tk.strain_energy(strain[m])
            elastic = np.sum(density * self.l0 * self.bond_ok)
        kin = 0.5 * np.sum(self.node_mass * np.einsum("ij,ij->i", self.v, self.v))
        pot = -np.sum(self.node_weight * self.r[:, 2])
        return float(kin + elastic + pot)

    def check_health(self) -> None:
        """Raise :class:`SimulationDiverged` if any node state is non-finite or absurdly fast."""
        bad = ~np.isfinite(self.r).all(axis=1) | ~np.isfinite(self.v).all(axis=1)
        fast = np.einsum("ij,ij->i", self.v, self.v) > MAX_NODE_SPEED**2
        bad |= fast
        if np.any(bad):
            i = int(np.argmax(bad))
            j = int(self.line_of_node[i])
            k = int(i - self.node_start[j])
            what = "non-finite" if not np.isfinite(self.r[i]).all() or not np.isfinite(self.v[i]).all() else \
                f"unphysical speed {np.linalg.norm(self.v[i]):.3g} m/s"
            raise SimulationDiverged(
                f"FEM mooring state {what} at t = {self.t:.3f} s, line {self.lines.ids[j]!r}, node {k}; "
                "reduce the time step (a smaller 'safety' factor), use fewer segments, or check the "
                "line properties (EA, mass) and the imposed fairlead motion",
                time=self.t, line=self.lines.ids[j], node=k)
