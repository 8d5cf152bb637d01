"""Composite mooring lines (sections and points): quasi-static solve against closed forms, MoorPy
reference numbers and the homogeneous catenary; scenario validation; the workbench's models on a
composite mooring; sections of a tension-strain table (nonlinear EA)."""

from __future__ import annotations

import numpy as np
import pytest

from tapm_opt.config import load_scenario, scenario_from_dict
from tapm_opt.config.loader import scenario_to_dict
from tapm_opt.errors import CatenaryError, ScenarioError
from tapm_opt.models import catenary
from tapm_opt.models.composite import CompositeLine, WarmStart, points, profile, solve
from tapm_opt.models.mooring import MooringModel
from tapm_opt.strain_table import StrainTable


def line(L, EA, w, W, CB=None):
    L = np.asarray(L, float)
    return CompositeLine(L, np.asarray(EA, float), np.asarray(w, float),
                         np.zeros(L.size) if CB is None else np.asarray(CB, float), np.asarray(W, float))


# ------------------------------------------------------------------------------------------
# the solve
# ------------------------------------------------------------------------------------------

def test_one_section_is_the_catenary_itself():
    ln = line([2300.0], [1.163e9], [1319.3], [], CB=[0.5])
    XF = np.linspace(1800.0, 2200.0, 7)
    a = solve(XF, 950.0, ln)
    b = catenary.solve(XF, 950.0, 2300.0, 1.163e9, 1319.3, CB=0.5)
    for k in ("HF", "VF", "HA", "VA", "LBot", "dHF_dXF", "dVF_dZF"):
        np.testing.assert_array_equal(getattr(a, k), getattr(b, k))


@pytest.mark.parametrize("split", [300.0, 1000.0, 2000.0])
def test_two_equal_sections_with_a_plain_joint_are_the_homogeneous_line(split):
    """Cutting a line anywhere (on the seabed or in the water) changes nothing."""
    ln = line([split, 2300.0 - split], [1.163e9] * 2, [1319.3] * 2, [0.0])
    XF = np.linspace(1800.0, 2200.0, 9)
    a = solve(XF, 950.0, ln)
    b = catenary.solve(XF, 950.0, 2300.0, 1.163e9, 1319.3)
    np.testing.assert_allclose(a.HF, b.HF, rtol=1e-9)
    np.testing.assert_allclose(a.VF, b.VF, rtol=1e-9)
    np.testing.assert_allclose(a.HA, b.HA, rtol=1e-8, atol=1e-3)
    np.testing.assert_allclose(a.LBot, b.LBot, atol=1e-5)
    np.testing.assert_allclose(a.dHF_dXF, b.dHF_dXF, rtol=1e-8)
    np.testing.assert_allclose(a.dVF_dZF, b.dVF_dZF, rtol=1e-8)


def test_two_section_suspended_line_against_its_closed_form():
    """Inextensible-in-form, elastic two-section suspended line: spans written independently from
    (HF, VF) section by section (Irvine's closed form per section with the vertical tension
    carried down), then solved back."""
    L1, L2, w1, w2, EA1, EA2 = 600.0, 900.0, 2500.0, 400.0, 2.0e9, 8.0e8
    HF, VF = 6.0e5, 2.5e6
    V1 = VF - w2 * L2  # vertical tension at the joint
    V0 = V1 - w1 * L1  # at the anchor (> 0: suspended)
    assert V0 > 0

    def span(H, Vt, Vb, w, L, EA):
        X = H / w * (np.arcsinh(Vt / H) - np.arcsinh(Vb / H)) + H * L / EA
        Z = (np.hypot(H, Vt) - np.hypot(H, Vb)) / w + (Vb * L + 0.5 * w * L * L) / EA
        return X, Z

    Xa, Za = span(HF, V1, V0, w1, L1, EA1)
    Xb, Zb = span(HF, VF, V1, w2, L2, EA2)
    s = solve(Xa + Xb, Za + Zb, line([L1, L2], [EA1, EA2], [w1, w2], [0.0]))
    assert float(s.HF) == pytest.approx(HF, rel=1e-9)
    assert float(s.VF) == pytest.approx(VF, rel=1e-9)
    assert float(s.VA) == pytest.approx(V0, rel=1e-8)
    px, pz = points(Xa + Xb, Za + Zb, line([L1, L2], [EA1, EA2], [w1, w2], [0.0]))
    assert float(np.ravel(px)[0]) == pytest.approx(Xa, rel=1e-9)
    assert float(np.ravel(pz)[0]) == pytest.approx(Za, rel=1e-9)


