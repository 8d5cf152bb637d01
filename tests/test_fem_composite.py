"""The FEM plant on composite mooring lines (sections joined by points with a clump or a buoy).

* settled at rest, the fairlead tensions and the points' positions approach the quasi-static
  composite solution (:mod:`tapm_opt.models.composite`) as the segments are refined;
* a line cut into sections of its own type with plain joints, and a one-section line, are the
  homogeneous line to the bit;
* a buoy's node sits above its neighbours, a clump's below, and the vertical forces on the joint
  node balance its net weight W;
* under forced surge the fairlead tensions follow MoorDyn-C's, the sections written as MoorDyn
  lines joined by free points (mass, volume, CdA, Ca);
* the stable step honours the stiffest section and the light points; the two kernels agree; a
  composite line refuses a length change (no winch) while the homogeneous lines beside it winch.

``moordyn`` is a test dependency: its absence fails the MoorDyn test instead of skipping it.
"""

from __future__ import annotations

import dataclasses
import math
import types

import numpy as np
import pytest

from tapm_opt.config import load_scenario, scenario_from_dict, scenario_to_dict
from tapm_opt.config import moordyn as md_config
from tapm_opt.errors import ModelError
from tapm_opt.models import composite
from tapm_opt.plant.fem import FEMLines
from tapm_opt.plant.forced_motion import forced_motion
from tapm_opt.plant.mooring_fem import MooringFEM, line_set_from_scenario

ZERO = np.zeros(3)

CHAIN = {"id": "chain137", "diameter": 0.2466, "mass_per_length": 373.5, "submerged_weight": 3185.6,
         "EA": 1.603e9, "MBS": 16.99e6, "MBS_std": 8.5e5, "Cd_normal": 2.4, "Cd_tangential": 1.15,
         "Ca_normal": 1.0, "Ca_tangential": 0.5, "axial_damping_ratio": 0.7071}
"""R4 studless chain 137 mm (fpso's header: OrcaFlex chain, hydrodynamic diameter 1.8 d)."""
WIRE = {"id": "wire165", "diameter": 0.165, "mass_per_length": 108.6, "submerged_weight": 926.4, "EA": 1.100e9,
        "MBS": 17.24e6, "MBS_std": 8.6e5, "Cd_normal": 1.2, "Cd_tangential": 0.025, "Ca_normal": 1.0,
        "axial_damping_ratio": 0.7071}
"""IWRC wire 165 mm (fpso's header)."""
BUOY = {"id": "buoy", "mass": 5000.0, "volume": 40.0, "CdA": 20.0, "Ca": 1.0}
"""A submerged buoy: net buoyancy (1025 x 40 - 5000) x 9.81 = 353 kN."""
CLUMP = {"id": "clump", "mass": 20000.0, "volume": 2.6, "CdA": 5.0, "Ca": 1.0}
"""A 20 t steel clump weight: net weight 170 kN."""


def composite_fpso(*, lower: str | None = "buoy", upper: str | None = None, lines: tuple[int, ...] | None = None,
                   segments: tuple[int, int, int] | None = None):
    """fpso_equivalent (fpso's former homogeneous mooring, 1970 m anchor circle) with its lines as
    the chain-wire-chain they stand for (300 m chain, 1900 m wire, 100 m chain from the anchor up),
    point types ``lower`` and ``upper`` at the two joints, only the lines ``lines`` (indices) when
    given, each section's ``segments`` when given. (fpso itself is composite, without points and
    on a wider anchor circle.)"""
    d = scenario_to_dict(load_scenario("fpso_equivalent"))
    d["line_types"] += [dict(CHAIN), dict(WIRE)]
    d["point_types"] = [dict(BUOY), dict(CLUMP)]
    if lines is not None:
        d["lines"] = [d["lines"][i] for i in lines]
    seg = segments or (None, None, None)
    for ln in d["lines"]:
        del ln["type"], ln["length"]
        for k in ("winch_max_rate", "min_length", "max_length"):  # no winches (tests/test_winch_composite.py)
            ln.pop(k, None)
        secs = [{"type": "chain137", "length": 300.0}, {"type": "wire165", "length": 1900.0},
                {"type": "chain137", "length": 100.0}]
        for s, top in zip(secs, (lower, upper)):
            if top is not None:
                s["top"] = top
        for s, n in zip(secs, seg):
            if n is not None:
                s["segments"] = n
        ln["sections"] = secs
    return scenario_from_dict(d, source="composite fpso")


def quasi_static(m: MooringFEM, j: int):
    """The composite solution of line j for the FEM's anchor and fairlead: (solution, point x
    [m] from the anchor, point height above the seabed [m])."""
    fem = m.fem
    a, rf = fem.anchors[j], fem.r[fem.fairlead_idx[j]]
    XF, ZF = float(np.hypot(*(rf[:2] - a[:2]))), float(a[2] - rf[2])
    line = composite.CompositeLine.from_arrays(m.scenario.line_sections[j])
    hA = float(m.geometry.h_A[j])
    px, pz = composite.points(XF, ZF, line, h_A=hA)
    return composite.solve(XF, ZF, line, h_A=hA), np.ravel(px), np.ravel(pz)


def joints_of(m: MooringFEM, j: int) -> np.ndarray:
    """Node indices of line j's joints (one per point, from the anchor up)."""
    fem = m.fem
    cum = np.cumsum(fem.lines.sections[j]["segments"])[:-1]
    return fem.node_start[j] + cum


def fem_points(m: MooringFEM, j: int) -> tuple[np.ndarray, np.ndarray]:
    """The FEM's joint nodes of line j: horizontal distance from the anchor and height above the seabed [m]."""
    fem = m.fem
    r = fem.r[joints_of(m, j)]
    a = fem.anchors[j]
    return np.hypot(r[:, 0] - a[0], r[:, 1] - a[1]), fem.depth - r[:, 2]


