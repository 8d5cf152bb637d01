"""The limit-state statistics of tapm_opt.studies.verification against known answers: Gumbel fits
of samples drawn from a known Gumbel, partial safety factors on a hand example, rainflow counts
of the ASTM E1049 example and of a hand-counted series, Miner's damage of a sinusoid against the
closed form, and typed errors naming the bad argument."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.stats import gumbel_r

from tapm_opt.errors import TapmError
from tapm_opt.studies import verification as v
from tapm_opt.studies.verification import VerificationError

MU, BETA = 5.0e6, 3.0e5        # the true Gumbel of the drawn maxima [N]


@pytest.fixture(scope="module")
def maxima():
    return gumbel_r.rvs(loc=MU, scale=BETA, size=2000, random_state=np.random.default_rng(20240611))


# -- Gumbel most probable maximum ----------------------------------------------------------------

@pytest.mark.parametrize("method", ["moments", "mle"])
def test_gumbel_mpm_recovers_the_true_location(maxima, method):
    fit = v.gumbel_mpm(maxima, method=method)
    # a sign slip in mu = mean - gamma beta moves mu by 2 gamma beta = 3.5e5 N (7 %)
    assert fit.mpm == fit.mu
    assert fit.mu == pytest.approx(MU, rel=0.01)
    assert fit.beta == pytest.approx(BETA, rel=0.05)
    assert fit.method == method and fit.n == maxima.size


def test_gumbel_moments_by_hand():
    x = np.array([4.1e6, 4.6e6, 5.0e6, 5.3e6, 6.2e6])
    beta = np.std(x, ddof=1) * math.sqrt(6) / math.pi
    mu = x.mean() - 0.5772156649015329 * beta
    fit = v.gumbel_mpm(x)
    assert (fit.mu, fit.beta) == pytest.approx((mu, beta), rel=1e-12)


def test_gumbel_mle_matches_scipy(maxima):
    loc, scale = gumbel_r.fit(maxima)
    fit = v.gumbel_mpm(maxima, method="mle")
    assert fit.mu == pytest.approx(loc, rel=1e-4)
    assert fit.beta == pytest.approx(scale, rel=1e-3)
    small = maxima[:10]
    loc, scale = gumbel_r.fit(small)
    fit = v.gumbel_mpm(small, method="mle")
    assert (fit.mu, fit.beta) == pytest.approx((loc, scale), rel=1e-3)


def test_gumbel_degenerate_maxima():
    assert v.gumbel_mpm([3.0e6, 3.0e6, 3.0e6], method="mle")[:3] == (3.0e6, 3.0e6, 0.0)


def test_recommended_realisations():
    assert v.recommended_realisations(10) == (10, None)
    n, warn = v.recommended_realisations(5)
    assert n == 10 and "fewer than recommended" in warn and "unsourced" in warn
    n, warn = v.recommended_realisations(2)
    assert "below the floor of 3" in warn


# -- partial safety factors ----------------------------------------------------------------------

def test_partial_safety_factors_table():
    assert v.partial_safety_factors(1, "ULS") == (1.10, 1.50)
    assert v.partial_safety_factors(2, "ULS") == (1.40, 2.10)
    assert v.partial_safety_factors(1, "ALS") == (1.00, 1.10)
    assert v.partial_safety_factors(2, "als") == (1.00, 1.25)
    assert v.partial_safety_factors(1, "ULS", "quasi-static") == (1.70, 1.70)
    assert v.partial_safety_factors(2, "ALS", "quasi-static") == (1.35, 1.35)


def test_characteristic_tension_and_utilisation_hand_example():
    # T_mean = 1.0 MN, T_mpm = 2.5 MN  ->  T_dyn = 1.5 MN.
    # ULS class 2: 1.40 * 1.0 + 2.10 * 1.5 = 1.40 + 3.15 = 4.55 MN;
    # MBS = 6.0 MN: S_C = 0.95 * 6.0 = 5.70 MN, utilisation 4.55 / 5.70 = 0.7982456...
    t_mean, t_mpm = 1.0e6, 2.5e6
    tc = v.characteristic_tension(t_mean, t_mpm - t_mean, 2, "ULS")
    assert tc == pytest.approx(4.55e6, rel=1e-12)
    assert v.utilisation(tc, 6.0e6) == pytest.approx(4.55 / 5.70, rel=1e-12)
    # capacity factor as an argument: S_C = 1.0 * 6.0 MN -> 4.55 / 6.0
    assert v.utilisation(tc, 6.0e6, capacity_factor=1.0) == pytest.approx(4.55 / 6.0, rel=1e-12)
    # ALS class 1: 1.00 * 1.0 + 1.10 * 1.5 = 2.65 MN
    assert v.characteristic_tension(t_mean, 1.5e6, 1, "ALS") == pytest.approx(2.65e6, rel=1e-12)
    # quasi-static ULS class 1: 1.70 * (1.0 + 1.5) = 4.25 MN
    assert v.characteristic_tension(t_mean, 1.5e6, 1, "ULS", "quasi-static") == pytest.approx(4.25e6, rel=1e-12)


def test_class1_common_factor_replaces_the_two_factors_in_uls_class_1():
    # T_mean = 1.2 MN > 2/3 * T_dyn = 1.0 MN, ULS class 1: the common factor, 1.3 * 2.7 = 3.51 MN,
    # where the two factors would give 1.10 * 1.2 + 1.50 * 1.5 = 1.32 + 2.25 = 3.57 MN
    assert v.characteristic_tension(1.2e6, 1.5e6, 1, "ULS") == pytest.approx(3.51e6, rel=1e-12)
    assert v.characteristic_tension(1.2e6, 1.5e6, 1, "ULS", common_factor=False) == pytest.approx(3.57e6, rel=1e-12)
    # not in class 2, not in ALS, not below 2/3 T_dyn: T_mean = 0.9 MN < 1.0 MN -> 0.99 + 2.25 = 3.24 MN
    assert v.characteristic_tension(1.2e6, 1.5e6, 2, "ULS") == pytest.approx(1.4 * 1.2e6 + 2.1 * 1.5e6, rel=1e-12)
    assert v.characteristic_tension(1.2e6, 1.5e6, 1, "ALS") == pytest.approx(1.0 * 1.2e6 + 1.1 * 1.5e6, rel=1e-12)
    assert v.characteristic_tension(0.9e6, 1.5e6, 1, "ULS") == pytest.approx(3.24e6, rel=1e-12)


def test_the_kpis_line_check_is_this_design_tension():
    """The KPIs' DNV line check (kpis._dnv_ratio) is characteristic_tension / utilisation on the
    record's time-weighted mean and its maximum, with and without the common factor."""
    from tapm_opt.studies import kpis

    t = np.linspace(0.0, 100.0, 101)
    T = 2.0e6 + 0.5e6 * np.sin(t / 7.0)
    t_mean = kpis._tmean(t, T)
    for cf in (True, False):
        want = v.utilisation(v.characteristic_tension(t_mean, T.max() - t_mean, 1, "ULS", common_factor=cf), 17e6)
        assert kpis._dnv_ratio(t, T, 17e6, "ULS", 1, cf) == want
    assert kpis._dnv_ratio(t, T, 17e6, "ULS", 1, True) != kpis._dnv_ratio(t, T, 17e6, "ULS", 1, False)