@pytest.mark.parametrize("W, XF", [(2.0e5, 2000.0), (-1.5e5, 1900.0), (-1.5e5, 2050.0)])
def test_a_point_weight_is_the_jump_of_vertical_tension(W, XF):
    """Independent check of the equilibrium: at the solved joint, each section's catenary solved on
    its own (catenary.solve) pulls the joint so that their vertical forces differ by W."""
    L, EA, w = [800.0, 1500.0], [1.5e9, 1.0e9], [3000.0, 900.0]
    ln = line(L, EA, w, [W])
    ZF = 950.0
    px, pz = (float(np.ravel(a)[0]) for a in points(XF, ZF, ln))
    low = catenary.solve(px, pz, L[0], EA[0], w[0])  # anchor -> joint
    up_ = catenary.solve(XF - px, ZF - pz, L[1], EA[1], w[1], h_A=pz)  # joint -> fairlead
    assert float(low.HF) == pytest.approx(float(up_.HA), rel=1e-9)  # no horizontal load on the point
    assert float(up_.VA) - float(low.VF) == pytest.approx(W, rel=1e-7, abs=1e-3 * abs(W))
    s = solve(XF, ZF, ln)
    assert float(s.HF) == pytest.approx(float(up_.HF), rel=1e-9)


def test_a_buoy_lifts_a_grounded_stretch_off_the_seabed():
    """A chain lying on the seabed with a buoy in its middle: the buoy rises until the suspended
    chain on both sides weighs what it lifts, B = w (L_total - L_on_seabed) (closed form of a
    grounded line: no vertical tension where it touches down)."""
    w, B = 1500.0, 3.0e5
    ln = line([700.0, 700.0, 800.0], [1.5e9] * 3, [w] * 3, [0.0, -B])
    XF, ZF = 1700.0, 400.0
    s = solve(XF, ZF, ln)
    bare = solve(XF, ZF, line([700.0, 700.0, 800.0], [1.5e9] * 3, [w] * 3, [0.0, 0.0]))
    _, pz = points(XF, ZF, ln)
    assert float(np.ravel(pz)[0]) == 0.0  # the plain joint still on the seabed
    z_buoy = float(np.ravel(pz)[1])
    assert z_buoy > 1.0  # lifted
    # vertical balance of the whole line: VF + B = weight of the line in water + anchor's VA (= 0 here)
    assert float(s.VF) + B == pytest.approx(w * 2200.0 - float(bare.LBot) * 0 - w * float(s.LBot), rel=1e-7)
    assert float(s.LBot) < float(bare.LBot)


# MoorPy 1.3.0 (System with two fixed points, free points with m = W/g or v = -W/(rho g),
# rho 1025, g 9.81, solveEquilibrium(tol=1e-6)): fairlead (HF, VF) of three composite lines.
MOORPY = [
    ((300.0, 1900.0, 100.0), (1.5e9, 1.0e9, 1.5e9), (1500.0, 400.0, 1500.0), (2e5, -1e5),
     {1400.0: (4878.576956752974, 394781.0545809714), 1800.0: (193899.41390433736, 550534.8992678155)}),
    ((400.0, 1000.0), (1e9, 1e8), (1000.0, 50.0), (-4e5,),
     {1400.0: (23241461.867471687, 15753631.380424472), 1800.0: (54037521.10720604, 28508365.894836634)}),
    ((800.0, 700.0), (1e9, 1e9), (1000.0, 1000.0), (3e5,),
     {1400.0: (105862547.16622995, 72746552.43352818), 1800.0: (315615993.1353311, 167485417.7778676)}),
]


@pytest.mark.parametrize("case", range(len(MOORPY)))
def test_composite_lines_against_moorpy(case):
    L, EA, w, W, ref = MOORPY[case]
    ln = line(L, EA, w, W)
    for XF, (H, V) in ref.items():
        s = solve(XF, 950.0, ln)
        assert float(s.HF) == pytest.approx(H, rel=2e-6)
        assert float(s.VF) == pytest.approx(V, rel=2e-6)


