"""Buoyant sections of composite lines (submerged weight w < 0: distributed buoyancy, a lazy wave's
arch): the inverted catenary against closed forms, lazy-wave lines against MoorPy reference numbers
and their joint equilibrium from the usual start, exact stiffness, the refusals (the sea surface,
a line that floats), and the rule of where a buoyant section may be in a scenario.

MoorPy is not a dependency: its numbers below were measured once and are hard-coded.
"""

from __future__ import annotations

import numpy as np
import pytest

from tapm_opt.config import load_scenario, scenario_from_dict, scenario_to_dict
from tapm_opt.config.loader import buoyant_line_problem
from tapm_opt.errors import CatenaryError, ScenarioError
from tapm_opt.models import catenary, composite
from tapm_opt.models.composite import CompositeLine, points, profile, solve
from tapm_opt.models.mooring import MooringModel


def line(L, EA, w, W=None, surface=None):
    L = np.asarray(L, float)
    return CompositeLine(L, np.asarray(EA, float), np.asarray(w, float), np.zeros(L.size),
                         np.zeros(L.size - 1) if W is None else np.asarray(W, float), surface=surface)


def spans(H, Vb, w, L, EA):
    """Horizontal and vertical span of a suspended elastic catenary of any sign of weight w [N/m]
    from the end where its vertical tension (along the line, upward positive) is ``Vb`` to the one
    where it is ``Vb + w L`` (Irvine's closed form; no flip)."""
    Vt = Vb + w * L
    X = H / w * (np.arcsinh(Vt / H) - np.arcsinh(Vb / H)) + H * L / EA
    Z = (np.hypot(H, Vt) - np.hypot(H, Vb)) / w + (Vb * L + 0.5 * w * L * L) / EA
    return X, Z


# A lazy wave in 1000 m of water: 500 m of chain from the anchor (on the seabed), 400 m of buoyant
# line (1400 N/m of net lift, 1.5 times the wire's weight) arching up, 1500 m of wire to the
# fairlead 982 m above the anchor.
LAZY = ((500.0, 400.0, 1500.0), (1.6e9, 4.0e8, 1.1e9), (3185.0, -1400.0, 926.0))
ZF = 982.0


def lazy(**kw) -> CompositeLine:
    return line(*LAZY, **kw)


def section_forces(x, z, k, ln: CompositeLine, top=1e4):
    """Forces [N] (x, z up) of section k on its two ends (lower, upper index), from
    :func:`catenary.solve` of that section alone between the given end positions; a buoyant one by
    hand, its geometry mirrored about the height ``top``."""
    L, EA, w = float(ln.L[k]), float(ln.EA[k]), float(ln.w[k])
    zz = np.asarray(z, float) if w > 0 else top - np.asarray(z, float)
    a, b = (k, k + 1) if zz[k + 1] >= zz[k] else (k + 1, k)
    sg = 1.0 if x[b] >= x[a] else -1.0
    s = catenary.solve(abs(x[b] - x[a]), zz[b] - zz[a], L, EA, abs(w), h_A=max(zz[a], 0.0))
    flip = 1.0 if w > 0 else -1.0
    fa = np.array([sg * float(s.HA), flip * float(s.VA)])   # on the (mirrored) lower end
    fb = np.array([-sg * float(s.HF), -flip * float(s.VF)])  # on the (mirrored) upper end
    return (fa, fb) if a == k else (fb, fa)


# ------------------------------------------------------------------------------------------
# one buoyant section: the inverted catenary
# ------------------------------------------------------------------------------------------