# -- fatigue ---------------------------------------------------------------------------------------

def _as_dict(ranges, counts):
    return {float(r): float(c) for r, c in zip(ranges, counts)}


def test_rainflow_astm_e1049_example():
    # ASTM E1049-85 rainflow example (points A..I); counted by hand: half cycles of 3 (A-B) and
    # 4 (B-C), a full cycle of 4 (E-F), a half of 8 (C-D), then the residue D-G, G-H, H-I as halves
    # of 9, 8 and 6.  Range 3: 0.5, 4: 1.5, 6: 0.5, 8: 1.0, 9: 0.5.
    r, n = v.rainflow_ranges([-2, 1, -3, 5, -1, 3, -4, 4, -2])
    assert _as_dict(r, n) == {3.0: 0.5, 4.0: 1.5, 6.0: 0.5, 8.0: 1.0, 9.0: 0.5}
    assert np.all(np.diff(r) > 0)


def test_rainflow_hand_counted_series():
    # reversals 0, 4, 1, 3, 0 (2, 2.5 and 2 are not reversals). At 0 (last): X = |0 - 3| = 3 >=
    # Y = |3 - 1| = 2, Y not at the start -> full cycle of 2, drop 1 and 3; then 0, 4, 0: X = 4 >=
    # Y = 4, Y contains the start -> half cycle of 4, drop the first 0; residue 4-0: half of 4.
    # -> range 2: 1.0, range 4: 1.0; a constant record has no cycles.
    r, n = v.rainflow_ranges([0.0, 2.0, 4.0, 2.5, 1.0, 2.0, 3.0, 0.0])
    assert _as_dict(r, n) == {2.0: 1.0, 4.0: 1.0}
    r, n = v.rainflow_ranges([1.0, 1.0, 1.0])
    assert r.size == 0 and n.size == 0