def settled(sc, segments=None, **kw) -> MooringFEM:
    m = MooringFEM(sc, segments=segments)
    m.initialise(ZERO)
    m.settle(ZERO, **kw)
    return m


# --------------------------------------------------------------------------------------------
# (a) settled at rest against the quasi-static composite solution
# --------------------------------------------------------------------------------------------


def test_settled_composite_lines_approach_the_quasi_static_solution():
    """Fairlead tension and point positions of the settled FEM against ``models.composite``, for a
    buoy at the lower joint and a clump at the upper one, at 20, 40 and 80 segments per line, each
    section's segments doubled (3 / 16 / 1, 6 / 32 / 2, 12 / 64 / 4), so every segment is halved.

    The tolerance is the FEM's discretisation: each section's catenary becomes chords of length
    ``l0`` with the weight lumped at the nodes, which misplaces the line by O(l0^2 / R) where the
    line bends with radius R (sharpest at the buoy, whose lift kinks the line) and puts a chord's
    tension ``EA (chord / l0 - 1)`` where the arc's is. The errors fall at least 3x per doubling of
    the segments (second order); at 80 segments (25 m of wire, 15 m of chain) the tension is within
    1e-4 and the points within 0.2 m. Settled to 1e-9 per 5 s, so settling does not decide them.
    """
    errs = []
    for n in (20, 40, 80):
        k = n // 20
        sc = composite_fpso(lower="buoy", upper="clump", lines=(0, 4, 8), segments=(3 * k, 16 * k, k))
        m = settled(sc, tol=1e-9, speed_tol=1e-4, max_time=2000.0)
        eT, eP = 0.0, 0.0
        for j in range(3):
            sol, px, pz = quasi_static(m, j)
            T = m.fairlead_tension()[j]
            eT = max(eT, abs(T / float(sol.TF) - 1.0))
            x, z = fem_points(m, j)
            eP = max(eP, float(np.max(np.hypot(x - px, z - pz))))
        errs.append((n, eT, eP))
        secs = m.fem.lines.sections[0]["segments"].tolist()
        print(f"{n} segments {secs}: fairlead tension {eT:.2e}, points {eP:.3f} m")
    (_, t20, p20), (_, t40, p40), (_, t80, p80) = errs
    assert t20 < 5e-3 and p20 < 5.0, errs
    assert t40 < t20 / 3 and p40 < p20 / 3, errs
    assert p80 < p40 / 3 and t80 <= max(t40 / 3, 2e-5), errs
    assert t80 < 1e-4 and p80 < 0.2, errs


def test_initial_nodes_are_on_the_quasi_static_shape_with_the_joints_at_the_points():
    """initialise puts every joint node exactly where models.composite puts the point, each
    section's nodes on its own catenary (equal steps of unstretched arc length: segment strains
    within the section's tension range / EA)."""
    sc = composite_fpso(lower="buoy", upper="clump", lines=(0, 4, 8))
    m = MooringFEM(sc, segments=40)
    m.initialise(ZERO)
    fem = m.fem
    for j in range(3):
        _, px, pz = quasi_static(m, j)
        x, z = fem_points(m, j)
        assert np.allclose(x, px, rtol=0, atol=1e-9) and np.allclose(z, pz, rtol=0, atol=1e-9)
        b = slice(fem.node_start[j], fem.fairlead_idx[j])
        lv = fem.r[b.start + 1:b.stop + 1] - fem.r[b]
        strain = np.linalg.norm(lv, axis=1) / fem.l0[b] - 1.0
        assert np.all(strain > -1e-3) and np.all(strain < 5e-3)
    # and the settling from there is short
    info = m.settle(ZERO)
    assert info.converged and info.time < 120.0


# --------------------------------------------------------------------------------------------
# (b) one section, and equal sections with plain joints, are the homogeneous line
# --------------------------------------------------------------------------------------------


def _run(ls, sc, kernel, steps=400, r0=None):
    """FEMLines of ``ls`` initialised on the scenario's lines (then put at ``r0`` when given) and
    moved for ``steps`` steps of 0.01 s in a current: (fem, bond tensions, fairlead forces, the
    initial positions)."""
    env = sc.environment
    f = FEMLines(ls, np.array(sc.anchors), water_depth=env.water_depth, rho_w=env.water_density, kernel=kernel)
    m = MooringFEM(sc, segments=int(ls.segments[0]))
    m.fem = f
    m.initialise(ZERO)
    init = f.r.copy()
    if r0 is not None:
        f.r = r0.copy()
    t = (np.arange(steps) + 1.0) * 0.01
    eta = np.column_stack([3.0 * np.sin(t), 2.0 * np.sin(0.7 * t), 0.02 * np.sin(0.5 * t)])
    etad = np.column_stack([3.0 * np.cos(t), 1.4 * np.cos(0.7 * t), 0.01 * np.cos(0.5 * t)])
    r, v = m.fairlead_states(eta, etad)
    vc = np.tile([0.5, 0.2, 0.0], (f.n_nodes, 1))
    T = f.advance(0.01, r, v, vc, fairlead_force_out=(out := np.zeros((steps, f.n_lines, 3))))
    return f, T, out, init