@pytest.mark.parametrize("xlo, zlo, xhi, zhi, EA", [
    (0.0, 150.0, 300.0, 220.0, 4e8),     # an arch: its top between its ends
    (0.0, 150.0, 120.0, 420.0, 4e8),     # rising all the way (its top at the upper end)
    (0.0, 300.0, 250.0, 180.0, 4e8),     # written from its upper end down (a section below a buoy)
    (50.0, 10.0, 300.0, 80.0, 1e15),     # nearly inextensible
])
def test_a_buoyant_section_between_fixed_points_is_the_catenary_upside_down(xlo, zlo, xhi, zhi, EA):
    """A section of L = 400 m and w = -1400 N/m between two fixed points: its forces on its ends
    are the catenary of weight |w| on the mirrored geometry (the upper end as the lower one), they
    balance its net buoyancy (F_lo + F_hi = (0, |w| L)), Irvine's closed form with the negative
    weight (no flip) gives back its spans, and its Jacobian is the derivative of its forces.
    (The section solve is the composite solver's own, composite._section.)"""
    L, w, top = 400.0, -1400.0, 1000.0
    args = [np.array([v]) for v in (xlo, zlo, xhi, zhi, L, EA, w, 0.0)]
    F_lo, F_hi, J_lo, J_hi, _ = composite._section(*args, top=np.array([top]))
    F_lo, F_hi = F_lo[0], F_hi[0]
    # mirrored: heights down from the top; the real upper end is the mirrored lower end
    up = zhi >= zlo
    (xa, za), (xb, zb) = ((xhi, zhi), (xlo, zlo)) if up else ((xlo, zlo), (xhi, zhi))
    m = catenary.solve(abs(xb - xa), za - zb, L, EA, -w, h_A=top - za)
    sg = 1.0 if xb >= xa else -1.0
    on_a = np.array([sg * float(m.HA), -float(m.VA)])   # the real upper end: pulled down by VA
    on_b = np.array([-sg * float(m.HF), float(m.VF)])   # the real lower end: pulled up by VF
    lo_ref, hi_ref = (on_b, on_a) if up else (on_a, on_b)
    T = float(np.hypot(*F_lo))
    np.testing.assert_allclose(F_lo, lo_ref, rtol=0, atol=1e-10 * T)
    np.testing.assert_allclose(F_hi, hi_ref, rtol=0, atol=1e-10 * T)
    # the section's own balance: its ends hold its net buoyancy
    np.testing.assert_allclose(F_lo + F_hi, [0.0, -w * L], rtol=0, atol=1e-9 * T)
    # Irvine's spans with the negative weight, from the lower end (its vertical tension upward
    # there is the line's pull on it) to the upper end
    f_low = F_lo if up else F_hi
    H, Vb = abs(float(f_low[0])), float(f_low[1])
    X, Z = spans(H, Vb, w, L, EA)
    assert X == pytest.approx(abs(xhi - xlo), rel=1e-9)
    assert Z == pytest.approx(abs(zhi - zlo), rel=1e-9, abs=1e-8)
    # exact Jacobian of the end forces with respect to the ends (x_lo, z_lo, x_hi, z_hi)
    e = 1e-3
    for c in range(4):
        d = np.zeros(4)
        d[c] = e
        p = [np.array([v]) for v in np.array([xlo, zlo, xhi, zhi]) + d] + args[4:]
        q = [np.array([v]) for v in np.array([xlo, zlo, xhi, zhi]) - d] + args[4:]
        Fp = composite._section(*p, top=np.array([top]))
        Fq = composite._section(*q, top=np.array([top]))
        for i, J in ((0, J_lo), (1, J_hi)):
            np.testing.assert_allclose(J[0, :, c], (Fp[i][0] - Fq[i][0]) / (2 * e), rtol=2e-5, atol=1e-6 * T)


def test_a_suspended_line_with_a_buoyant_section_against_its_closed_form():
    """chain - buoyant line - chain, suspended: the spans of Irvine's closed form section by section
    (the vertical tension carried down, rising by |w| L across the buoyant section), solved back."""
    Ls, EAs, ws = (600.0, 300.0, 400.0), (1.5e9, 4e8, 1.5e9), (1500.0, -1200.0, 1500.0)
    HF, VF = 4.0e5, 1.2e6
    V = [VF]
    for k in (2, 1, 0):
        V.insert(0, V[0] - ws[k] * Ls[k])   # vertical tension below section k
    assert V[0] > 0   # the anchor lifted: every section suspended
    X = Z = 0.0
    xs, zs = [], []
    for k in range(3):
        dx, dz = spans(HF, V[k], ws[k], Ls[k], EAs[k])
        X, Z = X + dx, Z + dz
        xs.append(X)
        zs.append(Z)
    ln = line(Ls, EAs, ws)
    s = solve(X, Z, ln)
    assert float(s.HF) == pytest.approx(HF, rel=1e-9)
    assert float(s.VF) == pytest.approx(VF, rel=1e-9)
    assert float(s.VA) == pytest.approx(V[0], rel=1e-8)
    # the whole line's vertical balance: what the fairlead and anchor hold is its weight in water
    assert float(s.VF) - float(s.VA) == pytest.approx(sum(w * L for w, L in zip(ws, Ls)), rel=1e-9)
    px, pz = points(X, Z, ln)
    np.testing.assert_allclose(np.ravel(px), xs[:2], rtol=1e-9)
    np.testing.assert_allclose(np.ravel(pz), zs[:2], rtol=1e-9)


