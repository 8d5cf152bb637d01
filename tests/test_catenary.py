"""Tests of the elastic catenary (tapm_opt.models.catenary): analytic limits, physical invariants,
closure of every regime, sensitivities against finite differences, the symbolic CasADi path, the
line profile, random and invalid input, and a cross-check against MoorPy (independent code); the
same for lines whose lower end is above the seabed (argument h_A), and for lines of a nonlinear
axial law, a tension-strain table (argument table)."""

from __future__ import annotations

import csv
import itertools
import math
from pathlib import Path

import casadi as ca
import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st
from scipy.integrate import quad
from scipy.optimize import brentq

from tapm_opt.errors import CatenaryError
from tapm_opt.models import catenary as cat
from tapm_opt.strain_table import StrainTable, StrainTableError

DATA = Path(__file__).parent / "data"

# A chain-like line: 1000 m, EA = 5e8 N, w = 1000 N/m (order of a 100 mm studless chain in water).
L0, EA0, W0 = 1000.0, 5.0e8, 1000.0


def hanging_length(ZF, EA, w):
    """Ls of a vertical hanging line: root of ZF = Ls + w Ls^2 / (2 EA), by bisection (independent
    of the closed form in the module)."""
    return brentq(lambda Ls: Ls + w * Ls * Ls / (2.0 * EA) - ZF, 0.0, ZF, xtol=1e-13, rtol=1e-15)


def inextensible_catenary(XF, ZF, L, w):
    """Classical inextensible catenary through two points with length L: (HF, VF, VA).

    With the catenary parameter a = HF/w, L^2 - ZF^2 = (2 a sinh(XF/(2a)))^2 and
    VF + VA = w ZF coth(XF/(2a)), VF - VA = w L.
    """
    target = math.sqrt(L * L - ZF * ZF)

    def f(log_a):
        a = math.exp(log_a)
        u = XF / (2.0 * a)
        if u > 300:  # sinh overflows; far on the "too short" side
            return math.inf
        return math.log(2.0 * a * math.sinh(u)) - math.log(target)

    a = math.exp(brentq(f, math.log(XF / 600.0), math.log(1e9 * L), xtol=1e-15, rtol=1e-15))
    VF = 0.5 * w * (L + ZF / math.tanh(XF / (2.0 * a)))
    return w * a, VF, VF - w * L


def scalar(sol, name):
    return float(np.asarray(getattr(sol, name)))


# ------------------------------------------------------------------------------------------
# analytic limits
# ------------------------------------------------------------------------------------------


@pytest.mark.parametrize("EA", [5.0e8, 2.0e7])
@pytest.mark.parametrize("ZF_extra", [1e-3, 0.5, 20.0])  # metres beyond the just-taut length
def test_vertical_fully_suspended_line(EA, ZF_extra):
    L, w = L0, W0
    ZF = L + w * L * L / (2.0 * EA) + ZF_extra  # beyond the self-weight stretch: anchor lifts
    sol = cat.solve(0.0, ZF, L, EA, w)
    VF = EA * (ZF - L) / L + w * L / 2.0
    assert cat.REGIMES[int(sol.regime)] == "vertical"
    assert scalar(sol, "HF") == 0.0
    assert scalar(sol, "VF") == pytest.approx(VF, rel=1e-12)
    assert scalar(sol, "VA") == pytest.approx(VF - w * L, rel=1e-9)
    assert scalar(sol, "VA") > 0.0  # anchor uplift
    assert scalar(sol, "TF") == pytest.approx(VF, rel=1e-12)
    assert scalar(sol, "dVF_dZF") == pytest.approx(EA / L, rel=1e-12)


@pytest.mark.parametrize("EA", [5.0e8, 1.0e6])  # the soft line stretches visibly under its weight
@pytest.mark.parametrize("XF", [0.0, 100.0])
@pytest.mark.parametrize("ZF", [50.0, 400.0, 850.0])
def test_slack_hanging_line(EA, XF, ZF):
    L, w = L0, W0
    Ls = hanging_length(ZF, EA, w)
    assert L - Ls >= XF  # precondition: the rest lies on the seabed without tension
    sol = cat.solve(XF, ZF, L, EA, w)
    assert cat.REGIMES[int(sol.regime)] == "slack"
    assert scalar(sol, "HF") == 0.0
    assert scalar(sol, "VF") == pytest.approx(w * Ls, rel=1e-12)
    assert scalar(sol, "LBot") == pytest.approx(L - Ls, rel=1e-12)
    assert scalar(sol, "HA") == 0.0 and scalar(sol, "VA") == 0.0
    # the stretch is there: the hanging length is shorter than ZF for a soft line
    if EA == 1.0e6 and ZF > 100:
        assert Ls < ZF - 1.0


def test_slack_vertical_line_becomes_suspended_at_its_stretched_length():
    """Just below ZF* = L + wL^2/(2EA) the line is slack; just above, vertical and suspended,
    with VF = wL on both sides (continuity at the lift-off of the anchor)."""
    L, w, EA = L0, W0, 2.0e7
    Zstar = L + w * L * L / (2 * EA)  # 1025 m
    below = cat.solve(0.0, Zstar - 1e-6, L, EA, w)
    above = cat.solve(0.0, Zstar + 1e-6, L, EA, w)
    assert cat.REGIMES[int(below.regime)] == "slack"
    assert cat.REGIMES[int(above.regime)] == "vertical"
    assert scalar(below, "VF") == pytest.approx(w * L, rel=1e-6)
    assert scalar(above, "VF") == pytest.approx(w * L, rel=1e-6)


@pytest.mark.parametrize("XF,ZF", [(900.0, 600.0), (1000.0, 100.0), (0.0, 1200.0), (1100.0, 0.0),
                                   (300.0, 200.0), (0.0, 0.0), (800.0, 600.0)])
def test_weightless_line_is_a_straight_elastic_bar(XF, ZF):
    L, EA = L0, EA0
    ell = math.hypot(XF, ZF)
    T = EA * max(ell / L - 1.0, 0.0)
    sol = cat.solve(XF, ZF, L, EA, 0.0)
    assert cat.REGIMES[int(sol.regime)] == "weightless"
    assert scalar(sol, "TF") == pytest.approx(T, rel=1e-12, abs=1e-9)
    if T > 0:
        assert scalar(sol, "HF") == pytest.approx(T * XF / ell, rel=1e-12, abs=1e-9)
        assert scalar(sol, "VF") == pytest.approx(T * ZF / ell, rel=1e-12, abs=1e-9)
        # no weight, no friction: the same force at both ends
        assert scalar(sol, "HA") == scalar(sol, "HF") and scalar(sol, "VA") == scalar(sol, "VF")
    else:
        assert scalar(sol, "HF") == 0.0 and scalar(sol, "VF") == 0.0


INEXT_CASES = [(700.0, 700.0), (500.0, 850.0), (300.0, 950.0), (800.0, 550.0), (900.0, 400.0)]


@pytest.mark.parametrize("XF,ZF", INEXT_CASES)
def test_inextensible_limit_matches_classical_catenary(XF, ZF):
    L, w = L0, W0
    HF, VF, VA = inextensible_catenary(XF, ZF, L, w)
    assert VA > 0  # precondition: the closed form is the fully suspended catenary
    for EA in (1e15, np.inf):
        sol = cat.solve(XF, ZF, L, EA, w)
        assert cat.REGIMES[int(sol.regime)] == "suspended"
        assert scalar(sol, "HF") == pytest.approx(HF, rel=1e-6)
        assert scalar(sol, "VF") == pytest.approx(VF, rel=1e-6)
        assert scalar(sol, "VA") == pytest.approx(VA, rel=1e-6)
    # EA = inf is exact, not only a limit
    sol = cat.solve(XF, ZF, L, np.inf, w)
    assert scalar(sol, "HF") == pytest.approx(HF, rel=1e-10)
    assert scalar(sol, "VF") == pytest.approx(VF, rel=1e-10)


def test_elastic_correction_vanishes_like_one_over_EA():
    """HF(EA) - HF(inf) = O(1/EA): the error falls tenfold per decade of EA (observed order 1)."""
    XF, ZF = 300.0, 950.0
    ref = scalar(cat.solve(XF, ZF, L0, np.inf, W0, tol=1e-12), "HF")
    errs = [abs(scalar(cat.solve(XF, ZF, L0, EA, W0, tol=1e-12), "HF") - ref) for EA in (1e11, 1e12, 1e13)]
    order = np.log10(np.array(errs[:-1]) / np.array(errs[1:]))
    assert np.all(np.abs(order - 1.0) < 0.02), order


def test_inextensible_line_shorter_than_the_distance_raises():
    with pytest.raises(CatenaryError, match="inextensible"):
        cat.solve(900.0, 500.0, L0, np.inf, W0)


@pytest.mark.parametrize("EA", [5.0e8, 2.0e7])
@pytest.mark.parametrize("stretch", [0.01, 0.3, 5.0, 40.0])
def test_line_on_the_seabed_without_friction(EA, stretch):
    L = L0
    sol = cat.solve(L + stretch, 0.0, L, EA, W0)
    assert cat.REGIMES[int(sol.regime)] == "seabed"
    assert scalar(sol, "HF") == pytest.approx(EA * stretch / L, rel=1e-12)
    assert scalar(sol, "HA") == pytest.approx(EA * stretch / L, rel=1e-12)
    assert scalar(sol, "VF") == 0.0 and scalar(sol, "LBot") == L


@pytest.mark.parametrize("CB", [0.1, 0.5, 1.0])
@pytest.mark.parametrize("stretch", [0.01, 0.3, 5.0, 40.0])
def test_line_on_the_seabed_with_friction(CB, stretch):
    """The seabed holds the line with friction CB w per metre; the tension falls from HF at the
    fairlead to max(HF - CB w (L - s), 0) and integrates to the stretch XF - L (checked by
    quadrature, not with the closed form)."""
    L, EA, w = L0, 2.0e7, W0
    sol = cat.solve(L + stretch, 0.0, L, EA, w, CB=CB)
    HF, HA = scalar(sol, "HF"), scalar(sol, "HA")
    cbw = CB * w

    def tension(s):
        return max(HF - cbw * (L - s), 0.0)

    s0 = max(L - HF / cbw, 0.0)  # where the tension reaches zero (kink of the integrand)
    stretch_q = quad(tension, s0, L, epsabs=1e-14, epsrel=1e-13)[0] / EA
    assert stretch_q == pytest.approx(stretch, rel=1e-9)
    assert HA == pytest.approx(tension(0.0), rel=1e-12, abs=1e-6)
    # closed forms: partly slack (anchor unloaded) or loaded along its whole length
    if HF < cbw * L:
        assert HF == pytest.approx(math.sqrt(2.0 * EA * cbw * stretch), rel=1e-12)
        assert HA == 0.0
    else:
        assert HF == pytest.approx(EA * stretch / L + cbw * L / 2.0, rel=1e-12)
    # friction always costs fairlead tension for the same stretch
    assert HF > scalar(cat.solve(L + stretch, 0.0, L, EA, w), "HF")


def test_seabed_friction_both_closed_forms_occur():
    """The parameter set of the friction test above reaches both sub-cases (else it proves little)."""
    L, EA, w, CB = L0, 2.0e7, W0, 0.5
    part = cat.solve(L + 0.3, 0.0, L, EA, w, CB=CB)
    full = cat.solve(L + 40.0, 0.0, L, EA, w, CB=CB)
    assert scalar(part, "HA") == 0.0
    assert scalar(full, "HA") > 0.0


