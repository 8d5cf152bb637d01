"""The closed loop's fast paths give the numbers of the computations they replace, exactly: the
condensed QP's reused hard rows and per-group maxima, the MPC's shift as an index map and its
buffered cost, the PID's written-out error and clip, the reliability state built without copies,
the result rows filled in place and the runner's vector norm."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest

import tapm_opt
from tapm_opt.control import mpc_condensed as mc
from tapm_opt.control.estimate import Estimate, Setpoint
from tapm_opt.control.mpc import LinearMPC, MPCSettings, NonlinearMPC
from tapm_opt.control.pid import TAPMPID, PIDGains
from tapm_opt.estimation.reliability import ReliabilityMonitor, ReliabilityState
from tapm_opt.geometry import rot_z, ssa, turret_offset
from tapm_opt.results import ResultBuilder
from tapm_opt.studies.closed_loop import _norm
from tapm_opt.studies.controllers import MPC_DEAD_BAND, MPC_DEFAULTS


@pytest.fixture(scope="module")
def fpso():
    return tapm_opt.load_scenario("fpso")


def _largest_reference(cq, z):
    """``CondensedQP._largest`` as numpy writes it (the first largest row of each group)."""
    v = cq._excess(cq._order, z)
    at_max = np.flatnonzero(v >= np.repeat(np.maximum.reduceat(v, cq._starts), cq._counts))
    group = np.searchsorted(cq._starts, at_max, side="right") - 1
    return cq._order[at_max[np.unique(group, return_index=True)[1]]]


def test_first_max_per_group_is_numpys_first_largest():
    rng = np.random.default_rng(3)
    for _ in range(200):
        counts = rng.integers(1, 6, size=rng.integers(1, 8))
        starts = np.r_[0, np.cumsum(counts)[:-1]].astype(np.int64)
        v = rng.integers(-3, 3, size=int(counts.sum())).astype(float)   # ties on purpose
        v[rng.random(v.size) < 0.1] = -np.inf
        out = np.zeros(len(counts), np.int64)
        assert mc._first_max_per_group(v, starts, counts.astype(np.int64), out)
        at_max = np.flatnonzero(v >= np.repeat(np.maximum.reduceat(v, starts), counts))
        group = np.searchsorted(starts, at_max, side="right") - 1
        np.testing.assert_array_equal(out, at_max[np.unique(group, return_index=True)[1]])
    v = np.array([1.0, np.nan, 0.0])
    assert not mc._first_max_per_group(v, np.array([0, 2]), np.array([2, 1]), np.zeros(2, np.int64))


def _drive(ctrl, n, seed=0):
    """``n`` updates of ``ctrl`` on a slowly drifting state pushed out by a load."""
    rng = np.random.default_rng(seed)
    out = []
    for k in range(n):
        psi = 0.1 + 0.01 * k
        eta = np.array([20.0 + 1.5 * k, -10.0 + 0.7 * k, psi])
        nu = np.array([0.1, 0.05, 1e-3]) + 0.01 * rng.standard_normal(3)
        tau_env = rot_z(psi).T @ np.array([3e6, 1.5e6, 2e6])
        out.append(ctrl.update(5.0 * k, Estimate(5.0 * k, eta, nu, tau_env), Setpoint(np.zeros(3))))
    return out


@pytest.mark.parametrize("kind", ["lmpc", "rti"])
def test_condensed_qp_with_reused_hard_rows_equals_a_fresh_condensing(fpso, kind):
    s = MPCSettings(**{**MPC_DEFAULTS, "dead_band": MPC_DEAD_BAND * fpso.limits.safe_radius, "horizon": 20,
                       "move_blocks": (1, 1, 2, 4, 4, 8), **({"solver": "rti"} if kind == "rti" else {})})
    ctrl = LinearMPC(fpso, s, qp_solver="daqp") if kind == "lmpc" else NonlinearMPC(fpso, s, qp_solver="daqp")
    cq = ctrl._daqp.cq
    seen = []
    real = cq.condense

    def condense(*args, **kw):   # every step condensed afresh too, by a copy without the reuse
        real(*args, **kw)
        ref = mc.CondensedQP.__new__(mc.CondensedQP)
        ref.__dict__.update({k: (v.copy() if isinstance(v, np.ndarray) else v) for k, v in cq.__dict__.items()})
        ref._hard_vals = None
        ref._AT[:] = np.nan
        ref.A[:] = np.nan
        mc.CondensedQP.condense(ref, *args, **kw)
        seen.append(cq._rows_of_last_step())
        for name in ("H", "f", "A", "bu", "bl", "sense", "chosen"):
            np.testing.assert_array_equal(getattr(cq, name), getattr(ref, name), err_msg=name)
        rows = cq._largest(cq._z_of(kw["u_pred"]))
        np.testing.assert_array_equal(rows, _largest_reference(cq, cq._z_of(kw["u_pred"])))

    cq.condense = condense
    _drive(ctrl, 6)
    assert cq._hard_in_moves and any(seen[1:])   # the reuse did happen


def test_shift_map_and_buffered_cost(fpso):
    s = MPCSettings(**{**MPC_DEFAULTS, "dead_band": MPC_DEAD_BAND * fpso.limits.safe_radius, "horizon": 20,
                       "move_blocks": (1, 1, 2, 4, 4, 8), "solver": "rti"})
    ctrl = NonlinearMPC(fpso, s, qp_solver="daqp")
    _drive(ctrl, 2)
    rng = np.random.default_rng(1)
    z = rng.standard_normal(ctrl._prob.z.numel())
    np.testing.assert_array_equal(ctrl._shift(z), ctrl._shift_reference(z))
    np.testing.assert_array_equal(ctrl._shift(ctrl._z), ctrl._shift_reference(ctrl._z))
    p = ctrl._last_p
    assert ctrl._cost_at(z, p) == float(ctrl._f_fun(z, p))


def _pid_reference(ctrl, t, est, sp):
    """One update of TAPMPID written as before its components were written out (geometry's
    turret_offset, ssa and rot_z, np.clip): tau and the integral after it."""
    eta, nu, eta_d, nu_d = (np.array(v, float) for v in (est.eta, est.nu, sp.eta_d, sp.nu_d))
    e = np.empty(3)
    e[:2] = np.asarray(turret_offset(eta, ctrl._p_ref)) - eta_d[:2]
    e[2] = ssa(eta[2] - eta_d[2])
    nu = nu + np.array([-nu[2] * ctrl._p_ref[1], nu[2] * ctrl._p_ref[0], 0.0])
    Rt = rot_z(eta[2]).T
    e_b = Rt @ e
    xi = ctrl._xi
    if ctrl._t_prev is not None and t > ctrl._t_prev:
        step_b = np.where(ctrl._mask, e_b * (t - ctrl._t_prev), 0.0)
        push = -np.diag(ctrl._Ki) * step_b * ctrl._tau_unsat
        step_b = np.where(ctrl._sat & (push > 0.0), 0.0, step_b)
        xi = xi + Rt.T @ step_b
        q = ctrl._Ki @ (Rt @ xi)
        q_c = np.clip(q, -ctrl._integral_limit, ctrl._integral_limit)
        if np.any(q_c != q):
            xi = xi + Rt.T @ (ctrl._Ki_pinv @ (q_c - q))
    tau = -(ctrl._Ki @ (Rt @ xi)) - ctrl._Kp @ e_b - ctrl._Kd @ (nu - nu_d)
    return np.clip(tau, -ctrl._tau_limit, ctrl._tau_limit), xi


def test_pid_update_equals_the_reference_law():
    g = PIDGains(Kp=[2e5, 2e5, 5e7], Ki=[2e3, 2e3, 4e5], Kd=[4e6, 4e6, 8e8])
    ctrl = TAPMPID(g, tau_limit=[3e6, 2e6, 5e7], integral_limit=[1e6, 1e6, 2e7], reference_point=(90.0, 3.0))
    rng = np.random.default_rng(7)
    for k in range(60):
        t = float(k)
        est = Estimate(t, rng.normal(0, 20, 3) * [1, 1, 0.05], rng.normal(0, 0.3, 3) * [1, 1, 0.01], np.zeros(3))
        sp = Setpoint(rng.normal(0, 5, 3) * [1, 1, 0.1])
        ref_tau, ref_xi = _pid_reference(ctrl, t, est, sp)
        tau = ctrl.update(t, est, sp)
        np.testing.assert_array_equal(tau, ref_tau)
        np.testing.assert_array_equal(ctrl._xi, ref_xi)
    with pytest.raises(ValueError, match="estimate.eta"):
        ctrl.update(61.0, Estimate(61.0, [0.0, np.inf, 0.0], np.zeros(3), np.zeros(3)), sp)
    # lists (a setpoint layer of its own) take the checked path, to the same numbers
    a = TAPMPID(g, tau_limit=[3e6, 2e6, 5e7])
    b = TAPMPID(g, tau_limit=[3e6, 2e6, 5e7])
    est = Estimate(0.0, [10.0, -4.0, 0.2], [0.1, 0.0, 0.001], np.zeros(3))
    np.testing.assert_array_equal(a.update(0.0, est, Setpoint([1.0, 2.0, 0.1])),
                                  b.update(0.0, est, SimpleNamespace(eta_d=[1.0, 2.0, 0.1], nu_d=[0, 0, 0])))
    with pytest.raises(ValueError, match="setpoint.eta_d"):
        b.update(1.0, est, SimpleNamespace(eta_d=[1.0, 2.0], nu_d=[0, 0, 0]))


def test_reliability_state_without_copies_equals_the_constructor():
    rng = np.random.default_rng(2)
    mon = ReliabilityMonitor([10.0, 12.0, 9.0], [1.0, 1.5, 0.8], lp_window=10.0, sigma_window=30.0)
    for k in range(80):
        x = 5.0 + np.sin(0.9 * k + np.arange(3)) + 0.1 * rng.standard_normal(3)
        st = mon.update(0.5 * k, x)
        ref = ReliabilityState(t=st.t, names=st.names, x_lf=st.x_lf, sigma=st.sigma, n=st.n, k=st.k,
                               delta=st.delta, span=st.span, ready=st.ready)
        for f in ("x_lf", "sigma", "n", "k", "delta"):
            v = getattr(st, f)
            np.testing.assert_array_equal(v, getattr(ref, f))
            assert v.dtype == np.float64 and not v.flags.writeable
        assert (st.t, st.names, st.span, st.ready) == (ref.t, ref.names, ref.span, ref.ready)
    with pytest.raises(ValueError, match="not finite"):
        mon.update(100.0, [1.0, np.nan, 1.0])
    big = np.array([1e308, 1e308, 1.0])   # a sum that overflows: still finite entries
    with np.errstate(over="ignore"):
        _, x = mon._check(101.0, big)
    np.testing.assert_array_equal(x, big)


def test_result_rows_filled_in_place_equal_appended_rows():
    a, b = ResultBuilder([("x", "m"), ("y", "m")], capacity=2), ResultBuilder([("x", "m"), ("y", "m")], capacity=2)
    for k in range(5):   # past the capacity: the storage grows
        a.append(float(k), np.array([k, -k], float))
        row = b.next_row(float(k))
        row[0], row[1] = k, -k
    ra, rb = a.build(), b.build()
    np.testing.assert_array_equal(ra.time, rb.time)
    np.testing.assert_array_equal(ra.data, rb.data)


def test_norm_is_numpys():
    rng = np.random.default_rng(5)
    for _ in range(500):
        v = rng.standard_normal(rng.integers(1, 7)) * 10.0 ** rng.integers(-5, 9)
        assert _norm(v) == float(np.linalg.norm(v))
    assert _norm([3, 4]) == 5.0
    assert math.isnan(_norm(np.array([np.nan, 1.0])))


def test_setpoint_layers_equal_their_reference():
    from tapm_opt.control.setpoint import FixedSetpoint, HeadingChasing

    fixed = FixedSetpoint((1.0, 2.0, 0.3))
    a = fixed.update(0.0, None)
    assert fixed.update(1.0, None) is a and not a.eta_d.flags.writeable
    fixed.eta_d[0] = 5.0   # the layer's own array changed: a new setpoint
    np.testing.assert_array_equal(fixed.update(2.0, None).eta_d, [5.0, 2.0, 0.3])
    layer = HeadingChasing(FixedSetpoint(), 100.0, 0.2)
    psi = 0.2
    rng = np.random.default_rng(4)
    for k in range(30):
        est = Estimate(float(k), rng.normal(0, 1, 3), np.zeros(3), rng.normal(0, 1e6, 3))
        b_E = rot_z(est.eta[2]) @ est.tau_env
        if k:
            psi = psi + (1 - math.exp(-1.0 / 100.0)) * float(ssa(math.atan2(-b_E[1], -b_E[0]) - psi))
        assert layer.update(float(k), est).eta_d[2] == psi
