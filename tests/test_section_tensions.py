"""The tension at the top of each section of a composite line below its fairlead section, logged
by the plant as ``T_section[<line>/<k>]`` (docs/plant.md, "Logged channels"):

* only lines of several sections get the channels, one per section below the fairlead section, right
  after the ``T_anchor`` block; single-section scenarios keep their channel list;
* the logged value is the FEM's top segment of the section, recomputed here from the node
  positions and velocities with the full bond path;
* settled at rest it agrees with the quasi-static composite solution (models.composite.profile) to
  the FEM's discretisation, as the fairlead tension does;
* statics along a hanging line: the tension at a section's top exceeds the one at its bottom by
  about its submerged weight times its depth span; across fpso_deep's buoy the vertical component
  jumps by the buoy's net buoyancy, which the naive section-to-section difference misses.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from tapm_opt.config import load_scenario
from tapm_opt.models import composite
from tapm_opt.plant.mooring_fem import MooringFEM
from tapm_opt.plant.simulator import Plant, section_channel

ZERO = np.zeros(3)


@pytest.fixture(scope="module")
def deep():
    return load_scenario("fpso_deep")


@pytest.fixture(scope="module")
def settled_line(deep):
    """fpso_deep's line 1 alone, settled at eta = 0 in still water (to 1e-9 per 5 s)."""
    sc = dataclasses.replace(deep, lines=(deep.lines[0],))
    m = MooringFEM(sc)
    m.initialise(ZERO)
    m.settle(ZERO, tol=1e-9, speed_tol=1e-4, max_time=3000.0)
    return sc, m


def _names(p: Plant) -> list[str]:
    return [c for c, _ in p.channels()]


def test_channels_only_for_lines_of_several_sections(deep):
    ren8 = Plant(load_scenario("ren8"), sea_state="none", seed=0, segments=6)
    names = _names(ren8)
    assert not any(c.startswith("T_section[") for c in names)
    assert ren8.section_tops == ()
    p = Plant(deep, sea_state="none", seed=0)
    names = _names(p)
    sec = [c for c in names if c.startswith("T_section[")]
    # two sections below the fairlead section on each of the 12 lines, in line order, from the anchor up
    assert sec == [section_channel(ln.id, k) for ln in deep.lines for k in (0, 1)]
    assert sec[:3] == ["T_section[1/0]", "T_section[1/1]", "T_section[2/0]"]
    i0 = names.index("T_section[1/0]")
    assert names[i0 - 1] == "T_anchor[12]" and names[i0 + len(sec)] == "L[1]"
    assert all(u == "N" for c, u in p.channels() if c.startswith("T_section["))
    assert len(p.sample_row()) == len(names)
    # the channels of the other scenarios' lines: removing the section channels gives the old list
    rest = [c for c in names if not c.startswith("T_section[")]
    assert rest[9:9 + 12] == [f"T_fairlead[{ln.id}]" for ln in deep.lines]
    assert rest[21:33] == [f"T_anchor[{ln.id}]" for ln in deep.lines]


def _recompute(p: Plant, full: bool = True) -> np.ndarray:
    """Section-top tensions from the FEM state, written out here: each section's top bond from the
    section segment counts, its strain, EA strain plus the internal damping on the strain rate (the
    full bond path of FEMLines.segment_state), plus the upper half segment's weight w l0 / 2."""
    fem = p.mooring.fem
    T_all = fem.segment_state(fem.r, fem.v)[2]   # every bond, not the subset path
    out = []
    for j, ln in enumerate(p.scenario.lines):
        if not ln.composite:
            continue
        sec = p.scenario.line_sections[j]
        seg = np.asarray(sec["segments"], int)
        for k in range(len(seg) - 1):
            top = int(fem.node_start[j] + seg[:k + 1].sum())   # the joint above section k
            b = top - 1
            lv = fem.r[top] - fem.r[top - 1]
            l0 = sec["L"][k] / seg[k]
            assert fem.l0[b] == pytest.approx(l0, rel=1e-12)
            eps = np.linalg.norm(lv)
            f = -T_all[b] * lv / eps
            f[2] += 0.5 * sec["w"][k] * l0
            out.append(np.linalg.norm(f) if fem.active[j] else 0.0)
            if not full:
                # at rest: the elastic part alone, EA (|lv| / l0 - 1)
                Te = sec["EA"][k] * (eps / l0 - 1.0)
                f = -Te * lv / eps
                f[2] += 0.5 * sec["w"][k] * l0
                out[-1] = np.linalg.norm(f)
    return np.array(out)


def test_the_logged_channel_is_the_top_segment_of_the_section_in_motion(deep):
    """In the storm, after 20 s of motion (the internal damping acts): the logged T_section values
    equal the recomputation from the node states; and a broken line logs 0 at its sections."""
    from tapm_opt.config.schema import Fault

    p = Plant(deep, sea_state="storm", seed=2, faults=[Fault(kind="line_break", time=10.0, line="3")])
    p.step(20.0)
    names = _names(p)
    row = p.sample_row()
    got = np.array([row[i] for i, c in enumerate(names) if c.startswith("T_section[")])
    want = _recompute(p)
    assert np.allclose(got, want, rtol=1e-12, atol=0.0)
    assert got[names.index("T_section[3/0]") - names.index("T_section[1/0]")] == 0.0
    alive = got[got > 0]
    assert alive.size == 22 and np.all(alive > 1e6)
    # the damping term matters here: the elastic part alone differs
    fem = p.mooring.fem
    assert np.max(np.abs(fem.v)) > 0.01
    # the compiled kernel (fem_kernel.section_tensions) and the numpy path: the same bits
    compiled = fem.section_tension(p._sec_bonds, p._sec_lines)
    kern, fem._kernel_fn = fem._kernel_fn, None
    try:
        numpy_path = fem.section_tension(p._sec_bonds, p._sec_lines)
    finally:
        fem._kernel_fn = kern
    assert kern is not None and np.array_equal(compiled, numpy_path)