@pytest.mark.parametrize("XF,ZF", [(980.0, 100.0), (925.0, 100.0), (887.0, 300.0), (940.0, 300.0)])
@pytest.mark.parametrize("CB", [0.3, 0.6, 2.0])
def test_touchdown_anchor_tension_with_friction(XF, ZF, CB):
    L, EA, w = L0, EA0, W0
    sol = cat.solve(XF, ZF, L, EA, w, CB=CB)
    assert cat.REGIMES[int(sol.regime)] == "touchdown"
    HF, VF, LB = scalar(sol, "HF"), scalar(sol, "VF"), scalar(sol, "LBot")
    assert LB == pytest.approx(L - VF / w, rel=1e-12)
    assert scalar(sol, "HA") == pytest.approx(max(HF - CB * w * LB, 0.0), rel=1e-12, abs=1e-9)
    assert scalar(sol, "VA") == 0.0
    # friction takes load off the anchor but needs more fairlead tension than no friction
    free = cat.solve(XF, ZF, L, EA, w)
    assert HF > scalar(free, "HF")
    assert scalar(sol, "HA") < scalar(free, "HA")
    assert scalar(free, "HA") == scalar(free, "HF")


def test_friction_anchor_tension_reaches_zero_for_a_short_laid_length():
    sol = cat.solve(925.0, 100.0, L0, EA0, W0, CB=0.6)
    assert scalar(sol, "HA") == 0.0 and scalar(sol, "HF") > 0.0


# ------------------------------------------------------------------------------------------
# MoorPy-style invariants
# ------------------------------------------------------------------------------------------


@pytest.mark.parametrize("HF", [2.0e4, 3.0e5, 4.0e6])
@pytest.mark.parametrize("EA", [5.0e8, 3.0e7])
def test_half_of_a_symmetric_U_line_has_its_anchor_at_the_vertex(HF, EA):
    """A U-shaped line hung between two points at equal height (span 2X, length 2L) is two mirrored
    half lines from the vertex. Each half, anchored at the vertex, carries VF = w L (the weight of
    its own length, nothing at the vertex) and the U's horizontal tension; the two ends of the U
    together carry the whole weight 2wL."""
    L, w = 600.0, W0
    X, Z = cat.closure(np.array(HF), np.array(w * L), L, EA, w)  # the half line's spans
    sol = cat.solve(float(X), float(Z), L, EA, w)
    assert scalar(sol, "HF") == pytest.approx(HF, rel=1e-8)
    assert scalar(sol, "VF") == pytest.approx(w * L, rel=1e-8)
    assert abs(scalar(sol, "VA")) <= 1e-6 * w * L and scalar(sol, "LBot") <= 1e-6 * L
    # the U: both halves at once (mirror images have equal spans) hold up the whole line
    both = cat.solve(np.array([X, X]), np.array([Z, Z]), L, EA, w)
    assert np.sum(both.VF) == pytest.approx(2.0 * w * L, rel=1e-8)
    assert both.HF[0] == both.HF[1]


@pytest.mark.parametrize("XF,ZF", [(700.0, 700.0), (1000.0, 300.0), (500.0, 860.0), (980.0, 400.0)])
@pytest.mark.parametrize("EA", [5.0e8, 3.0e7])
def test_suspended_line_is_the_top_of_a_longer_line_from_its_vertex(XF, ZF, EA):
    """A fully suspended line (anchor uplift VA > 0) is the upper part of a longer line whose
    'anchor' sits at the catenary's vertex: extend it below the anchor by Le = VA/w (the piece that
    would carry VA) and the longer line has the same fairlead tensions."""
    L, w = L0, W0
    sol = cat.solve(XF, ZF, L, EA, w, tol=1e-11)
    HF, VF, VA = scalar(sol, "HF"), scalar(sol, "VF"), scalar(sol, "VA")
    assert cat.REGIMES[int(sol.regime)] == "suspended" and VA > 0  # precondition
    Le = VA / w
    Xe, Ze = cat.closure(np.array(HF), np.array(VA), Le, EA, w)  # vertex -> old anchor
    ext = cat.solve(XF + float(Xe), ZF + float(Ze), L + Le, EA, w, tol=1e-11)
    assert scalar(ext, "HF") == pytest.approx(HF, rel=1e-7)
    assert scalar(ext, "VF") == pytest.approx(VF, rel=1e-7)
    assert abs(scalar(ext, "VA")) <= 1e-6 * VF


# ------------------------------------------------------------------------------------------
# closure over every regime
# ------------------------------------------------------------------------------------------


def regime_grid():
    """A dense grid of configurations that covers every regime (L = 1000 m)."""
    L = L0
    xf = np.linspace(0.0, 1.05 * L, 36)
    zf = np.linspace(0.0, 1.05 * L, 36)
    X, Z, EA, W, CB = (a.ravel() for a in np.meshgrid(xf, zf, [3.0e7, 5.0e8, 1.0e12], [0.0, 150.0, 1000.0],
                                                       [0.0, 0.8], indexing="ij"))
    keep = np.hypot(X, Z) <= 1.06 * L  # taut up to 6 % beyond the inextensible limit
    return X[keep], Z[keep], np.full(keep.sum(), L), EA[keep], W[keep], CB[keep]


def test_closure_reproduces_the_spans_in_every_regime():
    XF, ZF, L, EA, w, CB = regime_grid()
    sol = cat.solve(XF, ZF, L, EA, w, CB=CB)
    names = sol.regime_names()
    assert set(names) == set(cat.REGIMES)
    assert all(np.sum(names == r) >= 4 for r in cat.REGIMES)
    # taut beyond the inextensible limit and near-inextensible lines are part of the grid
    taut = np.hypot(XF, ZF) > L
    assert np.any(taut & (names == "suspended") & (EA == 1e12))
    assert np.any(taut & (names == "suspended") & (EA == 3e7))
    assert np.any((names == "touchdown") & (CB > 0))

    for k in ("HF", "VF", "HA", "VA", "TF", "TA", "LBot", "dHF_dXF", "dHF_dZF", "dVF_dXF"):
        assert np.all(np.isfinite(getattr(sol, k))), k
    assert np.all(np.isfinite(sol.dVF_dZF[names != "seabed"]))
    assert np.all(sol.HF >= 0) and np.all(sol.VF >= 0) and np.all(sol.HA >= 0) and np.all(sol.VA >= 0)
    np.testing.assert_allclose(sol.TF, np.hypot(sol.HF, sol.VF), rtol=1e-15)
    assert np.all(sol.HA <= sol.HF * (1 + 1e-15))  # friction and weight only take load off
    assert np.all(sol.TA <= sol.TF * (1 + 1e-15))

    reg = (names == "touchdown") | (names == "suspended")
    X, Z = cat.closure(sol.HF[reg], sol.VF[reg], L[reg], EA[reg], w[reg], CB[reg])
    np.testing.assert_allclose(X, XF[reg], rtol=0, atol=1e-8)
    np.testing.assert_allclose(Z, ZF[reg], rtol=0, atol=1e-8)
    assert np.all(sol.VF[names == "suspended"] >= w[names == "suspended"] * L[names == "suspended"])
    assert np.all(sol.VF[names == "touchdown"] < w[names == "touchdown"] * L[names == "touchdown"])

    m = names == "slack"  # hanging vertically over Ls = VF/w, the rest untensioned on the seabed
    Ls = sol.VF[m] / w[m]
    np.testing.assert_allclose(Ls + w[m] * Ls**2 / (2 * EA[m]), ZF[m], rtol=1e-12, atol=1e-9)
    assert np.all(L[m] - Ls >= XF[m] - 1e-9) and np.all(sol.HF[m] == 0)
    np.testing.assert_allclose(sol.LBot[m], L[m] - Ls, rtol=1e-12)

    m = names == "vertical"
    assert np.all(XF[m] == 0) and np.all(sol.HF[m] == 0)
    np.testing.assert_allclose(sol.VF[m], EA[m] * (ZF[m] - L[m]) / L[m] + w[m] * L[m] / 2, rtol=1e-12)

    m = names == "seabed"
    assert np.all(ZF[m] == 0) and np.all(XF[m] > L[m]) and np.all(sol.VF[m] == 0)
    cbw = CB[m] * w[m]
    H_full = EA[m] * (XF[m] - L[m]) / L[m] + cbw * L[m] / 2
    H_part = np.sqrt(2 * EA[m] * cbw * (XF[m] - L[m]))
    np.testing.assert_allclose(sol.HF[m], np.where(H_part < cbw * L[m], H_part, H_full), rtol=1e-12)

    m = names == "weightless"
    ell = np.hypot(XF[m], ZF[m])
    np.testing.assert_allclose(sol.TF[m], EA[m] * np.maximum(ell / L[m] - 1, 0), rtol=1e-12, atol=1e-6)


def test_vectorised_solve_equals_one_by_one():
    XF, ZF, L, EA, w, CB = (a[::97] for a in regime_grid())
    vec = cat.solve(XF, ZF, L, EA, w, CB=CB)
    for i in range(XF.size):
        one = cat.solve(XF[i], ZF[i], L[i], EA[i], w[i], CB=CB[i])
        assert np.asarray(one.HF).shape == ()
        assert scalar(one, "HF") == pytest.approx(vec.HF[i], rel=1e-9, abs=1e-9)
        assert scalar(one, "VF") == pytest.approx(vec.VF[i], rel=1e-9, abs=1e-9)
        assert int(one.regime) == vec.regime[i]
    # broadcasting keeps the input shape
    sol = cat.solve(XF.reshape(-1, 1)[:6], np.array([100.0, 300.0]), L0, EA0, W0)
    assert sol.HF.shape == (6, 2) and sol.regime.shape == (6, 2)


# ------------------------------------------------------------------------------------------
# sensitivities
# ------------------------------------------------------------------------------------------

SENS_CASES = {
    # name: (XF, ZF, L, EA, w, CB, expected regime)
    "touchdown": (950.0, 250.0, L0, EA0, W0, 0.0, "touchdown"),
    "touchdown-soft": (880.0, 400.0, L0, 3.0e7, W0, 0.0, "touchdown"),
    "touchdown-near-slack": (700.0, 500.0, L0, EA0, W0, 0.0, "touchdown"),
    "suspended": (700.0, 700.0, L0, EA0, W0, 0.0, "suspended"),
    "suspended-taut": (960.0, 300.0, L0, EA0, W0, 0.0, "suspended"),
    "friction-anchor-loaded": (990.0, 150.0, L0, EA0, W0, 1.0, "touchdown"),
    "friction-anchor-unloaded": (925.0, 100.0, L0, EA0, W0, 0.6, "touchdown"),
    "weightless": (900.0, 600.0, L0, EA0, 0.0, 0.0, "weightless"),
}


def central_difference(f, x, h):
    return (f(x + h) - f(x - h)) / (2 * h)


@pytest.mark.parametrize("case", list(SENS_CASES))
def test_sensitivities_equal_finite_differences(case):
    XF, ZF, L, EA, w, CB, regime = SENS_CASES[case]
    sol = cat.solve(XF, ZF, L, EA, w, CB=CB)
    assert cat.REGIMES[int(sol.regime)] == regime
    h = 1e-3  # [m]; the solver closes the spans to 1e-12 m here, truncation error O(h^2)

    def HV(x, z):
        s = cat.solve(x, z, L, EA, w, CB=CB, tol=1e-12)
        return np.array([scalar(s, "HF"), scalar(s, "VF")])

    dX = central_difference(lambda x: HV(x, ZF), XF, h)
    dZ = central_difference(lambda z: HV(XF, z), ZF, h)
    exact = np.array([[scalar(sol, "dHF_dXF"), scalar(sol, "dHF_dZF")],
                      [scalar(sol, "dVF_dXF"), scalar(sol, "dVF_dZF")]])
    fd = np.column_stack([dX, dZ])
    np.testing.assert_allclose(exact, fd, rtol=1e-5, atol=1e-5 * np.abs(fd).max())
    assert exact[0, 0] > 0 and exact[1, 1] > 0  # a line gets tighter when pulled away


