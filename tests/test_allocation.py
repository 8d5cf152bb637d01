"""Tests of the QP thrust allocation (tapm_opt.control.allocation): the analytic weighted
pseudo-inverse when no bound is active, exact force balance, graceful saturation, agreement with an
independent cvxpy formulation, thrust-rate, azimuth-rate and forbidden-sector limits over command
sequences, thruster failure without a new OSQP setup, tunnel/fixed thrusters, the fallback path,
bad arguments and a hypothesis property over random demands and previous states."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from tapm_opt import load_scenario
from tapm_opt.config import Thruster, scenario_from_dict, scenario_to_dict
from tapm_opt.control.allocation import (
    AllocationError,
    AllocationResult,
    ThrustAllocator,
    allocate_reference,
    pseudo_inverse,
)
from tapm_opt.errors import TapmError
from tapm_opt.geometry import ssa
from tapm_opt.models.thrust import configuration_matrix, extended_columns

FPSO = load_scenario("fpso")           # six 1.2 MN azimuths, 1.2e5 N/s, 10 deg/s
BIG_DT = 1e4                           # s: no thrust-rate or azimuth-rate limit can bind
DEG = math.pi / 180.0


def azimuth(id, x, y, **kw) -> Thruster:
    base = dict(id=id, kind="azimuth", position=(x, y), angle=0.0, max_thrust=1.2e6, max_thrust_rate=1.2e5,
                max_azimuth_rate=10 * DEG, time_constant=5.0)
    return Thruster(**{**base, **kw})


def mixed_thrusters() -> list[Thruster]:
    """Four azimuths, a bow tunnel (toward starboard) and a reversible fixed stern propeller."""
    return [azimuth("A1", -140.0, -14.0), azimuth("A2", -140.0, 14.0), azimuth("F1", 128.0, -10.0),
            azimuth("F2", 128.0, 10.0),
            Thruster(id="T1", kind="tunnel", position=(150.0, 0.0), angle=90 * DEG, max_thrust=4e5,
                     max_reverse_thrust=3e5, max_thrust_rate=2e5, time_constant=2.0),
            Thruster(id="P1", kind="fixed", position=(-155.0, 0.0), angle=0.0, max_thrust=1.5e6,
                     max_reverse_thrust=6e5, max_thrust_rate=1.5e5, time_constant=5.0)]


def sector_scenario():
    """fpso with thruster A2 forbidden to push aft: sector 160..200 deg (docs/scenarios.md example)."""
    data = scenario_to_dict(FPSO)
    data["thrusters"][1]["forbidden_sectors_deg"] = [[160.0, 200.0]]
    return scenario_from_dict(data)


def geometry(thrusters):
    x = np.array([th.position[0] for th in thrusters])
    y = np.array([th.position[1] for th in thrusters])
    return x, y


def force_vectors(res: AllocationResult) -> np.ndarray:
    """Thrust as a complex number f e^(i alpha) (fixed axis: signed f along its angle)."""
    return res.f * np.exp(1j * res.alpha)


def check_limits(thrusters, res: AllocationResult, *, f_prev=None, alpha_prev=None, dt=None, tol=1e-9):
    """Every hard limit of a result (and its rates against a previous command)."""
    assert np.all(np.isfinite(res.f)) and np.all(np.isfinite(res.alpha)) and np.all(np.isfinite(res.tau))
    for i, th in enumerate(thrusters):
        fmax = th.max_thrust
        fmin = 0.0 if th.kind == "azimuth" else -th.max_reverse_thrust
        assert fmin - tol * fmax <= res.f[i] <= fmax * (1 + tol), (th.id, res.f[i])
        if th.kind != "azimuth":
            assert res.alpha[i] == pytest.approx(ssa(th.angle), abs=1e-12)
        if f_prev is not None:
            assert abs(res.f[i] - f_prev[i]) <= th.max_thrust_rate * dt * (1 + tol) + 1e-6, (th.id, res.f[i], f_prev[i])
            if th.kind == "azimuth" and th.max_azimuth_rate is not None:
                assert abs(ssa(res.alpha[i] - alpha_prev[i])) <= th.max_azimuth_rate * dt * (1 + tol) + 1e-12, th.id


# --- analytic limit and force balance -----------------------------------------------------------

@pytest.mark.parametrize("weights", [None, {"A1": 4.0, "F3": 0.5}])
def test_equals_weighted_pseudo_inverse_when_no_bound_is_active(weights):
    al = ThrustAllocator.from_scenario(FPSO, dt=BIG_DT, weights=weights)
    k = np.ones(6) if weights is None else np.array([4.0, 1, 1, 1, 1, 0.5])
    x, y = geometry(FPSO.thrusters)
    B = np.hstack([extended_columns(x[i], y[i]) for i in range(6)])          # (3, 12): (fx_i, fy_i)
    Winv = np.repeat(np.array([th.max_thrust for th in FPSO.thrusters]) ** 2 / k, 2)
    rng = np.random.default_rng(0)
    for _ in range(10):
        tau = rng.uniform(-1, 1, 3) * [8e5, 8e5, 5e7]                         # ~10 % of capacity
        u = Winv * (B.T @ np.linalg.solve(B @ (Winv[:, None] * B.T), tau))     # W^-1 B^T (B W^-1 B^T)^-1 tau
        np.testing.assert_allclose(pseudo_inverse(B, tau, 1.0 / Winv), u, rtol=1e-10, atol=1e-6)
        res = al.allocate(tau)
        assert res.status == "solved" and not res.fallback
        comps = np.stack([res.f * np.cos(res.alpha), res.f * np.sin(res.alpha)], axis=1).ravel()
        np.testing.assert_allclose(comps, u, rtol=0, atol=1e-4 * np.abs(u).max())
        assert np.all(res.f < 0.5 * 1.2e6)                                     # nothing near a bound


def test_meets_tau_exactly_when_feasible_in_one_step_and_in_the_loop():
    x, y = geometry(FPSO.thrusters)
    scale = np.array([1.2e6, 1.2e6, 1.2e6 * 141.0])  # F_ref, F_ref, F_ref * L_ref
    tau = np.array([1.5e6, -9e5, 6e7])
    res = ThrustAllocator.from_scenario(FPSO, dt=BIG_DT).allocate(tau)
    np.testing.assert_allclose(configuration_matrix(res.alpha, x, y) @ res.f, tau, rtol=0, atol=1e-5 * scale.min())
    assert np.all(np.abs(res.slack) <= 1e-6 * scale)
    al = ThrustAllocator.from_scenario(FPSO)  # dt = 0.1 s: thrusters ramp and turn for ~20 s
    for k in range(400):
        res = al.allocate(tau)
        assert not res.fallback, (k, res.status)
    assert res.status == "solved"
    np.testing.assert_allclose(configuration_matrix(res.alpha, x, y) @ res.f, tau, rtol=0, atol=1e-5 * scale.min())
    assert np.all(np.abs(res.slack) <= 1e-6 * scale)


@pytest.mark.parametrize("tau", [[3e7, 0, 0], [0, -3e7, 0], [0, 0, 4e9], [2e7, 2e7, -2e9]])
def test_saturates_gracefully_far_beyond_capacity(tau):
    tau = np.array(tau, float)
    for dt, steps in [(BIG_DT, 1), (0.1, 300)]:
        al = ThrustAllocator.from_scenario(FPSO, dt=dt)
        for _ in range(steps):
            prev = (al.f_prev, al.alpha_prev)
            res = al.allocate(tau)
            check_limits(FPSO.thrusters, res, f_prev=prev[0], alpha_prev=prev[1], dt=dt)
        assert not res.fallback, res.status
        assert np.linalg.norm(res.slack) > 0.5 * np.linalg.norm(tau)                    # slack takes the rest
        np.testing.assert_allclose(res.tau + res.slack, tau, rtol=1e-12)
        assert res.f.max() >= 0.98 * 1.2e6                                     # and thrusters saturate
        idle = dataclasses.replace(res, f=np.zeros(6), slack=tau)
        assert al.cost(res) < al.cost(idle)                                    # better than doing nothing


# --- the independent reference ----------------------------------------------------------------------

def _agreement_cases():
    yield "fpso, no rate limits", FPSO.thrusters, dict(dt=BIG_DT), 0
    yield "fpso, in the loop", FPSO.thrusters, dict(), 60
    yield "mixed, no rate limits", mixed_thrusters(), dict(dt=BIG_DT), 0
    yield "mixed, in the loop", mixed_thrusters(), dict(), 60
    yield "sector, in the loop", sector_scenario().thrusters, dict(), 60


@pytest.mark.parametrize("name, thrusters, kw, warmup", list(_agreement_cases()), ids=lambda v: v if isinstance(v, str) else "")
def test_osqp_and_cvxpy_agree_on_feasible_and_infeasible_tau(name, thrusters, kw, warmup):
    al = ThrustAllocator(thrusters, solver="osqp", **kw)
    rng = np.random.default_rng(7)
    for k in range(warmup):  # leave the rest state: thrusters loaded and turned
        al.allocate([1e6 * math.sin(0.05 * k), 8e5, 3e7])
    if "mixed" in name:
        al.set_failed("F2")
    for k in range(8):
        big = 6.0 if k % 2 else 0.25                       # alternately infeasible and feasible
        tau = rng.uniform(-1, 1, 3) * np.array([1.5e6, 1.5e6, 8e7]) * big
        ref = allocate_reference(al, tau)
        res = al.allocate(tau)
        assert res.status in ("solved", "solved_inaccurate"), res.status
        c, c_ref = al.cost(res), al.cost(ref)
        assert c == pytest.approx(c_ref, rel=1e-3, abs=1e-6), (k, c, c_ref)
        scale = al.F_ref * np.array([1.0, 1.0, al.L_ref])
        np.testing.assert_allclose(res.tau / scale, ref.tau / scale, rtol=0, atol=1e-3, err_msg=f"step {k}")
        # Feasible: the optimum is unique (strictly convex in u). Beyond capacity the saturated
        # thrusters all cost the same, so the split between near-parallel thrusters is only weakly
        # determined (flat to ~1/slack_weight): forces agree to 1 % of max_thrust there.
        feasible = np.all(np.abs(ref.slack / scale) < 1e-5)
        atol = (1e-3 if feasible else 1e-2) * al.F_ref
        np.testing.assert_allclose(force_vectors(res), force_vectors(ref), rtol=0, atol=atol, err_msg=f"step {k}")


# --- limits over sequences -------------------------------------------------------------------------

@pytest.mark.parametrize("thrusters", [FPSO.thrusters, mixed_thrusters()], ids=["fpso", "mixed"])
def test_rate_limits_hold_over_step_changes_of_tau(thrusters):
    al = ThrustAllocator(thrusters)
    steps = [np.zeros(3)] * 10 + [np.array([2e6, 0, 0])] * 150 + [np.array([-2e6, 1e6, -8e7])] * 250
    steps += [np.array([1e6 * math.sin(0.02 * k), 5e5, 4e7 * math.cos(0.03 * k)]) for k in range(200)]
    steps += [np.array([5e5, 5e5, 2e7])] * 200
    f_prev, a_prev = al.f_prev, al.alpha_prev
    turned = np.zeros(len(thrusters))
    n_fallback = 0
    for k, tau in enumerate(steps):
        dt = 0.05 if k % 3 else 0.2                     # varying sample time
        res = al.allocate(tau, dt)
        check_limits(thrusters, res, f_prev=f_prev, alpha_prev=a_prev, dt=dt)
        turned += np.abs(ssa(res.alpha - a_prev))
        n_fallback += res.fallback
        f_prev, a_prev = res.f, res.alpha
    assert n_fallback == 0
    az = np.array([th.kind == "azimuth" for th in thrusters])
    assert np.all(turned[az] > math.pi / 2)             # the azimuths did turn (the limits were tested)
    np.testing.assert_allclose(res.slack / steps[-1], 0.0, atol=1e-5)  # and the final hold is met


def test_idle_azimuths_turn_toward_the_demand_instead_of_sticking_behind_their_wedge():
    ths = [azimuth(f"A{i}", -100.0 + 60 * i, (-1) ** i * 10.0) for i in range(4)]
    tau = np.array([-1.5e6, 0.0, 0.0])                  # astern; every thruster points ahead
    for steer, met in [(True, True), (False, False)]:
        al = ThrustAllocator(ths, steer_idle=steer)
        for _ in range(300):                            # 30 s: 180 deg at 10 deg/s takes 18 s
            res = al.allocate(tau)
        assert bool(abs(res.slack[0]) < 1e-5 * 1.5e6) == met, (steer, res.slack)
    assert np.all(res.alpha == 0.0)                     # without steering they never moved


def test_failed_thruster_gets_exactly_zero_and_the_others_take_over_without_a_new_setup():
    al = ThrustAllocator.from_scenario(FPSO, dt=BIG_DT)
    solver = al.solver
    tau = np.array([1.5e6, 8e5, 4e7])
    res0 = al.allocate(tau)
    al.set_failed("A2")
    res1 = al.allocate(tau)
    assert res1.f[1] == 0.0 and al.failed[1]
    assert np.all(np.abs(res1.slack) < 1e-3 * np.abs(tau).max())           # still met
    assert res1.f[[0, 2]].sum() > res0.f[[0, 2]].sum()                     # neighbours work harder
    al.set_failed(1, failed=False)
    res2 = al.allocate(tau)
    assert res2.f[1] > 0
    np.testing.assert_allclose(res2.f, res0.f, rtol=0, atol=1e-6 * al.F_ref)
    assert al.solver is solver                                             # no new OSQP setup
    # in the loop: from the step it fails, zero thrust, azimuth frozen, the rest rate-limited
    al = ThrustAllocator.from_scenario(FPSO)
    solver = al.solver
    for _ in range(150):
        res = al.allocate(tau)
    al.set_failed("F1")
    f_prev, a_prev = res.f.copy(), res.alpha.copy()
    f_prev[3] = 0.0
    for _ in range(200):
        res = al.allocate(tau)
        assert res.f[3] == 0.0 and res.alpha[3] == a_prev[3]
        check_limits(FPSO.thrusters, res, f_prev=f_prev, alpha_prev=a_prev, dt=0.1)
        f_prev, a_prev = res.f, res.alpha
    assert np.all(np.abs(res.slack) < 1e-6 * np.abs(tau)) and al.solver is solver


def test_forbidden_sector_is_respected():
    sc = sector_scenario()
    lo, hi = 160 * DEG, 200 * DEG

    def inside(a):
        return 0.0 < (a - lo) % (2 * math.pi) < hi - lo - 1e-9

    al = ThrustAllocator.from_scenario(sc)
    tau = np.array([-2.5e6, 0.0, 0.0])                  # astern: A2 would like to point at 180 deg
    for _ in range(400):
        res = al.allocate(tau)
        assert not (res.f[1] > 0 and inside(res.alpha[1] + 1e-9) and inside(res.alpha[1] - 1e-9)), res.alpha[1]
    assert abs(abs(res.alpha[0]) - math.pi) < 0.2        # its neighbour does point aft
    assert min(abs(ssa(res.alpha[1] - lo)), abs(ssa(res.alpha[1] - hi))) < 1e-3   # A2 at the sector edge
    assert res.f[1] > 1e5
    # started inside the sector (measured state): no thrust until it has turned out at full rate
    al.reset(f=np.full(6, 6e5), alpha=np.full(6, math.pi))
    a = [al.alpha_prev[1]]
    for _ in range(40):
        res = al.allocate(tau)
        a.append(res.alpha[1])
        if inside(res.alpha[1]):
            assert res.f[1] == 0.0
    assert np.all(np.abs(ssa(np.diff(a))) <= 1 * DEG + 1e-12) and not inside(a[-1])
    rng = np.random.default_rng(3)
    al = ThrustAllocator.from_scenario(sc, dt=BIG_DT)
    for _ in range(20):
        res = al.allocate(rng.uniform(-1, 1, 3) * [3e6, 3e6, 2e8])
        assert not (res.f[1] > 1.0 and inside(res.alpha[1])), np.degrees(res.alpha[1])


def test_tunnel_and_fixed_thrusters_give_signed_thrust_within_their_limits():
    ths = mixed_thrusters()
    al = ThrustAllocator(ths, dt=BIG_DT)
    for tid in ("A1", "A2", "F1", "F2"):
        al.set_failed(tid)
    res = al.allocate([-3e5, -2e5, -2e5 * 150.0])       # astern and to port at the bow
    np.testing.assert_allclose(res.f, [0, 0, 0, 0, -2e5, -3e5], rtol=1e-4, atol=1.0)
    res = al.allocate([-5e6, 5e6, 0.0])                  # beyond both: saturate at -reverse / +max
    assert res.f[4] == pytest.approx(4e5) and res.f[5] == pytest.approx(-6e5)
    rng = np.random.default_rng(5)
    for tid in ("A1", "A2", "F1", "F2"):
        al.set_failed(tid, False)
    for _ in range(30):
        res = al.allocate(rng.uniform(-1, 1, 3) * [6e6, 6e6, 4e8])
        check_limits(ths, res)


# --- fallback and bad input ---------------------------------------------------------------------------

def test_fallback_when_osqp_does_not_solve_is_reported_finite_and_saturated():
    al = ThrustAllocator.from_scenario(FPSO, osqp_settings=dict(max_iter=1, polishing=False))
    f_prev, a_prev = al.f_prev, al.alpha_prev
    for k in range(20):
        res = al.allocate([2e6, 1e6, 5e7])
        assert res.fallback and not res.success
        assert res.status.startswith("fallback:") and "max_iter" in res.status and "OSQP" in res.message
        check_limits(FPSO.thrusters, res, f_prev=f_prev, alpha_prev=a_prev, dt=0.1)
        np.testing.assert_array_equal(res.alpha, a_prev)              # azimuths held
        np.testing.assert_allclose(res.tau + res.slack, [2e6, 1e6, 5e7], rtol=1e-12)
        f_prev, a_prev = res.f, res.alpha
    assert res.f.max() > 0                                             # it does push


@pytest.mark.parametrize("bad", [[np.nan, 0, 0], [0, np.inf, 0], [0, 0, -np.inf]])
def test_non_finite_tau_in_the_loop_gives_zero_thrust_and_a_status(bad):
    al = ThrustAllocator.from_scenario(FPSO)
    for _ in range(30):
        al.allocate([1e6, 0, 0])
    res = al.allocate(bad)
    assert res.fallback and res.status == "fallback:invalid_tau" and "not finite" in res.message
    assert np.all(res.f == 0.0) and np.all(np.isfinite(res.alpha)) and np.all(res.tau == 0.0)
    assert al.allocate([1e6, 0, 0]).status == "solved"                # and the loop carries on


@pytest.mark.parametrize("tau, words", [([1.0, 2.0], "shape (2,)"), ([[1.0], [2.0], [3.0]], "shape (3, 1)"),
                                        ("abc", "not numeric"), (None, "shape ()"), ([1, 2, 3, 4], "shape (4,)")])
def test_bad_tau_raises_allocation_error_naming_it(tau, words):
    al = ThrustAllocator.from_scenario(FPSO)
    with pytest.raises(AllocationError, match="tau_cmd") as e:
        al.allocate(tau)
    assert words in str(e.value)
    assert isinstance(e.value, TapmError) and isinstance(e.value, ValueError)


def test_bad_arguments_raise_allocation_error_naming_them():
    al = ThrustAllocator.from_scenario(FPSO)
    for call, words in [(lambda: al.set_failed("X9"), "'X9'"), (lambda: al.set_failed(6), "thruster=6"),
                        (lambda: al.allocate([0, 0, 0], dt=0.0), "dt=0.0"),
                        (lambda: al.allocate([0, 0, 0], dt=math.nan), "dt=nan"),
                        (lambda: al.reset(f=np.zeros(5)), "shape (5,)"),
                        (lambda: al.reset(alpha=[0, 0, math.nan, 0, 0, 0]), "'A3'"),
                        (lambda: ThrustAllocator.from_scenario(FPSO, weights={"nope": 1.0}), "'nope'"),
                        (lambda: ThrustAllocator.from_scenario(FPSO, weights=[1, 2]), "weights"),
                        (lambda: ThrustAllocator.from_scenario(FPSO, polygon_sides=3), "polygon_sides=3"),
                        (lambda: ThrustAllocator([]), "empty"),
                        (lambda: ThrustAllocator([azimuth("A", 0, 0), azimuth("A", 1, 0)]), "not unique"),
                        (lambda: ThrustAllocator([azimuth("A", 0, 0, max_thrust=-1.0)]), "max_thrust=-1.0"),
                        (lambda: ThrustAllocator([dataclasses.replace(mixed_thrusters()[4], forbidden_sectors=((0.0, 1.0),))]),
                         "only allowed for azimuth"),
                        (lambda: ThrustAllocator([azimuth("A", 0, 0, forbidden_sectors=((0.0, 3.0), (3.0, 6.3)))]),
                         "forbid every direction")]:
        with pytest.raises(AllocationError) as e:
            call()
        assert words in str(e.value), str(e.value)


def test_result_is_immutable_and_timed():
    res = ThrustAllocator.from_scenario(FPSO).allocate([1e5, 0, 0])
    with pytest.raises(dataclasses.FrozenInstanceError):
        res.status = "x"
    with pytest.raises(ValueError):
        res.f[0] = 1.0
    assert res.success and res.solve_time > 0 and res.iterations > 0


# --- property ----------------------------------------------------------------------------------------

_ALLOCATORS = {"fpso": ThrustAllocator.from_scenario(FPSO), "mixed": ThrustAllocator(mixed_thrusters())}
_THRUSTERS = {"fpso": FPSO.thrusters, "mixed": mixed_thrusters()}


@settings(max_examples=80, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(which=st.sampled_from(["fpso", "mixed"]),
       tau=st.tuples(st.floats(-8e6, 8e6), st.floats(-8e6, 8e6), st.floats(-5e8, 5e8)),
       dt=st.sampled_from([0.05, 0.1, 1.0, 30.0, BIG_DT]),
       load=st.lists(st.floats(0.0, 1.0), min_size=6, max_size=6),
       turn=st.lists(st.floats(-math.pi, math.pi), min_size=6, max_size=6))
def test_property_random_tau_and_state_give_finite_limited_consistent_commands(which, tau, dt, load, turn):
    al, ths = _ALLOCATORS[which], _THRUSTERS[which]
    fmin = np.array([0.0 if th.kind == "azimuth" else -th.max_reverse_thrust for th in ths])
    fmax = np.array([th.max_thrust for th in ths])
    f0 = fmin + np.array(load) * (fmax - fmin)
    al.reset(f0, turn)
    f0, a0 = al.f_prev, al.alpha_prev
    res = al.allocate(tau, dt)
    check_limits(ths, res, f_prev=f0, alpha_prev=a0, dt=dt)
    np.testing.assert_allclose(res.tau + res.slack, tau, rtol=1e-12, atol=1e-6)
    x, y = geometry(ths)
    np.testing.assert_allclose(res.tau, configuration_matrix(res.alpha, x, y) @ res.f, rtol=1e-9, atol=1e-3)
    assert res.status in ("solved", "solved_inaccurate") or res.fallback


@pytest.mark.parametrize("fn, doc", [(ThrustAllocator.__init__, ThrustAllocator.__doc__),
                                     (ThrustAllocator.allocate, None), (ThrustAllocator.reset, None),
                                     (pseudo_inverse, None)])
def test_every_public_argument_is_documented(fn, doc):
    import inspect
    doc = doc or fn.__doc__
    for name in inspect.signature(fn).parameters:
        if name != "self":
            assert f"{name} :" in doc, f"{fn.__qualname__}: argument {name!r} is not documented"