def test_stiffness_is_the_derivative_of_the_tensions():
    ln = line([300.0, 1900.0, 100.0], [1.5e9, 1.0e9, 1.5e9], [1500.0, 400.0, 1500.0], [2e5, -1e5])
    XF, ZF, e = np.array([1700.0, 1900.0, 2050.0]), 950.0, 1e-3
    s = solve(XF, ZF, ln)
    sp, sm = solve(XF + e, ZF, ln), solve(XF - e, ZF, ln)
    np.testing.assert_allclose((sp.HF - sm.HF) / (2 * e), s.dHF_dXF, rtol=1e-5)
    np.testing.assert_allclose((sp.VF - sm.VF) / (2 * e), s.dVF_dXF, rtol=1e-5)
    sp, sm = solve(XF, ZF + e, ln), solve(XF, ZF - e, ln)
    np.testing.assert_allclose((sp.HF - sm.HF) / (2 * e), s.dHF_dZF, rtol=1e-5)
    np.testing.assert_allclose((sp.VF - sm.VF) / (2 * e), s.dVF_dZF, rtol=1e-5)


def test_a_warm_start_gives_the_same_solution_in_fewer_iterations():
    """fpso's chain-wire-chain line: solved from the last solution's points (a fairlead moved
    0.3 m) the answer is the usual start's to the solve's tolerance, in fewer Newton iterations; a
    start from distances farther than its reach is not used, and a start that does not converge
    falls back to the usual one."""
    mm = MooringModel.from_scenario(load_scenario("fpso"))
    c, zf, hA = mm.composite[0], float(mm.ZF[0]), float(mm.h_A[0])
    XF = np.linspace(1950.0, 2080.0, 12)
    warm = WarmStart()
    solve(XF, zf, c, h_A=hA, warm=warm)
    cold = solve(XF + 0.3, zf, c, h_A=hA)
    hot = solve(XF + 0.3, zf, c, h_A=hA, warm=warm)
    scale = c.force_scale()
    for k in ("HF", "VF", "HA", "VA"):
        np.testing.assert_allclose(getattr(hot, k), getattr(cold, k), rtol=0, atol=1e-9 * scale)
    np.testing.assert_allclose(hot.dHF_dXF, cold.dHF_dXF, rtol=1e-6)
    assert hot.iterations < cold.iterations
    # out of reach (200 m on): not used, so the usual start's iterations
    far = solve(XF + 200.0, zf, c, h_A=hA, warm=warm)
    assert far.iterations == solve(XF + 200.0, zf, c, h_A=hA).iterations
    # a poisoned start: the points put far off; the answer is still the line's
    warm.y = warm.y + np.where(np.arange(warm.y.shape[1]) % 2 == 0, -400.0, 300.0)
    again = solve(XF + 200.1, zf, c, h_A=hA, warm=warm)  # within reach of the last (XF + 200)
    ref = solve(XF + 200.1, zf, c, h_A=hA)
    np.testing.assert_allclose(again.HF, ref.HF, rtol=0, atol=1e-9 * scale)
    # another fairlead height: not used
    assert warm.start(XF, np.full(12, zf + 1.0), np.full(12, hA), 100.0) is None


def test_profile_is_continuous_and_ends_at_the_fairlead():
    ln = line([300.0, 1900.0, 100.0], [1.5e9, 1.0e9, 1.5e9], [1500.0, 400.0, 1500.0], [2e5, -1e5])
    pr = profile(1900.0, 950.0, ln, n=200)
    assert pr["x"][0] == pytest.approx(0.0, abs=1e-9) and pr["z"][0] == pytest.approx(0.0, abs=1e-9)
    assert pr["x"][-1] == pytest.approx(1900.0, abs=1e-6) and pr["z"][-1] == pytest.approx(950.0, abs=1e-6)
    assert pr["T"][-1] == pytest.approx(float(pr["solution"].TF), rel=1e-8)
    assert np.all(np.diff(pr["s"]) >= -1e-9)
    assert np.max(np.hypot(np.diff(pr["x"]), np.diff(pr["z"]))) < 2300.0 / 50


def test_bad_input_is_named():
    ln = line([300.0, 1900.0], [1.5e9, 1.0e9], [1500.0, 400.0], [0.0])
    with pytest.raises(CatenaryError, match="XF"):
        solve(-1.0, 950.0, ln)
    with pytest.raises(CatenaryError, match="ZF"):
        solve(1800.0, np.nan, ln)
    with pytest.raises(CatenaryError, match="weighs -.* N in water with its buoyant sections"):   # it floats
        solve(1800.0, 950.0, line([300.0, 1900.0], [1.5e9, 1.0e9], [1500.0, -300.0], [0.0]))


