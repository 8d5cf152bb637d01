"""Tests of the tabulated mooring load (``MooringModel.load_evaluator``, ``force_fast``,
``tapm_opt.models.characteristics.TabulatedMooringLoad``) against the exact catenary load
``MooringModel.force``: every built-in scenario over random poses up to the tables' offset radius,
a locked off-centre turret, broken lines, anchors above the seabed and seabed friction (regime
changes inside the tables), poses beyond the tables, independence of the call history, the
numpy path, bad input, and its use in the low-pass estimator."""

from __future__ import annotations

import copy
import dataclasses
import math

import numpy as np
import pytest

import tapm_opt
from tapm_opt.config import builtin_scenarios, scenario_from_dict, scenario_to_dict
from tapm_opt.errors import ModelError
from tapm_opt.estimation.lowpass import LowPassEstimator
from tapm_opt.models import catenary as cat
from tapm_opt.models.characteristics import TabulatedMooringLoad
from tapm_opt.models.mooring import MooringModel

SCENARIOS = {name: tapm_opt.load_scenario(name) for name in builtin_scenarios()}


# ------------------------------------------------------------------------------------------
# helpers
# ------------------------------------------------------------------------------------------


def aamo4_variant(*, turret=None, shift=(0.0, 0.0), length_1=None):
    """aamo4 with turret fields replaced and the anchors shifted by ``shift`` [m]."""
    d = copy.deepcopy(scenario_to_dict(SCENARIOS["aamo4"]))
    ref = d["vessel"].get("reference_point")
    if ref is not None and not all(math.isfinite(v) for v in ref):
        del d["vessel"]["reference_point"]  # the default (nan, 0, nan) is not read back
    d["turret"].update(turret or {})
    for ln in d["lines"]:
        ln["anchor"][0] += shift[0]
        ln["anchor"][1] += shift[1]
    if length_1 is not None:
        d["lines"][0]["length"] = length_1
    return scenario_from_dict(d)


def raised(base, heights):
    """``base`` with anchor i ``heights[i]`` [m] above the seabed (as in tests/test_mooring.py)."""
    depth = base.environment.water_depth
    lines = tuple(dataclasses.replace(ln, anchor=(ln.anchor[0], ln.anchor[1], depth - h))
                  for ln, h in zip(base.lines, heights))
    return dataclasses.replace(base, lines=lines)


LOCKED = dict(turret={"mode": "locked", "position": [30.0, -4.0], "fairlead_radius": 15.0, "angle_deg": 10.0},
              shift=(30.0, -4.0))
# line 1 touches down from an anchor 60 m up, line 2 on the seabed, lines 3-4 sag below high anchors
RAISED_HEIGHTS = (60.0, 0.0, 400.0, 700.0)


def raised_model() -> MooringModel:
    return MooringModel.from_scenario(raised(aamo4_variant(length_1=2450.0, **LOCKED), RAISED_HEIGHTS))


def random_poses(n, radius, seed=0):
    """``n`` poses with the body origin uniformly in a disc of ``radius`` [m], any heading."""
    rng = np.random.default_rng(seed)
    r = radius * np.sqrt(rng.random(n))
    a = rng.uniform(-np.pi, np.pi, n)
    return np.stack([r * np.cos(a), r * np.sin(a), rng.uniform(-np.pi, np.pi, n)], axis=1)


def bounds(m: MooringModel, ev: TabulatedMooringLoad, eta, factor=10.0):
    """The documented error bound of ``ev`` at ``eta`` times ``factor``: (force [N], moment [N m])."""
    sol = m.solve_lines(eta)
    H0 = m.solve_lines(np.zeros(3)).HF
    per_line = ev.rtol * np.maximum(sol.HF, H0.max())
    arm = np.hypot(*m.p_cot_B) + np.hypot(m.p_T[:, 0], m.p_T[:, 1])
    return factor * per_line.sum(), factor * (per_line * arm).sum()


def assert_agrees(m: MooringModel, ev: TabulatedMooringLoad, poses):
    for eta in poses:
        got, want = ev(eta), m.force(eta)
        bF, bN = bounds(m, ev, eta)
        assert np.all(np.abs(got[:2] - want[:2]) <= bF), (eta, got, want, bF)
        assert abs(got[2] - want[2]) <= bN, (eta, got, want, bN)


