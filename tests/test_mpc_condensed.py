"""The MPC's QPs condensed for DAQP (module ``tapm_opt.control.mpc_condensed``): the linear MPC's
(``LinearMPC(qp_solver="daqp")``) checked against the sparse QP solved by piqp — the condensing is
exact (states, slacks and cost of the sparse QP at the sparse optimum), the condensed solution is
the sparse optimum when the chosen soft rows are those of the sparse optimum, never cheaper than it
(piqp's optimum is a lower bound of the sparse cost) and within a percent when the turret sits on a
polygon's corner; the failure path, thruster failures, the study option — and the real-time
iteration's Gauss-Newton QP (``NonlinearMPC(solver="rti", qp_solver="daqp")``) against CasADi's
one-iteration SQP and, in closed loop, the converged SQP.
"""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest

import tapm_opt
from tapm_opt.control.estimate import Estimate, Setpoint
from tapm_opt.control.mpc import LinearMPC, MPCError, MPCSettings
from tapm_opt.control.mpc_condensed import SCREEN_MARGIN
from tapm_opt.geometry import rot_z
from tapm_opt.models.system import ThrusterSet
from tapm_opt.studies.controllers import MPC_DEAD_BAND, MPC_DEFAULTS

BLOCKS_50 = (1, 1, 2, 4, 6, 8, 12, 16)
SP0 = Setpoint(np.zeros(3))


@pytest.fixture(scope="module")
def fpso():
    return tapm_opt.load_scenario("fpso")


@pytest.fixture(scope="module")
def equivalent():
    """fpso_equivalent: fpso on its former homogeneous equivalent lines, whose softer restoring
    leaves the MPC the saturating work the tests below were set up for."""
    return tapm_opt.load_scenario("fpso_equivalent")


def settings(sc, **kw) -> MPCSettings:
    """The study defaults (dead band 0.6 of the safe radius, MPC_DEFAULTS) with ``kw``."""
    return MPCSettings(**{**MPC_DEFAULTS, "dead_band": MPC_DEAD_BAND * sc.limits.safe_radius, **kw})


def drift(n: int, dt: float) -> list[Estimate]:
    """A slowly moving state: radius 28 -> 44 m at 0.1 m/s along 30 deg, heading drifting, a 0.5 MN load
    (it crosses the 30 m dead band)."""
    bearing, out = math.radians(30.0), []
    b_E = 0.5e6 * np.array([math.cos(bearing), math.sin(bearing), 0.0])
    for k in range(n):
        r, psi = 28.0 + 0.1 * k * dt, math.radians(2.0 + 0.05 * k)
        eta = np.array([r * math.cos(bearing), r * math.sin(bearing), psi])
        nu = rot_z(psi).T @ np.array([0.1 * math.cos(bearing), 0.1 * math.sin(bearing), 0.0])
        nu[2] = math.radians(0.05) / dt
        out.append(Estimate(k * dt, eta, nu, rot_z(psi).T @ b_E))
    return out


def outside(n: int, dt: float) -> list[Estimate]:
    """Beyond the 50 m safe circle, pushed out by 6 MN with a yaw moment: the safe circle, the dead
    band and the thrust polytope all in play."""
    bearing, out = math.radians(200.0), []
    b_E = np.array([6e6 * math.cos(bearing + 0.3), 6e6 * math.sin(bearing + 0.3), 1e6])
    for k in range(n):
        r = 54.0 + 0.3 * k * math.sin(k / 3)
        eta = np.array([r * math.cos(bearing), r * math.sin(bearing), math.radians(15.0) + 0.01 * k])
        nu = rot_z(eta[2]).T @ np.array([0.3 * math.cos(bearing), 0.3 * math.sin(bearing), 0.0])
        out.append(Estimate(k * dt, eta, nu, rot_z(eta[2]).T @ b_E))
    return out