@pytest.mark.parametrize("kernel", ["numba", "numpy"])
def test_one_section_and_equal_sections_are_the_homogeneous_line_to_the_bit(kernel):
    """aamo4's cable as sections: one section of the whole line, and three sections of the same
    type joined by plain points (no mass, volume or drag) with the segments in proportion to the
    lengths: the FEM state, tensions and fairlead forces are the homogeneous line's to the bit (the
    one section from its initialisation on; the three sections from the same initial nodes, their
    own initialisation being the composite solution's, the same to 1e-6 m)."""
    sc = load_scenario("aamo4")
    ls = line_set_from_scenario(sc, segments=30)

    def sec(L, seg):  # the line's own values in every section
        n = len(L)
        d = {k: np.full(n, getattr(ls, k)[0]) for k in ("EA", "w", "mass", "d", "Cdn", "Cdt", "Can", "Cat",
                                                         "damping_ratio", "mu")}
        d.update(L=np.array(L), segments=np.array(seg))
        d.update({k: np.zeros(n - 1) for k in ("W", "point_mass", "point_volume", "point_CdA", "point_Ca")})
        return d

    L = float(ls.L[0])
    one = dataclasses.replace(ls, sections=(sec([L], [30]),) + (None,) * 3)
    three = dataclasses.replace(ls, sections=(None, sec([L * 0.2, L * 0.5, L * 0.3], [6, 15, 9]), None,
                                              sec([L * 0.1, L * 0.9], [3, 27])))
    f0, T0, F0, init0 = _run(ls, sc, kernel)
    for cut in (one, three):
        f1, T1, F1, init1 = _run(cut, sc, kernel, r0=None if cut is one else init0)
        if cut is one:
            assert np.array_equal(init1, init0)
        else:
            assert np.abs(init1 - init0).max() < 1e-6
        assert f1.composite.any() and f1.joint_node.size == 0  # plain joints are ordinary nodes
        assert np.array_equal(f1.l0, f0.l0) and np.array_equal(f1.node_mass, f0.node_mass)
        assert np.array_equal(f1.r, f0.r) and np.array_equal(f1.v, f0.v)
        assert np.array_equal(T1, T0) and np.array_equal(F1, F0)
        assert np.array_equal(f1.end_tensions()[0], f0.end_tensions()[0])
    # a section of another type is not the homogeneous line (the test can fail)
    other = sec([L * 0.2, L * 0.8], [6, 24])
    other["EA"] = other["EA"] * np.array([1.0, 1.01])
    f2, *_ = _run(dataclasses.replace(ls, sections=(other, None, None, None)), sc, kernel, r0=init0)
    assert not np.array_equal(f2.r, f0.r)


# --------------------------------------------------------------------------------------------
# (c) the joint node: buoy up, clump down, vertical balance
# --------------------------------------------------------------------------------------------


@pytest.mark.parametrize("point", ["buoy", "clump"])
def test_joint_node_of_a_buoy_rises_a_clump_sinks_and_balances_W(point):
    """The upper joint (wire to top chain, suspended): with a buoy the line kinks upward there
    (the node above the chord of its two neighbours), with a clump downward (below it); at rest
    the vertical components of the two segment tensions at the node balance the node's weight:
    the point's W plus half of each adjacent segment's submerged weight."""
    sc = composite_fpso(lower=None, upper=point, lines=(0,))
    m = settled(sc, 40, tol=1e-9, speed_tol=1e-5, max_time=2000.0)
    fem = m.fem
    k = int(joints_of(m, 0)[1])
    z = fem.depth - fem.r[k - 1:k + 2, 2]  # heights above the seabed of the node and its neighbours
    chord = z[0] + (z[2] - z[0]) * np.linalg.norm(fem.r[k, :2] - fem.r[k - 1, :2]) / np.linalg.norm(
        fem.r[k + 1, :2] - fem.r[k - 1, :2])
    W = sc.line_sections[0]["W"][1]
    if point == "buoy":
        assert W < 0 and z[1] > chord + 1.0
    else:
        assert W > 0 and z[1] < chord - 1.0
    lv, eps, T = fem.segment_state(fem.r, fem.v, np.array([k - 1, k]))
    pull_z = T[1] * lv[1, 2] / eps[1] - T[0] * lv[0, 2] / eps[0]  # the segments' pull on the node, NED z (+ down)
    l0 = fem.l0[[k - 1, k]]
    w_half = 0.5 * (WIRE["submerged_weight"] * l0[0] + CHAIN["submerged_weight"] * l0[1])
    assert fem.node_weight[k] == pytest.approx(W + w_half, rel=1e-12)
    assert fem.node_mass[k] == pytest.approx(0.5 * (WIRE["mass_per_length"] * l0[0] + CHAIN["mass_per_length"] * l0[1])
                                             + (BUOY if point == "buoy" else CLUMP)["mass"], rel=1e-12)
    # at rest: tension pull + weight = 0 (to the settling's residual, far below W)
    assert abs(pull_z + fem.node_weight[k]) < 1e-4 * abs(W)


def test_a_clump_on_the_seabed_and_a_buoy_keep_the_seabed_contact_sound():
    """A clump at the lower joint rests on the seabed, pressed in by its own weight as much as a
    node of line by its own (the seabed spring carries the clump: 1 cm); a buoy node never gets a
    negative seabed stiffness."""
    sc = composite_fpso(lower="clump", upper="buoy", lines=(0,))
    m = settled(sc, 40, tol=1e-8, speed_tol=1e-4, max_time=2000.0)
    fem = m.fem
    lo, up = (int(k) for k in joints_of(m, 0))
    assert np.all(fem._kb >= 0.0)
    assert fem.r[lo, 2] - fem.depth == pytest.approx(0.01, rel=0.05)
    assert fem.r[up, 2] < fem.depth - 100.0


# --------------------------------------------------------------------------------------------
# buoyant sections: a lazy wave
# --------------------------------------------------------------------------------------------