# ------------------------------------------------------------------------------------------
# scenarios
# ------------------------------------------------------------------------------------------

def composite_fpso(buoy: bool = True):
    """fpso_equivalent (fpso's former homogeneous mooring, 1970 m anchor circle) with its lines as
    the chain-wire-chain they stand for (300 m chain, 1900 m wire, 100 m chain), with a buoy at the
    bottom joint when ``buoy``."""
    d = scenario_to_dict(load_scenario("fpso_equivalent"))
    d["line_types"] += [
        {"id": "chain137", "diameter": 0.2466, "mass_per_length": 373.5, "submerged_weight": 3185.6, "EA": 1.603e9,
         "MBS": 16.99e6, "MBS_std": 0.1 * 16.99e6, "Cd_normal": 2.4, "Cd_tangential": 1.15, "Ca_normal": 1.0},
        {"id": "wire165", "diameter": 0.165, "mass_per_length": 108.6, "submerged_weight": 926.4, "EA": 1.100e9,
         "MBS": 17.24e6, "MBS_std": 0.1 * 17.24e6, "Cd_normal": 1.2, "Cd_tangential": 0.025, "Ca_normal": 1.0},
    ]
    d["point_types"] = [{"id": "buoy", "mass": 5000.0, "volume": 40.0, "CdA": 20.0, "Ca": 1.0}]
    for ln in d["lines"]:
        del ln["type"], ln["length"]
        for k in ("winch_max_rate", "min_length", "max_length"):  # no winches (tests/test_winch_composite.py)
            ln.pop(k, None)
        ln["sections"] = [{"type": "chain137", "length": 300.0, **({"top": "buoy"} if buoy else {})},
                          {"type": "wire165", "length": 1900.0}, {"type": "chain137", "length": 100.0}]
    return scenario_from_dict(d, source="composite fpso")


def test_composite_scenario_loads_and_round_trips():
    sc = composite_fpso()
    ln = sc.lines[0]
    assert ln.composite and ln.type == "chain137" and ln.length == pytest.approx(2300.0)
    sec = sc.line_sections[0]
    assert sec["L"].tolist() == [300.0, 1900.0, 100.0]
    assert sec["W"][0] == pytest.approx((5000.0 - 1025.0 * 40.0) * 9.81, rel=1e-3)
    assert sum(sec["segments"]) == ln.segments
    again = scenario_from_dict(scenario_to_dict(sc), source="again")
    assert again == sc


@pytest.mark.parametrize("edit, field", [
    (lambda ln: ln.update(type="wire165"), "lines[0]"),
    (lambda ln: ln["sections"][0].update(top="boy"), "lines[0].sections[0].top"),
    (lambda ln: ln["sections"][-1].update(top="buoy"), "lines[0].sections[2].top"),
    (lambda ln: ln["sections"][1].update(type="wire"), "lines[0].sections[1].type"),
])
def test_composite_scenario_errors_name_the_field(edit, field):
    d = scenario_to_dict(composite_fpso())
    ln = d["lines"][0]
    ln.pop("type", None)
    ln.pop("length", None)
    edit(ln)
    with pytest.raises(ScenarioError) as ei:
        scenario_from_dict(d, source="bad")
    assert any(iss.path == field for iss in ei.value.issues), [i.path for i in ei.value.issues]