@pytest.mark.parametrize("case", list(SENS_CASES))
def test_tension_magnitude_sensitivity_equals_finite_difference(case):
    """dTF/dXF of the solution (from HF, VF and their sensitivities) against a central difference
    of TF itself."""
    XF, ZF, L, EA, w, CB, _ = SENS_CASES[case]
    sol = cat.solve(XF, ZF, L, EA, w, CB=CB)
    fd = central_difference(lambda x: scalar(cat.solve(x, ZF, L, EA, w, CB=CB, tol=1e-12), "TF"), XF, 1e-3)
    assert scalar(sol, "dTF_dXF") == pytest.approx(fd, rel=1e-5, abs=1e-5 * abs(scalar(sol, "dHF_dXF")))


@pytest.mark.parametrize("case", ["touchdown", "touchdown-soft", "touchdown-near-slack", "suspended",
                                  "suspended-taut", "weightless"])
def test_line_stiffness_is_symmetric(case):
    """Without friction the line is conservative: (HF, VF) is the gradient of its potential energy
    in (XF, ZF), so dHF/dZF = dVF/dXF, and the stiffness is positive definite."""
    XF, ZF, L, EA, w, CB, _ = SENS_CASES[case]
    sol = cat.solve(XF, ZF, L, EA, w, CB=CB)
    K = np.array([[scalar(sol, "dHF_dXF"), scalar(sol, "dHF_dZF")],
                  [scalar(sol, "dVF_dXF"), scalar(sol, "dVF_dZF")]])
    assert K[0, 1] == pytest.approx(K[1, 0], rel=1e-10)
    assert np.all(np.linalg.eigvalsh(0.5 * (K + K.T)) > 0)


@pytest.mark.parametrize("ZF,CB,EA", [(0.0, 0.0, EA0), (0.0, 0.5, 2e7), (0.0, 0.5, EA0)])
def test_seabed_horizontal_stiffness_equals_finite_differences(ZF, CB, EA):
    for XF in (L0 + 0.3, L0 + 40.0):
        sol = cat.solve(XF, ZF, L0, EA, W0, CB=CB)
        fd = central_difference(lambda x: scalar(cat.solve(x, ZF, L0, EA, W0, CB=CB), "HF"), XF, 1e-4)
        assert scalar(sol, "dHF_dXF") == pytest.approx(fd, rel=1e-5)
        assert np.isinf(scalar(sol, "dVF_dZF"))


@pytest.mark.parametrize("XF,ZF,EA", [(0.0, 1100.0, EA0), (0.0, 1100.0, 2e7), (0.0, 400.0, 1e6),
                                      (200.0, 400.0, 1e6)])
def test_vertical_and_slack_vertical_stiffness_equals_finite_differences(XF, ZF, EA):
    sol = cat.solve(XF, ZF, L0, EA, W0)
    fd = central_difference(lambda z: scalar(cat.solve(XF, z, L0, EA, W0), "VF"), ZF, 1e-3)
    assert scalar(sol, "dVF_dZF") == pytest.approx(fd, rel=1e-6)


def test_vertical_line_horizontal_stiffness_equals_one_sided_difference():
    """A vertical suspended line pulled sideways by h: HF/h -> dHF/dXF (the pendulum stiffness)."""
    ZF = 1100.0
    sol = cat.solve(0.0, ZF, L0, EA0, W0)
    k = scalar(sol, "dHF_dXF")
    h1, h2 = 1e-2, 5e-3
    k1 = scalar(cat.solve(h1, ZF, L0, EA0, W0, tol=1e-12), "HF") / h1
    k2 = scalar(cat.solve(h2, ZF, L0, EA0, W0, tol=1e-12), "HF") / h2
    k_extrap = 2 * k2 - k1  # Richardson: the one-sided error is O(h)
    assert k > 0
    assert k_extrap == pytest.approx(k, rel=1e-5)


# ------------------------------------------------------------------------------------------
# symbolic (CasADi) path
# ------------------------------------------------------------------------------------------

def regular(XF, ZF, CB, EA):
    sol = cat.solve(XF, ZF, L0, EA, W0, CB=CB)
    return sol, cat.REGIMES[int(sol.regime)] in ("touchdown", "suspended")


# the symbolic path is valid in the regular regimes only (touching down, fully suspended)
SYM_CASES = [(XF, ZF, CB, EA) for XF, ZF, CB, EA in itertools.product(
    [700.0, 850.0, 940.0, 980.0, 995.0], [100.0, 300.0, 500.0, 700.0], [0.0, 0.6], [EA0, 3e7])
    if math.hypot(XF, ZF) < 1.01 * L0 and regular(XF, ZF, CB, EA)[1]]


def test_symbolic_grid_covers_touchdown_and_suspended():
    assert len(SYM_CASES) >= 20
    regs = [cat.REGIMES[int(regular(*c)[0].regime)] for c in SYM_CASES]
    assert regs.count("touchdown") >= 5 and regs.count("suspended") >= 5
    assert any(c[2] > 0 and r == "touchdown" for c, r in zip(SYM_CASES, regs))


# A steep, nearly taut, fully suspended line from a +-20 % guess: full Newton steps without line
# search once left this at a non-root (HF ~ 8.5e8 N instead of 8.97e5 N) without any error.
SYM_PARAMS = [
    pytest.param(*c, g, id=f"{c[0]:g}-{c[1]:g}-CB{c[2]:g}-EA{c[3]:.0e}-g{g[0]}/{g[1]}")
    for c in SYM_CASES for g in [(1.2, 1.2), (0.8, 0.8), (1.2, 0.8), (0.8, 1.2)]
]


def test_symbolic_function_reports_a_failed_root():
    """From a guess Newton cannot recover from, the closure error says so (never a silent non-root)."""
    fn = cat.symbolic_function(max_iter=2)
    HF, VF, err = (float(x) for x in fn(700.0, 700.0, 1000.0, 5e8, 1000.0, 0.0, 0.0, 1e3, 1e9))
    true = cat.solve(700.0, 700.0, 1000.0, 5e8, 1000.0)
    assert not (HF == pytest.approx(float(true.HF), rel=1e-6))  # Newton really failed here ...
    assert err > 1e-3  # ... and says so


def test_symbolic_function_signature():
    fn = cat.symbolic_function()
    assert fn.name_in() == ["XF", "ZF", "L", "EA", "w", "CB", "h_A", "HF0", "VF0"]
    assert fn.name_out() == ["HF", "VF", "closure_error"]
    assert cat.symbolic_function() is fn  # built once, cached


@pytest.mark.parametrize("XF,ZF,CB,EA,guess", SYM_PARAMS)
def test_symbolic_function_agrees_with_numeric_solve(XF, ZF, CB, EA, guess):
    sol, _ = regular(XF, ZF, CB, EA)
    HF, VF = scalar(sol, "HF"), scalar(sol, "VF")
    h, v, err = cat.symbolic_function()(XF, ZF, L0, EA, W0, CB, 0.0, guess[0] * HF, guess[1] * VF)
    assert float(err) < 1e-8
    assert float(h) == pytest.approx(HF, rel=1e-9)
    assert float(v) == pytest.approx(VF, rel=1e-9)


def test_symbolic_derivatives_equal_the_analytic_sensitivities():
    fn = cat.symbolic_function()
    XF, ZF = ca.MX.sym("XF"), ca.MX.sym("ZF")
    HF0, VF0 = ca.MX.sym("HF0"), ca.MX.sym("VF0")
    L, EA, w, CB, h_A = (ca.MX.sym(s) for s in ("L", "EA", "w", "CB", "h_A"))
    h, v, _ = fn(XF, ZF, L, EA, w, CB, h_A, HF0, VF0)
    J = ca.Function("J", [XF, ZF, L, EA, w, CB, h_A, HF0, VF0],
                    [ca.jacobian(ca.vertcat(h, v), ca.vertcat(XF, ZF))])
    for XF_, ZF_, CB_, EA_ in SYM_CASES:
        sol, _ = regular(XF_, ZF_, CB_, EA_)
        Jn = np.array(J(XF_, ZF_, L0, EA_, W0, CB_, 0.0, 1.1 * scalar(sol, "HF"), 0.9 * scalar(sol, "VF")))
        assert Jn[0, 0] == pytest.approx(scalar(sol, "dHF_dXF"), rel=1e-7)
        exact = np.array([[scalar(sol, "dHF_dXF"), scalar(sol, "dHF_dZF")],
                          [scalar(sol, "dVF_dXF"), scalar(sol, "dVF_dZF")]])
        np.testing.assert_allclose(Jn, exact, rtol=1e-7, atol=1e-7 * np.abs(exact).max())


def test_symbolic_function_maps_over_lines():
    fn = cat.symbolic_function().map(3)
    XF = np.array([[950.0, 700.0, 980.0]])
    ZF = np.array([[250.0, 700.0, 150.0]])
    sol = cat.solve(XF, ZF, L0, EA0, W0, CB=0.5)
    h, v, err = fn(XF, ZF, L0, EA0, W0, 0.5, 0.0, 0.9 * sol.HF, 1.1 * sol.VF)
    assert float(np.max(np.asarray(err))) < 1e-8
    np.testing.assert_allclose(np.array(h), sol.HF, rtol=1e-9)
    np.testing.assert_allclose(np.array(v), sol.VF, rtol=1e-9)


# ------------------------------------------------------------------------------------------
# continuity across the touchdown / suspended boundary
# ------------------------------------------------------------------------------------------


@pytest.mark.parametrize("HF_b", [5.0e4, 8.0e5])
@pytest.mark.parametrize("CB", [0.0, 0.6])
def test_tensions_continuous_across_touchdown_boundary(HF_b, CB):
    """At VF = wL the anchor just lifts off. Sweep XF through that point at fixed ZF: the line
    changes regime and the tensions and their slopes are continuous."""
    L, EA, w = L0, EA0, W0
    Xb, Zb = (float(a) for a in cat.closure(np.array(HF_b), np.array(w * L), L, EA, w, CB))
    delta = 1e-3
    xs = Xb + delta * np.linspace(-5, 5, 11)
    sol = cat.solve(xs, Zb, L, EA, w, CB=CB, tol=1e-12)
    names = sol.regime_names()
    assert names[0] == "touchdown" and names[-1] == "suspended"  # the sweep does cross
    for k, dk in (("HF", "dHF_dXF"), ("VF", "dVF_dXF")):
        y, dy = getattr(sol, k), getattr(sol, dk)
        # each step is the slope times the step (no jump), and the slope itself does not jump
        steps = np.diff(y)
        mid_slope = 0.5 * (dy[1:] + dy[:-1])
        np.testing.assert_allclose(steps, mid_slope * delta, rtol=1e-4)
        np.testing.assert_allclose(dy, dy[5], rtol=1e-3)
    mid = cat.solve(Xb, Zb, L, EA, w, CB=CB, tol=1e-12)
    assert scalar(mid, "HF") == pytest.approx(HF_b, rel=1e-9)
    assert scalar(mid, "VF") == pytest.approx(w * L, rel=1e-9)