def side_by_side(sc, s, states, passes=None):
    """Both QP paths on the same states, the DAQP one given piqp's previous plan before each step
    (so both solve the same QP); (first moves, costs) of each, and the DAQP controller."""
    a, b = LinearMPC(sc, s, qp_solver="piqp"), LinearMPC(sc, s, qp_solver="daqp")
    if passes is not None:
        b._daqp.passes = passes
    moves, costs = {"piqp": [], "daqp": []}, {"piqp": [], "daqp": []}
    for e in states:
        for name, c in (("piqp", a), ("daqp", b)):
            moves[name].append(c.update(e.t, e, SP0))
            d = c.last_step()
            assert d.success and not d.fallback, (name, d.status)
            costs[name].append(d.cost)
        b._u_prev, b._z = a._u_prev.copy(), a._z.copy()
    return {k: np.array(v) for k, v in moves.items()}, {k: np.array(v) for k, v in costs.items()}, b


def fail_daqp(monkeypatch, ctrl, flag: int) -> None:
    """Make the controller's DAQP model return exit flag ``flag`` (a failure) from now on."""
    monkeypatch.setattr(ctrl._daqp, "_model", SimpleNamespace(
        update=lambda **kw: None, solve=lambda: (np.zeros(ctrl._daqp.cq.nU), 0.0, flag, {"iterations": 3})))


@pytest.mark.parametrize("N, blocks", [(20, None), (50, BLOCKS_50)], ids=["N20", "N50-8moves"])
def test_condensed_qp_gives_the_sparse_optimum(fpso, N, blocks):
    """On a drift across the dead band (one face of it violated at a time) the condensed QP has
    the sparse QP's solution: first moves to 1e-6 of the single-DOF maxima, costs to 1e-7."""
    s = settings(fpso, horizon=N, move_blocks=blocks)
    moves, costs, _ = side_by_side(fpso, s, drift(24, s.dt))
    scale = ThrusterSet.from_scenario(fpso).max_tau()
    assert np.max(np.abs(moves["daqp"] - moves["piqp"]) / scale) < 1e-6
    assert np.allclose(costs["daqp"], costs["piqp"], rtol=1e-7, atol=0)
    assert np.max(np.abs(moves["piqp"]) / scale) > 0.05   # the moves are not trivially zero


def test_condensing_is_exact_at_the_sparse_optimum(fpso):
    """At piqp's solution z* of one step's sparse QP, the condensed plan of its moves has z*'s
    states (the dynamics eliminated exactly), z*'s slacks (each the largest violation of its rows)
    and z*'s cost."""
    s = settings(fpso, horizon=20)
    a = LinearMPC(fpso, s, qp_solver="piqp")
    b = LinearMPC(fpso, s, qp_solver="daqp")
    for e in outside(3, s.dt):
        a.update(e.t, e, SP0)
        b.update(e.t, e, SP0)
    z_star = a._z
    Hx, Ax, Gx, q, g_eq, g_in = a._data[:6]
    cq, prob = b._daqp.cq, a._prob
    cq.condense(Hx, Ax, Gx, q, a._b_eq, g_eq, g_in, prob.lbz, prob.ubz, u_pred=z_star[prob.idx["U"]])
    z = cq.expand(z_star[prob.idx["U"]])
    x_ref = np.abs(z_star[prob.idx["X"]]).max()
    assert np.max(np.abs(z[prob.idx["X"]] - z_star[prob.idx["X"]])) < 1e-9 * x_ref
    assert np.max(np.abs(z[cq.nXU:] - z_star[cq.nXU:])) < 1e-6
    assert np.max(z_star[prob.idx["S_safe"]]) > 0.05          # the safe circle is violated here
    assert cq.cost(Hx, q, z) == pytest.approx(cq.cost(Hx, q, z_star), rel=1e-7)
    # the condensed QP's own objective at the optimum's moves (soft rows at the chosen rows) is the
    # sparse one: the chosen rows are the largest of each group
    u = z_star[prob.idx["U"]]
    viol = np.maximum(cq.A @ u - cq.bu[cq.nU:], 0.0)[len(cq.hard_rows):]
    soft = np.sum(cq.w[cq.nU + len(cq.hard_rows):] * viol + viol ** 2 / (2 * cq.rho[cq.nU + len(cq.hard_rows):]))
    xu_cost = 0.5 * u @ cq.H @ u + cq.f @ u
    z0 = cq.expand(np.zeros(cq.nU))
    z0[cq.nXU:] = 0.0
    const = cq.cost(Hx, q, z0)
    assert xu_cost + const + soft == pytest.approx(cq.cost(Hx, q, z), rel=1e-7)