# ------------------------------------------------------------------------------------------
# lazy waves
# ------------------------------------------------------------------------------------------

# MoorPy 1.3.0, measured once: System(depth=1000, rho=1025, g=9.81), line types of m = 1000 kg/m
# and the w above, anchor fixed at (0, 0, -1000), the fairlead fixed at (XF, 0, -18), the two free
# points started near the answer, solveEquilibrium(tol=1e-10, maxIter=5000); the fairlead force
# of the top line, (HF, VF) [N]. At XF = 1400 m the wire sags from the arch onto the seabed, where
# MoorPy's catenary returns end forces that do not balance (fAH = 0 against fBH = 2.8e5 N at its
# equilibrium), so there is no reference there.
MOORPY = {1800.0: (351258.1663000683, 1174317.818425946), 2050.0: (876084.2194725198, 1378890.586976421)}


@pytest.mark.parametrize("XF", sorted(MOORPY))
def test_a_lazy_wave_against_moorpy(XF):
    H, V = MOORPY[XF]
    s = solve(XF, ZF, lazy())
    assert float(s.HF) == pytest.approx(H, rel=1e-9)
    assert float(s.VF) == pytest.approx(V, rel=1e-9)


def test_a_lazy_wave_balances_every_joint_from_the_usual_start_at_every_offset():
    """From 1300 m to 2150 m (the anchor 700 m closer to 150 m further than at 2000 m), each
    distance solved alone from the equivalent line's start: every joint balances the forces of its
    two sections, each solved on its own between the joints, to 1e-8 of the fairlead tension; the
    line is a lazy wave (chain on the seabed, an arch above both its ends); all at once (with
    continuation) the same answer."""
    ln = lazy()
    XF = np.linspace(1300.0, 2150.0, 18)
    TF = []
    for X in XF:
        s = solve(X, ZF, ln, continuation=False)
        px, pz = points(X, ZF, ln)
        x, z = np.r_[0.0, np.ravel(px), X], np.r_[0.0, np.ravel(pz), ZF]
        F = [section_forces(x, z, k, ln) for k in range(3)]
        for j in (1, 2):
            assert np.max(np.abs(F[j - 1][1] + F[j][0])) <= 1e-8 * float(s.TF), (X, j)
        assert np.allclose(-F[2][1], [float(s.HF), float(s.VF)], rtol=1e-9)
        assert float(s.LBot) > 100.0
        pr = profile(X, ZF, ln, n=600)
        arch = (pr["s"] >= 500.0) & (pr["s"] <= 900.0)
        assert np.all(pr["z"][arch] >= z[1] - 1e-9)   # never below its lower end
        if X <= 1950.0:   # an arch; beyond, pulled nearly straight, it rises to its upper end
            assert pr["z"][arch].max() > max(z[1], z[2]) + 10.0, X
        TF.append(float(s.TF))
    np.testing.assert_allclose(solve(XF, ZF, ln).TF, TF, rtol=1e-9)


def test_stiffness_of_a_lazy_wave_is_the_derivative_of_the_tensions():
    ln = lazy()
    XF, e = np.array([1400.0, 1800.0, 2050.0]), 1e-3
    s = solve(XF, ZF, ln)
    for name, d in (("XF", (e, 0.0)), ("ZF", (0.0, e))):
        sp, sm = solve(XF + d[0], ZF + d[1], ln), solve(XF - d[0], ZF - d[1], ln)
        for f in ("HF", "VF"):
            fd = (getattr(sp, f) - getattr(sm, f)) / (2 * e)
            np.testing.assert_allclose(getattr(s, f"d{f}_d{name}"), fd, rtol=1e-5, atol=1e-6 * float(np.max(s.TF)))