# ------------------------------------------------------------------------------------------
# line profile
# ------------------------------------------------------------------------------------------

PROFILE_CASES = [
    (950.0, 250.0, EA0, W0, 0.0),   # touchdown
    (925.0, 100.0, 2e7, W0, 0.6),   # touchdown with friction, anchor unloaded
    (990.0, 150.0, EA0, W0, 1.0),   # touchdown with friction, anchor loaded
    (700.0, 700.0, EA0, W0, 0.0),   # suspended
    (1002.0, 100.0, 2e7, W0, 0.0),  # taut
    (600.0, 300.0, EA0, W0, 0.0),   # slack
    (1020.0, 0.0, 2e7, W0, 0.5),    # seabed
    (900.0, 600.0, EA0, 0.0, 0.0),  # weightless
]


@pytest.mark.parametrize("XF,ZF,EA,w,CB", PROFILE_CASES)
def test_line_profile_ends_at_the_fairlead(XF, ZF, EA, w, CB):
    prof = cat.line_profile(XF, ZF, L0, EA, w, CB=CB, n=401)
    sol = prof["solution"]
    s, x, z, T = prof["s"], prof["x"], prof["z"], prof["T"]
    assert s[0] == 0.0 and s[-1] == L0 and s.shape == x.shape == z.shape == T.shape == (401,)
    assert x[0] == pytest.approx(0.0, abs=1e-9) and z[0] == pytest.approx(0.0, abs=1e-9)
    assert x[-1] == pytest.approx(XF, abs=1e-6)
    assert z[-1] == pytest.approx(ZF, abs=1e-6)
    assert T[-1] == pytest.approx(scalar(sol, "TF"), rel=1e-9, abs=1e-9)
    assert np.all(T >= 0) and np.all(np.isfinite(T)) and np.all(np.isfinite(x)) and np.all(np.isfinite(z))
    on_bed = s <= scalar(sol, "LBot")
    assert np.all(z[on_bed] == 0.0)
    assert np.all(z >= -1e-9)
    assert np.all(np.diff(x) >= -1e-9)  # the line never doubles back
    if scalar(sol, "LBot") > 0 and np.any(on_bed):
        assert T[0] == pytest.approx(scalar(sol, "HA"), rel=1e-9, abs=1e-6)


def test_line_profile_is_the_stretched_curve():
    """The profile's arc length is the stretched length: ds_stretched = (1 + T/EA) ds."""
    EA = 2e7
    prof = cat.line_profile(880.0, 400.0, L0, EA, W0, n=4001)
    s, x, z, T = prof["s"], prof["x"], prof["z"], prof["T"]
    arc = np.sum(np.hypot(np.diff(x), np.diff(z)))
    stretched = np.trapezoid(1 + T / EA, s) if hasattr(np, "trapezoid") else np.trapz(1 + T / EA, s)
    assert arc == pytest.approx(stretched, rel=1e-6)


# ------------------------------------------------------------------------------------------
# random and invalid input
# ------------------------------------------------------------------------------------------

valid = st.fixed_dictionaries({
    "L": st.floats(10.0, 5000.0),
    "xf": st.floats(0.0, 1.1),
    "zf": st.floats(0.0, 1.1),
    "EA": st.floats(5.0, 12.0).map(lambda e: 10.0**e),
    "w": st.one_of(st.just(0.0), st.floats(0.0, 5000.0)),
    "CB": st.one_of(st.just(0.0), st.floats(0.0, 1.0)),
})


@settings(max_examples=300, deadline=None)
@given(valid)
def test_random_valid_input_solves_or_raises_catenary_error(p):
    L, EA, w, CB = p["L"], p["EA"], p["w"], p["CB"]
    XF, ZF = p["xf"] * L, p["zf"] * L
    try:
        sol = cat.solve(XF, ZF, L, EA, w, CB=CB)
    except CatenaryError as exc:
        assert str(exc)
        return
    for k in ("HF", "VF", "HA", "VA", "TF", "LBot", "dHF_dXF"):
        assert np.isfinite(scalar(sol, k)), k
    HF, VF = scalar(sol, "HF"), scalar(sol, "VF")
    assert HF >= 0 and VF >= 0
    name = cat.REGIMES[int(sol.regime)]
    if name in ("touchdown", "suspended"):
        X, Z = cat.closure(np.array(HF), np.array(VF), L, EA, w, CB)
        assert abs(float(X) - XF) <= 1e-8 and abs(float(Z) - ZF) <= 1e-8
    elif name == "weightless":
        assert scalar(sol, "TF") == pytest.approx(EA * max(math.hypot(XF, ZF) / L - 1, 0), rel=1e-12, abs=1e-6)
    elif name == "slack":
        Ls = L - scalar(sol, "LBot")
        assert Ls + w * Ls * Ls / (2 * EA) == pytest.approx(ZF, rel=1e-10, abs=1e-9)
        assert VF == pytest.approx(w * Ls, rel=1e-12, abs=1e-12 * w * L + 1e-300) and L - Ls >= XF - 1e-9


@settings(max_examples=150, deadline=None)
@given(valid)
@example({"L": 10.0, "xf": 0.0, "zf": 1.0625, "EA": 1e5, "w": 8.76e-170, "CB": 0.0})  # cancellation in z
@example({"L": 1000.0, "xf": 1.02, "zf": 0.0, "EA": 2e7, "w": 1000.0, "CB": 0.5})  # seabed with friction
# a weight so small that w s (V + V0) underflows in the hanging piece's span (it lost the arc length)
@example({"L": 1146.0, "xf": 1.03125, "zf": 3.511302923904085e-193, "EA": 1e5, "w": 3.511302923904085e-193,
          "CB": 0.0})
def test_random_line_profile_closes(p):
    L, EA, w, CB = p["L"], p["EA"], p["w"], p["CB"]
    XF, ZF = p["xf"] * L, p["zf"] * L
    try:
        prof = cat.line_profile(XF, ZF, L, EA, w, CB=CB, n=51)
    except CatenaryError:
        return
    assert np.all(np.isfinite(prof["x"])) and np.all(np.isfinite(prof["z"])) and np.all(prof["T"] >= 0)
    assert prof["T"][-1] == pytest.approx(scalar(prof["solution"], "TF"), rel=1e-9, abs=1e-9)
    assert abs(prof["x"][-1] - XF) <= 1e-6 * max(1.0, L / 1000) and abs(prof["z"][-1] - ZF) <= 1e-6 * max(1.0, L / 1000)


GOOD = dict(XF=900.0, ZF=300.0, L=1000.0, EA=5e8, w=1000.0, CB=0.0, h_A=0.0)


@pytest.mark.parametrize("name,value", [
    ("XF", -1.0), ("ZF", -0.5), ("L", -10.0), ("L", 0.0), ("EA", -1.0), ("EA", 0.0), ("w", -2.0),
    ("CB", -0.1), ("XF", np.nan), ("ZF", np.nan), ("L", np.nan), ("EA", np.nan), ("w", np.nan),
    ("XF", np.inf), ("ZF", np.inf), ("L", np.inf), ("w", np.inf), ("XF", -np.inf),
    ("h_A", -1.0), ("h_A", -1e-9), ("h_A", np.nan), ("h_A", np.inf), ("h_A", -np.inf),
])
def test_invalid_input_raises_catenary_error_naming_the_input(name, value):
    args = dict(GOOD, **{name: value})
    with pytest.raises(CatenaryError, match=rf"^{name} = "):
        cat.solve(args["XF"], args["ZF"], args["L"], args["EA"], args["w"], CB=args["CB"], h_A=args["h_A"])


def test_invalid_entry_in_an_array_is_located():
    XF = np.array([900.0, 950.0, np.nan, 800.0])
    with pytest.raises(CatenaryError, match=r"^XF = nan at index \(2,\) must be finite"):
        cat.solve(XF, 300.0, L0, EA0, W0)


# ------------------------------------------------------------------------------------------
# MoorPy cross-check (independent code; data made by tests/data/make_catenary_reference.py)
# ------------------------------------------------------------------------------------------


def load_reference():
    with (DATA / "catenary_reference.csv").open() as fh:
        rows = list(csv.DictReader(line for line in fh if not line.startswith("#")))
    cols = ("XF", "ZF", "L", "EA", "w", "CB", "HF", "VF", "HA", "VA", "profile_type")
    return {k: np.array([float(r[k]) for r in rows]) for k in cols}


# MoorPy ProfileType -> our regime
MOORPY_REGIME = {1: "suspended", 2: "touchdown", 3: "touchdown", 4: "slack", 6: "vertical"}


def test_matches_moorpy_reference():
    """Both codes close the spans to <= 1e-9 m (MoorPy was run with Tol = 1e-10 m); the tension
    error is then about stiffness x 1e-9 m <= 5e5 N/m x 1e-9 m, far below 1e-8 of the fairlead
    tension, so rtol = 1e-8 (relative to TF, because HA, VA may be 0) leaves margin for
    platform round-off while catching any modelling difference."""
    ref = load_reference()
    assert ref["XF"].size >= 60
    # the reference covers every regime it can (MoorPy profile types 1, 2, 3 (friction), 4, 6)
    assert set(ref["profile_type"].astype(int)) == set(MOORPY_REGIME)
    sol = cat.solve(ref["XF"], ref["ZF"], ref["L"], ref["EA"], ref["w"], CB=ref["CB"])
    expected = np.array([MOORPY_REGIME[int(p)] for p in ref["profile_type"]])
    assert np.all(sol.regime_names() == expected)
    TF = np.hypot(ref["HF"], ref["VF"])
    for k in ("HF", "VF", "HA", "VA"):
        err = np.abs(getattr(sol, k) - ref[k]) / TF
        assert err.max() <= 1e-8, (k, int(err.argmax()), err.max())


# ------------------------------------------------------------------------------------------
# lower end above the seabed (h_A > 0)
# ------------------------------------------------------------------------------------------


def seabed_reach(HF, h, EA, w):
    """V1 of an elevated end: the vertical tension at a point h above the seabed of a catenary
    with horizontal tension HF that meets the seabed horizontally, by bisection on
    h = HF/w (sqrt(1 + (V/HF)^2) - 1) + V^2/(2 EA w) (independent of the closed form)."""
    def drop(V):
        return HF / w * (math.sqrt(1.0 + (V / HF) ** 2) - 1.0) + V * V / (2.0 * EA * w) - h

    return brentq(drop, 0.0, w * h + math.sqrt(2.0 * HF * w * h) + 1.0, xtol=1e-12, rtol=1e-15)


ELEVATED_TOUCHDOWN = [  # (XF, ZF, h_A, EA): touching down from a lower end above the seabed
    (900.0, 200.0, 50.0, EA0), (900.0, 200.0, 50.0, 3e7), (960.0, 50.0, 10.0, EA0), (950.0, 0.0, 30.0, EA0)]