FLOAT = {"id": "float800", "diameter": 0.8, "mass_per_length": 250.0, "density": 650.0, "EA": 4.0e8,
         "MBS": 1.0e7, "MBS_std": 5.0e5, "Cd_normal": 1.2, "Cd_tangential": 0.1, "Ca_normal": 1.0,
         "axial_damping_ratio": 0.7071}
"""Distributed buoyancy on a line: 250 kg/m in 0.385 m^3/m, a net lift of 1415 N/m (1.5 times the wire's weight)."""


def lazy_wave_fpso(*, lines: tuple[int, ...] = (0, 4, 8), segments: tuple[int, int, int] | None = None):
    """fpso_equivalent's anchors with lazy-wave lines: 500 m of chain from the anchor (on the
    seabed), 400 m of buoyant line arching up, 1500 m of wire to the fairlead; each section's
    ``segments`` when given."""
    d = scenario_to_dict(load_scenario("fpso_equivalent"))
    d["line_types"] += [dict(CHAIN), dict(WIRE), dict(FLOAT)]
    d["lines"] = [d["lines"][i] for i in lines]
    for ln in d["lines"]:
        del ln["type"], ln["length"]
        for k in ("winch_max_rate", "min_length", "max_length"):
            ln.pop(k, None)
        ln["sections"] = [{"type": t, "length": L} | ({"segments": segments[k]} if segments else {})
                          for k, (t, L) in enumerate((("chain137", 500.0), ("float800", 400.0), ("wire165", 1500.0)))]
    return scenario_from_dict(d, source="lazy wave fpso")


def test_a_lazy_wave_settles_to_its_quasi_static_shape():
    """The FEM with a buoyant section (nodes of negative weight) against models.composite, as the
    chain-wire-chain line above: 20, 40 and 80 segments per line (4 / 4 / 12 each doubled, the
    loader's share at 20), settled to 1e-9 per 5 s. The lazy wave bends more than the chain-wire-
    chain line (the arch, the sag below it, the chain lifting off steeply under the arch's pull):
    measured fairlead tension 5.2e-3, 1.1e-3, 1.0e-4 and joints 1.9, 0.47, 0.18 m; the tension
    falls faster than second order, the joints about 4x then 2.6x per doubling (the chain's
    lift-off is lumped at a node). The buoyant nodes weigh negative, float off the seabed and keep
    a seabed spring of their weight's magnitude."""
    errs = []
    for n in (20, 40, 80):
        k = n // 20
        m = settled(lazy_wave_fpso(segments=(4 * k, 4 * k, 12 * k)), tol=1e-9, speed_tol=1e-4, max_time=3000.0)
        eT, eP = 0.0, 0.0
        for j in range(3):
            sol, px, pz = quasi_static(m, j)
            eT = max(eT, abs(m.fairlead_tension()[j] / float(sol.TF) - 1.0))
            x, z = fem_points(m, j)
            eP = max(eP, float(np.max(np.hypot(x - px, z - pz))))
        errs.append((n, eT, eP))
        fem = m.fem
        lo, up = (int(i) for i in joints_of(m, 0))
        arch = np.arange(lo + 1, up)   # the buoyant section's inner nodes
        assert np.all(fem.node_weight[arch] < 0.0)
        assert np.all(fem._kb[arch] == pytest.approx(np.abs(fem.node_weight[arch]) / 0.01, rel=1e-12))
        assert np.all(np.isfinite(fem._cb)) and np.isfinite(fem.stable_dt())
        assert np.all(fem.depth - fem.r[arch, 2] > 40.0)
        print(f"{n} segments: fairlead tension {eT:.2e}, joints {eP:.3f} m")
    (_, t20, p20), (_, t40, p40), (_, t80, p80) = errs
    assert t20 < 6e-3 and p20 < 5.0, errs
    assert t40 < t20 / 3 and p40 < p20 / 3, errs
    assert t80 < t40 / 3 and p80 < p40 / 2, errs
    assert t80 < 2e-4 and p80 < 0.2, errs


def test_a_lazy_wave_starts_on_its_quasi_static_shape():
    """initialise puts the joints where models.composite puts them and the buoyant section's nodes
    on its inverted catenary (catenary.line_profile of a negative weight), so settling is short."""
    m = MooringFEM(lazy_wave_fpso(), segments=40)
    m.initialise(ZERO)
    fem = m.fem
    for j in range(3):
        _, px, pz = quasi_static(m, j)
        x, z = fem_points(m, j)
        assert np.allclose(x, px, rtol=0, atol=1e-9) and np.allclose(z, pz, rtol=0, atol=1e-9)
    lo, up = (int(i) for i in joints_of(m, 0))
    sec = m.scenario.line_sections[0]
    a = fem.anchors[0]
    h = fem.depth - fem.r[lo:up + 1, 2]
    d = np.hypot(fem.r[lo:up + 1, 0] - a[0], fem.r[lo:up + 1, 1] - a[1])
    pr = composite.profile(float(np.hypot(*(fem.r[fem.fairlead_idx[0], :2] - a[:2]))), fem.depth - m.fairlead_z,
                           composite.CompositeLine.from_arrays(sec), n=2401)
    on = (pr["s"] >= 500.0) & (pr["s"] <= 900.0)
    assert np.max(np.abs(h - np.interp(d, pr["x"][on], pr["z"][on]))) < 1e-6 * 400.0
    info = m.settle(ZERO)
    assert info.converged and info.time < 400.0


# --------------------------------------------------------------------------------------------
# (d) against MoorDyn-C under forced surge
# --------------------------------------------------------------------------------------------