def test_mooring_model_of_a_composite_scenario():
    sc = composite_fpso()
    m = MooringModel.from_scenario(sc)
    assert m.has_composite
    eta = np.array([20.0, -10.0, 0.05])
    sol = m.solve_lines(eta)
    _, _, XF = m.spans(eta)
    for i in (0, 5):
        ref = solve(XF[i], m.ZF[i], m.composite[i], h_A=m.h_A[i])
        assert float(sol.TF[i]) == float(ref.TF)
    # the tabulated load follows the exact one
    tau = m.force(eta)
    np.testing.assert_allclose(m.force_fast(eta), tau, rtol=1e-7, atol=1e-6 * np.max(np.abs(tau)))
    # exact stiffness against central differences of the load
    K = m.stiffness(eta)
    e = np.array([1e-3, 1e-3, 1e-6])
    for j in range(3):
        d = np.zeros(3)
        d[j] = e[j]
        col = -(m.force(eta + d) - m.force(eta - d)) / (2 * e[j])
        np.testing.assert_allclose(K[:, j], col, rtol=1e-4, atol=1e-4 * np.max(np.abs(K)))
    # the symbolic "catenary" kind: composite lines through the spline of their exact solve
    f = m.force_function("catenary", with_closure_error=True)
    for e in (eta, np.array([-35.0, 20.0, -0.08])):
        t_sym, err = f(e)
        assert float(err) == 0.0
        # the splines' error is a few 1e-6 of a line's tension (checked at the sample midpoints)
        np.testing.assert_allclose(np.ravel(t_sym), m.force(e), rtol=3e-5)
    worst = max(m.line_interpolant(i).max_error for i in range(m.n_lines))
    assert 0.0 < worst < 2e-5
    T_sym = m.tension_function("catenary")
    np.testing.assert_allclose(np.ravel(T_sym(eta)), m.tensions(eta), rtol=1e-5)
    # far beyond the sampled distances: NaN, not an extrapolated load
    assert np.all(np.isnan(np.ravel(f(np.array([900.0, 0.0, 0.0]))[0])))
    f = m.force_function("characteristic", eta0=eta)
    np.testing.assert_allclose(np.ravel(f(eta)), tau, rtol=1e-9)
    # a broken line leaves the others composite
    assert m.without([m.line_ids[0]]).has_composite


def test_composite_differs_from_its_homogeneous_equivalent():
    """The chain-wire-chain line is not its length-weighted equivalent: its fairlead tension at the
    same geometry differs (heavier chain at the bottom, lighter wire in the water column)."""
    comp = MooringModel.from_scenario(composite_fpso(buoy=False))
    homo = MooringModel.from_scenario(load_scenario("fpso_equivalent"))
    Tc, Th = comp.tensions(np.zeros(3)), homo.tensions(np.zeros(3))
    assert not np.allclose(Tc, Th, rtol=0.01)


def test_detection_and_anchor_slam_build_on_a_composite_mooring():
    from tapm_opt.estimation.anchor_slam import TensionRangeMap
    from tapm_opt.estimation.detection import _TensionTable as TensionTables

    sc = composite_fpso()
    m = MooringModel.from_scenario(sc)
    tt = TensionTables(m)
    eta = np.array([15.0, 5.0, 0.02])
    np.testing.assert_allclose(tt(eta), m.tensions(eta), rtol=1e-5)
    tm = TensionRangeMap(m)
    T = m.tensions(np.zeros(3))
    _, _, XF = m.spans(np.zeros(3))
    np.testing.assert_allclose(tm.distance(T), XF, rtol=1e-6)


# ------------------------------------------------------------------------------------------
# sections of a tension-strain table (nonlinear EA)
# ------------------------------------------------------------------------------------------

POLY_ROWS = ((0.0, 0.0), (0.005, 1.0e6), (0.01, 2.4e6), (0.02, 5.6e6), (0.03, 9.2e6), (0.05, 17.0e6))
"""A polyester-like law that stiffens with load (slopes 200-390 MN, secant 340 MN)."""


def chain_poly_chain(table, W=(-3.5e5, 0.0)):
    """300 m of chain from the anchor, 1000 m of polyester of ``table`` (its secant as EA), 100 m of
    chain to the fairlead; a buoy at the lower joint."""
    tab = StrainTable.from_rows(table)
    return CompositeLine(np.array([300.0, 1000.0, 100.0]), np.array([1.6e9, tab.secant, 1.6e9]),
                         np.array([3185.6, 138.19, 3185.6]), np.zeros(3), np.asarray(W, float),
                         tables=(None, tab, None))


def section_regimes(sol, n):
    """The section regimes (catenary codes, from the anchor up) in a composite solution's code."""
    c = int(sol.regime) >> (n - 1)
    out = []
    for _ in range(n):
        out.append(catenary.regime_name(c % 6))
        c //= 6
    return out[::-1]