def test_corner_of_a_polygon_costs_a_fraction_of_a_percent(fpso):
    """Outside the safe circle and saturated, the turret's predicted path can sit on a corner of a
    polygon, where the sparse QP's slack is the larger of two faces and one soft row per group
    cannot say so: the condensed plan is never cheaper than the sparse optimum (a lower bound of
    the same cost) and within 1 % of it; choosing the rows again on the solution (up to
    DAQP_PASSES solves) does at least as well as one solve and recovers the optimum at most steps."""
    s = settings(fpso, horizon=20)
    states = outside(25, s.dt)
    _, costs, ctrl = side_by_side(fpso, s, states)
    _, costs1, _ = side_by_side(fpso, s, states, passes=1)
    gap, gap1 = costs["daqp"] / costs["piqp"] - 1, costs1["daqp"] / costs1["piqp"] - 1
    assert np.all(gap > -1e-7) and np.all(gap1 > -1e-7)
    assert np.max(gap) < 0.01
    assert np.all(gap <= gap1 + 1e-7)
    assert np.mean(gap < 1e-6) >= 0.8
    assert np.max(gap1) > np.max(gap)                 # the passes matter here
    assert ctrl._daqp.passes == 4


@pytest.mark.parametrize("margin", [SCREEN_MARGIN, 1e-12], ids=["default", "tiny-margin"])
def test_screened_hard_rows_give_the_full_qps_plan(fpso, margin):
    """Outside the safe circle, saturated (the thrust polytope and its rate rows bind): DAQP given
    only the hard rows near the predicted plan has the plan of DAQP given all 2560 of them, to
    1e-7 of the single-DOF maxima, with a small share of the rows. With a margin so tight that
    the rows that bind are left out, the check against every row adds them and solves again."""
    s = settings(fpso, horizon=20)
    full, scr = LinearMPC(fpso, s, qp_solver="daqp"), LinearMPC(fpso, s, qp_solver="daqp")
    full._daqp.screen = math.inf
    scr._daqp.screen = margin
    scale = ThrusterSet.from_scenario(fpso).max_tau()
    kept, added, moves = [], 0, []
    for e in outside(25, s.dt):
        a, b = full.update(e.t, e, SP0), scr.update(e.t, e, SP0)
        assert full.last_step().success and scr.last_step().success
        nh, n_in, n_add = scr._daqp.screen_stats
        kept.append(n_in / nh)
        added += n_add
        moves.append(a)
        assert np.max(np.abs(b - a) / scale) < 1e-7
        assert scr.last_step().cost == pytest.approx(full.last_step().cost, rel=1e-9, abs=1e-9)
        scr._u_prev, scr._z = full._u_prev.copy(), full._z.copy()   # the same QP at the next step
    assert nh == 2560
    ths = ThrusterSet.from_scenario(fpso)
    A, b_poly = ths.attainable_polytope(MPCSettings().polytope_directions)
    assert np.max(np.array(moves) @ A.T / b_poly) > 0.99          # the polytope binds
    assert np.median(kept) < 0.05
    if margin < 1e-9:
        assert added > 0                                          # the check had rows to add
    assert full._daqp.screen_stats[1] == 2560


