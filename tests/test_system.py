"""The system built once (models.system), the turret ruler, the one thrust-capacity model, the
control-loop protocols (tapm_opt.interfaces) with a third-party controller, and the import
architecture."""

from __future__ import annotations

import ast
import math
import pathlib
from dataclasses import replace

import numpy as np
import pytest

import tapm_opt
from tapm_opt.config import schema
from tapm_opt.control.mpc import MPCSettings, build_problem
from tapm_opt.control.pid import PIDGains, TAPMPID
from tapm_opt.errors import ModelError
from tapm_opt.geometry import body_from_turret, turret_offset
from tapm_opt.interfaces import (Controller, ControllerStep, Estimate, Setpoint, ThrusterCommand,
                                 ThrusterController)
from tapm_opt.models.system import CAPACITY_FRACTION, System, ThrusterSet
from tapm_opt.plant.simulator import Plant
from tapm_opt.results import ResultBuilder
from tapm_opt.studies.closed_loop import ClosedLoopError, ClosedLoopSettings, run_closed_loop
from tapm_opt.studies.controllers import build_controller
from tapm_opt.studies.kpis import basic_kpis

FPSO = tapm_opt.load_scenario("fpso")
PKG = pathlib.Path(tapm_opt.__file__).parent


# -- the turret ruler ---------------------------------------------------------------------------

def _weathervane(psi_deg):
    c = FPSO.turret.position
    psi = np.radians(psi_deg)
    x, y = body_from_turret((np.zeros_like(psi), np.zeros_like(psi)), psi, c)
    return np.stack([x, y, psi], axis=-1)


def test_pure_weathervane_about_the_turret_has_zero_offset():
    """The hull turns 0 -> 20 deg about the turret (no mooring load): the body origin moves ~32 m,
    the offset KPIs (turret-referenced) stay 0 and the vessel never leaves the safe circle."""
    eta = _weathervane(np.linspace(0.0, 20.0, 41))
    assert np.hypot(eta[-1, 0], eta[-1, 1]) > 30.0  # the body origin does move
    np.testing.assert_allclose(np.hypot(*turret_offset(eta, FPSO.turret.position)), 0.0, atol=1e-9)
    n_l = len(FPSO.lines)
    T0 = 0.19 * FPSO.line_arrays["MBS"]
    chans = [("x", "m"), ("y", "m"), ("psi", "rad"), ("psi_d", "rad")] + \
        [(f"T_fairlead[{ln.id}]", "N") for ln in FPSO.lines] + [(f"P[{t.id}]", "W") for t in FPSO.thrusters]
    rb = ResultBuilder(chans, capacity=len(eta))
    for k, e in enumerate(eta):
        rb.append(float(k), np.concatenate([e, [e[2]], T0, np.zeros(len(FPSO.thrusters))]))
    assert n_l == len(T0)
    k = basic_kpis(rb.build({}), FPSO)
    assert k["offset_max"] == pytest.approx(0.0, abs=1e-9)
    assert k["time_outside_safe"] == 0.0


def test_turret_offset_is_the_body_offset_plus_the_lever():
    eta = np.array([10.0, -4.0, math.radians(90.0)])
    c = np.array([91.44, 0.0])
    # heading east: the turret is 91.44 m east of the body origin, at rest it was 91.44 m north
    np.testing.assert_allclose(turret_offset(eta, c), (10.0 - 91.44, -4.0 + 91.44), atol=1e-9)
    np.testing.assert_allclose(body_from_turret(turret_offset(eta, c), eta[2], c), eta[:2], atol=1e-9)


def test_pid_sees_no_position_error_when_the_hull_turns_about_the_turret():
    gains = PIDGains(Kp=np.diag([1e5, 1e5, 1e8]), Ki=np.zeros((3, 3)), Kd=np.diag([1e6, 1e6, 1e9]))
    pid = TAPMPID(gains, modes=("restoring", "heading"), reference_point=FPSO.turret.position)
    eta = _weathervane(np.array([15.0]))[0]
    tau = pid.update(0.0, Estimate(0.0, eta, np.zeros(3), np.zeros(3)), Setpoint([0.0, 0.0, eta[2]]))
    np.testing.assert_allclose(tau, 0.0, atol=1e-6)
    # the same pose, referenced at the body origin, is a 24 m position error
    pid0 = TAPMPID(gains, modes=("restoring", "heading"))
    tau0 = pid0.update(0.0, Estimate(0.0, eta, np.zeros(3), np.zeros(3)), Setpoint([0.0, 0.0, eta[2]]))
    assert np.hypot(tau0[0], tau0[1]) > 1e5 * 20.0