def test_a_buoy_on_a_buoyant_section_and_a_clump_below_it():
    """Points on a lazy wave (a buoy at the top of the arch, a clump at its foot): still balanced."""
    ln = lazy(W=[2.0e5, -1.0e5])
    X = 1800.0
    s = solve(X, ZF, ln)
    px, pz = points(X, ZF, ln)
    x, z = np.r_[0.0, np.ravel(px), X], np.r_[0.0, np.ravel(pz), ZF]
    F = [section_forces(x, z, k, ln) for k in range(3)]
    for j, W in ((1, 2.0e5), (2, -1.0e5)):
        r = F[j - 1][1] + F[j][0] + [0.0, -W]
        assert np.max(np.abs(r)) <= 1e-8 * float(s.TF), (j, r)


# ------------------------------------------------------------------------------------------
# refusals
# ------------------------------------------------------------------------------------------

def test_a_buoyant_section_that_reaches_the_surface_is_refused():
    """In 100 m of water a 150 m buoyant section rises to the surface at 450 m and closer, not at
    470 m (its top 4 m below the surface); the error names the section, the surface's height and
    what would float. Without the water depth the fairlead's height (90 m) stands for the surface."""
    ln = line((300.0, 150.0, 150.0), (1.6e9, 4e8, 1.1e9), (3185.6, -1000.0, 926.4), surface=100.0)
    pr = profile(470.0, 90.0, ln, n=600)
    assert 95.0 < pr["z"][(pr["s"] > 300.0) & (pr["s"] < 450.0)].max() < 97.0
    assert float(solve(470.0, 90.0, ln).TF) > 0
    for call in (solve, points, profile):
        with pytest.raises(CatenaryError, match=r"buoyant section 1 \(150 m, w = -1000 N/m\) reaches the sea surface: "
                                                r"it rises to the sea surface 100 m above the seabed, where [0-9.]+ m of "
                                                r"it would float"):
            call(450.0, 90.0, ln)
    with pytest.raises(CatenaryError, match="XF = 400 m, ZF = 90 m"):
        solve(np.array([500.0, 400.0]), 90.0, ln)
    # the surface unknown: the fairlead's height (90 m) bounds it
    with pytest.raises(CatenaryError, match="taken at the fairlead's height 90 m above the seabed"):
        solve(470.0, 90.0, line(ln.L, ln.EA, ln.w))
    # an end above the surface
    with pytest.raises(CatenaryError, match="above the sea surface"):
        solve(500.0, 90.0, line(ln.L, ln.EA, ln.w, surface=95.0, W=[0.0, -5e5]))


def test_a_line_that_floats_is_refused():
    with pytest.raises(CatenaryError, match=r"weighs -\d+ N in water with its buoyant sections: a line must weigh"):
        solve(300.0, 90.0, line((100.0, 300.0, 150.0), (1.6e9, 4e8, 1.1e9), (3185.6, -2575.0, 926.4)))
    with pytest.raises(CatenaryError, match="weighs"):
        solve(300.0, 90.0, line((400.0,), (4e8,), (-100.0,)))


# ------------------------------------------------------------------------------------------
# scenarios: the rule, and the models on a lazy-wave mooring
# ------------------------------------------------------------------------------------------

FLOAT = {"id": "float800", "diameter": 0.8, "mass_per_length": 250.0, "density": 650.0, "EA": 4.0e8,
         "MBS": 1.0e7, "MBS_std": 5.0e5, "Cd_normal": 1.2, "Cd_tangential": 0.1, "Ca_normal": 1.0}
"""Distributed buoyancy modules on a line: 250 kg/m in 0.385 m^3/m (density 650 kg/m^3), a net
lift of 1415 N/m in 1025 kg/m^3."""


def lazy_wave_fpso(sections=(("chain137", 500.0), ("float800", 400.0), ("wire165", 1500.0)), **extra):
    """fpso_equivalent (1970 m anchor circle in 1000 m) with lazy-wave lines: chain, buoyant line,
    wire from the anchor up."""
    d = scenario_to_dict(load_scenario("fpso_equivalent"))
    d["line_types"] += [
        {"id": "chain137", "diameter": 0.2466, "mass_per_length": 373.5, "submerged_weight": 3185.6, "EA": 1.603e9,
         "MBS": 16.99e6, "MBS_std": 0.1 * 16.99e6, "Cd_normal": 2.4, "Cd_tangential": 1.15, "Ca_normal": 1.0},
        {"id": "wire165", "diameter": 0.165, "mass_per_length": 108.6, "submerged_weight": 926.4, "EA": 1.100e9,
         "MBS": 17.24e6, "MBS_std": 0.1 * 17.24e6, "Cd_normal": 1.2, "Cd_tangential": 0.025, "Ca_normal": 1.0},
        dict(FLOAT)]
    d.update(extra)
    for ln in d["lines"]:
        del ln["type"], ln["length"]
        for k in ("winch_max_rate", "min_length", "max_length"):
            ln.pop(k, None)
        if isinstance(sections, str):   # a homogeneous line of that type
            ln.update(type=sections, length=2400.0)
        else:
            ln["sections"] = [{"type": t, "length": L} for t, L in sections]
    return d