def test_failed_daqp_solve_applies_shifted_previous_plan(fpso, monkeypatch):
    """DAQP stopping at its iteration limit is reported by name and the shifted plan applied; a
    condensing error is reported as an error and DAQP set up afresh at the next step."""
    s = settings(fpso, horizon=10)
    ctrl = LinearMPC(fpso, s, qp_solver="daqp")
    e = drift(3, s.dt)
    ctrl.update(e[0].t, e[0], SP0)
    plan = ctrl.plan_u.copy()
    real = ctrl._daqp._model
    fail_daqp(monkeypatch, ctrl, -4)
    tau = ctrl.update(e[1].t, e[1], SP0)
    d = ctrl.last_step()
    assert d.fallback and not d.success and d.status == "max_iter_reached"
    assert np.allclose(tau, plan[1], rtol=1e-12, atol=1e-6)
    ctrl._daqp._model = real
    data = ctrl._data

    def corrupt():
        ctrl._data = list(data)
        ctrl._data[1] = data[1].copy()
        ctrl._data[1][ctrl._daqp.cq._eq_diag[0]] = 2.0    # the dynamics' diagonal is not 1
        return ctrl._data
    monkeypatch.setattr(ctrl, "_qp_arrays", lambda p: corrupt())
    ctrl.update(e[2].t, e[2], SP0)
    d = ctrl.last_step()
    assert d.fallback and d.status.startswith("error: condensing") and ctrl._daqp._model is None


def test_condensing_refuses_a_changed_slack_cost(fpso):
    """The soft rows' weights are fixed at the first step: a slack whose cost changes later is an
    MPCError, not a silently different problem."""
    s = settings(fpso, horizon=5)
    ctrl = LinearMPC(fpso, s, qp_solver="daqp")
    e = drift(1, s.dt)[0]
    ctrl.update(e.t, e, SP0)
    Hx, Ax, Gx, q, g_eq, g_in = ctrl._data[:6]
    cq, prob = ctrl._daqp.cq, ctrl._prob
    H2 = Hx.copy()
    H2[cq._diag_pos[cq.groups[0]]] *= 2.0       # the first step's dead-band slack costs twice as much
    with pytest.raises(MPCError, match="weights changed"):
        cq.condense(H2, Ax, Gx, q, ctrl._b_eq, g_eq, g_in, prob.lbz, prob.ubz, u_pred=np.zeros(cq.nU))


@pytest.mark.parametrize("decision", ["tau", "thrusters"])
def test_failed_thrusters_in_the_condensed_qp(equivalent, decision):
    """Two azimuths fail while the thrust is saturated: both paths keep the thrust inside what the
    remaining thrusters can deliver and agree (with ``decision="thrusters"`` the failed thrusters'
    columns are held at zero). On fpso_equivalent: on fpso's stiffer chain-wire-chain lines the
    mooring does more of the work and the thrust reaches only 74 % of the reduced set's bound."""
    fpso = equivalent
    s = settings(fpso, horizon=8, decision=decision, w_position=50.0)
    failed = frozenset(t.id for t in fpso.thrusters[:2])
    out = {}
    for qp in ("piqp", "daqp"):
        ctrl = LinearMPC(fpso, s, qp_solver=qp)
        x = Estimate(0.0, np.array([35.0, -25.0, 0.1]), np.zeros(3), np.zeros(3))
        ctrl.update(0.0, x, SP0)
        ctrl.set_failed_thrusters(failed)
        taus = [ctrl.update(k * s.dt, Estimate(k * s.dt, x.eta, x.nu, x.tau_env), SP0) for k in range(1, 5)]
        assert all(d.success for d in ctrl.diagnostics), [d.status for d in ctrl.diagnostics]
        out[qp] = np.array(taus)
        if decision == "thrusters":
            f, _ = ctrl.thruster_forces(ctrl._u_prev)
            assert np.all(f[:2] < 1e-6 * ThrusterSet.from_scenario(fpso).f_max[:2])
    ths = ThrusterSet.from_scenario(fpso).without(failed)
    A, b = ths.attainable_polytope(MPCSettings().polytope_directions)
    scale = ths.max_tau()
    if decision == "tau":
        assert np.all(out["daqp"] @ A.T <= b * (1 + 1e-4) + 1e-6)
        assert np.max(out["daqp"][-1] @ A.T / b) > 0.99          # saturated on the reduced set
    assert np.max(np.abs(out["daqp"] - out["piqp"]) / scale) < 1e-4
    assert np.max(np.abs(out["daqp"][-1]) / scale) > 0.2         # a real move, not a zero one