def composite_moordyn_text(scenario, *, segments=None, dtM=None, scheme=None, outputs=True, extra_options=None,
                           ic=None):
    """A MoorDyn v2 input of a scenario with composite lines, as :func:`tapm_opt.config.moordyn.moordyn_text`
    writes a homogeneous one (the same body, frames, line-type mapping and options), each section a
    MoorDyn line and each joint a ``Free`` point with the point type's mass, volume, CdA and Ca
    (a plain joint: zeros), placed at its quasi-static position. MoorDyn lines 1..n are the
    fairlead sections of tapm_opt's lines 1..n (what ``MoorDynMooring`` reads the fairlead
    tensions from); the lower sections follow. kBot and cBot are the bottom section's (the part
    on the seabed). The time step is :func:`~tapm_opt.config.moordyn.moordyn_time_step` over the
    sections (each section a line of its own length and segments)."""
    env = scenario.environment
    assert segments is None, "the sections carry their segments"
    types_md = {lt.id: md_config.moordyn_line_type(lt, env) for lt in scenario.line_types}
    bottom = scenario.line_type_by_id(scenario.lines[0].parts[0].type)
    kb, cb = md_config.seabed_constants(bottom.w(env), bottom.mass_per_length, types_md[bottom.id]["d"])
    if dtM is None or scheme is None:  # the stiffest section decides: every section a line of its own
        secs = []
        for ln in scenario.lines:
            for s, n in zip(ln.parts, ln.section_segments()):
                part = types.SimpleNamespace(type=s.type, length=s.length, segments=n, top=None)
                secs.append(types.SimpleNamespace(type=s.type, length=s.length, segments=n, parts=(part,),
                                                  section_segments=(lambda n=n: (n,))))
        fake = types.SimpleNamespace(environment=env, lines=secs, line_type=lambda s: scenario.line_type_by_id(s.type),
                                     line_type_by_id=scenario.line_type_by_id)
        dt0, sch0 = md_config.moordyn_time_step(fake)
        dtM, scheme = dtM or dt0, scheme or sch0
    tur = scenario.turret
    body = md_config.md_from_ned((tur.position[0], tur.position[1], 0.0))
    fT = scenario.fairleads_T
    f = md_config._f
    pts, lines_top, lines_low = [], [], []
    for i, ln in enumerate(scenario.lines):
        sec = scenario.line_sections[i]
        a = scenario.anchors[i]
        fl = np.array([fT[i, 0], fT[i, 1], tur.fairlead_depth])
        XF = float(np.hypot(*(fl[:2] - a[:2])))
        u = (fl[:2] - a[:2]) / XF
        hA = float(scenario.line_arrays["h_A"][i])
        px, pz = composite.points(XF, float(a[2] - fl[2]), composite.CompositeLine.from_arrays(sec), h_A=hA)
        ids = [len(pts) + 1]
        pts.append(f"{ids[0]}  Fixed  " + "  ".join(f(v) for v in md_config.md_from_ned(a)) + "  0  0  0  0")
        for k, (x, z) in enumerate(zip(np.ravel(px), np.ravel(pz))):
            p = md_config.md_from_ned((a[0] + x * u[0], a[1] + x * u[1], env.water_depth - z))
            ids.append(len(pts) + 1)
            pts.append(f"{ids[-1]}  Free  " + "  ".join(f(v) for v in p) + f"  {f(sec['point_mass'][k])}  "
                       f"{f(sec['point_volume'][k])}  {f(sec['point_CdA'][k])}  {f(sec['point_Ca'][k])}")
        ids.append(len(pts) + 1)
        pts.append(f"{ids[-1]}  Body1  " + "  ".join(f(v) for v in md_config.md_from_ned(fl)) + "  0  0  0  0")
        for k, (s, n) in enumerate(zip(ln.parts, ln.section_segments())):
            row = (s.type, ids[k], ids[k + 1], f(s.length), int(n))
            (lines_top if k == len(ln.parts) - 1 else lines_low).append(row)
    out = ["--------------------- MoorDyn Input File ------------------------------------",
           f"Composite mooring of tapm_opt scenario {scenario.name!r} (test writer)",
           "---------------------- LINE TYPES -----------------------------------------------------",
           "TypeName   Diam    Mass/m    EA     BA/-zeta    EI      Cd     Ca     CdAx    CaAx",
           "(name)     (m)     (kg/m)    (N)    (N-s/-)   (N-m^2)   (-)    (-)    (-)     (-)"]
    for lt in scenario.line_types:
        t = types_md[lt.id]
        out.append(f"{lt.id}  {f(t['d'])}  {f(t['mass'])}  {f(t['EA'])}  {f(t['BA'])}  0  {f(t['Cd'])}  "
                   f"{f(t['Ca'])}  {f(t['CdAx'])}  {f(t['CaAx'])}")
    out += ["---------------------- BODIES -----------------------------------------------------------",
            "ID  Attachment  X0   Y0   Z0   r0   p0   y0   Mass  CG*  I*  Volume  CdA*  Ca*",
            "(#) (word)      (m)  (m)  (m) (deg) (deg) (deg) (kg)  (m) (kg-m^2) (m^3) (m^2) (-)",
            f"1   Coupled  {f(body[0])}  {f(body[1])}  0  0  0  {f(-math.degrees(tur.angle))}  0  0  0  0  0  0",
            "---------------------- POINTS -----------------------------------------------------------",
            "ID  Attachment  X    Y    Z    Mass  Volume  CdA   Ca",
            "(#) (word/ID)  (m)  (m)  (m)  (kg)  (m^3)  (m^2)  (-)", *pts,
            "---------------------- LINES ------------------------------------------------------------",
            "ID  LineType  AttachA  AttachB  UnstrLen  NumSegs  LineOutputs",
            "(#)  (name)    (ID)     (ID)      (m)      (-)      (-)"]
    for i, (t, a, b, L, n) in enumerate(lines_top + lines_low):
        out.append(f"{i + 1}  {t}  {a}  {b}  {L}  {n}  -")
    out += ["---------------------- OPTIONS ----------------------------------------------------------",
            f"{f(dtM)}  dtM", f"{scheme}  tScheme", f"{f(env.gravity)}  g", f"{f(env.water_density)}  rho",
            f"{f(env.water_depth)}  WtrDpth", f"{f(kb)}  kBot", f"{f(cb)}  cBot"]
    opts = {"dtIC": 2.0, "TmaxIC": 600.0, "threshIC": 1e-3, **(ic or {}), **(extra_options or {})}
    out += [f"{v if isinstance(v, str) else f(v)}  {k}" for k, v in opts.items()]
    out += ["---------------------- OUTPUTS ----------------------------------------------------------",
            "------------------------- need this line ------------------------------------------------"]
    info = md_config.ExportInfo(dtM=float(dtM), scheme=str(scheme), kBot=kb, cBot=cb, n_lines=len(lines_top))
    return "\n".join(out) + "\n", info