# ------------------------------------------------------------------------------------------
# agreement with the exact load
# ------------------------------------------------------------------------------------------


@pytest.mark.parametrize("name", list(SCENARIOS))
def test_agrees_with_the_catenary_load_over_random_poses(name):
    m = MooringModel.from_scenario(SCENARIOS[name])
    ev = m.load_evaluator()
    assert ev.kernel == "numba" and ev.max_error <= 1.0
    poses = random_poses(150, ev.max_offset, seed=1)
    assert_agrees(m, ev, poses)
    assert ev.exact_calls == 0  # every pose in the disc is inside the tables
    # far tighter than 0.1 % of the largest line's contribution
    for eta in poses[:20]:
        assert np.max(np.abs(ev(eta)[:2] - m.force(eta)[:2])) <= 1e-3 * 1e-3 * m.solve_lines(eta).HF.max()


def test_fpso_at_100_m_in_every_direction_and_heading():
    m = MooringModel.from_scenario(SCENARIOS["fpso"])
    ev = m.load_evaluator()
    poses = [(100.0 * math.cos(a), 100.0 * math.sin(a), psi)
             for a in np.radians(np.arange(0.0, 360.0, 30.0)) for psi in np.radians([-180.0, -60.0, 0.0, 45.0, 170.0])]
    assert_agrees(m, ev, np.array(poses))
    # the load is large there: the agreement is not trivially that of small numbers
    assert np.hypot(*m.force(np.array([100.0, 0.0, 0.0]))[:2]) > 1e6


def test_locked_off_centre_turret():
    m = MooringModel.from_scenario(aamo4_variant(**LOCKED))
    assert m.turret_mode == "locked"
    ev = m.load_evaluator()
    assert_agrees(m, ev, random_poses(100, ev.max_offset, seed=2))


@pytest.mark.parametrize("name,broken", [("fpso", ("1",)), ("ren8", ("1", "2")), ("aamo4", ("3",))])
def test_broken_lines_are_left_out(name, broken):
    sc = SCENARIOS[name]
    ids = [ln.id for ln in sc.lines]
    broken = tuple(ids[int(b) - 1] for b in broken)
    m = MooringModel.from_scenario(sc, broken=broken)
    ev = m.load_evaluator()
    assert ev.xf_ranges.shape == (len(ids) - len(broken), 2)
    poses = random_poses(60, 100.0, seed=3)
    assert_agrees(m, ev, poses)
    intact = MooringModel.from_scenario(sc)
    eta = np.array([0.0, 0.0, 0.0])
    # a broken line leaves a net load at the field zero point; the fast path sees it
    assert np.hypot(*ev(eta)[:2]) > 1e4
    assert np.hypot(*(ev(eta) - intact.force_fast(eta))[:2]) > 1e4


def test_anchors_above_the_seabed_and_regime_changes_inside_the_tables():
    m = raised_model()
    np.testing.assert_array_equal(m.h_A, RAISED_HEIGHTS)
    ev = m.load_evaluator()
    assert len(ev._tables) == 4  # four line configurations
    assert_agrees(m, ev, random_poses(100, ev.max_offset, seed=4))
    # a sweep through the regime changes: lines 1 (raised anchor) and 2 lift off along it
    poses = np.array([(x, 0.5 * x, 0.1) for x in np.linspace(-250.0, 250.0, 201)])
    regimes = np.array([m.solve_lines(e).regime_names() for e in poses])
    for i in (0, 1):
        assert set(regimes[:, i]) == {"touchdown", "suspended"}, f"line {i + 1}: {set(regimes[:, i])}"
    assert_agrees(m, ev, poses)
    # each line's tabulated HF against the catenary across its table, incl. the regime changes
    lo, hi = ev.xf_ranges.T
    for i in range(m.n_lines):
        xs = np.linspace(lo[i], hi[i], 1501)
        XF = np.tile(ev.xf_ranges[:, :1].T, (xs.size, 1))
        XF[:, i] = xs
        H = np.array([ev.horizontal_tensions(x)[i] for x in XF])
        ref = cat.solve(xs, m.ZF[i], m.L[i], m.EA[i], m.w[i], CB=m.CB[i], h_A=m.h_A[i])
        if i < 3:  # line 4, 700 m up, stays suspended over its table
            assert len(set(ref.regime_names())) > 1
        H0 = m.solve_lines(np.zeros(3)).HF[i]
        np.testing.assert_array_less(np.abs(H - ref.HF), 10 * ev.rtol * np.maximum(ref.HF, H0) + 1e-9)