def test_nominal_area():
    d = 0.1
    assert v.nominal_area("studless_chain", d) == pytest.approx(2 * math.pi * d**2 / 4, rel=1e-15)
    assert v.nominal_area("studlink_chain", d) == pytest.approx(2 * math.pi * d**2 / 4, rel=1e-15)
    assert v.nominal_area("six_strand_wire", d) == pytest.approx(math.pi * d**2 / 4, rel=1e-15)
    assert v.TN_CURVES["spiral_strand_wire"].m == 4.8 and v.TN_CURVES["studlink_chain"].a_D == 1.2e11


def test_miner_damage_of_a_sinusoid():
    # T = T0 - A cos(2 pi t / P) over N whole periods, starting at a trough: the reversals are
    # trough, crest, ..., trough, 2N half cycles of range 2A = N cycles.
    N, A, T0, per = 50, 1.0e5, 1.0e6, 40
    t = np.arange(N * per + 1) / per
    series = T0 - A * np.cos(2 * np.pi * t)
    c = v.TN_CURVES["studless_chain"]
    area = v.nominal_area("studless_chain", 0.1)
    expected = N * (2 * A / area / 1e6) ** c.m / c.a_D
    assert v.miner_damage(series, c.a_D, c.m, area) == pytest.approx(expected, rel=1e-9)
    # a wire curve (m = 4.8): the exponent is applied to the stress range in MPa
    w = v.TN_CURVES["spiral_strand_wire"]
    aw = v.nominal_area("spiral_strand_wire", 0.1)
    assert v.miner_damage(series, w.a_D, w.m, aw) == pytest.approx(N * (2 * A / aw / 1e6) ** w.m / w.a_D, rel=1e-9)


def test_polyester_damage_is_the_tension_ratio_curve():
    """DNV-OS-E301's polyester curve n_c = 0.259 R^-13.46 in the ratio R = range / MBS: a sinusoid
    of range 2A on a rope of strength MBS does N (2A / MBS)^13.46 / 0.259; its 'area' is MBS / 1 MPa,
    so the stress-range formula of the other curves gives the same; the area needs the MBS."""
    c = v.TN_CURVES["polyester_rope"]
    assert (c.m, c.a_D) == (13.46, 0.259)
    N, A, T0, per, MBS = 40, 1.5e6, 4.0e6, 32, 1.5e7
    t = np.arange(N * per + 1) / per
    series = T0 - A * np.cos(2 * np.pi * t)
    area = v.nominal_area("polyester_rope", MBS=MBS)
    assert area == pytest.approx(15.0, rel=1e-15)
    assert v.miner_damage(series, c.a_D, c.m, area) == pytest.approx(N * (2 * A / MBS) ** 13.46 / 0.259, rel=1e-9)
    with pytest.raises(v.VerificationError, match="range / MBS; give MBS"):
        v.nominal_area("polyester_rope", 0.24)