def test_forced_surge_tensions_match_moordyn_with_free_points(monkeypatch):
    """Three chain-wire-chain lines of fpso (300 m chain in 6 segments, 1900 m wire in 38, 100 m
    chain in 4) with a buoy at the lower joint and a clump at the upper one, surged 10 m at 100 s
    for 300 s, in the FEM and in MoorDyn-C (the sections as MoorDyn lines joined by Free points,
    written by :func:`composite_moordyn_text`, which ``moordyn_forced_motion`` uses in place of
    the scenario export). Measured: fairlead tension RMS difference 1.2e-4 of the mean tension
    (largest line; 0.3 % of the line's tension range), largest difference 9e-4, surge damping
    within 0.2 %. Without the buoy's added mass in the FEM the RMS difference is 1.3e-3 (3.6 % of
    the range): the bounds 5e-4 and 1.5 % see it."""
    from tapm_opt.plant.moordyn_reference import moordyn_forced_motion

    sc = composite_fpso(lower="buoy", upper="clump", lines=(0, 4, 8), segments=(6, 38, 4))
    monkeypatch.setattr(md_config, "moordyn_text", composite_moordyn_text)
    kw = {"dof": "surge", "amplitude": 10.0, "period": 100.0, "duration": 300.0, "dt_out": 1.0}
    m = moordyn_forced_motion(sc, **kw)
    f = forced_motion(sc, **kw)
    assert m.input_text.count("  Free  ") == 6 and "  buoy" not in m.input_text  # 2 free points per line
    assert np.allclose(m.t, f.t) and np.allclose(m.eta, f.eta)
    d = m.T - f.T
    mean = f.T.mean(axis=0)
    rms = np.sqrt((d**2).mean(axis=0)) / mean
    peak = np.abs(d).max(axis=0) / mean
    rng = (f.T.max(axis=0) - f.T.min(axis=0)) / mean
    print(f"fairlead tension against MoorDyn-C: RMS {rms.max():.2e} of the mean (largest line), "
          f"{(rms / rng).max():.2e} of the range; largest {peak.max():.2e}; surge damping {f.damping:.5g} "
          f"(MoorDyn {m.damping:.5g} N s/m); MoorDyn {m.wall_time:.1f} s wall, FEM {f.wall_time:.1f} s")
    assert rng.min() > 0.02  # the motion moves every line's tension by far more than the difference
    assert rms.max() <= 5e-4, rms
    assert (rms / rng).max() <= 0.015, rms / rng
    assert peak.max() <= 3e-3, peak
    assert m.damping == pytest.approx(f.damping, rel=0.01)
    assert np.sqrt(((m.force - f.force)[:, 0] ** 2).mean()) <= 0.01 * np.abs(f.force[:, 0]).max()


# --------------------------------------------------------------------------------------------
# the joint node's equations, the kernels, the step
# --------------------------------------------------------------------------------------------


def test_joint_node_force_and_mass_are_moordyns_point_with_its_two_half_segments():
    """The acceleration of a moving joint node, from an independent evaluation: the two segment
    tensions; its weight W + half of each segment's w l0; Morison drag of each half segment with
    its own diameter and coefficients on its own stretched length, normal and tangential to the
    node tangent; the point's isotropic drag 1/2 rho CdA |v_r| v_r; and the mass matrix
    (m_point + half segment masses) I + sum of the halves' added mass (normal C_MN, tangential
    C_MT about the tangent) + Ca rho V I, solved as a 3 x 3 system."""
    sc = composite_fpso(lower="buoy", upper="clump", lines=(0,), segments=(6, 38, 4))
    m = MooringFEM(sc, segments=None)
    m.initialise(ZERO)
    fem = m.fem
    rng = np.random.default_rng(3)
    fem.v = rng.normal(scale=0.5, size=fem.v.shape)
    vc = np.tile([0.4, -0.3, 0.05], (fem.n_nodes, 1))
    rho = sc.environment.water_density
    for kernel in ("numpy", "numba"):
        fem.kernel = kernel
        a, _ = fem.accelerations(fem.r, fem.v, vc)
        for k, pt, (lo, hi) in zip(joints_of(m, 0), (BUOY, CLUMP), ((CHAIN, WIRE), (WIRE, CHAIN))):
            lv, eps, T = fem.segment_state(fem.r, fem.v, np.array([k - 1, k]))
            q_lo, q_hi = lv[0] / eps[0], lv[1] / eps[1]
            F = T[1] * q_hi - T[0] * q_lo
            F[2] += fem.node_weight[k]
            q = (q_lo + q_hi) / np.linalg.norm(q_lo + q_hi)
            vr = fem.v[k] - vc[k]
            vt = vr @ q * q
            vn = vr - vt
            M = (fem.node_mass[k] + pt["Ca"] * rho * pt["volume"]) * np.eye(3)
            for lt, e in ((lo, eps[0]), (hi, eps[1])):
                dd = lt["diameter"]
                F -= 0.5 * rho * lt["Cd_normal"] * dd * (0.5 * e) * np.linalg.norm(vn) * vn
                F -= 0.5 * rho * lt["Cd_tangential"] * dd * (0.5 * e) * np.linalg.norm(vt) * vt
                A = 0.25 * np.pi * dd**2 * rho * 0.5 * e
                qq = np.outer(q, q)
                M += lt["Ca_normal"] * A * (np.eye(3) - qq) + lt.get("Ca_tangential", 0.0) * A * qq
            F -= 0.5 * rho * pt["CdA"] * np.linalg.norm(vr) * vr
            assert fem.r[k, 2] < fem.depth  # no seabed force on these nodes
            assert np.allclose(a[k], np.linalg.solve(M, F), rtol=1e-10, atol=1e-12 * np.abs(a[k]).max()), kernel
    assert fem.joint_c.shape == (2, 10)