def test_seabed_friction_is_honoured():
    base = MooringModel.from_scenario(SCENARIOS["ren8"])
    m = dataclasses.replace(base, CB=np.full(base.n_lines, 0.6), _cache={})
    ev = m.load_evaluator()
    poses = random_poses(80, 150.0, seed=5)
    assert_agrees(m, ev, poses)
    eta = np.array([80.0, 30.0, 0.3])
    # friction changes the load (by ~300 N here), far more than the tables' error
    change = np.max(np.abs(ev(eta) - base.force_fast(eta))[:2])
    assert change > 100.0 and change > 1e3 * bounds(m, ev, eta)[0]


# ------------------------------------------------------------------------------------------
# coverage, call history, paths
# ------------------------------------------------------------------------------------------


def test_poses_beyond_the_tables_get_the_exact_load():
    m = MooringModel.from_scenario(SCENARIOS["ren8"])
    ev = m.load_evaluator(max_offset=5.0)
    inside = np.array([2.0, -1.0, 0.4])
    outside = np.array([60.0, -20.0, 0.4])
    assert_agrees(m, ev, [inside])
    assert ev.exact_calls == 0
    np.testing.assert_array_equal(ev(outside), m.force(outside))
    assert ev.exact_calls == 1


def test_the_answer_depends_on_the_pose_alone():
    """Slow motion, a jump of 150 m and 3 rad, and back: every answer equals a fresh
    evaluator's, bit for bit, and the same pose repeated gives the same load."""
    m = MooringModel.from_scenario(SCENARIOS["fpso"])
    ev = m.load_evaluator()
    t = np.arange(200) * 0.5
    slow = np.stack([10.0 + 0.2 * t, -5.0 + 0.05 * t, 0.1 + 0.001 * t], axis=1)
    jump = np.array([[-120.0, 90.0, -2.9], [-119.9, 90.1, -2.9]])
    seq = np.concatenate([slow, jump, slow[::-1]])
    got = np.array([ev(e) for e in seq])
    fresh = TabulatedMooringLoad(m)
    np.testing.assert_array_equal(got, np.array([fresh(e) for e in seq[::-1]])[::-1])
    np.testing.assert_array_equal(got[:200], got[-200:][::-1])
    assert_agrees(m, ev, seq[195:205])


def test_numpy_path_agrees_with_the_compiled_one():
    m = MooringModel.from_scenario(aamo4_variant(**LOCKED))
    a, b = m.load_evaluator(kernel="numba"), m.load_evaluator(kernel="numpy")
    assert (a.kernel, b.kernel) == ("numba", "numpy")
    for eta in random_poses(50, a.max_offset, seed=6):
        scale = np.abs(m.force(eta)).max()
        np.testing.assert_allclose(a(eta), b(eta), rtol=0, atol=1e-10 * scale)


def test_evaluator_is_kept_with_the_model_and_force_fast_uses_it():
    m = MooringModel.from_scenario(SCENARIOS["aamo4"])
    ev = m.load_evaluator()
    assert m.load_evaluator() is ev
    assert m.load_evaluator(rtol=1e-7) is not ev
    eta = np.array([12.0, -3.0, 0.5])
    np.testing.assert_array_equal(m.force_fast(eta), ev(eta))
    np.testing.assert_array_equal(m.force_fast(list(eta)), ev(eta))   # any array-like
    ro = eta.copy()
    ro.flags.writeable = False
    np.testing.assert_array_equal(m.force_fast(ro), ev(eta))
    # a copy with other line data gets its own tables, though dataclasses.replace shares the cache
    heavier = dataclasses.replace(m, w=m.w * 1.1)
    assert heavier.load_evaluator() is not ev
    assert np.max(np.abs(heavier.force_fast(eta) - m.force_fast(eta))) > 1e3