def test_a_polyester_line_type_takes_its_curve_and_strength():
    import tapm_opt
    from tapm_opt.studies.verification_study import (
        line_type_curves,
        verification_settings,
    )

    sc = tapm_opt.load_scenario("fpso_deep")
    st = verification_settings({"standard": "DNV-OS-E301", "consequence_class": 1}, sc)
    cur = line_type_curves(st, sc, ["poly240", "chain137"])
    poly = cur["poly240"]
    assert poly.component == "polyester_rope" and (poly.m, poly.a_D) == (13.46, 0.259)
    assert poly.area == pytest.approx(sc.line_type_by_id("poly240").MBS / 1e6, rel=1e-15)
    assert cur["chain137"].component == "studless_chain"


def test_annual_damage_and_fatigue_life():
    # 3-h records (10800 s): 365.25 * 86400 / 10800 = 2922 records a year.
    # sum p D = 0.7 * 1e-6 + 0.3 * 4e-6 = 1.9e-6  ->  D_year = 2922 * 1.9e-6 = 5.5518e-3
    d_year = v.annual_damage([1e-6, 4e-6], [0.7, 0.3], 10800.0)
    assert d_year == pytest.approx(5.5518e-3, rel=1e-12)
    # DFF 5: life = 1 / (5 * 5.5518e-3) = 36.0243 years
    assert v.fatigue_life(d_year, 5.0) == pytest.approx(1 / 0.027759, rel=1e-12)
    assert v.fatigue_life(0.0, 10.0) == math.inf


# -- errors ----------------------------------------------------------------------------------------

@pytest.mark.parametrize("call, needle", [
    (lambda: v.gumbel_mpm([1.0e6]), "maxima: need at least 2"),
    (lambda: v.gumbel_mpm([1.0e6, float("nan"), 2.0e6]), "maxima[1] = nan"),
    (lambda: v.gumbel_mpm([1.0e6, 2.0e6], method="lsq"), "method = 'lsq'"),
    (lambda: v.recommended_realisations(-1), "n_given = -1"),
    (lambda: v.partial_safety_factors(3, "ULS"), "consequence_class = 3"),
    (lambda: v.partial_safety_factors(1, "SLS"), "limit_state = 'SLS'"),
    (lambda: v.partial_safety_factors(1, "ULS", "static"), "analysis = 'static'"),
    (lambda: v.characteristic_tension(1e6, -2e5, 1, "ULS"), "T_dyn = -200000.0"),
    (lambda: v.characteristic_tension(float("inf"), 2e5, 1, "ULS"), "T_mean = inf"),
    (lambda: v.utilisation(1e6, 0.0), "MBS = 0.0"),
    (lambda: v.utilisation(1e6, 1e7, capacity_factor=1.5), "capacity_factor = 1.5"),
    (lambda: v.nominal_area("fibre", 0.1), "component = 'fibre'"),
    (lambda: v.nominal_area("studless_chain", -0.1), "d = -0.1"),
    (lambda: v.rainflow_ranges([1.0]), "series: need at least 2"),
    (lambda: v.miner_damage([0.0, 1.0, 0.0], 6e10, 3.0, 0.0), "area = 0.0"),
    (lambda: v.annual_damage([1e-6, 2e-6], [1.0], 10800.0), "probabilities: 1 values for 2 damages"),
    (lambda: v.annual_damage([1e-6], [1.2], 10800.0), "probabilities[0] = 1.2"),
    (lambda: v.annual_damage([1e-6, 1e-6], [0.6, 0.6], 10800.0), "probabilities sum to"),
    (lambda: v.annual_damage([1e-6], [1.0], 0.0), "record_duration = 0.0"),
    (lambda: v.fatigue_life(1e-3, 0.5), "design_fatigue_factor = 0.5"),
])
def test_bad_input_is_a_typed_error_naming_the_argument(call, needle):
    with pytest.raises(VerificationError) as info:
        call()
    assert isinstance(info.value, TapmError) and isinstance(info.value, ValueError)
    assert needle in str(info.value)