def test_study_files_take_the_linear_mpc_qp_solver(fpso, tmp_path):
    """``qp_solver`` of an ``lmpc`` controller in a study file reaches the controller; a bad one,
    or DAQP for a nonlinear MPC that is not the real-time iteration, is an error saying so."""
    from tapm_opt.studies.study import load_study
    from tapm_opt.studies.controllers import build_controller

    assert build_controller(fpso, {"type": "lmpc", "horizon": 3, "qp_solver": "daqp"}).qp_solver == "daqp"
    base = ('[study]\nname = "q"\nscenario = "fpso"\nduration = 10.0\n[[sea_states]]\nid = "calm"\n'
            '[[controllers]]\nname = "L"\n')
    path = tmp_path / "ok.toml"
    path.write_text(base + 'type = "lmpc"\nqp_solver = "daqp"\nhorizon = 3\n')
    study = load_study(path)
    assert [c for c in study.cases if c.labels["controller"] == "L"][0].inputs["controller"]["qp_solver"] == "daqp"
    for body, message in (('type = "lmpc"\nqp_solver = "qrqp"\n', "qp_solver = 'qrqp'"),
                          ('type = "mpc"\nsolver = "sqp"\nqp_solver = "daqp"\n', "needs solver = 'rti'")):
        path.write_text(base + body)
        with pytest.raises(Exception, match=message.replace("[", r"\[").replace("]", r"\]")):
            load_study(path)


# --- the real-time iteration's Gauss-Newton QP, condensed -------------------------------------------

@pytest.mark.parametrize("blocks", [None, (1, 1, 2, 4, 12)], ids=["N20", "N20-5moves"])
def test_rti_with_daqp_is_the_sqp_methods_real_time_iteration(fpso, blocks):
    """``NonlinearMPC(solver="rti", qp_solver="daqp")`` takes the step of CasADi's one-iteration SQP
    (its Gauss-Newton QP solved by piqp) along the drift: first moves to 1e-5 of the single-DOF
    maxima, costs (the NLP's, at the new plan) to 1e-6; both within 5 % of the converged SQP."""
    from tapm_opt.control.mpc import NonlinearMPC

    s = settings(fpso, horizon=20, move_blocks=blocks, solver="rti")
    states = drift(20, s.dt)
    out = {}
    for qp in ("piqp", "daqp"):
        ctrl = NonlinearMPC(fpso, s, qp_solver=qp)
        u = np.array([ctrl.update(e.t, e, SP0) for e in states])
        d = ctrl.diagnostics
        assert all(x.success and not x.fallback and x.status == NonlinearMPC.RTI_STATUS for x in d)
        out[qp] = (u, np.array([x.cost for x in d]))
    sqp = NonlinearMPC(fpso, settings(fpso, horizon=20, move_blocks=blocks, solver="sqp"))
    u_sqp = np.array([sqp.update(e.t, e, SP0) for e in states])
    scale = ThrusterSet.from_scenario(fpso).max_tau()
    assert np.max(np.abs(out["daqp"][0] - out["piqp"][0]) / scale) < 1e-5
    assert np.allclose(out["daqp"][1], out["piqp"][1], rtol=1e-6)
    assert np.max(np.abs(out["daqp"][0] - u_sqp) / scale) < 0.05


