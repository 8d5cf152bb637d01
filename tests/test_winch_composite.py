"""Winches on composite lines: the winch pays out and hauls in the fairlead section.

The scenario checks (a winch range that would haul in more than the fairlead section is refused,
naming ``min_length``), the FEM (only the fairlead section's segments change; after the payout the
line settles on the composite quasi-static solution at the new length), the quasi-static model
(``MooringModel.solve_xf(L=)`` against the composite solve of the line with its fairlead section
changed, and the analytic limit: a length change of a homogeneous one-section line is the
catenary's), the controller's tables in distance and length (``LengthTables`` against the exact
solve between grid lengths), and the tension controller in closed loop on a composite mooring.
"""

from __future__ import annotations

import numpy as np
import pytest

from tapm_opt.config import scenario_from_dict, scenario_to_dict
from tapm_opt.errors import CatenaryError, ScenarioError
from tapm_opt.models import catenary, composite
from tapm_opt.models.characteristics import LengthTables
from tapm_opt.models.system import System

from test_fem_composite import composite_fpso

TOTAL = 2300.0       # 300 m chain, 1900 m wire, 100 m chain from the anchor up
TOP = 100.0


def winched(min_length: float = TOTAL - 60.0, max_length: float = TOTAL + 60.0, lines=(0, 4, 8), **kw):
    """The chain-wire-chain fpso (``composite_fpso``) on three lines with winches on the top chain."""
    d = scenario_to_dict(composite_fpso(lines=lines, **kw))
    for ln in d["lines"]:
        ln.update(winch_max_rate=0.15, min_length=min_length, max_length=max_length)
    return scenario_from_dict(d, source="winched composite fpso")


def test_a_winch_range_beyond_the_fairlead_section_is_refused():
    sc = winched()
    assert all(ln.composite and ln.winch_max_rate == 0.15 for ln in sc.lines)
    with pytest.raises(ScenarioError, match=r"lines\[0\]\.min_length.*2200"):
        winched(min_length=TOTAL - TOP)
    winched(min_length=TOTAL - TOP + 1.0)   # 1 m of the top chain left: allowed


def test_solve_xf_pays_out_the_fairlead_section():
    """``solve_xf(L=)`` of a composite line is the composite solve of the line whose top section is
    that much longer; paying out lowers the tension; the length of a section is never negative."""
    sc = winched()
    m = System.from_scenario(sc).lines
    _, _, XF = m.spans(np.zeros(3))
    L = np.array(m.L, float)
    L[0] += 20.0
    L[1] -= 30.0
    sol = m.solve_xf(XF, L=L)
    base = m.solve_xf(XF)
    c = m.composite[0]
    ref = composite.solve(XF[0], float(m.ZF[0]), c.with_length(TOTAL + 20.0), h_A=float(m.h_A[0]))
    assert c.with_length(TOTAL + 20.0).L.tolist() == [300.0, 1900.0, 120.0]
    assert sol.TF[0] == pytest.approx(float(ref.TF), rel=1e-12)
    assert sol.TF[0] < base.TF[0] < sol.TF[1]           # paid out: slacker; hauled in: tauter
    assert sol.TF[2] == base.TF[2]                       # its own length: unchanged
    with pytest.raises(CatenaryError, match="fairlead section"):
        c.with_length(TOTAL - TOP)


def test_length_change_of_a_one_section_line_is_the_catenarys():
    """Analytic limit: a composite line of one section is a homogeneous line; its length change
    through ``with_length`` is the elastic catenary's at that length."""
    c = composite.CompositeLine(*(np.array(v, float) for v in ([2300.0], [1.2e9], [1300.0], [0.0], [])))
    sol = composite.solve(1950.0, 982.0, c.with_length(2315.0))
    ref = catenary.solve(1950.0, 982.0, 2315.0, 1.2e9, 1300.0)
    assert float(sol.TF) == pytest.approx(float(ref.TF), rel=1e-12)