# -- one thrust capacity --------------------------------------------------------------------------

def _azimuth(tid, x, y, fmax=1e6, sectors=()):
    return schema.Thruster(id=tid, kind="azimuth", position=(x, y), max_thrust=fmax, max_thrust_rate=1e5,
                           time_constant=5.0, forbidden_sectors=tuple(sectors))


def test_capacity_of_two_azimuths_is_the_closed_form():
    """Two 1 MN azimuths at (+-50, 0): X and Y alone 2 MN, N alone 2 * 50 m * 1 MN (the LP on the
    inscribed 128-gon is within cos(pi/128) of it, never above)."""
    ths = ThrusterSet(specs=(_azimuth("a", 50.0, 0.0), _azimuth("b", -50.0, 0.0)))
    exact = np.array([2e6, 2e6, 1e8])
    cap = ths.max_tau()
    assert np.all(cap <= exact * (1 + 1e-9)) and np.all(cap >= exact * math.cos(math.pi / 128) * (1 - 1e-9))
    np.testing.assert_allclose(ths.capacity_box(), CAPACITY_FRACTION * cap)
    one = ths.without(["b"]).max_tau()
    # one azimuth at (50, 0): Y alone needs N = 50 f_y = 0, so no pure sway is left
    assert one[0] == pytest.approx(1e6, rel=1e-3) and one[1] == pytest.approx(0.0, abs=1e-3)


def test_forbidden_sector_cuts_the_capacity_at_its_chord():
    """An azimuth at the origin that may not point within +-45 deg of ahead: +X only through the
    chord of the wedge (F cos 45 deg), -X the full F; the capacity is the smaller sign."""
    th = _azimuth("a", 0.0, 0.0, sectors=[(math.radians(-45.0), math.radians(45.0))])
    cap = ThrusterSet(specs=(th,)).max_tau()
    assert cap[0] == pytest.approx(1e6 * math.cos(math.radians(45.0)), rel=1e-3)
    assert cap[1] == pytest.approx(1e6, rel=1e-3)


def test_forbidden_sector_wider_than_half_a_turn_leaves_a_convex_wedge():
    """Two azimuths at the origin, one allowed only within +-60 deg of ahead (forbidden 60 -> 300
    deg), one only within +-60 deg of astern: X alone F each way; Y alone 2 F sin 60 deg (both
    at 60 / 120 deg, their x parts cancel). A direction in the forbidden side is not attainable."""
    fwd = _azimuth("f", 0.0, 0.0, sectors=[(math.radians(60.0), math.radians(300.0))])
    aft = _azimuth("a", 0.0, 0.0, sectors=[(math.radians(240.0), math.radians(120.0))])
    cap = ThrusterSet(specs=(fwd, aft)).max_tau()
    assert cap[0] == pytest.approx(1e6, rel=1e-3)
    assert cap[1] == pytest.approx(2e6 * math.sin(math.radians(60.0)), rel=1e-3)
    A, b = ThrusterSet(specs=(fwd,))._hull_rows()
    for deg, ok in ((0.0, True), (30.0, True), (-30.0, True), (90.0, False), (180.0, False)):
        u = 0.9e6 * np.array([math.cos(math.radians(deg)), math.sin(math.radians(deg))])
        assert bool(np.all(A @ u <= b + 1e-6)) == ok, deg


def test_failed_thruster_id_is_checked():
    with pytest.raises(ModelError, match="nope"):
        ThrusterSet.from_scenario(FPSO).without(["nope"])


def test_one_capacity_serves_pid_saturation_mpc_box_and_lqr_weights():
    system = System.from_scenario(FPSO)
    box = np.asarray(system.thrusters.capacity_box())
    pid = build_controller(system, {"type": "pid"})
    np.testing.assert_allclose(pid.tau_limit, box, rtol=1e-12)
    np.testing.assert_allclose(build_problem(system, MPCSettings(thrust_set="box")).scale["u"], box, rtol=1e-12)
    # the default polytope is drawn from the same ThrusterSet: its box is the single-DOF maxima
    np.testing.assert_allclose(build_problem(system, MPCSettings()).scale["u"], system.thrusters.max_tau(), rtol=1e-12)
    from tapm_opt.design.gains import DEFAULT_LQR, gain_table

    weights = replace(DEFAULT_LQR["extreme"], tau_share=CAPACITY_FRACTION)
    table = gain_table(FPSO, sea_states=["storm"], broken=[], headings=[0.0], lqr_weights=weights)
    row = list(table)[0]
    np.testing.assert_allclose(row.lqr.R, 1.0 / box ** 2, rtol=1e-12)  # R = diag(1 / tau_ref^2)