def test_rti_with_daqp_settles_to_the_sqp_steady_thrust(fpso):
    """In closed loop on the design model (RK4, 5 substeps) under a steady load the RTI with DAQP
    settles where the converged SQP does: the same thrust after 200 s to 1e-4 of the maxima."""
    from tapm_opt.control.mpc import NonlinearMPC
    from tapm_opt.models.mooring import MooringModel
    from tapm_opt.models.vessel import VesselParams, moored_function

    vp = VesselParams.from_scenario(fpso)
    fn = moored_function(vp, MooringModel.from_scenario(fpso).force_function("characteristic").expand(), form="design")
    b_E = np.array([4e5, -2e5, 1e6])

    def loop(ctrl, steps=40, dt=5.0):
        x, taus = np.array([6.0, -4.0, math.radians(2.0), 0.0, 0.0, 0.0]), []
        for k in range(steps):
            tau = ctrl.update(k * dt, Estimate(k * dt, x[:3], x[3:], rot_z(x[2]).T @ b_E), SP0)
            taus.append(tau)
            h = dt / 5
            for _ in range(5):
                f = lambda xx: np.asarray(fn(xx, tau, rot_z(xx[2]).T @ b_E, np.zeros(2))).ravel()  # noqa: E731
                k1 = f(x)
                k2 = f(x + h / 2 * k1)
                k3 = f(x + h / 2 * k2)
                k4 = f(x + h * k3)
                x = x + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        assert all(d.success and not d.fallback for d in ctrl.diagnostics)
        return np.array(taus)

    s = settings(fpso, horizon=10, w_position_in=1.0, dead_band=0.0, w_position=0.0)
    tau_s = loop(NonlinearMPC(fpso, s))
    tau_r = loop(NonlinearMPC(fpso, MPCSettings(**{**s.__dict__, "solver": "rti"}), qp_solver="daqp"))
    scale = ThrusterSet.from_scenario(fpso).max_tau()
    assert np.max(np.abs(tau_s[-1] - tau_s[-2]) / scale) < 1e-3
    assert np.max(np.abs(tau_r[-1] - tau_s[-1]) / scale) < 1e-4


def test_rti_with_daqp_failure_falls_back_and_bad_options(fpso, monkeypatch):
    """A DAQP failure in an RTI step applies the shifted plan and names DAQP's status; qp_solver =
    "daqp" needs the real-time iteration with the Gauss-Newton Hessian; unknown QP solvers are
    refused, from Python and from a study's controller table."""
    from tapm_opt.control.mpc import NonlinearMPC
    from tapm_opt.studies.controllers import ControllerSpecError, build_controller

    s = settings(fpso, horizon=8, solver="rti")
    ctrl = NonlinearMPC(fpso, s, qp_solver="daqp")
    e = drift(2, s.dt)
    ctrl.update(e[0].t, e[0], SP0)
    plan = ctrl.plan_u.copy()
    fail_daqp(monkeypatch, ctrl, -1)
    tau = ctrl.update(e[1].t, e[1], SP0)
    d = ctrl.last_step()
    assert d.fallback and not d.success and d.status == "primal_infeasible"
    assert np.allclose(tau, plan[1], rtol=1e-12, atol=1e-6)
    with pytest.raises(MPCError, match="needs solver = 'rti'"):
        NonlinearMPC(fpso, settings(fpso, horizon=3, solver="sqp"), qp_solver="daqp")
    with pytest.raises(MPCError, match="hessian = 'exact'"):
        NonlinearMPC(fpso, settings(fpso, horizon=3, solver="rti", hessian="exact"), qp_solver="daqp")
    with pytest.raises(MPCError, match="qp_solver = 'osqp'"):
        NonlinearMPC(fpso, settings(fpso, horizon=3), qp_solver="osqp")
    rti = build_controller(fpso, {"type": "mpc", "horizon": 3, "solver": "rti", "qp_solver": "daqp"})
    assert rti.qp_solver == "daqp"
    with pytest.raises(ControllerSpecError, match="needs solver = 'rti'"):
        build_controller(fpso, {"type": "mpc", "horizon": 3, "solver": "sqp", "qp_solver": "daqp"})
    assert build_controller(fpso, {"type": "mpc", "horizon": 3, "qp_solver": "daqp"}).settings.solver == "rti"   # the default