# ------------------------------------------------------------------------------------------
# bad input
# ------------------------------------------------------------------------------------------


@pytest.mark.parametrize("bad,match", [
    ([0.0, np.nan, 0.0], r"eta = \[0.0, nan, 0.0\] must be finite"),
    ([np.inf, 0.0, 0.0], r"eta = \[inf, 0.0, 0.0\] must be finite"),
    ([0.0, 0.0, -np.inf], r"must be finite"),
    (np.zeros(2), r"shape \(2,\)"),
    (np.zeros(4), r"shape \(4,\)"),
    (np.zeros((3, 1)), r"shape \(3, 1\)"),
])
@pytest.mark.parametrize("kernel", ["numba", "numpy"])
def test_bad_pose_raises_model_error_naming_it(bad, match, kernel):
    m = MooringModel.from_scenario(SCENARIOS["aamo4"])
    ev = m.load_evaluator(kernel=kernel)
    with pytest.raises(ModelError, match=match):
        ev(np.asarray(bad, dtype=float))
    with pytest.raises(ModelError, match="eta"):
        m.force_fast(bad)
    assert ev.exact_calls == 0


@pytest.mark.parametrize("kw,match", [
    (dict(rtol=0.0), "rtol = 0.0"),
    (dict(rtol=float("nan")), "rtol = nan"),
    (dict(rtol=0.1), "rtol = 0.1"),
    (dict(max_offset=-1.0), "max_offset = -1.0"),
    (dict(max_offset=float("inf")), "max_offset = inf"),
    (dict(kernel="fortran"), "kernel = 'fortran'"),
    (dict(rtol="small"), "rtol = 'small'"),
    (dict(max_offset=[100.0]), r"max_offset = \[100.0\]"),
])
def test_bad_settings_raise_model_error_naming_them(kw, match):
    m = MooringModel.from_scenario(SCENARIOS["aamo4"])
    with pytest.raises(ModelError, match=match):
        m.load_evaluator(**kw)


def test_horizontal_tensions_check_their_input():
    m = MooringModel.from_scenario(SCENARIOS["aamo4"])
    ev = m.load_evaluator()
    with pytest.raises(ModelError, match=r"XF must have shape \(4,\)"):
        ev.horizontal_tensions(np.zeros(3))
    lo, hi = ev.xf_ranges.T
    H = ev.horizontal_tensions(np.where(np.arange(4) == 0, hi + 1.0, lo))
    assert np.isnan(H[0]) and np.all(np.isfinite(H[1:]))


# ------------------------------------------------------------------------------------------
# the estimator
# ------------------------------------------------------------------------------------------


def test_lowpass_estimator_balances_with_the_tabulated_load():
    m = MooringModel.from_scenario(SCENARIOS["fpso"], broken=(SCENARIOS["fpso"].lines[0].id,))
    est = LowPassEstimator(m, T_env=10.0)
    eta = np.array([60.0, -40.0, 0.7])
    tau_thr = np.array([2e6, -5e5, 4e7])
    for k in range(400):
        *_, tau_env = est.filter(float(k), eta[:2], eta[2], tau_thr)
    assert est._load is m.load_evaluator()
    np.testing.assert_array_equal(est.mooring_load(eta), m.force_fast(eta))
    bF, bN = bounds(m, m.load_evaluator(), eta)
    ref = -(m.force(eta) + tau_thr)
    assert np.all(np.abs(tau_env[:2] - ref[:2]) <= bF + 1e-6 * np.abs(ref[:2]))
    assert abs(tau_env[2] - ref[2]) <= bN + 1e-6 * abs(ref[2])


def test_lowpass_estimator_follows_a_replaced_model_and_accepts_a_plain_one():
    fpso = MooringModel.from_scenario(SCENARIOS["fpso"])
    ren8 = MooringModel.from_scenario(SCENARIOS["ren8"])
    est = LowPassEstimator(fpso)
    eta = np.array([20.0, 10.0, 0.1])
    np.testing.assert_array_equal(est.mooring_load(eta), fpso.force_fast(eta))
    est.model = ren8
    np.testing.assert_array_equal(est.mooring_load(eta), ren8.force_fast(eta))

    class Plain:  # a model with force() only
        def force(self, eta):
            return np.array([1.0, 2.0, 3.0])

    est.model = Plain()
    np.testing.assert_array_equal(est.mooring_load(eta), [1.0, 2.0, 3.0])