def test_the_models_on_a_lazy_wave_mooring():
    """A lazy-wave fpso loads; its mooring model's tensions are composite.solve's, its stiffness the
    derivative of its load, its load tables and the symbolic spline follow the exact load."""
    sc = scenario_from_dict(lazy_wave_fpso(), source="lazy wave")
    sec = sc.line_sections[0]
    assert sec["w"][1] == pytest.approx(250.0 * 9.81 * (650.0 - 1025.0) / 650.0, rel=1e-12)
    m = MooringModel.from_scenario(sc)
    eta = np.array([20.0, -10.0, 0.05])
    _, _, XF = m.spans(eta)
    ref = solve(XF[0], m.ZF[0], CompositeLine.from_arrays(sec), h_A=m.h_A[0])
    assert float(m.solve_lines(eta).TF[0]) == float(ref.TF)
    tau = m.force(eta)
    K = m.stiffness(eta)
    e = np.array([1e-3, 1e-3, 1e-6])
    for j in range(3):
        d = np.zeros(3)
        d[j] = e[j]
        col = -(m.force(eta + d) - m.force(eta - d)) / (2 * e[j])
        np.testing.assert_allclose(K[:, j], col, rtol=1e-4, atol=1e-4 * np.max(np.abs(K)))
    np.testing.assert_allclose(m.force_fast(eta), tau, rtol=1e-7, atol=1e-6 * np.max(np.abs(tau)))
    t_sym, err = m.force_function("catenary", with_closure_error=True)(eta)
    assert float(err) == 0.0
    np.testing.assert_allclose(np.ravel(t_sym), tau, rtol=3e-5)


@pytest.mark.parametrize("sections, path, words", [
    ("float800", "lines[0].type", ("= 'float800' is not heavier than water (submerged weight -1414.9 N/m): "
                                   "a line of it floats")),
    ((("float800", 500.0), ("wire165", 1900.0)), "lines[0].sections[0].type", "is the line's anchor section"),
    ((("chain137", 500.0), ("float800", 1900.0)), "lines[0].sections[1].type", "is the line's fairlead section"),
    ((("chain137", 100.0), ("float800", 1900.0), ("wire165", 400.0)), "lines[0].sections",
     "the line would float"),
])
def test_where_a_buoyant_section_may_be(sections, path, words):
    """Between weighted sections of a line that weighs in water, and nowhere else: each refusal
    names the line (or section) and the reason."""
    with pytest.raises(ScenarioError) as ei:
        scenario_from_dict(lazy_wave_fpso(sections), source="bad")
    said = [i for i in ei.value.issues if i.path == path]
    assert said and words in said[0].message, [str(i) for i in ei.value.issues]
    # the rule itself
    assert buoyant_line_problem([3185.6, -1415.0, 926.4], [500.0, 400.0, 1500.0]) is None
    assert buoyant_line_problem([3185.6, 926.4], [500.0, 400.0]) is None
    assert buoyant_line_problem([3185.6, -1415.0, 926.4], [500.0, 400.0, 1500.0], [-2.5e6])[0] is None


def test_a_scenario_gives_its_buoyant_lines_the_water_depth_as_their_surface():
    """The sea surface that bounds a buoyant section is the water depth above the seabed (not the
    fairlead's height); lines without a buoyant section carry none."""
    sc = scenario_from_dict(lazy_wave_fpso(), source="lazy wave")
    sec = sc.line_sections[0]
    assert sec["surface"] == sc.environment.water_depth
    assert CompositeLine.from_arrays(sec).surface == sc.environment.water_depth
    assert "surface" not in load_scenario("fpso").line_sections[0]
