"""Move blocking of the MPC's thrust decision (``MPCSettings.move_blocks``) on the fpso scenario.

The blocked problem is a restriction of the full one: a blocked plan, written out step by step, is
a feasible plan of the full problem with the same cost, so the full optimum can only be lower; unit
blocks are the full problem; the plan is held over each block; the warm start shifts the plan by
one step; bad blocks are typed errors naming the field.
"""

from __future__ import annotations

import math

import casadi as ca
import numpy as np
import pytest

import tapm_opt
from tapm_opt.control.estimate import Estimate, Setpoint
from tapm_opt.control.mpc import LinearMPC, MPCError, MPCSettings, NonlinearMPC
from tapm_opt.geometry import rot_z
from tapm_opt.models.system import ThrusterSet

# 45 m off in a 3 MN storm load: the thrust polytope, its rate rows and the safe circle are in play
X_STORM = np.array([44.0, -10.0, math.radians(5.0), 0.1, 0.02, 0.0])
B_STORM = np.array([-3.0e6, -1.0e6, -2.0e7])
SP = Setpoint([0.0, 0.0, 0.1])
BASE = dict(dead_band=40.0, w_thrust=10.0, w_rate=5.0, horizon=30)
BLOCKS = (1, 1, 2, 4, 8, 14)


@pytest.fixture(scope="module")
def fpso():
    return tapm_opt.load_scenario("fpso")


def storm_estimate(t: float = 0.0) -> Estimate:
    return Estimate(t, X_STORM[:3], X_STORM[3:], rot_z(X_STORM[2]).T @ B_STORM)


def expand(ctrl_b, prob_full) -> np.ndarray:
    """The blocked controller's last plan in the full problem's layout (its move at every step)."""
    pb, z = ctrl_b._prob, ctrl_b._z
    out = np.zeros(prob_full.z.numel())
    U = z[pb.idx["U"]].reshape(pb.n_moves, pb.n_u)[pb.block_of]
    out[prob_full.idx["U"]] = U.ravel()
    for key in ("X", "S_db", "S_safe", "S_T", "S_R"):
        out[prob_full.idx[key]] = z[pb.idx[key]]
    return out


@pytest.mark.parametrize("cls", [LinearMPC, NonlinearMPC], ids=["linear", "nonlinear"])
def test_blocked_plan_is_feasible_for_the_full_problem_at_its_cost(fpso, cls):
    """One cold solve in the storm with and without blocking (the same parameters): the blocked
    plan written out step by step meets every row of the full problem (the rate rows inside a
    block see no change, the polytope rows hold for each block) with the same cost, the full
    optimum is no higher, and the plan is constant over each block."""
    blocked = cls(fpso, MPCSettings(**BASE, move_blocks=BLOCKS))
    full = cls(fpso, MPCSettings(**BASE))
    blocked.update(0.0, storm_estimate(), SP)
    full.update(0.0, storm_estimate(), SP)
    for c in (blocked, full):
        assert c.diagnostics[-1].success, c.diagnostics[-1].status
    assert blocked._prob.n_moves == len(BLOCKS)
    p = blocked._last_p
    np.testing.assert_array_equal(p, full._last_p)     # the same parameters (operating point included)
    pf = full._prob
    fg = ca.Function("fg", [pf.z, pf.p], [pf.f, pf.g])
    z = expand(blocked, pf)
    f, g = (np.asarray(v, float).ravel() for v in fg(z, p))
    tol = 1e-5 * (1.0 + np.abs(g))
    assert np.all(g >= pf.lbg - tol) and np.all(g <= pf.ubg + tol)
    assert np.all(z[pf.idx["U"]] >= pf.lbz[pf.idx["U"]] - 1e-7)
    assert np.all(z[pf.idx["U"]] <= pf.ubz[pf.idx["U"]] + 1e-7)
    c_b, c_f = blocked.diagnostics[-1].cost, full.diagnostics[-1].cost
    assert f[0] == pytest.approx(c_b, rel=1e-5, abs=1e-6)
    assert c_f <= c_b * (1 + 1e-5) + 1e-6
    assert c_f < c_b   # holding the thrust over 14 steps of a storm costs something
    plan = blocked.plan_u
    assert plan.shape == (BASE["horizon"], 3)
    starts = np.cumsum((0,) + BLOCKS[:-1])
    for s0, n in zip(starts, BLOCKS):
        np.testing.assert_array_equal(plan[s0:s0 + n], np.broadcast_to(plan[s0], (n, 3)))
    assert np.max(np.abs(plan) / ThrusterSet.from_scenario(fpso).max_tau()) > 0.05   # the plan pushes


def test_unit_blocks_are_the_full_problem(fpso):
    """move_blocks = (1,) * N writes the full problem: the same moves over three warm-started
    steps and the same costs."""
    a = LinearMPC(fpso, MPCSettings(**BASE, move_blocks=(1,) * BASE["horizon"]))
    b = LinearMPC(fpso, MPCSettings(**BASE))
    for k in range(3):
        ua = a.update(5.0 * k, storm_estimate(5.0 * k), SP)
        ub = b.update(5.0 * k, storm_estimate(5.0 * k), SP)
        np.testing.assert_allclose(ua, ub, rtol=1e-9, atol=1e-6)
        assert a.diagnostics[-1].cost == pytest.approx(b.diagnostics[-1].cost, rel=1e-9)