@pytest.mark.parametrize("XF,ZF,h,EA", ELEVATED_TOUCHDOWN)
def test_touchdown_from_an_elevated_end_is_two_lines_anchored_on_the_seabed(XF, ZF, h, EA):
    """A line from an end h above the seabed that touches down: cut it where A's part meets the
    seabed. That part, seen from the seabed, is a line anchored there that just lifts off (VA = 0)
    and rises h to A with the horizontal tension HF; the rest is an ordinary line anchored on the
    seabed, spanning the remaining distance and ZF + h, with the same fairlead tensions."""
    L, w = L0, W0
    sol = cat.solve(XF, ZF, L, EA, w, h_A=h, tol=1e-11)
    assert cat.REGIMES[int(sol.regime)] == "touchdown" and scalar(sol, "LBot") > 0
    HF, VF, VA = scalar(sol, "HF"), scalar(sol, "VF"), scalar(sol, "VA")
    assert VA < 0 and scalar(sol, "HA") == HF  # pulled down at A; frictionless grounded stretch
    assert -VA == pytest.approx(seabed_reach(HF, h, EA, w), rel=1e-10)
    L1 = -VA / w
    X1, Z1 = (float(v) for v in cat.closure(np.array(HF), np.array(-VA), L1, EA, w))
    assert Z1 == pytest.approx(h, rel=1e-10)
    rest = cat.solve(XF - X1, ZF + h, L - L1, EA, w, tol=1e-11)
    assert cat.REGIMES[int(rest.regime)] == "touchdown"
    assert scalar(rest, "HF") == pytest.approx(HF, rel=1e-9)
    assert scalar(rest, "VF") == pytest.approx(VF, rel=1e-9)
    assert scalar(rest, "LBot") == pytest.approx(scalar(sol, "LBot"), rel=1e-9)


@pytest.mark.parametrize("X,Z,EA", [(485.0, 20.0, EA0), (470.0, 60.0, 3e7), (440.0, 100.0, EA0)])
def test_symmetric_U_line_on_the_seabed_is_two_mirrored_anchored_halves(X, Z, EA):
    """Both ends Z above the seabed, span 2X, length 2L, touching the seabed in the middle: each
    half is a line of length L anchored at the middle of the grounded stretch (MoorPy's U test)."""
    L, w = 500.0, W0
    half = cat.solve(X, Z, L, EA, w, tol=1e-11)
    assert cat.REGIMES[int(half.regime)] == "touchdown"  # precondition
    U = cat.solve(2.0 * X, 0.0, 2.0 * L, EA, w, h_A=Z, tol=1e-11)
    assert cat.REGIMES[int(U.regime)] == "touchdown"
    assert scalar(U, "HF") == pytest.approx(scalar(half, "HF"), rel=1e-9)
    assert scalar(U, "VF") == pytest.approx(scalar(half, "VF"), rel=1e-9)
    assert scalar(U, "VA") == pytest.approx(-scalar(U, "VF"), rel=1e-9)  # mirror image
    assert scalar(U, "HA") == scalar(U, "HF")
    assert scalar(U, "LBot") == pytest.approx(2.0 * scalar(half, "LBot"), rel=1e-9)


@pytest.mark.parametrize("XF,ZF,EA", [(800.0, 100.0, EA0), (850.0, 300.0, 3e7), (980.0, 150.0, EA0)])
def test_seabed_plays_no_part_while_the_sag_stays_above_it(XF, ZF, EA):
    """A line leaving its elevated lower end downward sags to a lowest point below A. Any seabed
    below that point leaves the solution unchanged; a seabed above it makes the line touch down."""
    L, w = L0, W0
    deep = cat.solve(XF, ZF, L, EA, w, h_A=1.0e4, tol=1e-11)
    HF, VA = scalar(deep, "HF"), scalar(deep, "VA")
    assert cat.REGIMES[int(deep.regime)] == "suspended" and VA < 0  # precondition: a sag
    sag = HF / w * (math.sqrt(1.0 + (VA / HF) ** 2) - 1.0) + VA * VA / (2.0 * EA * w)
    prof = cat.line_profile(XF, ZF, L, EA, w, h_A=1.0e4, n=20001)
    assert -prof["z"].min() == pytest.approx(sag, rel=1e-5)
    for h in (1.001 * sag, 2.0 * sag):
        sol = cat.solve(XF, ZF, L, EA, w, h_A=h, tol=1e-11)
        assert cat.REGIMES[int(sol.regime)] == "suspended" and scalar(sol, "LBot") == 0.0
        assert scalar(sol, "HF") == pytest.approx(HF, rel=1e-10)
        assert scalar(sol, "VF") == pytest.approx(scalar(deep, "VF"), rel=1e-10)
    low = cat.solve(XF, ZF, L, EA, w, h_A=0.9 * sag)
    assert cat.REGIMES[int(low.regime)] == "touchdown" and scalar(low, "LBot") > 0


@pytest.mark.parametrize("HF_b,h", [(5.0e4, 20.0), (8.0e5, 80.0)])
def test_tensions_continuous_where_the_sag_reaches_the_seabed(HF_b, h):
    """At VF + V1 = w L the sag of a line from an elevated end just touches the seabed. Sweep XF
    through that point at fixed ZF: the line changes regime and the tensions do not jump; the
    slopes do (a one-sided contact starts to carry the sag), each side's being the exact slope of
    its side."""
    L, EA, w = L0, EA0, W0
    V1 = seabed_reach(HF_b, h, EA, w)
    VF_b = w * L - V1
    Xb, Zb = (float(a) for a in cat.closure(np.array(HF_b), np.array(VF_b), L, EA, w, 0.0, h))
    delta = 1e-3
    xs = Xb + delta * np.linspace(-5, 5, 11)
    sol = cat.solve(xs, Zb, L, EA, w, h_A=h, tol=1e-12)
    names = sol.regime_names()
    assert list(names[:5]) == ["touchdown"] * 5 and list(names[6:]) == ["suspended"] * 5
    for k, dk in (("HF", "dHF_dXF"), ("VF", "dVF_dXF")):
        y, dy = getattr(sol, k), getattr(sol, dk)
        steps, mid_slope = np.diff(y), 0.5 * (dy[1:] + dy[:-1]) * delta
        side = np.r_[0:4, 6:10]  # steps within one regime
        np.testing.assert_allclose(steps[side], mid_slope[side], rtol=1e-4)
        np.testing.assert_allclose(dy[:5], dy[0], rtol=1e-3)
        np.testing.assert_allclose(dy[6:], dy[-1], rtol=1e-3)
        # across the boundary (at xs[5]) one step of each side's slope: no jump in the tension
        assert y[6] - y[4] == pytest.approx((dy[4] + dy[6]) * delta, rel=1e-3)
        assert abs(dy[6] - dy[4]) > 1e-2 * abs(dy[4])  # the kink is there
    mid = cat.solve(Xb, Zb, L, EA, w, h_A=h, tol=1e-12)
    assert scalar(mid, "HF") == pytest.approx(HF_b, rel=1e-9)
    assert scalar(mid, "VF") == pytest.approx(VF_b, rel=1e-9)


@pytest.mark.parametrize("XF,ZF,h", [(900.0, 200.0, 50.0), (800.0, 100.0, 300.0)])
def test_friction_is_not_applied_with_an_elevated_lower_end(XF, ZF, h):
    free = cat.solve(XF, ZF, L0, EA0, W0, h_A=h)
    rough = cat.solve(XF, ZF, L0, EA0, W0, CB=0.8, h_A=h)
    for k in ("HF", "VF", "HA", "VA", "LBot", "dHF_dXF", "dVF_dZF"):
        assert scalar(rough, k) == scalar(free, k), k
    # from an anchor on the seabed the same friction does matter
    on_seabed = [scalar(cat.solve(950.0, 250.0, L0, EA0, W0, CB=cb), "HF") for cb in (0.0, 0.8)]
    assert on_seabed[1] > on_seabed[0]


@pytest.mark.parametrize("EA", [EA0, 1.0e6])
@pytest.mark.parametrize("XF,ZF,h", [(600.0, 0.0, 200.0), (400.0, 200.0, 200.0), (0.0, 100.0, 300.0)])
def test_slack_line_hangs_from_both_ends(EA, XF, ZF, h):
    L, w = L0, W0
    L1, L2 = hanging_length(h, EA, w), hanging_length(ZF + h, EA, w)
    assert L - L1 - L2 >= XF  # precondition
    sol = cat.solve(XF, ZF, L, EA, w, h_A=h)
    assert cat.REGIMES[int(sol.regime)] == "slack"
    assert scalar(sol, "HF") == 0.0 and scalar(sol, "HA") == 0.0
    assert scalar(sol, "VF") == pytest.approx(w * L2, rel=1e-12)
    assert scalar(sol, "VA") == pytest.approx(-w * L1, rel=1e-12)
    assert scalar(sol, "LBot") == pytest.approx(L - L1 - L2, rel=1e-12)
    fd = central_difference(lambda z: scalar(cat.solve(XF, z, L, EA, w, h_A=h), "VF"), ZF + 1.0, 1e-3)
    assert scalar(cat.solve(XF, ZF + 1.0, L, EA, w, h_A=h), "dVF_dZF") == pytest.approx(fd, rel=1e-6)


@pytest.mark.parametrize("EA", [EA0, 2.0e7])
@pytest.mark.parametrize("ZF", [0.0, 300.0, 900.0])
def test_vertical_line_hangs_doubled_from_an_elevated_end(EA, ZF):
    """XF = 0 and the line too long to hang straight: it runs down from A over L1 and up to the
    fairlead over L2 = L - L1, with ZF = stretched(L2) - stretched(L1), its fold above the seabed."""
    L, w, h = L0, W0, 1000.0

    def stretched(ell):
        return ell + w * ell * ell / (2.0 * EA)

    L2 = brentq(lambda x: stretched(x) - stretched(L - x) - ZF, 0.5 * L, L, xtol=1e-13, rtol=1e-15)
    assert stretched(L - L2) < h  # precondition: the fold is above the seabed
    sol = cat.solve(0.0, ZF, L, EA, w, h_A=h)
    assert cat.REGIMES[int(sol.regime)] == "vertical"
    assert scalar(sol, "HF") == 0.0 and scalar(sol, "LBot") == 0.0
    assert scalar(sol, "VF") == pytest.approx(w * L2, rel=1e-12)
    assert scalar(sol, "VA") == pytest.approx(-w * (L - L2), rel=1e-9)
    fd = central_difference(lambda z: scalar(cat.solve(0.0, z, L, EA, w, h_A=h), "VF"), ZF + 1.0, 1e-3)
    assert scalar(cat.solve(0.0, ZF + 1.0, L, EA, w, h_A=h), "dVF_dZF") == pytest.approx(fd, rel=1e-6)
    # a taut vertical line is the same with or without the seabed below
    taut = cat.solve(0.0, 1.05 * L, L, EA, w, h_A=h)
    assert scalar(taut, "VA") > 0 and scalar(taut, "VF") == scalar(cat.solve(0.0, 1.05 * L, L, EA, w), "VF")


ELEV_SENS = {
    # name: (XF, ZF, h_A, EA, expected regime)
    "touchdown-elevated": (900.0, 200.0, 50.0, EA0, "touchdown"),
    "touchdown-elevated-soft": (900.0, 200.0, 50.0, 3e7, "touchdown"),
    "U-on-the-seabed": (950.0, 5.0, 30.0, EA0, "touchdown"),
    "touchdown-near-slack": (960.0, 50.0, 10.0, EA0, "touchdown"),
    "sag": (800.0, 100.0, 300.0, EA0, "suspended"),
    "sag-soft": (850.0, 300.0, 100.0, 3e7, "suspended"),
    "uplift": (700.0, 700.0, 100.0, EA0, "suspended"),
    "taut": (1000.0, 100.0, 50.0, EA0, "suspended"),
}