def test_length_tables_match_the_exact_solve_between_grid_lengths():
    """The controller's tables: HF and TF at lengths between the 2 m grid points within 2e-4 of the
    exact composite solve (linear in L over 2 m of 2300), and to the table's tolerance on a grid
    length; beyond their distances the exact solve answers."""
    sc = winched(lower="buoy", upper="clump")
    m = System.from_scenario(sc).lines
    _, _, XF = m.spans(np.zeros(3))
    T0 = float(m.solve_xf(XF).TF[0])
    tab = LengthTables(m, 0, XF[0] - 40.0, XF[0] + 40.0, L0=TOTAL, dL=2.0, H_ref=T0)
    worst_mid, worst_grid = 0.0, 0.0
    for L in (TOTAL - 7.0, TOTAL - 0.5, TOTAL + 3.3):
        for x in (XF[0] - 25.0, XF[0], XF[0] + 31.0):
            H, T = tab(x, L)
            ex = m.line_solver(0, L=L)(x)
            worst_mid = max(worst_mid, abs(T - float(ex.TF)) / T0, abs(H - float(ex.HF)) / T0)
    for L in (TOTAL - 6.0, TOTAL + 4.0):
        H, T = tab(XF[0] + 5.0, L)
        ex = m.line_solver(0, L=L)(XF[0] + 5.0)
        worst_grid = max(worst_grid, abs(T - float(ex.TF)) / T0)
    assert worst_grid < 1e-6
    assert 1e-7 < worst_mid < 2e-4          # the interpolation in L is there, and small
    assert tab.exact_calls == 0
    H, T = tab(XF[0] + 60.0, TOTAL + 1.0)   # beyond the tables' distances
    ex = m.line_solver(0, L=TOTAL + 1.0)(XF[0] + 60.0)
    assert T == pytest.approx(float(ex.TF), rel=1e-12) and tab.exact_calls == 1


def test_fem_pays_out_the_top_section_and_settles_on_the_quasi_static_line():
    """The plant pays out 6 m of line 1's top chain at 0.15 m/s: the line's length grows by 6 m and
    only the top section's segments get longer. Settled with the vessel at the field zero point, the
    line and the line 30 m longer have the composite quasi-static fairlead tensions at their
    lengths (within 1 %), and the tension the payout removes is the quasi-static one's (within 10 %)."""
    from tapm_opt.plant.simulator import Plant, run_open_loop

    sc = winched(lines=(0, 4, 8), segments=(3, 12, 3))
    p = Plant(sc, sea_state="none", segments=18)
    fem = p.mooring.fem
    on0 = fem.line_of_bond == 0
    l0_before = fem.l0[on0].copy()
    w = np.zeros(3)
    w[0] = 0.15
    run_open_loop(p, 40.0, winch_cmd=w)
    assert fem.L[0] == pytest.approx(TOTAL + 6.0, abs=1e-9)
    grew = fem.l0[on0] - l0_before
    top = fem._top_bond[on0]
    assert top.sum() >= 1 and np.allclose(grew[~top], 0.0) and np.allclose(grew[top], 6.0 / top.sum())
    # the line at its length and 30 m longer, each settled with the vessel at the field zero point
    from tapm_opt.plant.mooring_fem import MooringFEM

    m = System.from_scenario(sc).lines
    _, _, XF = m.spans(np.zeros(3))
    T_fem, T_qs = [], []
    for dL in (0.0, 30.0):
        L = np.array([TOTAL + dL, TOTAL, TOTAL])
        mf = MooringFEM(sc, segments=18)
        mf.fem.L[:] = L
        mf.fem._update_lengths()
        mf.initialise(np.zeros(3))
        mf.settle(np.zeros(3))
        T_fem.append(mf.fairlead_tension()[0])
        T_qs.append(float(m.solve_xf(XF, L=L).TF[0]))
    assert T_fem == pytest.approx(T_qs, rel=0.01)
    drop_fem, drop_qs = T_fem[0] - T_fem[1], T_qs[0] - T_qs[1]
    assert drop_qs > 0.04 * T_qs[0]                       # 30 m of payout: 5 % slacker
    assert drop_fem == pytest.approx(drop_qs, rel=0.1)


def test_tension_control_on_a_composite_mooring_in_closed_loop():
    """The passivity-based tension controller on the winched composite fpso (12 lines) in the storm:
    it runs, moves the winches within their limits, and its model reads the tables (no exact solve
    inside their distances)."""
    from tapm_opt.studies import ClosedLoopSettings
    from tapm_opt.studies.recipe import run_case_on

    sc = winched(lines=None)
    system = System.from_scenario(sc)
    st = ClosedLoopSettings(duration=60.0, heading="fixed", winch="tension", detector="none")
    run = run_case_on(system, "pid", st, sea_state="storm", seed=1, segments=12)
    res = run.result
    L = np.column_stack([res[f"L[{ln.id}]"] for ln in sc.lines])
    assert np.all(L >= TOTAL - 60.0 - 1e-9) and np.all(L <= TOTAL + 60.0 + 1e-9)
    assert np.ptp(L, axis=0).max() > 1.0                  # the winches moved
    assert np.isfinite(run.kpis["offset_max"])
    ctrl_tables = [t for t in _controller_tables(system)]
    assert ctrl_tables and all(t.exact_calls == 0 for t in ctrl_tables)


def _controller_tables(system):
    """The tables of a tension controller built on ``system`` and run over a few updates."""
    from tapm_opt.control.winch import WinchTensionController

    w = WinchTensionController(system)
    H, T = w.measured_horizontal_tensions(np.array([5.0, -3.0, 0.02]), None)
    assert np.all(np.isfinite(H)) and np.all(H > 0) and np.all(H < T)
    return list(w._tables.values())