# ------------------------------------------------------------------------------------------
# tabulated line characteristics (the MPC's parameters)
# ------------------------------------------------------------------------------------------


def assert_characteristics_agree(m: MooringModel, ev: TabulatedMooringLoad, poses, *, slope_rtol=1e-5):
    """Tabulated characteristics against ``MooringModel.characteristics``: H0 and T0 within the
    tables' bound (10 x rtol x max(value, largest pretension)), XF0 exact, the slopes within
    ``slope_rtol`` of the largest exact slope of each line over the poses."""
    exact = np.array([m.characteristics(e) for e in poses])
    got = np.array([ev.characteristics(e) for e in poses])
    H0 = m.solve_lines(np.zeros(3)).HF.max()
    for row in (0, 3):
        np.testing.assert_array_less(np.abs(got[:, row] - exact[:, row]),
                                     10 * ev.rtol * np.maximum(exact[:, row], H0) + 1e-9)
    np.testing.assert_array_equal(got[:, 2], exact[:, 2])
    for row in (1, 4):
        scale = np.max(np.abs(exact[:, row]), axis=0)
        assert np.all(np.abs(got[:, row] - exact[:, row]) <= slope_rtol * scale + 1e-9), row


@pytest.mark.parametrize("name", list(SCENARIOS))
def test_tabulated_characteristics_agree_with_the_catenary(name):
    m = MooringModel.from_scenario(SCENARIOS[name])
    ev = m.load_evaluator()
    assert_characteristics_agree(m, ev, random_poses(60, 0.8 * ev.max_offset, seed=11))
    assert ev.exact_calls == 0


def test_tabulated_characteristics_through_regime_changes():
    """Lines that lift off and touch down along the sweep: the slopes jump at a regime change,
    and the tables (a node pair there) still follow the catenary on both sides."""
    m = raised_model()
    ev = m.load_evaluator()
    poses = np.array([(x, 0.5 * x, 0.1) for x in np.linspace(-250.0, 250.0, 101)])
    assert_characteristics_agree(m, ev, poses, slope_rtol=1e-4)
    assert ev.exact_calls == 0


def test_tabulated_slopes_are_the_derivatives_of_the_tabulated_tensions():
    """The slope rows are the derivatives of the H0 and T0 rows (central differences of the
    tables themselves along a line's distance), and the characteristics are linear models
    that reproduce the catenary's tensions at a nearby pose to second order."""
    m = MooringModel.from_scenario(SCENARIOS["fpso"])
    ev = m.load_evaluator()
    eta, d = np.array([35.0, -12.0, 0.2]), np.array([0.05, 0.0, 0.0])
    c0, cp, cm = ev.characteristics(eta), ev.characteristics(eta + d), ev.characteristics(eta - d)
    dX = cp[2] - cm[2]
    np.testing.assert_allclose((cp[0] - cm[0]) / dX, c0[1], rtol=1e-6)
    np.testing.assert_allclose((cp[3] - cm[3]) / dX, c0[4], rtol=1e-6)
    far = eta + np.array([2.0, 1.0, 0.0])
    tau, T = m.characteristic_load(far, c0)
    exact = m.solve_lines(far)
    step = np.abs(m.spans(far)[2] - c0[2])
    assert np.all(np.abs(T - exact.TF) <= 0.05 * np.abs(c0[4]) * step + 1.0)


def test_tabulated_characteristics_beyond_the_tables_and_bad_pose():
    m = MooringModel.from_scenario(SCENARIOS["ren8"])
    ev = m.load_evaluator(max_offset=5.0)
    outside = np.array([60.0, -20.0, 0.4])
    np.testing.assert_array_equal(ev.characteristics(outside), m.characteristics(outside))
    assert ev.exact_calls == 1
    with pytest.raises(ModelError, match="eta"):
        ev.characteristics([np.nan, 0.0, 0.0])
    with pytest.raises(ModelError, match="eta"):
        ev.characteristics([1.0, 2.0])