@pytest.mark.parametrize("case", list(ELEV_SENS))
def test_sensitivities_with_an_elevated_end_equal_finite_differences(case):
    XF, ZF, h, EA, regime = ELEV_SENS[case]
    sol = cat.solve(XF, ZF, L0, EA, W0, h_A=h)
    assert cat.REGIMES[int(sol.regime)] == regime

    def HV(x, z):
        s = cat.solve(x, z, L0, EA, W0, h_A=h, tol=1e-12)
        return np.array([scalar(s, "HF"), scalar(s, "VF")])

    step = 1e-3
    fd = np.column_stack([central_difference(lambda x: HV(x, ZF), XF, step),
                          central_difference(lambda z: HV(XF, z), ZF, step)])
    K = np.array([[scalar(sol, "dHF_dXF"), scalar(sol, "dHF_dZF")],
                  [scalar(sol, "dVF_dXF"), scalar(sol, "dVF_dZF")]])
    np.testing.assert_allclose(K, fd, rtol=1e-5, atol=1e-5 * np.abs(fd).max())
    # no friction: the line is conservative, its stiffness symmetric and positive definite
    assert K[0, 1] == pytest.approx(K[1, 0], rel=1e-9)
    assert np.all(np.linalg.eigvalsh(0.5 * (K + K.T)) > 0)


@pytest.mark.parametrize("case", list(ELEV_SENS))
@pytest.mark.parametrize("guess", [(1.2, 1.2), (0.8, 0.8), (1.2, 0.8), (0.8, 1.2)])
def test_symbolic_function_with_an_elevated_end(case, guess):
    XF, ZF, h, EA, _ = ELEV_SENS[case]
    sol = cat.solve(XF, ZF, L0, EA, W0, h_A=h)
    HF, VF = scalar(sol, "HF"), scalar(sol, "VF")
    fn = cat.symbolic_function()
    hs, vs, err = fn(XF, ZF, L0, EA, W0, 0.0, h, guess[0] * HF, guess[1] * VF)
    assert float(err) < 1e-8
    assert float(hs) == pytest.approx(HF, rel=1e-9) and float(vs) == pytest.approx(VF, rel=1e-9)
    x, z = ca.MX.sym("x"), ca.MX.sym("z")
    out = fn(x, z, L0, EA, W0, 0.0, h, guess[0] * HF, guess[1] * VF)
    J = np.array(ca.Function("J", [x, z], [ca.jacobian(ca.vertcat(out[0], out[1]), ca.vertcat(x, z))])(XF, ZF))
    exact = np.array([[scalar(sol, "dHF_dXF"), scalar(sol, "dHF_dZF")],
                      [scalar(sol, "dVF_dXF"), scalar(sol, "dVF_dZF")]])
    np.testing.assert_allclose(J, exact, rtol=1e-7, atol=1e-7 * np.abs(exact).max())


def test_symbolic_function_on_the_seabed_still_has_finite_derivatives():
    """h_A = 0 through the elevated-end branch: derivatives with respect to every input finite
    (the seabed-reach term must not put 0 * inf into the Jacobian)."""
    fn = cat.symbolic_function()
    args = [ca.MX.sym(nm) for nm in fn.name_in()]
    h, v, _ = fn(*args)
    J = ca.Function("J", args, [ca.jacobian(ca.vertcat(h, v), ca.vertcat(*args[:7]))])
    sol = cat.solve(950.0, 250.0, L0, EA0, W0, CB=0.5)
    Jn = np.array(J(950.0, 250.0, L0, EA0, W0, 0.5, 0.0, scalar(sol, "HF"), scalar(sol, "VF")))
    assert np.all(np.isfinite(Jn[:, :6]))  # h_A's own column may be one-sided at 0
    assert Jn[0, 0] == pytest.approx(scalar(sol, "dHF_dXF"), rel=1e-7)


ELEV_PROFILES = [  # (XF, ZF, h_A, EA)
    (900.0, 200.0, 50.0, EA0),    # touchdown from an elevated end
    (950.0, 0.0, 30.0, 2e7),      # U on the seabed, soft
    (800.0, 100.0, 300.0, EA0),   # sag above the seabed
    (700.0, 700.0, 100.0, EA0),   # uplift
    (600.0, 0.0, 200.0, 1e6),     # slack, hanging from both ends
    (0.0, 300.0, 1000.0, 2e7),    # vertical, doubled
]


@pytest.mark.parametrize("XF,ZF,h,EA", ELEV_PROFILES)
def test_line_profile_with_an_elevated_end(XF, ZF, h, EA):
    n = 20001
    prof = cat.line_profile(XF, ZF, L0, EA, W0, h_A=h, n=n)
    sol = prof["solution"]
    s, x, z, T = prof["s"], prof["x"], prof["z"], prof["T"]
    assert x[0] == pytest.approx(0.0, abs=1e-9) and z[0] == pytest.approx(0.0, abs=1e-9)
    assert x[-1] == pytest.approx(XF, abs=1e-6) and z[-1] == pytest.approx(ZF, abs=1e-6)
    assert T[-1] == pytest.approx(scalar(sol, "TF"), rel=1e-9)
    assert T[0] == pytest.approx(scalar(sol, "TA"), rel=1e-9, abs=1e-6)
    assert np.all(z >= -h - 1e-9) and np.all(np.diff(x) >= -1e-9) and np.all(T >= 0)
    LB = scalar(sol, "LBot")
    on_bed = np.isclose(z, -h, rtol=0, atol=1e-9)
    assert np.sum(on_bed) == pytest.approx(LB / L0 * (n - 1), abs=2)  # the grounded stretch, and only it
    # continuous tension; the curve's length is the stretched length (1 + T/EA) ds
    assert np.max(np.abs(np.diff(T))) <= W0 * (s[1] - s[0]) * 1.0001 + 1e-9 * scalar(sol, "TF")
    if cat.REGIMES[int(sol.regime)] in ("touchdown", "suspended"):  # (the slack stretch lies bunched)
        arc = np.sum(np.hypot(np.diff(x), np.diff(z)))
        stretched = np.sum(0.5 * (2 + (T[1:] + T[:-1]) / EA) * np.diff(s))
        assert arc == pytest.approx(stretched, rel=1e-6)


def elevated_grid():
    L = L0
    xf = np.linspace(0.0, 1.03 * L, 24)
    zf = np.linspace(0.0, 1.03 * L, 24)
    X, Z, H, EA, W, CB = (a.ravel() for a in np.meshgrid(xf, zf, [5.0, 60.0, 400.0], [3.0e7, 5.0e8],
                                                          [150.0, 1000.0], [0.0, 0.8], indexing="ij"))
    keep = np.hypot(X, Z) <= 1.04 * L
    return X[keep], Z[keep], np.full(keep.sum(), L), EA[keep], W[keep], CB[keep], H[keep]


def test_closure_with_an_elevated_end_reproduces_the_spans_in_every_regime():
    XF, ZF, L, EA, w, CB, h = elevated_grid()
    sol = cat.solve(XF, ZF, L, EA, w, CB=CB, h_A=h)
    names = sol.regime_names()
    assert set(names) == {"slack", "touchdown", "suspended", "vertical"}
    susp = names == "suspended"
    assert np.sum(susp & (sol.VA < 0)) >= 20 and np.sum(susp & (sol.VA > 0)) >= 20  # sags and uplift
    assert np.sum(susp & (np.hypot(XF, ZF) > L)) >= 10  # taut
    assert np.sum(names == "touchdown") >= 20
    for k in ("HF", "VF", "HA", "VA", "TF", "TA", "LBot", "dHF_dXF", "dHF_dZF", "dVF_dXF", "dVF_dZF"):
        assert np.all(np.isfinite(getattr(sol, k))), k
    assert np.all(sol.HF >= 0) and np.all(sol.VF >= 0) and np.all(sol.LBot >= 0)
    np.testing.assert_array_equal(sol.HA, sol.HF)  # frictionless with an elevated end
    reg = (names == "touchdown") | susp
    X, Z = cat.closure(sol.HF[reg], sol.VF[reg], L[reg], EA[reg], w[reg], CB[reg], h[reg])
    np.testing.assert_allclose(X, XF[reg], rtol=0, atol=1e-8)
    np.testing.assert_allclose(Z, ZF[reg], rtol=0, atol=1e-8)
    # a suspended line's lowest point is above the seabed; a touching-down one lies on it
    m = susp & (sol.VA < 0)
    HF, VA = sol.HF[m], sol.VA[m]
    sag = VA * VA / (w[m] * (np.hypot(HF, VA) + HF)) + VA * VA / (2 * EA[m] * w[m])
    assert np.all(sag <= h[m] * (1 + 1e-9))
    td = names == "touchdown"
    assert np.all(sol.LBot[td] > 0) and np.all(sol.VA[td] < 0)
    np.testing.assert_allclose(sol.VF[td] - sol.VA[td], w[td] * (L[td] - sol.LBot[td]), rtol=1e-12)
    # vectorised equals one by one, also with mixed heights
    for i in np.flatnonzero(reg)[::53]:
        one = cat.solve(XF[i], ZF[i], L[i], EA[i], w[i], CB=CB[i], h_A=h[i])
        assert scalar(one, "HF") == pytest.approx(sol.HF[i], rel=1e-9, abs=1e-9)
        assert scalar(one, "VF") == pytest.approx(sol.VF[i], rel=1e-9, abs=1e-9)


@settings(max_examples=200, deadline=None)
@given(valid, st.floats(0.0, 1.5))
@example({"L": 10.0, "xf": 0.0, "zf": 0.0, "EA": 1e5, "w": 5e-324, "CB": 0.0}, 1.0)  # doubled, w L underflows
@example({"L": 1000.0, "xf": 0.95, "zf": 0.0, "EA": 2e7, "w": 1000.0, "CB": 0.5}, 0.03)  # U on the seabed
def test_random_input_with_an_elevated_end_solves_and_closes(p, h_frac):
    L, EA, w, CB = p["L"], p["EA"], p["w"], p["CB"]
    XF, ZF, h = p["xf"] * L, p["zf"] * L, h_frac * L
    try:
        sol = cat.solve(XF, ZF, L, EA, w, CB=CB, h_A=h)
    except CatenaryError as exc:
        assert str(exc)
        return
    for k in ("HF", "VF", "HA", "VA", "TF", "LBot", "dHF_dXF"):
        assert np.isfinite(scalar(sol, k)), k
    if cat.REGIMES[int(sol.regime)] in ("touchdown", "suspended"):
        X, Z = cat.closure(np.array(scalar(sol, "HF")), np.array(scalar(sol, "VF")), L, EA, w, CB, h)
        assert abs(float(X) - XF) <= 1e-8 and abs(float(Z) - ZF) <= 1e-8
    try:
        prof = cat.line_profile(XF, ZF, L, EA, w, CB=CB, h_A=h, n=51)
    except CatenaryError:
        return
    assert np.all(np.isfinite(prof["x"])) and np.all(np.isfinite(prof["z"])) and np.all(prof["T"] >= 0)
    tol = 1e-6 * max(1.0, L / 1000)
    assert abs(prof["x"][-1] - XF) <= tol and abs(prof["z"][-1] - ZF) <= tol


def load_elevated_reference():
    with (DATA / "catenary_reference_elevated.csv").open() as fh:
        rows = list(csv.DictReader(line for line in fh if not line.startswith("#")))
    cols = ("XF", "ZF", "L", "EA", "w", "h_A", "HF", "VF", "HA", "VA", "LBot")
    ref = {k: np.array([float(r[k]) for r in rows]) for k in cols}
    ref["line"] = np.array([r["line"] for r in rows])
    ref["profile_type"] = np.array([r["profile_type"] for r in rows])
    return ref