# -- the protocols and a third-party controller ---------------------------------------------------

class SpringDamper:
    """A controller written against the protocols only: a stiff spring on the turret offset and a
    damper, in {B}."""

    period = 2.0

    def __init__(self, k=2e5, d=5e6):
        self.k, self.d, self.calls, self._last = k, d, 0, None

    def update(self, t, estimate, setpoint):
        self.calls += 1
        ex, ey = np.asarray(turret_offset(estimate.eta, FPSO.turret.position)) - setpoint.eta_d[:2]
        c, s = math.cos(estimate.eta[2]), math.sin(estimate.eta[2])
        tau = np.array([-self.k * (c * ex + s * ey) - self.d * estimate.nu[0],
                        -self.k * (-s * ex + c * ey) - self.d * estimate.nu[1], 0.0])
        self._last = ControllerStep(t=t, active=("spring",))
        return tau

    def reset(self):
        self.calls = 0

    def last_step(self):
        return self._last


def test_runner_works_with_a_third_party_controller():
    ctrl = SpringDamper()
    assert isinstance(ctrl, Controller) and not isinstance(ctrl, ThrusterController)
    plant = Plant(FPSO, sea_state="normal", seed=2, segments=6, eta0=(12.0, 0.0, 0.0))
    res = run_closed_loop(plant, ctrl, ClosedLoopSettings(duration=60.0, true_state=True))
    d = res.meta["diagnostics"]
    assert ctrl.calls == 30 == d["controller_calls"]  # every 2 s over 60 s
    assert d["active_constraints"] == {"spring": 30}
    assert "solver_time_median" not in d  # it solves nothing
    # the spring pulls the vessel back toward the setpoint: the command points to -x at first
    assert res["tau_cmd[X]"][1] < -1e6


class HoldAzimuths:
    """A thruster-level controller: every thruster pushes 100 kN toward -x (astern)."""

    period = None
    owns_allocation = True

    def __init__(self, n):
        self.n = n

    def update(self, t, estimate, setpoint):
        return np.array([-1e5 * self.n, 0.0, 0.0])

    def reset(self):
        pass

    def last_step(self):
        return None

    def thruster_command(self):
        return ThrusterCommand(f=np.full(self.n, 1e5), alpha=np.full(self.n, math.pi))


def test_runner_applies_a_thruster_controller_without_allocation():
    n = len(FPSO.thrusters)
    ctrl = HoldAzimuths(n)
    assert isinstance(ctrl, ThrusterController)
    plant = Plant(FPSO, sea_state="none", seed=0, segments=6)
    res = run_closed_loop(plant, ctrl, ClosedLoopSettings(duration=120.0))
    assert res.meta["diagnostics"]["allocation_calls"] == 0
    np.testing.assert_allclose(res.group("f")[-1], 1e5, rtol=1e-6)
    assert res["x"][-1] < -0.5  # pushed astern


# -- architecture -------------------------------------------------------------------------------