def test_the_kernels_agree_on_composite_lines_with_current_friction_and_points():
    """The compiled kernel and the numpy reference path step composite lines (buoy and clump
    joints, seabed friction, a current, settling damping) to the same state to round-off."""
    sc = composite_fpso(lower="clump", upper="buoy", lines=(0, 4, 8))
    ls = line_set_from_scenario(sc, segments=30)
    ls = dataclasses.replace(ls, sections=tuple(dict(s, mu=np.full(3, 0.8)) for s in ls.sections))
    env = sc.environment
    fems = {}
    for kernel in ("numba", "numpy"):
        f = FEMLines(ls, np.array(sc.anchors), water_depth=env.water_depth, rho_w=env.water_density, kernel=kernel)
        m = MooringFEM(sc, segments=30)
        m.fem = f
        m.initialise(ZERO)
        t = (np.arange(3000) + 1.0) * 0.004
        r, v = m.fairlead_states(np.column_stack([4 * np.sin(t), 2 * np.sin(0.6 * t), 0.01 * t]),
                                 np.column_stack([4 * np.cos(t), 1.2 * np.cos(0.6 * t), np.full_like(t, 0.01)]))
        vc = np.column_stack([0.9 - 5e-4 * f.r[:, 2], 0.3 + 0 * f.r[:, 2], 0 * f.r[:, 2]])
        f.advance(0.004, r[:1500], v[:1500], vc, extra_damping=0.2)
        f.advance(0.004, r[1500:], v[1500:], vc)
        fems[kernel] = f
    a, b = fems["numba"], fems["numpy"]
    assert a._has_friction and a.joint_node.size == 6
    scale = np.abs(a.r).max()
    assert np.abs(a.r - b.r).max() <= 1e-11 * scale
    assert np.abs(a.v - b.v).max() <= 1e-9 * max(np.abs(a.v).max(), 1.0)
    assert np.allclose(a.end_tensions()[0], b.end_tensions()[0], rtol=1e-10)


def test_the_compiled_plant_on_composite_lines_is_the_numpy_plant():
    """The plant's fused compiled outer step (fem_kernel.mooring_step with the joints) and its
    numpy path give the same logged channels (bit for bit where the machine allows) for fpso
    on composite lines in its current and waves."""
    from _bitwise import assert_same

    from tapm_opt.interfaces import ThrusterCommand
    from tapm_opt.plant.simulator import Plant, run_open_loop

    sc = composite_fpso(lower="buoy", upper="clump", lines=(0, 4, 8))
    runs = []
    for compiled in (True, False):
        p = Plant(sc, segments=20, sea_state="normal", seed=1)
        p.compiled = compiled
        cmd = ThrusterCommand(np.full(len(sc.thrusters), 2e5), np.linspace(-2.5, 2.5, len(sc.thrusters)))
        runs.append(run_open_loop(p, 20.0, thruster_cmd=cmd))
    assert runs[0].channels == runs[1].channels
    assert_same(runs[0].data, runs[1].data)


def _stiff_pendant_scenario():
    """Three lines whose stiffest segments are a 20 m wire pendant in 10 segments in the middle
    (2 m: l0 sqrt(m / EA) = 0.63 ms), a float of 1 kg and 20 m^3 below it and a 20 t clump lower
    down; no internal damping, so the stability limit is sharp."""
    d = scenario_to_dict(load_scenario("fpso_equivalent"))
    d["line_types"] += [dict(CHAIN, axial_damping_ratio=0.0), dict(WIRE, axial_damping_ratio=0.0)]
    d["point_types"] = [{"id": "float", "mass": 1.0, "volume": 20.0, "CdA": 10.0, "Ca": 1.0}, dict(CLUMP)]
    d["lines"] = [d["lines"][i] for i in (0, 4, 8)]
    for ln in d["lines"]:
        del ln["type"], ln["length"]
        for k in ("winch_max_rate", "min_length", "max_length"):
            ln.pop(k, None)
        ln["sections"] = [{"type": "chain137", "length": 300.0, "segments": 6, "top": "clump"},
                          {"type": "wire165", "length": 1880.0, "segments": 37, "top": "float"},
                          {"type": "wire165", "length": 20.0, "segments": 10},
                          {"type": "chain137", "length": 100.0, "segments": 4}]
    return scenario_from_dict(d, source="stiff pendant")