# MoorPy ProfileType with the lower end off the seabed -> our regime
MOORPY_ELEVATED_REGIME = {"1": "suspended", "U": "touchdown", "5": "slack", "6": "vertical"}


def test_matches_moorpy_reference_with_the_lower_end_above_the_seabed():
    """MoorPy (CB = -h_A) against tapm_opt (h_A), to the same tolerance as the anchored reference:
    fully suspended lines with a sag below A and with uplift, taut lines, lines whose sag rests on
    the seabed, slack and vertical doubled lines, and the elevated cases of MoorPy's test suite."""
    ref = load_elevated_reference()
    assert ref["XF"].size >= 100
    assert set(ref["profile_type"]) == set(MOORPY_ELEVATED_REGIME)
    susp = ref["profile_type"] == "1"
    assert np.sum(susp & (ref["VA"] < 0)) >= 20 and np.sum(susp & (ref["VA"] > 0)) >= 5
    assert np.sum(ref["profile_type"] == "U") >= 20
    # MoorPy's own test cases: tests/test_catenary.py, CB = -372.7 (twice) and the U shape, CB = -20
    own = ref["line"] == "moorpy-test"
    np.testing.assert_array_equal(ref["h_A"][own], [372.7, 372.7])
    np.testing.assert_array_equal(ref["XF"][own], [400.0, 89.9])
    assert np.sum(ref["line"] == "moorpy-test-U") == 1
    sol = cat.solve(ref["XF"], ref["ZF"], ref["L"], ref["EA"], ref["w"], h_A=ref["h_A"])
    expected = np.array([MOORPY_ELEVATED_REGIME[p] for p in ref["profile_type"]])
    assert np.all(sol.regime_names() == expected)
    TF = np.hypot(ref["HF"], ref["VF"])
    for k in ("HF", "VF", "HA", "VA"):
        err = np.abs(getattr(sol, k) - ref[k]) / TF
        assert err.max() <= 1e-8, (k, int(err.argmax()), err.max())
    np.testing.assert_allclose(sol.LBot, ref["LBot"], rtol=0, atol=1e-8 * ref["L"].max())


def test_a_negative_cb_points_to_h_a():
    """MoorPy encodes an elevated lower end as a negative CB; tapm_opt names it h_A and says so."""
    with pytest.raises(CatenaryError, match=r"CB = -372.7 .*h_A = -CB"):
        cat.solve(800.0, 300.0, 900.0, 1e9, 1000.0, CB=-372.7)
    sol = cat.solve(800.0, 300.0, 900.0, 1e9, 1000.0, h_A=372.7)
    assert np.all(np.isfinite([sol.HF, sol.VF]))


@pytest.mark.parametrize("args", [
    (500.0, 100.0, 1000.0, 1e9, 1000.0, 0.0, 0.0),     # slack, lying on the seabed
    (0.0, 300.0, 290.0, 1e9, 1000.0, 0.0, 50.0),       # vertical, taut
    (0.0, 100.0, 300.0, 1e9, 1000.0, 0.0, 150.0),      # vertical, hanging doubled from an elevated end
    (1001.0, 0.0, 1000.0, 1e8, 1000.0, 0.5, 0.0),      # both ends on the seabed, friction
    (800.0, 600.0, 990.0, 1e8, 0.0, 0.0, 0.0),         # weightless, taut
    (800.0, 500.0, 1000.0, 1e9, 1000.0, 0.0, 0.0),     # regular (touchdown)
])
def test_symbolic_catenary_covers_every_regime_of_the_numeric_one(args):
    """The symbolic function gives the numeric solve's tensions in every regime with a zero (or
    tiny) closure error, from a start 30 % off; in the slack regime it used to return a wrong VF
    with a 43 m closure error."""
    f = cat.symbolic_function()
    s = cat.solve(*args[:5], CB=args[5], h_A=args[6])
    H, V, e = (float(v) for v in f(*args, 1.3 * float(s.HF) + 1.0, 1.3 * float(s.VF) + 1.0))
    assert H == pytest.approx(float(s.HF), rel=1e-8, abs=1e-6)
    assert V == pytest.approx(float(s.VF), rel=1e-8, abs=1e-6)
    assert e <= 1e-8


# ------------------------------------------------------------------------------------------
# nonlinear axial stiffness: a tension-strain table (docs/models.md, "Nonlinear axial stiffness")
# ------------------------------------------------------------------------------------------


POLY_ROWS = ((0.0, 0.0), (0.005, 1.0e6), (0.01, 2.4e6), (0.02, 5.6e6), (0.03, 9.2e6), (0.05, 17.0e6))
"""A polyester-like law that stiffens with load (slopes 200, 280, 320, 360, 390 MN), secant 340 MN."""
POLY = StrainTable.from_rows(POLY_ROWS)
W_POLY = 138.19  # N/m: 52 kg/m polyester of 0.217 m in water


def linear_tables(EA):
    """The constant-EA law as a two-row table and as four collinear rows (intercepts at round-off)."""
    return (StrainTable.from_rows([[0.0, 0.0], [0.01, 0.01 * EA]]),
            StrainTable.from_rows([[0.0, 0.0], [0.003, 0.003 * EA], [0.007, 0.007 * EA], [0.02, 0.02 * EA]]))


def strain_of(T):
    """eps(T) of POLY_ROWS, written independently of StrainTable: np.interp, and the last slope beyond."""
    e, t = np.array(POLY_ROWS).T
    T = np.asarray(T, dtype=float)
    return np.where(T <= t[-1], np.interp(T, t, e), e[-1] + (T - t[-1]) * (e[-1] - e[-2]) / (t[-1] - t[-2]))


# every regime of the solver, as (XF, ZF, L, w, CB, h_A)
TABLE_REGIMES = {
    "suspended": (1190.0, 300.0, 1200.0, 800.0, 0.0, 0.0),
    "touchdown": (900.0, 300.0, 1200.0, 800.0, 0.0, 0.0),
    "touchdown, friction": (900.0, 300.0, 1200.0, 800.0, 0.7, 0.0),
    "touchdown, friction to zero": (600.0, 300.0, 1200.0, 800.0, 1.0, 0.0),
    "touchdown, elevated end": (950.0, 300.0, 1200.0, 800.0, 0.0, 40.0),
    "suspended, sag below an elevated end": (1100.0, 100.0, 1200.0, 800.0, 0.0, 300.0),
    "slack": (300.0, 300.0, 1200.0, 800.0, 0.0, 0.0),
    "slack, elevated end": (300.0, 300.0, 1200.0, 800.0, 0.0, 50.0),
    "vertical, taut": (0.0, 1201.0, 1200.0, 800.0, 0.0, 0.0),
    "vertical, doubled": (0.0, 600.0, 1200.0, 800.0, 0.0, 400.0),
    "seabed": (1201.0, 0.0, 1200.0, 800.0, 0.0, 0.0),
    "seabed, friction over part": (1200.2, 0.0, 1200.0, 800.0, 0.8, 0.0),
    "seabed, friction all along": (1205.0, 0.0, 1200.0, 800.0, 0.1, 0.0),
    "weightless": (1000.0, 500.0, 1110.0, 0.0, 0.0, 0.0),
}


@pytest.mark.parametrize("case", sorted(TABLE_REGIMES))
def test_a_linear_table_is_the_constant_ea_catenary(case):
    """A table whose rows lie on T = EA eps gives solve()'s constant-EA answer in every regime, to
    round-off: tensions within 1e-12 of the largest tension, stiffness within 1e-10 of the largest,
    profiles within 1e-9 m (measured 2.2e-16, 2.8e-16 and 2.8e-13 m over the 14 regimes)."""
    XF, ZF, L, w, CB, h = TABLE_REGIMES[case]
    EA = 5e8
    ref = cat.solve(XF, ZF, L, EA, w, CB=CB, h_A=h)
    for tab in linear_tables(EA):
        sol = cat.solve(XF, ZF, L, EA, w, CB=CB, h_A=h, table=tab)
        assert int(sol.regime) == int(ref.regime), case
        scale = max(scalar(ref, "TF"), scalar(ref, "TA"), 1.0)
        for k in ("HF", "VF", "HA", "VA"):
            assert abs(scalar(sol, k) - scalar(ref, k)) <= 1e-12 * scale, (case, k)
        assert abs(scalar(sol, "LBot") - scalar(ref, "LBot")) <= 1e-9 * L
        ks = max(abs(scalar(ref, k)) for k in ("dHF_dXF", "dHF_dZF", "dVF_dXF")) or 1.0
        for k in ("dHF_dXF", "dHF_dZF", "dVF_dXF", "dVF_dZF"):
            a, b = scalar(sol, k), scalar(ref, k)
            assert a == b or abs(a - b) <= 1e-10 * max(ks, abs(b)), (case, k, a, b)
        p0 = cat.line_profile(XF, ZF, L, EA, w, CB=CB, h_A=h, n=41)
        p1 = cat.line_profile(XF, ZF, L, EA, w, CB=CB, h_A=h, n=41, table=tab)
        assert np.max(np.abs(p1["x"] - p0["x"])) < 1e-9 and np.max(np.abs(p1["z"] - p0["z"])) < 1e-9, case
        assert np.allclose(p1["T"], p0["T"], rtol=1e-12, atol=1e-12 * scale)


def _spans_by_quadrature(HF, VF, L, w, CB, h):
    """(X, Z) of a line of POLY_ROWS with fairlead tensions (HF, VF), integrated numerically along
    its unstretched length (scipy quad, cut at the table's rows): the catenary's geometry with the
    strain of the table, written without the module's closed forms. Suspended, or touching down
    (friction on the grounded stretch from an anchor on the seabed; from an elevated end, the
    part that runs down to the seabed ends where its drop is h)."""
    knots = np.array(POLY_ROWS)[1:, 1]

    def run(V0, length):  # from vertical tension V0 over length: (dx, dz)
        def T(s):
            return math.hypot(HF, V0 + w * s)
        brk = [(math.copysign(math.sqrt(Tk * Tk - HF * HF), v) - V0) / w for Tk in knots if Tk > HF for v in (1, -1)]
        brk = [b for b in brk if 0 < b < length] + ([-V0 / w] if 0 < -V0 / w < length else [])
        kw = dict(points=sorted(brk) or None, epsabs=1e-12, epsrel=1e-13, limit=200)
        dx = quad(lambda s: (1 + float(strain_of(T(s)))) * HF / T(s), 0.0, length, **kw)[0]
        dz = quad(lambda s: (1 + float(strain_of(T(s)))) * (V0 + w * s) / T(s), 0.0, length, **kw)[0]
        return dx, dz

    VA = VF - w * L
    if VA >= 0 or (h > 0 and -run(VA, -VA / w)[1] < h):  # suspended: its lowest point above the seabed
        return run(VA, L)
    V1 = 0.0
    if h > 0:  # the downward vertical tension where the line from the elevated end meets the seabed
        V1 = brentq(lambda V: -run(-V, V / w)[1] - h, 1e-9, -VA, xtol=1e-12)
    LB = L - (VF + V1) / w
    cbw = CB * w if h == 0 else 0.0
    if cbw > 0:
        s0 = max(LB - HF / cbw, 0.0)
        bed = LB + quad(lambda s: float(strain_of(HF - cbw * (LB - s))), s0, LB, epsabs=1e-12, epsrel=1e-13,
                        limit=200)[0]
    else:
        bed = LB * (1 + float(strain_of(HF)))
    dxA, dzA = run(-V1, V1 / w) if V1 > 0 else (0.0, 0.0)
    dxF, dzF = run(0.0, VF / w)
    return dxA + bed + dxF, dzF - h