def _imports(path: pathlib.Path) -> list[str]:
    tree = ast.parse(path.read_text())
    pkg = ".".join(path.relative_to(PKG.parent).with_suffix("").parts[:-1])
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out += [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = pkg.split(".")[: len(pkg.split(".")) - node.level + 1]
                mod = ".".join(base + ([node.module] if node.module else []))
            else:
                mod = node.module or ""
            out.append(mod)
            out += [f"{mod}.{a.name}" for a in node.names]
    return out


@pytest.mark.parametrize("layer", ["models", "control", "estimation"])
def test_no_module_below_studies_reaches_into_the_plant_or_the_scenario_parser(layer):
    bad = []
    for path in sorted((PKG / layer).glob("*.py")):
        for mod in _imports(path):
            if mod.startswith("tapm_opt.plant") or mod.startswith("tapm_opt.config.loader") \
                    or mod.startswith("tapm_opt.studies") or mod.startswith("tapm_opt.report"):
                bad.append(f"{path.name}: {mod}")
            if mod.startswith("tapm_opt.config.") and mod.rsplit(".", 1)[-1].startswith("_"):
                bad.append(f"{path.name}: {mod}")
    assert not bad, bad


def test_the_runner_uses_only_the_protocols_and_the_plant_interface():
    tree = ast.parse((PKG / "studies" / "closed_loop.py").read_text())
    plant_attrs = {n.attr for n in ast.walk(tree)
                   if isinstance(n, ast.Attribute) and isinstance(n.value, ast.Name) and n.value.id == "plant"}
    assert plant_attrs <= {"measure", "step", "system", "channels", "sample_row", "metadata"}, plant_attrs
    probes = [n for n in ast.walk(tree) if isinstance(n, ast.Call) and isinstance(n.func, ast.Name)
              and n.func.id in ("getattr", "hasattr") and isinstance(n.args[0], ast.Name)
              and n.args[0].id in ("controller", "estimator", "layer", "plant", "alloc")]
    assert not probes


def test_runner_refuses_an_object_that_is_not_a_controller():
    class NoPeriod:
        def update(self, t, estimate, setpoint):
            return np.zeros(3)

    plant = Plant(FPSO, sea_state="none", seed=0, segments=4)
    with pytest.raises(ClosedLoopError, match="NoPeriod is not a Controller"):
        run_closed_loop(plant, NoPeriod(), ClosedLoopSettings(duration=2.0))


def test_measurements_carry_the_truth_only_on_request():
    plant = Plant(FPSO, sea_state="normal", seed=0, segments=4, eta0=(3.0, 1.0, 0.1))
    m = plant.measure()
    assert m.truth is None and m.thruster_failed is not None and m.tau_thr is not None
    np.testing.assert_allclose(plant.measure(truth=True).truth.eta, (3.0, 1.0, 0.1))


def test_turret_offset_rejects_a_pose_without_heading():
    with pytest.raises(ValueError, match="3 components"):
        turret_offset([1.0, 2.0], FPSO.turret.position)


def test_pid_saturation_follows_the_thrusters_that_are_left():
    system = System.from_scenario(FPSO)
    pid = build_controller(system, {"type": "pid"})
    failed = frozenset(t.id for t in FPSO.thrusters[:3])
    pid.set_failed_thrusters(failed)
    np.testing.assert_allclose(pid.tau_limit, system.thrusters.without(failed).capacity_box(), rtol=1e-12)
    pid.set_failed_thrusters(frozenset())
    np.testing.assert_allclose(pid.tau_limit, system.thrusters.capacity_box(), rtol=1e-12)


def test_mpc_thrust_bounds_come_back_when_a_failure_clears():
    from tapm_opt.control.mpc import NonlinearMPC

    ctrl = NonlinearMPC(FPSO, MPCSettings(decision="thrusters", horizon=5))
    U = ctrl._prob.idx["U"]
    intact = ctrl._prob.ubz[U].copy()
    ctrl.set_failed_thrusters(frozenset({FPSO.thrusters[0].id}))
    assert np.count_nonzero(ctrl._prob.ubz[U] == 0.0) == 2 * 5  # (f_x, f_y) of one azimuth, 5 stages
    ctrl.update(0.0, Estimate(0.0, np.zeros(3), np.zeros(3), np.zeros(3)), Setpoint(np.zeros(3)))
    assert "thrust_capacity" not in ctrl.last_step().active  # a dead thruster is not a capacity limit
    ctrl.set_failed_thrusters(frozenset())
    np.testing.assert_array_equal(ctrl._prob.ubz[U], intact)


def test_the_riser_model_is_built_once_per_sea_state_and_shared():
    """The plant, the closed loop's setpoint layer and the MPC take the riser from the System:
    one model per sea state (built at first use), the same object for all of them."""
    import tapm_opt
    from tapm_opt.design import build
    from tapm_opt.models.system import System
    from tapm_opt.plant import Plant

    system = System.from_scenario(tapm_opt.load_scenario("fpso"))
    storm = system.riser("storm")
    assert storm is system.riser("storm") and storm is not system.riser(None)
    assert Plant(system, sea_state="storm", seed=1, segments=4).riser is storm
    assert build(system, {"type": "mpc", "reliability": True}).riser is system.riser(None)
    assert system.with_broken(["1"]).riser("storm") is storm   # the lines changed, the riser did not
    no_riser = System.from_scenario(tapm_opt.load_scenario("aamo4"))
    assert no_riser.scenario.riser is None and no_riser.riser("tidal") is None
