"""The FEM plant on lines of a tension-strain table (nonlinear EA, polyester):

* a polyester line settled at rest approaches the quasi-static catenary of its table
  (:mod:`tapm_opt.models.catenary`) at second order in the segment length;
* the compiled kernel and the numpy path give the same state (to the bit where the machine
  allows), on homogeneous polyester lines beside chain lines and on chain-polyester-chain lines;
* a chain line's state does not depend on a polyester line beside it (its bonds keep EA e);
* the segment tension is the table's, tension only; the elastic energy its integral;
* the stable step is set by the table's largest slope, and honoured.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from tapm_opt.config import load_scenario, scenario_from_dict, scenario_to_dict
from tapm_opt.models import MooringModel
from tapm_opt.plant.fem import FEMLines, SimulationDiverged
from tapm_opt.plant.mooring_fem import MooringFEM, line_set_from_scenario
from tapm_opt.strain_table import StrainTable

from _bitwise import assert_same

ZERO = np.zeros(3)

POLY = {"id": "poly", "diameter": 0.217, "mass_per_length": 52.0, "density": 1380.0,
        "EA_table": [[0.0, 0.0], [0.005, 1.0e6], [0.01, 2.4e6], [0.02, 5.6e6], [0.03, 9.2e6], [0.05, 17.0e6]],
        "MBS": 20e6, "MBS_std": 1e6, "Cd_normal": 1.6, "Cd_tangential": 0.025, "Ca_normal": 1.0,
        "axial_damping_ratio": 0.7071}
"""A polyester rope of 290 mm class (52 kg/m, 0.217 m), a law that stiffens with load: slopes 200,
280, 320, 360 and 390 MN, secant 340 MN at 5 % strain."""
CHAIN = {"id": "chain137", "diameter": 0.2466, "mass_per_length": 373.5, "submerged_weight": 3185.6,
         "EA": 1.603e9, "MBS": 16.99e6, "MBS_std": 8.5e5, "Cd_normal": 2.4, "Cd_tangential": 1.15,
         "Ca_normal": 1.0, "Ca_tangential": 0.5, "axial_damping_ratio": 0.7071}


def polyester_fpso(lines=(0, 4, 8), *, length=2170.0, table=None, damping=0.7071, chain=(), composite=()):
    """fpso_equivalent with its lines ``lines`` of polyester (2170 m: taut, 1.1 % strain at rest),
    those in ``chain`` of its equivalent chain-wire-chain line, those in ``composite``
    chain-polyester-chain (300 m, 1770 m, 100 m from the anchor up)."""
    d = scenario_to_dict(load_scenario("fpso_equivalent"))
    t = dict(POLY, axial_damping_ratio=damping)
    if table is not None:
        t["EA_table"] = table
    d["line_types"] = [d["line_types"][0], t, dict(CHAIN)]
    d["lines"] = [d["lines"][i] for i in lines]
    for i, ln in zip(lines, d["lines"]):
        for k in ("winch_max_rate", "min_length", "max_length"):
            ln.pop(k, None)
        if i in composite:
            del ln["type"], ln["length"]
            ln["sections"] = [{"type": "chain137", "length": 300.0}, {"type": "poly", "length": 1770.0},
                              {"type": "chain137", "length": 100.0}]
        elif i not in chain:
            ln["type"], ln["length"] = "poly", length
    d["faults"] = []
    return scenario_from_dict(d, source="polyester fpso")


def settled(sc, segments, **kw) -> MooringFEM:
    m = MooringFEM(sc, segments=segments)
    m.initialise(ZERO)
    m.settle(ZERO, **kw)
    return m


def test_a_settled_polyester_line_approaches_the_quasi_static_catenary_of_its_table():
    """Fairlead tensions of polyester lines settled at rest against the quasi-static catenary with
    the same table, at 20, 40 and 80 segments: errors within 2e-4, 5e-5, 1.5e-5 (measured 8.5e-5,
    2.2e-5, 5.5e-6: second order in the segment length, as the chords of a catenary), and the
    linear-table line's the constant-EA line's to 1e-9."""
    sc = polyester_fpso()
    T0 = MooringModel.from_scenario(sc).tensions(ZERO)
    errs = []
    for n in (20, 40, 80):
        m = settled(sc, n)
        errs.append(float(np.max(np.abs(m.fem.fairlead_tension() / T0 - 1.0))))
    print(f"settled polyester against the catenary of its table: {errs}")
    assert errs[0] < 2e-4 and errs[1] < 5e-5 and errs[2] < 1.5e-5, errs
    assert errs[0] / errs[1] > 3.5 and errs[1] / errs[2] > 3.5, errs


def test_a_linear_table_line_is_the_constant_ea_line():
    """A polyester line whose table lies on T = EA eps (rows at 1 % and 5 %) steps as the same line of
    constant EA: positions within 1e-9 m after 10 s of surge (only the rounding of T_k + s_k (e - e_k)
    against EA e differs)."""
    EA = 3.4e8
    runs = []
    for table in ([[0.0, 0.0], [0.01, 0.01 * EA], [0.05, 0.05 * EA]], None):
        sc = polyester_fpso(lines=(0,), table=table)
        if table is None:
            d = scenario_to_dict(sc)
            del d["line_types"][1]["EA_table"]
            d["line_types"][1]["EA"] = EA
            sc = scenario_from_dict(d)
        m = MooringFEM(sc, segments=30)
        m.initialise(ZERO)
        fem = m.fem
        dt = 0.8 * fem.stable_dt(1.0)
        t = (np.arange(int(10.0 / dt)) + 1.0) * dt
        r, v = m.fairlead_states(np.column_stack([5 * np.sin(0.3 * t), 0 * t, 0 * t]),
                                 np.column_stack([1.5 * np.cos(0.3 * t), 0 * t, 0 * t]))
        fem.advance(dt, r, v, np.zeros((fem.n_nodes, 3)))
        runs.append(fem.r.copy())
    assert np.max(np.abs(runs[0] - runs[1])) < 1e-9


@pytest.mark.parametrize("layout", ["homogeneous", "composite"])
def test_the_kernels_agree_on_polyester_lines(layout):
    """The compiled kernel and the numpy path on polyester lines beside a chain line, or on
    chain-polyester-chain lines, under forced surge and sway with settling damping and a current:
    the same positions, velocities and tensions (bit for bit where the machine allows)."""
    comp = (0, 4) if layout == "composite" else ()
    sc = polyester_fpso(lines=(0, 4, 8), chain=(8,), composite=comp)
    fems = {}
    for kernel in ("numba", "numpy"):
        m = MooringFEM(sc, segments=30)
        ls = line_set_from_scenario(sc, segments=30)
        m.fem = FEMLines(ls, np.array(sc.anchors), water_depth=sc.environment.water_depth,
                         rho_w=sc.environment.water_density, kernel=kernel)
        m.initialise(ZERO)
        f = m.fem
        assert f.kernel == kernel and len(f.tables) == 1
        dt = f.stable_dt()
        t = (np.arange(2000) + 1.0) * dt
        r, v = m.fairlead_states(np.column_stack([6 * np.sin(0.8 * t), 3 * np.sin(0.5 * t), 0 * t]),
                                 np.column_stack([4.8 * np.cos(0.8 * t), 1.5 * np.cos(0.5 * t), 0 * t]))
        vc = np.column_stack([0.5 + 0 * f.r[:, 2], 0.2 + 0 * f.r[:, 2], 0 * f.r[:, 2]])
        f.advance(dt, r[:1000], v[:1000], vc, extra_damping=0.2)
        T = f.advance(dt, r[1000:], v[1000:], vc)
        fems[kernel] = (f.r.copy(), f.v.copy(), T.copy(), np.column_stack(f.end_tensions()))
    for a, b in zip(fems["numba"], fems["numpy"]):
        assert_same(a, b)


def test_a_chain_line_does_not_see_the_polyester_beside_it():
    """The chain line's nodes step to the same bits whether the other lines are polyester (bonds of a
    table) or chain: the constant-EA bonds keep T = EA e."""
    out = []
    for other in ("poly", "chain"):
        sc = polyester_fpso(lines=(0, 4), chain=(0,) if other == "poly" else (0, 4))
        m = MooringFEM(sc, segments=20)
        m.initialise(ZERO)
        f = m.fem
        dt = 0.004
        t = (np.arange(1500) + 1.0) * dt
        r, v = m.fairlead_states(np.column_stack([4 * np.sin(t), 0 * t, 0 * t]),
                                 np.column_stack([4 * np.cos(t), 0 * t, 0 * t]))
        f.advance(dt, r, v, np.zeros((f.n_nodes, 3)))
        out.append(f.r[: f.node_start[1]].copy())
    np.testing.assert_array_equal(out[0], out[1])


def test_segment_tension_and_energy_are_the_tables():
    """A bond of a table: tension T(e) of the table for e > 0 (plus damping, none here), 0 for
    e <= 0; the elastic energy sum of int_0^e T de l0 over the bonds."""
    sc = polyester_fpso(lines=(0,), damping=0.0)
    m = MooringFEM(sc, segments=10)
    m.initialise(ZERO)
    f = m.fem
    tab = StrainTable.from_rows(POLY["EA_table"])
    strains = np.array([-0.01, 0.0, 0.002, 0.005, 0.017, 0.04, 0.08, 0.01, 0.03, 0.001])
    r = np.zeros_like(f.r)
    r[:, 0] = np.r_[0.0, np.cumsum(f.l0[:10] * (1.0 + strains))]
    f.r, f.v = r, np.zeros_like(r)
    _, _, T = f.segment_state(f.r, f.v)
    expected = np.where(strains > 0, np.interp(strains, tab.strain, tab.tension), 0.0)
    expected[6] = 17e6 + 3.9e8 * 0.03   # beyond the last row: its slope continued
    np.testing.assert_allclose(T, expected, rtol=1e-12, atol=1e-6)
    pot = -float(np.sum(f.node_weight * f.r[:, 2]))
    e_el = sum(float(tab.strain_energy(e)) * l for e, l in zip(strains, f.l0[:10]))
    assert f.energy() == pytest.approx(pot + e_el, rel=1e-12)


def test_the_stable_step_is_the_tables_largest_slope_and_is_honoured():
    """stable_dt of a line of a table is the bound of its stiffest slope (2 / omega, omega^2 =
    4 s_max / (m l0^2) without damping): for a law that softens (300 MN to 2 % strain, then 150 MN)
    worked in its first segment, surged for 20 s at 0.95 of it the line stays sound (nodes under 3
    m/s; measured 1.6), at 1.2 of it its zig-zag mode grows until the segments go slack (nodes over
    20 m/s; measured 52: the slack and the softer slope beyond 2 % bound it) and at 1.5 it blows up.
    A step from the secant, 200 MN, would be 1.22 times too long."""
    table = [[0.0, 0.0], [0.02, 6.0e6], [0.06, 1.2e7]]
    sc = polyester_fpso(lines=(0,), table=table, damping=0.0)
    m = MooringFEM(sc, segments=40, safety=1.0)
    f = m.fem
    l0 = 2170.0 / 40
    assert f.stable_dt(1.0) == pytest.approx(l0 * math.sqrt(52.0 / 3.0e8), rel=1e-9)
    m.initialise(ZERO)
    m.settle(ZERO)
    assert float(m.fem.fairlead_tension()[0]) < 5.0e6   # in the stiff first segment
    r0, v0 = f.r.copy(), f.v.copy()

    def surge(factor):
        f.r, f.v = r0.copy(), v0.copy()
        dt = factor * f.stable_dt(1.0)
        t = (np.arange(int(20.0 / dt)) + 1.0) * dt
        w = 2 * np.pi / 20.0
        r, v = m.fairlead_states(np.column_stack([5 * np.sin(w * t), 0 * t, 0 * t]),
                                 np.column_stack([5 * w * np.cos(w * t), 0 * t, 0 * t]))
        with np.errstate(all="ignore"):
            f.advance(dt, r, v, np.zeros((f.n_nodes, 3)))
        return float(np.abs(f.v).max())

    assert surge(0.95) < 3.0
    assert surge(1.2) > 20.0
    with pytest.raises(SimulationDiverged), np.errstate(all="ignore"):
        surge(1.5)
        f.check_health()


def test_a_polyester_line_changes_length_as_its_one_section():
    """A line of a table is a one-section line in the FEM: a change of its length is its section's
    (every segment's ``l0`` scales), and its length cannot drop to zero."""
    from tapm_opt.errors import ModelError

    sc = polyester_fpso(lines=(0, 4), chain=(4,))
    m = MooringFEM(sc, segments=10)
    f = m.fem
    assert f.composite.tolist() == [True, False]
    f.L = f.L + np.array([0.0, 5.0])
    f._update_lengths()   # the chain line winches
    l0 = f.l0[f.line_of_bond == 0][:10].copy()
    f.L = f.L + np.array([5.0, 0.0])
    f._update_lengths()
    assert np.allclose(f.l0[f.line_of_bond == 0][:10], l0 + 0.5)
    f.L = f.L - np.array([f.L[0], 0.0])
    with pytest.raises(ModelError, match="composite line"):
        f._update_lengths()


def test_line_set_carries_the_tables():
    sc = polyester_fpso(lines=(0, 4, 8), chain=(8,), composite=(4,))
    ls = line_set_from_scenario(sc, segments=12)
    assert ls.sections[2] is None
    assert [t is not None for t in ls.sections[0]["EA_table"]] == [True]
    assert [t is not None for t in ls.sections[1]["EA_table"]] == [False, True, False]
    assert ls.sections[0]["EA"][0] == pytest.approx(3.4e8)
    bad = dataclasses.replace(ls, sections=(dict(ls.sections[0], EA_table=(None, None)),) + ls.sections[1:])
    from tapm_opt.errors import ModelError
    with pytest.raises(ModelError, match="EA_table has 2 entries"):
        FEMLines(bad, np.array(sc.anchors), water_depth=sc.environment.water_depth, rho_w=1025.0)