def test_the_stable_step_is_the_stiffest_sections_and_is_honoured():
    """stable_dt is the Gershgorin bound of the stiffest section's nodes (the pendant: 2 / omega
    with omega^2 = 4 EA / (m l0^2), no damping), not the line's fairlead or bottom section's; the
    joint nodes (the 1 kg float, the clump) are no stiffer. Surged at 0.95 of it for 10 s the lines
    stay finite and slow; at 1.2 of it they blow up (the bound is sharp: a step from another section
    would fail)."""
    from tapm_opt.plant.fem import SimulationDiverged

    sc = _stiff_pendant_scenario()
    m = MooringFEM(sc, safety=1.0)
    fem = m.fem
    sec = sc.line_sections[0]
    l0 = sec["L"] / sec["segments"]
    bound = l0 * np.sqrt(sec["mass"] / sec["EA"])
    assert fem.stable_dt(1.0) == pytest.approx(bound.min(), rel=1e-9)
    assert np.argmin(bound) == 2
    m.initialise(ZERO)
    m.settle(ZERO)
    r0, v0 = fem.r.copy(), fem.v.copy()

    def surge(factor):
        fem.r, fem.v = r0.copy(), v0.copy()
        dt = factor * fem.stable_dt(1.0)
        t = (np.arange(int(10.0 / dt)) + 1.0) * dt
        w = 2 * np.pi / 20.0
        r, v = m.fairlead_states(np.column_stack([5 * np.sin(w * t), 0 * t, 0 * t]),
                                 np.column_stack([5 * w * np.cos(w * t), 0 * t, 0 * t]))
        for i in range(0, t.size, 2000):
            fem.advance(dt, r[i:i + 2000], v[i:i + 2000], np.zeros((fem.n_nodes, 3)))
            fem.check_health()
        return float(np.abs(fem.v).max())

    assert surge(0.95) < 3.0
    with pytest.raises(SimulationDiverged), np.errstate(all="ignore"):
        surge(1.2)


# --------------------------------------------------------------------------------------------
# winch, and the line set's checks
# --------------------------------------------------------------------------------------------


def test_homogeneous_lines_winch_beside_composite_lines():
    """fpso_equivalent with its lines 1, 5 and 9 composite (without winches) and the others homogeneous with
    their winches: the plant pays out a homogeneous line (its length and segments change, the
    composite lines' do not); a winch command on a composite line without a winch is refused, and
    in the FEM a composite line's length may not drop by its fairlead section (100 m) or more
    (``tests/test_winch_composite.py``: winches on composite lines)."""
    from tapm_opt.plant.environment import PlantError
    from tapm_opt.plant.simulator import Plant, run_open_loop

    d = scenario_to_dict(composite_fpso(lower="buoy", upper=None))
    fp = scenario_to_dict(load_scenario("fpso_equivalent"))
    for i, ln in enumerate(d["lines"]):
        if i % 4:
            d["lines"][i] = fp["lines"][i]
    sc = scenario_from_dict(d, source="mixed")
    assert [ln.composite for ln in sc.lines][:5] == [True, False, False, False, True]
    p = Plant(sc, segments=20)
    fem = p.mooring.fem
    l0_comp = fem.l0[fem.line_of_bond == 0].copy()
    w = np.zeros(12)
    w[1] = 0.15
    r = run_open_loop(p, 20.0, winch_cmd=w)
    L = r.data[:, r.channels.index(f"L[{sc.lines[1].id}]")]
    assert L[-1] > L[0] + 2.0
    assert np.array_equal(fem.l0[fem.line_of_bond == 0], l0_comp)
    assert fem.L[0] == pytest.approx(2300.0)
    w = np.zeros(12)
    w[0] = 0.1
    with pytest.raises(PlantError, match="has no winch"):
        p.step(1.0, winch_cmd=w)
    fem.L[0] -= 100.0
    with pytest.raises(ModelError, match="composite line.*fairlead section is 100 m"):
        fem._update_lengths()


@pytest.mark.parametrize("n,split", [(3, [1, 1, 1]), (4, [1, 2, 1]), (10, [2, 7, 1]), (16, [2, 13, 1]),
                                     (20, [3, 16, 1]), (40, [6, 32, 2])])
def test_a_line_s_segments_are_shared_so_the_longest_segment_is_shortest(n, split):
    """300 / 1900 / 100 m with n segments in all: the split whose longest segment is shortest,
    checked against every split by brute force (each section at least one segment)."""
    sc = composite_fpso(lines=(0,))
    got = line_set_from_scenario(sc, segments=n).sections[0]["segments"].tolist()
    assert got == split
    L = np.array([300.0, 1900.0, 100.0])
    best = min(max(L / np.array([a, b, n - a - b])) for a in range(1, n) for b in range(1, n - a))
    assert max(L / np.array(got)) == pytest.approx(best, rel=1e-12)


def test_line_set_sections_are_checked():
    sc = composite_fpso(lines=(0,))
    ls = line_set_from_scenario(sc, segments=20)
    assert ls.sections[0]["segments"].tolist() == [3, 16, 1] and int(ls.segments[0]) == 20
    env = sc.environment

    def build(**kw):
        s = dict(ls.sections[0], **kw)
        return FEMLines(dataclasses.replace(ls, sections=(s,)), np.array(sc.anchors), water_depth=env.water_depth,
                        rho_w=env.water_density)

    build()
    with pytest.raises(ModelError, match="add up to the line's 20"):
        build(segments=np.array([3, 16, 2]))  # 21
    with pytest.raises(ModelError, match="one per joint"):
        build(W=np.zeros(3))
    with pytest.raises(ModelError, match="sections 2301"):
        build(L=np.array([300.0, 1901.0, 100.0]))
    with pytest.raises(ModelError, match="one per line"):
        FEMLines(dataclasses.replace(ls, sections=(None, None)), np.array(sc.anchors), water_depth=1000.0,
                 rho_w=1025.0)