@pytest.mark.parametrize("HF, VF, CB, h", [
    (2.0e6, 1.2e6, 0.0, 0.0),    # suspended, every segment of the table along it
    (4.0e5, 5.0e5, 0.0, 0.0),    # touching down
    (4.0e5, 5.0e5, 0.7, 0.0),    # friction, some tension left at the anchor
    (1.5e5, 5.0e5, 1.0, 0.0),    # friction takes it all
    (4.0e5, 5.0e5, 0.0, 40.0),   # touching down from an elevated end
    (3.0e6, 7.0e5, 0.0, 300.0),  # suspended, sagging below an elevated end
    (1.2e7, 3.0e6, 0.0, 0.0),    # beyond the last row: the last slope continued
])
def test_table_closure_is_the_integral_of_the_strain_along_the_line(HF, VF, CB, h):
    """closure() with a table against numerical quadrature of (1 + eps(T(s))) along the line (an
    independent statement of the elastic catenary): within 1e-9 m (measured 2.3e-13 m)."""
    L, w = 1200.0, 800.0
    X, Z = cat.closure(np.array(HF), np.array(VF), L, POLY.secant, w, CB, h, POLY)
    Xq, Zq = _spans_by_quadrature(HF, VF, L, w, CB, h)
    assert abs(float(X) - Xq) < 1e-9 and abs(float(Z) - Zq) < 1e-9, (float(X) - Xq, float(Z) - Zq)


@pytest.mark.parametrize("case", ["suspended", "touchdown", "touchdown, friction", "touchdown, friction to zero",
                                  "touchdown, elevated end", "suspended, sag below an elevated end"])
def test_table_stiffness_equals_finite_differences(case):
    """The analytic stiffness of a line of a nonlinear table (implicit function theorem on the
    exact closure and its Jacobian) against central differences of solve(), 1e-5 m apart, over a
    range of spans that crosses the table's rows: within 1e-6 of the largest (measured 1.9e-7)."""
    XF, ZF, L, w, CB, h = TABLE_REGIMES[case]
    # spans clear of those where the line's lowest tension equals a row's tension: the stiffness has a
    # square-root kink there, which differences resolve poorly
    X = XF + np.linspace(-25.0, 25.0, 11) + 0.377
    d = 1e-5
    sol = cat.solve(X, ZF, L, POLY.secant, w, CB=CB, h_A=h, table=POLY)
    args = dict(CB=CB, h_A=h, table=POLY, tol=1e-11)
    xp, xm = (cat.solve(X + s, ZF, L, 1.0, w, **args) for s in (d, -d))
    zp, zm = (cat.solve(X, ZF + s, L, 1.0, w, **args) for s in (d, -d))
    for an, fd in ((sol.dHF_dXF, (xp.HF - xm.HF) / (2 * d)), (sol.dVF_dXF, (xp.VF - xm.VF) / (2 * d)),
                   (sol.dHF_dZF, (zp.HF - zm.HF) / (2 * d)), (sol.dVF_dZF, (zp.VF - zm.VF) / (2 * d))):
        assert np.max(np.abs(an - fd)) <= 1e-6 * np.max(np.abs(an)), (case, an, fd)


def test_table_degenerate_regimes_close():
    """The closed forms of a table line: the vertical line hangs (doubled, or taut) to its spans,
    the slack line hangs its own stretched length, and the straight line on the seabed or without
    weight carries the table's tension of its strain, all checked against the table directly."""
    w, L = 800.0, 1200.0
    # taut vertical: ZF = L + int eps over the line, the tension falling by w L from VF
    s = cat.solve(0.0, 1215.0, L, POLY.secant, w, table=POLY)
    VF = scalar(s, "VF")
    Z = L + quad(lambda u: float(strain_of(VF - w * u)), 0.0, L, epsabs=1e-12, limit=200)[0]
    assert cat.regime_name(int(s.regime)) == "vertical" and abs(Z - 1215.0) < 1e-9
    # doubled from an elevated end: L1 down, L2 up from the fold
    s = cat.solve(0.0, 600.0, L, POLY.secant, w, h_A=400.0, table=POLY)
    L2 = scalar(s, "VF") / w
    L1 = L - L2

    def rise(length):
        return length + quad(lambda u: float(strain_of(w * u)), 0.0, length, epsabs=1e-12)[0]
    assert abs(rise(L2) - rise(L1) - 600.0) < 1e-9
    # slack: the hanging length rises ZF + h_A with its own weight's stretch
    Ls = float(cat.hanging_length(300.0, w, POLY.secant, POLY))
    assert abs(rise(Ls) - 300.0) < 1e-9
    # weightless: a straight bar at its chord's strain
    s = cat.solve(1000.0, 500.0, 1110.0, POLY.secant, 0.0, table=POLY)
    e = math.hypot(1000.0, 500.0) / 1110.0 - 1.0
    assert abs(scalar(s, "TF") - float(np.interp(e, *np.array(POLY_ROWS).T))) < 1e-6
    # on the seabed without friction: HF = T(stretch / L)
    s = cat.solve(1210.0, 0.0, L, POLY.secant, w, table=POLY)
    assert abs(scalar(s, "HF") - float(np.interp(10.0 / L, *np.array(POLY_ROWS).T))) < 1e-6


# MoorPy 1.3.0 reference (moorpy.nonlinear.nonlinear(XF, ZF, L, Str, Ten, W) with POLY_ROWS):
# MoorPy reads a tension-strain table as a straight weightless bar at the chord's strain, its
# weight lumped half at each end, no seabed: exact for w = 0 and for a light taut pendant, where
# the catenary's sag and its tension's change along the line are small. (HF, VF at the fairlead,
# HA, VA at the anchor) [N].
MOORPY_NONLINEAR = {
    (190.0, 50.0, 192.0, 138.19): (6555847.325827027, 1738489.2204807966, 6555847.325827027, 1711956.7404807967),
    (95.0, 25.0, 96.0, 138.19): (6555847.325827027, 1731856.1004807968, 6555847.325827027, 1718589.8604807965),
    (190.0, 50.0, 192.0, 0.0): (6555847.325827027, 1725222.9804807967, 6555847.325827027, 1725222.9804807967),
}


@pytest.mark.parametrize("key", sorted(MOORPY_NONLINEAR))
def test_table_line_matches_moorpy_nonlinear(key):
    """Against MoorPy 1.3.0's nonlinear line (hard-coded above): a weightless bar to 1e-12, a taut
    192 m polyester pendant at 6.8 MN to 1e-4 of the tension (measured 3.1e-5, and 7.7e-6 for the
    96 m one, 3e-17 weightless: MoorPy's bar leaves out the sag and the change of tension along the
    line, which its catenary has)."""
    XF, ZF, L, w = key
    HF, VF, HA, VA = MOORPY_NONLINEAR[key]
    s = cat.solve(XF, ZF, L, POLY.secant, w, table=POLY)
    tol = 1e-12 if w == 0 else 1e-4
    T = math.hypot(HF, VF)
    for got, ref in ((s.HF, HF), (s.VF, VF), (s.HA, HA), (s.VA, VA)):
        assert abs(float(got) - ref) <= tol * T, (float(got), ref)


def test_table_profile_ends_at_the_fairlead_and_stretches_as_the_table_says():
    """line_profile of a table line in each regime ends at the fairlead (1e-8 m); along a suspended
    line each piece's arc length is its unstretched length stretched by the table's strain at its
    tension (the polygon of 4001 points, to 1e-6)."""
    for case, (XF, ZF, L, w, CB, h) in TABLE_REGIMES.items():
        p = cat.line_profile(XF, ZF, L, POLY.secant, w, CB=CB, h_A=h, n=51, table=POLY)
        assert abs(p["x"][-1] - XF) < 1e-8 and abs(p["z"][-1] - ZF) < 1e-8, case
        assert p["x"][0] == 0.0 and p["z"][0] == 0.0, case
    XF, ZF, L, w, CB, h = TABLE_REGIMES["suspended"]
    p = cat.line_profile(XF, ZF, L, POLY.secant, w, n=4001, table=POLY)
    arc = np.hypot(np.diff(p["x"]), np.diff(p["z"]))
    Tm = 0.5 * (p["T"][1:] + p["T"][:-1])
    assert np.max(np.abs(arc / np.diff(p["s"]) - 1.0 - strain_of(Tm))) < 1e-6


def test_a_table_line_solves_many_configurations_at_once():
    """Vectorised: a sweep of spans through slack, touchdown and suspended, one call against one by one."""
    X = np.linspace(100.0, 1195.0, 40)
    sol = cat.solve(X, 300.0, 1200.0, POLY.secant, 800.0, CB=0.3, table=POLY)
    one = [cat.solve(x, 300.0, 1200.0, POLY.secant, 800.0, CB=0.3, table=POLY) for x in X[::7]]
    assert {cat.regime_name(r) for r in sol.regime} == {"slack", "touchdown", "suspended"}
    for s, i in zip(one, range(0, 40, 7)):
        assert abs(scalar(s, "TF") - sol.TF[i]) <= 1e-9 * sol.TF.max()


@pytest.mark.parametrize("rows, match", [
    ([[0.0, 0.0]], "at least 2"),
    ([[0.001, 0.0], [0.01, 1e6]], r"row 0 = \[0.001, 0\] must be \[0, 0\]"),
    ([[0.0, 0.0], [0.01, 1e6], [0.005, 2e6]], r"row 2 = \[0.005, 2e\+06\] does not increase the strain"),
    ([[0.0, 0.0], [0.01, 1e6], [0.02, 1e6]], "does not increase the tension"),
    ([[0.0, 0.0], [0.01, -1e6]], "negative tension"),
    ([[0.0, 0.0], [0.01, float("nan")]], "must be finite"),
])
def test_an_invalid_table_is_refused_naming_the_row(rows, match):
    with pytest.raises(StrainTableError, match=match):
        StrainTable.from_rows(rows)
    with pytest.raises(CatenaryError, match=match):
        cat.solve(900.0, 300.0, 1200.0, 5e8, 800.0, table=rows)


def test_strain_table_law():
    """The table's law: strain and tension inverse to each other, linear between rows and beyond
    the last, its complementary energy E(T) the integral of the strain, rise() the closed-form
    root of alpha dT + E(T0 + dT) - E(T0) = R."""
    T = np.array([0.0, 5e5, 1e6, 3e6, 9.2e6, 2e7])
    e = POLY.strain_at(T)
    assert np.allclose(e, strain_of(T), rtol=0, atol=1e-15)
    assert np.allclose(POLY.tension_at(e), T, rtol=1e-14, atol=1e-8)
    for t in (3e5, 4e6, 2e7):
        assert abs(float(POLY.energy(t)) - quad(lambda x: float(strain_of(x)), 0.0, t, points=[1e6, 2.4e6, 5.6e6,
                                                                                              9.2e6, 1.7e7])[0]) < 1e-9
    for T0, R, alpha in ((0.0, 300.0 * 800.0, 1.0), (4e5, 40.0 * 800.0, 1.0), (0.0, 2e4, 0.0), (1e6, 1e5, 0.0)):
        dT = float(POLY.rise(T0, R, alpha))
        assert abs(alpha * dT + float(POLY.energy(T0 + dT) - POLY.energy(T0)) - R) <= 1e-12 * R
    assert math.isclose(POLY.secant, 3.4e8) and math.isclose(POLY.max_slope, 3.9e8)
    assert math.isclose(POLY.initial_slope, 2e8)
