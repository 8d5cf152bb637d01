"""Tests of the DAQP path of the QP thrust allocation (tapm_opt.control.allocation, the default
solver) against the OSQP path and the independent cvxpy reference: random demands within and far
beyond capacity, rate-limited sequences, forbidden sectors, failed thrusters; the two-sided
polygon the DAQP path uses in narrow steps; the fallback when DAQP does not solve; the choice and
checks of ``solver=`` and ``daqp_settings=``; the thruster order; the compiled step kernels
against their Python source."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest

from tapm_opt.control.allocation import (
    DAQP_STATUS,
    AllocationError,
    AllocationResult,
    DaqpModels,
    ThrustAllocator,
    allocate_reference,
)
from tapm_opt.geometry import ssa

from test_allocation import BIG_DT, DEG, FPSO, check_limits, force_vectors, mixed_thrusters, sector_scenario

SECTOR = sector_scenario()          # fpso, A2 forbidden 160..200 deg


def reference(al: ThrustAllocator, tau, dt=None):
    """cvxpy reference at the allocator's state: the lower-cost of cvxpy's OSQP at 1e-10 and
    CLARABEL (both post-processed as the allocator's results, so feasible). On the random cases
    below, HiGHS (the reference's default) gave up on one QP and stopped 5.5e-4 above the optimum
    on another (forces 2 % of max_thrust off); CLARABEL gave up on one and put forces 3e-3 of
    max_thrust off along a flat direction; OSQP at 1e-10 was within 1e-7 on all."""
    import cvxpy

    refs = []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for solver, opts in [("OSQP", dict(eps_abs=1e-10, eps_rel=1e-10, max_iter=200000, polish=True)), ("CLARABEL", {})]:
            try:
                refs.append(allocate_reference(al, tau, dt, solver=solver, **opts))
            except (AllocationError, cvxpy.error.SolverError):
                pass
    assert refs, "no reference solve succeeded"
    return min(refs, key=al.cost)


def scale(al: ThrustAllocator) -> np.ndarray:
    return al.F_ref * np.array([1.0, 1.0, al.L_ref])


def twin(thrusters, **kw):
    """A DAQP allocator and an OSQP allocator on the same data."""
    return ThrustAllocator(thrusters, **kw), ThrustAllocator(thrusters, solver="osqp", **kw)


def sync(src: ThrustAllocator, dst: ThrustAllocator) -> bool:
    """Give dst the previous command and failures of src; False when that changed them (reset
    takes an azimuth a rounding error inside a forbidden sector, at its edge, as idle)."""
    for i in range(src.n):
        dst.set_failed(i, bool(src.failed[i]))
    dst.reset(src.f_prev, src.alpha_prev)
    return bool(np.array_equal(dst.f_prev, src.f_prev))


def assert_agree(al, res, ref, *, exact: bool, k=None):
    """Same cost and forces; ``exact``: two exact solvers (DAQP and the reference), else DAQP and
    OSQP (its 1e-5 tolerance; beyond capacity the split between near-parallel saturated thrusters
    is flat to ~1/slack_weight, so OSQP's forces agree to 1 % of max_thrust there)."""
    c, c_ref = al.cost(res), al.cost(ref)
    feasible = np.all(np.abs(ref.slack / scale(al)) < 1e-5)
    if exact:
        assert c == pytest.approx(c_ref, rel=1e-6, abs=1e-9), (k, c, c_ref)
        atol = (1e-4 if feasible else 1e-3) * al.F_ref
    else:
        assert c == pytest.approx(c_ref, rel=1e-3, abs=1e-6), (k, c, c_ref)
        atol = (1e-3 if feasible else 1e-2) * al.F_ref
    np.testing.assert_allclose(res.tau / scale(al), ref.tau / scale(al), rtol=0, atol=atol / al.F_ref, err_msg=f"step {k}")
    np.testing.assert_allclose(force_vectors(res), force_vectors(ref), rtol=0, atol=atol, err_msg=f"step {k}")


# --- agreement: DAQP, OSQP and the cvxpy reference ----------------------------------------------

def _cases():
    loop = [(np.array([1e6 * math.sin(0.05 * k), 8e5, 3e7]), 0.1) for k in range(60)]
    astern = [(np.array([-2.5e6, 0.0, 0.0]), 0.1)] * 250            # A2 ends at its sector's edge
    yield "fpso, no rate limits", FPSO.thrusters, BIG_DT, [], None
    yield "fpso, in the loop", FPSO.thrusters, 0.1, loop, None
    yield "mixed, no rate limits", mixed_thrusters(), BIG_DT, [], "F2"
    yield "mixed, in the loop, F2 failed", mixed_thrusters(), 0.1, loop, "F2"
    yield "sector, at its edge", SECTOR.thrusters, 0.1, astern, None
    yield "sector, dt = 3 s (whole polygon)", SECTOR.thrusters, 3.0, [(t, 3.0) for t, _ in loop[:20]], None


@pytest.mark.parametrize("name, thrusters, dt, warmup, failed", list(_cases()), ids=lambda v: v if isinstance(v, str) else "")
def test_daqp_osqp_and_cvxpy_agree_on_random_demands_within_and_beyond_capacity(name, thrusters, dt, warmup, failed):
    al, ao = twin(thrusters, dt=dt)
    for tau, h in warmup:                                  # leave the rest state: loaded, turned
        al.allocate(tau, h)
    if failed:
        al.set_failed(failed)
    rng = np.random.default_rng(11)
    for k in range(8):
        big = 6.0 if k % 2 else 0.25                       # alternately beyond and within capacity
        tau = rng.uniform(-1, 1, 3) * np.array([1.5e6, 1.5e6, 8e7]) * big
        same = sync(al, ao)
        ref = reference(al, tau)
        f_prev, a_prev = al.f_prev, al.alpha_prev
        res, res_o = al.allocate(tau), ao.allocate(tau)
        assert res.status == "solved" and not res.fallback, res.status
        check_limits(thrusters, res, f_prev=f_prev, alpha_prev=a_prev, dt=dt)
        assert_agree(al, res, ref, exact=True, k=k)
        if same and not res_o.fallback:                     # OSQP stops at max_iter on ~1 % of such steps
            assert_agree(al, res, res_o, exact=False, k=k)
        np.testing.assert_allclose(res.tau + res.slack, tau, rtol=1e-12)
        if failed:
            assert res.f[al.index(failed)] == 0.0


def closed_loop_like(n: int, rng) -> list[np.ndarray]:
    """A controller's demand (fractions of capacity): from rest to a mean load of 35 % ahead whose
    direction swings slowly, wave-frequency motion and noise on it, a reversal at n/3 (astern:
    into fpso A2's forbidden sector) and a storm of 1.4 x capacity from 2n/3 to 14n/15, the mean
    moving at most 2 % of capacity per step."""
    out, m = [], np.zeros(3)
    cap = np.array([7.2e6, 7.0e6, 9.7e8])
    for k in range(n):
        t = 0.1 * k
        heading = 0.3 * math.sin(t / 20.0) + (math.pi if k > n // 3 else 0.0)
        mag = 1.4 if 2 * n // 3 < k < 14 * n // 15 else 0.35
        target = mag * np.array([math.cos(heading), math.sin(heading), 0.5 * math.sin(heading + 1.0)])
        m = m + np.clip(target - m, -0.02, 0.02)
        wave = 0.12 * np.array([math.sin(t / 1.5), math.sin(t / 1.5 + 1.3), 0.5 * math.sin(t / 1.5 + 2.1)])
        out.append((m + wave * min(t / 5.0, 1.0) + 0.02 * rng.standard_normal(3)) * cap)
    return out


@pytest.mark.parametrize("thrusters", [FPSO.thrusters, SECTOR.thrusters, mixed_thrusters()], ids=["fpso", "sector", "mixed"])
def test_daqp_osqp_and_cvxpy_agree_step_by_step_on_a_closed_loop_like_sequence(thrusters):
    """Each step from the same previous command (OSQP synced to DAQP's state): rate limits bind in
    the transients, thrusters saturate in the storm, A2 meets its sector in the sector case. Every
    25th step also against the reference."""
    al, ao = twin(thrusters)
    rng = np.random.default_rng(5)
    turned = np.zeros(len(thrusters))
    n_saturated = n_edge = 0
    sector = thrusters[1].forbidden_sectors
    for k, tau in enumerate(closed_loop_like(450, rng)):
        same = sync(al, ao)
        f_prev, a_prev = al.f_prev, al.alpha_prev
        ref = reference(al, tau) if k % 25 == 0 else None
        res, res_o = al.allocate(tau), ao.allocate(tau)
        assert res.status == "solved", (k, res.status)
        check_limits(thrusters, res, f_prev=f_prev, alpha_prev=a_prev, dt=0.1)
        turned += np.abs(ssa(res.alpha - a_prev))
        n_saturated += bool(np.any(res.f > 0.98 * al.f_max))
        if ref is not None:
            assert_agree(al, res, ref, exact=True, k=k)
        if same and not res_o.fallback:                        # OSQP may stop at max_iter in transients
            assert_agree(al, res, res_o, exact=False, k=k)
        if sector:
            lo, hi = sector[0]
            inside = 0.0 < (res.alpha[1] - lo) % (2 * math.pi) < (hi - lo) % (2 * math.pi) - 1e-9
            assert not (inside and res.f[1] > 0.0), (k, res.alpha[1])
            n_edge += bool(min(abs(ssa(res.alpha[1] - lo)), abs(ssa(res.alpha[1] - hi))) < 1e-6 and res.f[1] > 1e4)
    assert n_saturated > 50                                    # the storm did saturate thrusters
    az = np.array([th.kind == "azimuth" for th in thrusters])
    assert np.all(turned[az] > 0.5 * math.pi)                  # the reversal turned the azimuths
    assert n_edge > 10 or not sector                           # A2 pushed along its sector's edge


def test_two_sided_polygon_is_used_only_where_it_is_the_whole_polygons_qp():
    """Steps of hw <= 2 pi / m solve the QP with the polygon's two sides at b_i; wider steps (and
    sector boxes) the whole polygon. Both give the reference's optimum with the capacity binding,
    and switching between them (a cold start each time) keeps the exact optimum."""
    rng = np.random.default_rng(2)
    al = ThrustAllocator.from_scenario(SECTOR)
    for dt, two_sides in [(0.1, True), (2.0, True), (2.5, False), (BIG_DT, False), (0.1, True), (3.0, False)]:
        for _ in range(3):
            tau = rng.uniform(-1, 1, 3) * np.array([9e6, 9e6, 6e8])    # beyond capacity: sides bind
            ref = reference(al, tau, dt)
            res = al.allocate(tau, dt)
            assert res.status == "solved"
            assert isinstance(al.solver, DaqpModels)
            assert (al._k_last == 0) == two_sides, (dt, al._k_last)   # the model this step used
            assert_agree(al, res, ref, exact=True)
            assert np.all(res.f <= al.f_max * (1 + 1e-12))


# --- failure, fallback, arguments ---------------------------------------------------------------

def test_daqp_failure_gives_the_reported_saturated_fallback_and_the_next_solve_recovers():
    al = ThrustAllocator.from_scenario(FPSO)
    tau = np.array([2e6, 1e6, 5e7])
    for _ in range(5):
        al.allocate(tau)
    for model in al.solver:
        model.settings = {"iter_limit": 1}                     # DAQP stops before its first iteration
    f_prev, a_prev = al.f_prev, al.alpha_prev
    for _ in range(10):
        res = al.allocate(tau)
        assert res.fallback and not res.success
        assert res.status == "fallback:max_iter_reached" and "DAQP" in res.message
        check_limits(FPSO.thrusters, res, f_prev=f_prev, alpha_prev=a_prev, dt=0.1)
        np.testing.assert_array_equal(res.alpha, a_prev)      # azimuths held
        np.testing.assert_allclose(res.tau + res.slack, tau, rtol=1e-12)
        f_prev, a_prev = res.f, res.alpha
    assert res.f.max() > 0                                     # it does push
    for model in al.solver:
        model.settings = {"iter_limit": 1000}
    res = al.allocate(tau)
    assert res.status == "solved" and not res.fallback         # cold start after the failures
    ref_al = ThrustAllocator.from_scenario(FPSO, solver="osqp")
    ref_al.reset(f_prev, a_prev)
    assert_agree(al, res, ref_al.allocate(tau), exact=False)


def test_daqp_settings_iteration_limit_gives_the_fallback_from_the_constructor():
    al = ThrustAllocator.from_scenario(FPSO, daqp_settings={"iter_limit": 1})
    res = al.allocate([2e6, 1e6, 5e7])
    assert res.status == "fallback:max_iter_reached" and res.fallback and np.all(np.isfinite(res.f))


def test_exit_flags_have_status_names():
    assert DAQP_STATUS[1] == "solved"
    assert DAQP_STATUS[-1] == "primal_infeasible"
    assert DAQP_STATUS[-4] == "max_iter_reached"               # the name OSQP uses for the same thing
    assert len(set(DAQP_STATUS.values())) == len(DAQP_STATUS)


def test_solver_choice_and_bad_solver_arguments():
    assert ThrustAllocator.from_scenario(FPSO).solver_name == "daqp"
    assert ThrustAllocator.from_scenario(FPSO, solver="osqp").solver_name == "osqp"
    assert ThrustAllocator.from_scenario(FPSO, osqp_settings={"max_iter": 50}).solver_name == "osqp"
    for kw, words in [(dict(solver="gurobi"), "solver='gurobi'"), (dict(solver=3), "solver=3"),
                      (dict(solver="DAQP "), "solver='DAQP '"),
                      (dict(daqp_settings={"iter_limt": 5}), "'iter_limt'"),
                      (dict(daqp_settings={"iter_limit": "many"}), "daqp_settings"),
                      (dict(solver="daqp", osqp_settings={"max_iter": 5}), "osqp_settings"),
                      (dict(solver="osqp", daqp_settings={"iter_limit": 5}), "daqp_settings")]:
        with pytest.raises(AllocationError) as e:
            ThrustAllocator.from_scenario(FPSO, **kw)
        assert words in str(e.value), str(e.value)


@pytest.mark.parametrize("solver", ["daqp", "osqp"])
def test_both_solvers_keep_failed_thrusters_at_zero_and_steer_idle_ones(solver):
    ths = mixed_thrusters()
    al = ThrustAllocator(ths, solver=solver)
    al.set_failed("A1")
    tau = np.array([-1.5e6, 3e5, 0.0])                         # astern: the azimuths must turn
    for _ in range(300):
        res = al.allocate(tau)
        assert res.f[0] == 0.0 and res.alpha[0] == 0.0
    assert np.all(np.abs(res.slack / scale(al)) < 1e-5), res.slack
    assert np.all(np.abs(ssa(res.alpha[1:4] - math.pi)) < 60 * DEG)   # the live azimuths turned aft
    al.set_failed("A1", False)
    assert al.allocate(tau).f[0] >= 0.0


@pytest.mark.parametrize("solver", ["daqp", "osqp"])
def test_thruster_order_does_not_change_the_commands(solver):
    """Tunnel/fixed thrusters between the azimuths (the kernels' column maps): the same commands,
    in the given order, as with the azimuths first."""
    ths = mixed_thrusters()                                   # A1 A2 F1 F2 T1 P1
    perm = [4, 0, 5, 2, 1, 3]                                 # T1 A1 P1 F1 A2 F2
    a, b = ThrustAllocator(ths, solver=solver), ThrustAllocator([ths[i] for i in perm], solver=solver)
    tol = 1e-9 if solver == "daqp" else 1e-4                  # OSQP's iterates follow the column order
    rng = np.random.default_rng(9)
    for k in range(120):
        tau = np.array([1.5e6 * math.sin(0.03 * k), 8e5, 4e7]) + rng.uniform(-1, 1, 3) * [3e5, 3e5, 2e7]
        ra, rb = a.allocate(tau), b.allocate(tau)
        assert ra.status == rb.status == "solved", (k, ra.status, rb.status)
        np.testing.assert_allclose(rb.f, ra.f[perm], rtol=0, atol=tol * a.F_ref)
        np.testing.assert_allclose(np.exp(1j * rb.alpha), np.exp(1j * ra.alpha[perm]), rtol=0, atol=10 * tol)
        np.testing.assert_allclose(rb.tau / scale(a), ra.tau / scale(a), rtol=0, atol=tol)


def test_result_is_a_plain_allocation_result():
    import dataclasses

    res = ThrustAllocator.from_scenario(FPSO).allocate([1e6, 2e5, 3e7])
    assert type(res) is AllocationResult
    assert set(vars(res)) == {f.name for f in dataclasses.fields(AllocationResult)}
    again = dataclasses.replace(res, message="x")
    assert again.message == "x" and again.status == res.status and again.f is res.f
    assert not res.f.flags.writeable and not res.slack.flags.writeable


def test_compiled_kernels_match_their_python_source():
    """The numba kernels against the same functions run by Python (the path without numba), on
    random states of thrusters with sectors, failures, tunnel/fixed thrusters and any dt."""
    from tapm_opt.control import allocation_step as ks

    if not hasattr(ks.step_kernel, "py_func"):
        pytest.skip("numba not available: the kernels are the Python functions")
    rng = np.random.default_rng(4)
    ths = list(SECTOR.thrusters[:4]) + mixed_thrusters()[4:]
    al = ThrustAllocator(ths, polygon_sides=8)
    for k in range(300):
        dt = float(rng.choice([0.05, 0.1, 1.0, 3.0, 20.0, BIG_DT]))
        al.reset(rng.uniform(0.0, 1.0, len(ths)) * al.f_max, rng.uniform(-math.pi, math.pi, len(ths)))
        if k % 7 == 0:
            al.set_failed(int(rng.integers(len(ths))), bool(rng.integers(2)))
        tau = rng.uniform(-1, 1, 3) * np.array([6e6, 6e6, 5e8])
        outs = []
        for fn in (ks.step_kernel, ks.step_kernel.py_func):
            S, G, A, bu, bl = al._S.copy(), al._G.copy(), al._A.copy(), al._bu.copy(), al._bl.copy()
            code = fn(dt, tau, al._C, al._Sec, S, al.polygon_sides, al._tau_scale, G, True, A, bu, bl)
            outs.append((code, S, G, A, bu, bl))
        assert outs[0][0] == outs[1][0]
        for u, v in zip(outs[0][1:], outs[1][1:]):
            np.testing.assert_allclose(u, v, rtol=1e-13, atol=1e-13)
        x = rng.uniform(-1, 1, al._nv + 3)
        y = rng.uniform(-1, 1, 3) * (1e-6 if k % 2 else 1.0)
        res = []
        for fn in (ks.finish_kernel, ks.finish_kernel.py_func):
            S, out = al._S.copy(), np.empty(al._nout)
            flag = fn(x, y, 0, tau, outs[0][2], al._C, S, al.F_ref, al.L_ref, 0.3, True, True, out)
            res.append((flag, S, out))
        assert res[0][0] == res[1][0] == 0
        np.testing.assert_allclose(res[0][2], res[1][2], rtol=1e-12, atol=1e-6)
        np.testing.assert_allclose(res[0][1], res[1][1], rtol=1e-12, atol=1e-12)
    for alpha in rng.uniform(-10, 10, 200):
        assert ks.arc(alpha, al._Sec[1], 1) == pytest.approx(ks.arc.py_func(alpha, al._Sec[1], 1), abs=1e-12)
