"""The compiled outer step of the plant (``Plant.compiled``: thrusters, vessel and lines as numba
kernels, :mod:`tapm_opt.plant.fem_kernel`) against the numpy path of the same plant in the same
process: every logged channel and every event must be bit-identical (np.array_equal; to round-off
on a machine whose numpy has its own float64 sin/cos, ``_bitwise.LIBM_TRIG``), over short
runs that cover the intact sea state with its riser, a line break, an overload break, winches, a
thruster failure, a turning current, a locked turret and a closed PID loop. Independent path: the
numpy reference (``vessel_rhs``, ``ThrusterBank`` numpy step, ``MooringFEM.advance`` /
``fairlead_acceleration`` / ``tau``), which the compiled path does not call."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

import tapm_opt
from tapm_opt.config import schema
from tapm_opt.interfaces import ThrusterCommand
from tapm_opt.plant import fem_kernel
from tapm_opt.plant.fem import SimulationDiverged
from tapm_opt.plant.simulator import Plant, run_open_loop

from _bitwise import assert_same

pytestmark = pytest.mark.skipif(not fem_kernel.AVAILABLE, reason="numba is not installed")


@pytest.fixture(scope="module")
def fpso():
    return tapm_opt.load_scenario("fpso")


@pytest.fixture(scope="module")
def aamo4():
    return tapm_opt.load_scenario("aamo4")


def _pair(scenario, duration, *, post=None, **kw):
    """The same open-loop run (10 segments per line unless given) with the compiled and with the
    numpy outer step: (compiled result, numpy result, compiled plant, numpy plant)."""
    run_kw = {k: kw.pop(k) for k in ("thruster_cmd", "winch_cmd", "dt_log") if k in kw}
    kw.setdefault("segments", 10)
    out = []
    for compiled in (True, False):
        p = Plant(scenario, **kw)
        p.compiled = compiled
        if post is not None:
            post(p)
        out.append((run_open_loop(p, duration, **run_kw), p))
    (rc, pc), (rn, pn) = out
    return rc, rn, pc, pn


def _cmd(n, f=2.0e5):
    return ThrusterCommand(np.full(n, f), np.linspace(-2.5, 2.5, n))


@pytest.fixture
def count_kernel(monkeypatch):
    """Counts the outer steps of the compiled mooring step (to check the compiled path did run):
    its calls from Python (one outer step each) and the outer steps the multi-step call
    ``plant_steps`` took (it calls the mooring step from compiled code)."""
    calls = []
    real, multi = fem_kernel.mooring_step, fem_kernel.plant_steps

    def counted(*args):
        calls.append(1)
        return real(*args)

    def counted_steps(*args):
        out = multi(*args)
        calls.extend([1] * out[0])
        return out

    monkeypatch.setattr(fem_kernel, "mooring_step", counted)
    monkeypatch.setattr(fem_kernel, "plant_steps", counted_steps)
    return calls


def test_intact_sea_state_with_riser_is_bit_identical(fpso, count_kernel):
    rc, rn, pc, pn = _pair(fpso, 30.0, sea_state="normal", seed=1, thruster_cmd=_cmd(len(fpso.thrusters)))
    assert pc.riser is not None and "riser_top_angle" in rc.channels
    assert len(count_kernel) == 300  # every outer step of the compiled plant, none of the numpy one
    assert rc.channels == rn.channels and np.array_equal(rc.time, rn.time)
    assert_same(rc.data, rn.data)


def test_line_break_is_bit_identical(fpso):
    brk = [schema.Fault(kind="line_break", time=10.0, line=fpso.lines[0].id)]
    rc, rn, pc, pn = _pair(fpso, 30.0, sea_state="storm", seed=3, faults=brk, thruster_cmd=_cmd(len(fpso.thrusters)))
    assert pc.events == pn.events == [(10.0, f"line {fpso.lines[0].id} broke")]
    assert_same(rc.data, rn.data)
    assert np.all(rc.data[rc.time > 10.0, rc.channels.index(f"T_fairlead[{fpso.lines[0].id}]")] == 0.0)


@pytest.mark.parametrize("compiled", [True, False], ids=["compiled", "numpy"])
def test_a_diverging_fem_is_reported_on_both_paths(fpso, compiled):
    """FEM substeps 30x the stable step blow the lines up: both outer steps stop with
    SimulationDiverged naming a line (from the periodic node-speed check, or when a node is no
    longer finite before the current at the nodes is looked up), not with an error about the
    current profile's depths."""
    p = Plant(fpso, segments=10)
    p.compiled = compiled
    p.step(0.1)
    p._dt_stable *= 30.0   # every later step takes 1/30 of the substeps it needs
    p._h_last = None
    with pytest.raises(SimulationDiverged, match="line"), np.errstate(all="ignore"):
        for _ in range(600):
            p.step(0.1)