def test_shift_moves_a_blocked_plan_one_step(fpso):
    """The warm start of a blocked plan: every block takes the thrust the plan had one step after
    the block's start (blocks 1, 1, 2, 4, 8, 14 start at 0, 1, 2, 4, 8, 16), the last repeated;
    states and slacks move by one step."""
    ctrl = LinearMPC(fpso, MPCSettings(**BASE, move_blocks=BLOCKS))
    prob = ctrl._prob
    z = np.arange(prob.z.numel(), dtype=float)
    out = ctrl._shift(z)
    U = z[prob.idx["U"]].reshape(prob.n_moves, 3)
    per_step = U[prob.block_of]
    expect = per_step[np.minimum(np.array([0, 1, 2, 4, 8, 16]) + 1, BASE["horizon"] - 1)]
    np.testing.assert_array_equal(out[prob.idx["U"]].reshape(-1, 3), expect)
    X = z[prob.idx["X"]].reshape(-1, 6)
    np.testing.assert_array_equal(out[prob.idx["X"]].reshape(-1, 6), np.vstack([X[1:], X[-1:]]))
    S = z[prob.idx["S_T"]]
    np.testing.assert_array_equal(out[prob.idx["S_T"]], np.r_[S[1:], S[-1]])


def test_blocked_closed_loop_keeps_the_rate_and_the_polytope(fpso):
    """Ten warm-started steps from 45 m off with the thrusters' rate limit in play: every applied
    move is inside the attainable polytope and changes by at most the polytope scaled by the
    rate ratio x dt, and no solve fails."""
    s = MPCSettings(**BASE, move_blocks=BLOCKS)
    ctrl = LinearMPC(fpso, s)
    ths = ThrusterSet.from_scenario(fpso)
    A, b = ths.attainable_polytope(s.polytope_directions)
    prev = np.zeros(3)
    for k in range(10):
        tau = ctrl.update(5.0 * k, storm_estimate(5.0 * k), SP)
        assert np.all(A @ tau <= b * (1 + 1e-4) + 1e-6)
        assert np.all(A @ (tau - prev) <= ths.rate_ratio() * s.dt * b * (1 + 1e-4) + 1e-6)
        prev = tau
    assert all(d.success for d in ctrl.diagnostics)


@pytest.mark.parametrize("blocks,match", [
    ((1, 2), "sums to 3, not to horizon = 20"),
    ((0, 20), "whole numbers >= 1"),
    ((1.5, 18.5), "whole numbers >= 1"),
    ((True, 19), "whole numbers >= 1"),
    ((), "whole numbers >= 1"),
    ("1,19", "whole numbers >= 1"),
    (20, "whole numbers >= 1"),
])
def test_bad_move_blocks_raise_naming_the_field(blocks, match):
    with pytest.raises(MPCError, match=r"MPCSettings\.move_blocks = .*" + match):
        MPCSettings(move_blocks=blocks)


def test_move_blocks_are_whole_numbers_of_steps():
    """A list (a TOML array) becomes a tuple; whole numbers written as floats (a command line's
    2.0) are accepted as such."""
    assert MPCSettings(move_blocks=[1.0, 19.0]).move_blocks == (1, 19)
    # numpy numbers (a list built with numpy) and a 1-D array are whole numbers too
    assert MPCSettings(move_blocks=[np.int64(1), np.float64(19.0)]).move_blocks == (1, 19)
    assert MPCSettings(move_blocks=np.array([1, 1, 18])).move_blocks == (1, 1, 18)
    assert all(type(b) is int for b in MPCSettings(move_blocks=np.array([1, 19])).move_blocks)
    with pytest.raises(MPCError, match="whole numbers >= 1"):
        MPCSettings(move_blocks=[np.bool_(True), 19])
    assert MPCSettings(horizon=6, move_blocks=[1, 2, 3]).move_blocks == (1, 2, 3)
    assert MPCSettings().move_blocks is None


def test_move_blocks_from_a_study_spec(fpso):
    """A study's controller table gives move_blocks as a TOML array; it reaches the problem, and a
    bad one is the study's typed error naming it."""
    from tapm_opt.studies.controllers import ControllerSpecError, build_controller

    ctrl = build_controller(fpso, {"type": "lmpc", "horizon": 10, "move_blocks": [2, 3, 5]})
    assert ctrl.settings.move_blocks == (2, 3, 5) and ctrl._prob.n_moves == 3
    with pytest.raises(ControllerSpecError, match=r"controller: MPCSettings\.move_blocks = \[2, 3\] sums to 5"):
        build_controller(fpso, {"type": "lmpc", "horizon": 10, "move_blocks": [2, 3]})