def test_at_rest_the_section_tops_agree_with_the_quasi_static_composite_line(settled_line):
    """Settled at rest, the FEM's section-top tensions against models.composite.profile (the
    tension at the end of each section, an independent elastic-catenary path) on the FEM's own
    anchor-fairlead span: within 0.7 %, the discretisation (the fairlead tension is 0.47 % below the
    quasi-static one at these segments, tests/test_scenario_fpso_deep.py); and the recomputation of
    the elastic part alone (no node moves) gives the same numbers."""
    sc, m = settled_line
    fem = m.fem
    tops = fem.section_top_bonds()
    assert [(j, k) for j, k, _ in tops] == [(0, 0), (0, 1)]
    T = fem.section_tension(np.array([b for *_, b in tops]), np.zeros(2, int))
    a, rf = fem.anchors[0], fem.r[fem.fairlead_idx[0]]
    XF, ZF = float(np.hypot(*(rf[:2] - a[:2]))), float(a[2] - rf[2])
    line = composite.CompositeLine.from_arrays(sc.line_sections[0])
    pr = composite.profile(XF, ZF, line, n=400)
    ends = np.cumsum(line.L)[:-1]
    qs = np.array([pr["T"][int(np.flatnonzero(np.isclose(pr["s"], e, rtol=0, atol=1e-9))[0])] for e in ends])
    err = np.abs(T / qs - 1.0)
    print("section tops FEM", T, "quasi-static", qs, "rel. error", err)
    assert np.all(err < 7e-3), err
    # the fairlead's error is of the same size and sign (the same discretisation)
    eF = fem.fairlead_tension()[0] / float(composite.solve(XF, ZF, line).TF) - 1.0
    assert -7e-3 < eF < 0 and np.all(T / qs - 1.0 < 0)

    class _P:   # the recomputation helper on this settled FEM (no plant needed)
        scenario = sc
        mooring = m
    assert np.allclose(_recompute(_P, full=False), T, rtol=1e-9)


def test_statics_weight_times_depth_span_and_the_buoy(settled_line):
    """Along a hanging section at rest, T_top - T_bottom = w dz (1 - strain) for the elastic
    catenary of weight w per unstretched length (dT/ds0 = w sin(phi), dz/ds0 = sin(phi)(1 + e)):
    about w dz, within 2 % for polyester at 1.2 % strain. fpso_deep's top chain (plain joint below
    it): fairlead - T_section[1/1]. Its rope: T_section[1/1] minus the tension at the rope's lower
    end, which is section 0's top force plus the buoy's net weight W (negative: it lifts) on the
    joint, |f_0 + W e_z|; the naive difference T_section[1/1] - T_section[1/0] misses the buoy by
    more than the rope's own w dz."""
    sc, m = settled_line
    fem = m.fem
    sec = sc.line_sections[0]
    seg = np.asarray(sec["segments"], int)
    joints = fem.node_start[0] + np.cumsum(seg)[:-1]
    z = fem.r[:, 2]
    tops = fem.section_top_bonds()
    b = np.array([t[2] for t in tops])
    T0, T1 = fem.section_tension(b, np.zeros(2, int))
    TF = fem.fairlead_tension()[0]
    # the top chain: a plain joint, w dz
    dz2 = z[joints[1]] - z[fem.fairlead_idx[0]]
    w2 = sec["w"][2]
    assert (TF - T1) == pytest.approx(w2 * dz2, rel=2e-2)
    # the rope above the buoy
    lv = fem.r[b[0] + 1] - fem.r[b[0]]
    Tb = fem.segment_state(fem.r, fem.v)[2][b[0]]
    f0 = -Tb * lv / np.linalg.norm(lv)
    f0[2] += 0.5 * sec["w"][0] * fem.l0[b[0]]
    assert np.linalg.norm(f0) == pytest.approx(T0, rel=1e-12)
    W = sec["W"][0]
    assert W == pytest.approx(-296.5e3, rel=2e-3)   # the buoy's net buoyancy (fpso_deep's header)
    T_rope_bottom = np.linalg.norm(f0 + np.array([0.0, 0.0, W]))
    dz1 = z[joints[0]] - z[joints[1]]
    w1 = sec["w"][1]
    assert dz1 > 1500.0
    assert (T1 - T_rope_bottom) == pytest.approx(w1 * dz1, rel=2e-2)
    naive = T1 - T0
    assert abs(naive - w1 * dz1) > w1 * dz1   # the buoy's lift: the rope's bottom is below the chain's top
    assert T0 > T_rope_bottom + 0.5 * abs(W) * abs(f0[2]) / np.linalg.norm(f0)