# -- DNV-OS-E301's design fatigue factor from the adjacent line -----------------------------------

@pytest.mark.parametrize("d_F, gamma", [(0.0, 5.0), (0.5, 5.0), (0.8, 5.0), (0.9, 6.5), (1.0, 8.0)])
def test_adjacent_fatigue_factor_piecewise(d_F, gamma):
    """gamma_F = 5 up to d_F = 0.8, then 5 + 3 (d_F - 0.8) / 0.2: 8 for two equally damaged lines."""
    assert v.adjacent_fatigue_factor(d_F) == pytest.approx(gamma, rel=1e-12)
    # continuous at the knee, linear above it
    assert v.adjacent_fatigue_factor(0.8 + 1e-9) == pytest.approx(5.0, abs=1e-6)


@pytest.mark.parametrize("bad", [-0.1, 1.0001, math.nan, math.inf, None, [0.9]])
def test_adjacent_fatigue_factor_bad_input(bad):
    with pytest.raises(VerificationError, match="d_F"):
        v.adjacent_fatigue_factor(bad)


def test_damage_ratio():
    assert v.damage_ratio(2.0, 8.0) == v.damage_ratio(8.0, 2.0) == 0.25
    assert v.damage_ratio(0.0, 3.0) == 0.0 and v.damage_ratio(0.0, 0.0) == 1.0
    with pytest.raises(VerificationError, match="D_b = -1"):
        v.damage_ratio(1.0, -1.0)


def test_line_neighbours_on_fpso_layout():
    """fpso's 12 lines, 3 bundles of 4 at 120 deg (fairlead angles 352.5, 357.5, 2.5, 7.5, 112.5, ...):
    each line's neighbours are the lines beside it in its bundle, and across the gap the last line of
    the next bundle; line 1 (352.5 deg) lies between line 12 (247.5 deg) and line 2 (357.5 deg)."""
    import tapm_opt

    sc = tapm_opt.load_scenario("fpso")
    ids = [ln.id for ln in sc.lines]
    nb = v.line_neighbours([ln.fairlead_angle for ln in sc.lines])
    got = {ids[i]: {ids[a], ids[b]} for i, (a, b) in enumerate(nb)}
    assert got["1"] == {"12", "2"} and got["2"] == {"1", "3"} and got["3"] == {"2", "4"}
    assert got["4"] == {"3", "5"} and got["5"] == {"4", "6"} and got["8"] == {"7", "9"}
    assert got["12"] == {"11", "1"}
    # every line is the neighbour of its two neighbours (a ring)
    assert all(ids[i] in got[n] for i in range(12) for n in got[ids[i]])
    # angles are taken modulo 2 pi; one line has no neighbour, two lines are each other's
    assert v.line_neighbours([0.1, 0.1 + 2 * math.pi + 1.0, -0.5]) == [(2, 1), (0, 2), (1, 0)]
    assert v.line_neighbours([1.0]) == [(0, 0)] and v.line_neighbours([1.0, 2.0]) == [(1, 1), (0, 0)]
    with pytest.raises(VerificationError, match="azimuths"):
        v.line_neighbours([])
    with pytest.raises(VerificationError, match="azimuths"):
        v.line_neighbours([0.0, math.nan])