def test_overload_break_is_bit_identical(fpso):
    def weaken(p):  # the most loaded line just above its tension: it breaks from overload
        T = np.maximum(p.mooring.fairlead_tension(), p.mooring.anchor_tension())
        j = int(np.argmax(T))
        p.strength = p.strength.copy()
        p.strength[j] = 1.01 * T[j]

    rc, rn, pc, pn = _pair(fpso, 20.0, sea_state="storm", seed=5, post=weaken)
    assert any("overload" in e for _, e in pc.events)
    assert pc.events == pn.events
    assert_same(rc.data, rn.data)


def test_winches_are_bit_identical(aamo4):
    w = np.array([0.2, -0.2, 0.1, 0.0])
    rc, rn, pc, pn = _pair(aamo4, 30.0, seed=7, winch_cmd=w,
                           thruster_cmd=lambda t: ThrusterCommand(np.full(len(aamo4.thrusters),
                                                                          1e5 * (1 + math.sin(t / 5))), None))
    L = rc.data[:, rc.channels.index(f"L[{aamo4.lines[0].id}]")]
    assert L[-1] > L[0]  # the winch paid out
    assert_same(rc.data, rn.data)


def test_thruster_failure_is_bit_identical(fpso):
    fail = [schema.Fault(kind="thruster_failure", time=5.0, thruster=fpso.thrusters[1].id)]
    turn = lambda t: ThrusterCommand(np.full(len(fpso.thrusters), 3e5), np.full(len(fpso.thrusters), 0.1 * t))
    rc, rn, pc, pn = _pair(fpso, 20.0, sea_state="normal", seed=4, faults=fail, thruster_cmd=turn)
    f = rc.data[:, rc.channels.index(f"f[{fpso.thrusters[1].id}]")]
    assert np.all(f[rc.time > 5.0] == 0.0) and f[3] > 0.0
    assert_same(rc.data, rn.data)


def test_turning_current_is_bit_identical(aamo4):
    rc, rn, pc, pn = _pair(aamo4, 30.0, sea_state="tidal_rotating", seed=6)
    assert pc._current_turns
    assert_same(rc.data, rn.data)


def test_locked_turret_and_other_outer_step_are_bit_identical(aamo4):
    sc = dataclasses.replace(aamo4, turret=dataclasses.replace(aamo4.turret, position=(20.0, 3.0), mode="locked"))
    rc, rn, pc, pn = _pair(sc, 15.0, seed=8, outer_dt=0.07, dt_log=0.5, thruster_cmd=_cmd(len(sc.thrusters), 1e5))
    assert pc.mooring.geometry.turret_mode == "locked"
    assert_same(rc.data, rn.data)


def test_closed_pid_loop_is_bit_identical(fpso):
    from tapm_opt.models.system import System
    from tapm_opt.studies.closed_loop import DEFAULT_ESTIMATOR, ClosedLoopSettings, run_closed_loop
    from tapm_opt.studies.controllers import build_controller

    system = System.from_scenario(fpso)
    out = []
    for compiled in (True, False):
        ctrl = build_controller(system, {"type": "pid"}, where="--option", dt_control=1.0,
                                estimator=DEFAULT_ESTIMATOR, winch=None)
        plant = Plant(system, sea_state="normal", seed=0, segments=10)
        plant.compiled = compiled
        out.append(run_closed_loop(plant, ctrl, ClosedLoopSettings(duration=20.0, dt_control=1.0, dt_log=1.0),
                                   system=system))
    assert out[0].channels == out[1].channels
    assert_same(out[0].data, out[1].data)


def test_without_numba_the_numpy_path_runs(fpso, monkeypatch):
    """numba absent (``fem_kernel.AVAILABLE`` False): the FEM falls back to numpy and the plant to
    its numpy outer step; the run agrees with the compiled one to round-off (the numpy FEM step
    is not bit-identical to the compiled FEM kernel, tests/test_fem_kernel.py)."""
    ref = run_open_loop(Plant(fpso, sea_state="normal", seed=1, segments=10), 5.0)
    monkeypatch.setattr(fem_kernel, "AVAILABLE", False)
    p = Plant(fpso, sea_state="normal", seed=1, segments=10)
    assert p.mooring.fem.kernel == "numpy"
    res = run_open_loop(p, 5.0)
    assert np.all(np.isfinite(res.data))
    assert np.allclose(res.data, ref.data, rtol=1e-6, atol=1e-6)


def test_outer_steps_of_changing_length_are_bit_identical(fpso, count_kernel):
    """Plant.step with a different dt each call (outer steps of 0.01–0.1 s, the FEM substep count
    changing with them): the compiled and the numpy plant stay together."""
    plants = []
    for compiled in (True, False):
        p = Plant(fpso, sea_state="storm", seed=2, segments=4)
        p.compiled = compiled
        plants.append(p)
    cmd = _cmd(len(fpso.thrusters), 3.0e5)
    rows = [[], []]
    for dt in (0.1, 0.05, 0.13, 0.3, 0.01, 0.37, 0.2) * 3:
        for k, p in enumerate(plants):
            p.step(dt, cmd)
            rows[k].append(p.sample_row())
    assert len(count_kernel) > 0 and plants[0].t == plants[1].t
    assert_same(np.array(rows[0]), np.array(rows[1]))