def test_a_section_of_a_linear_table_is_a_section_of_constant_ea():
    """The polyester section as a table of rows on T = EA eps gives the constant-EA composite line's
    tensions and stiffness to round-off (1e-12 of the tension, 1e-10 of the stiffness; measured 8e-15
    and 2e-14)."""
    EA = 3.4e8
    lin = chain_poly_chain([[0.0, 0.0], [0.01, 0.01 * EA], [0.05, 0.05 * EA]])
    ref = line([300.0, 1000.0, 100.0], [1.6e9, EA, 1.6e9], [3185.6, 138.19, 3185.6], [-3.5e5, 0.0])
    XF = np.linspace(1000.0, 1300.0, 4)
    a, b = solve(XF, 300.0, lin), solve(XF, 300.0, ref)
    for k in ("HF", "VF", "HA", "VA"):
        assert np.max(np.abs(getattr(a, k) - getattr(b, k))) <= 1e-12 * np.max(b.TF)
    for k in ("dHF_dXF", "dHF_dZF", "dVF_dXF", "dVF_dZF"):
        assert np.max(np.abs(getattr(a, k) - getattr(b, k))) <= 1e-10 * np.max(np.abs(getattr(b, k)))


def test_one_section_of_a_table_is_the_catenary_of_the_table():
    tab = StrainTable.from_rows(POLY_ROWS)
    ln = CompositeLine(np.array([2170.0]), np.array([tab.secant]), np.array([138.19]), np.zeros(1), np.zeros(0),
                       tables=(tab,))
    XF = np.linspace(1800.0, 2000.0, 5)
    a, b = solve(XF, 982.0, ln), catenary.solve(XF, 982.0, 2170.0, tab.secant, 138.19, table=tab)
    for k in ("HF", "VF", "dHF_dXF"):
        np.testing.assert_array_equal(getattr(a, k), getattr(b, k))
    px, pz = points(1900.0, 982.0, ln)
    assert px.size == 0 and pz.size == 0


@pytest.mark.parametrize("XF", [1000.0, 1150.0, 1300.0])
def test_stiffness_of_table_sections_is_the_derivative_of_the_tensions(XF):
    """Chain-polyester-chain under a buoy, the polyester section touching down from the buoy's
    joint (its elevated end's V1 and the span's change with it from the table) or suspended: the
    exact stiffness against central differences 1e-4 m apart, within 2e-6 (measured 4.4e-7)."""
    ln = chain_poly_chain(POLY_ROWS)
    s = solve(XF, 300.0, ln)
    if XF == 1000.0:
        assert section_regimes(s, 3) == ["touchdown", "touchdown", "suspended"]
    d = 1e-4
    xp, xm = solve(XF + d, 300.0, ln), solve(XF - d, 300.0, ln)
    zp, zm = solve(XF, 300.0 + d, ln), solve(XF, 300.0 - d, ln)
    for an, fd in ((s.dHF_dXF, (xp.HF - xm.HF) / (2 * d)), (s.dVF_dXF, (xp.VF - xm.VF) / (2 * d)),
                   (s.dHF_dZF, (zp.HF - zm.HF) / (2 * d)), (s.dVF_dZF, (zp.VF - zm.VF) / (2 * d))):
        assert abs(float(an) - float(fd)) <= 2e-6 * max(abs(float(s.dHF_dXF)), abs(float(s.dVF_dZF))), (an, fd)


def test_joint_equilibrium_with_a_table_section():
    """At the solution the buoy's joint is in equilibrium: the polyester section's force on it, from
    its own catenary of the table between the joints, balances the chain's and the buoy's lift."""
    ln = chain_poly_chain(POLY_ROWS)
    XF, ZF = 1150.0, 300.0
    px, pz = (np.ravel(a) for a in points(XF, ZF, ln))
    x = np.r_[0.0, px, XF]
    z = np.r_[0.0, pz, ZF]
    s0 = catenary.solve(x[1] - x[0], z[1] - z[0], 300.0, 1.6e9, 3185.6)
    s1 = catenary.solve(x[2] - x[1], z[2] - z[1], 1000.0, ln.EA[1], 138.19, h_A=z[1], table=ln.tables[1])
    # joint 1: section 0 pulls it back and down (HF, VF), section 1 forward with (HA, VA), the buoy lifts 3.5e5 N
    Fx = -float(s0.HF) + float(s1.HA)
    Fz = -float(s0.VF) + float(s1.VA) + 3.5e5
    assert abs(Fx) < 1e-6 * float(s1.HA) and abs(Fz) < 1e-6 * 3.5e5, (Fx, Fz)
