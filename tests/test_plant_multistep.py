"""The outer steps of a ``Plant.step`` in one compiled call (``Plant._fused_steps``,
``fem_kernel.plant_steps``) against one fused outer step at a time (``Plant._multi_step = False``:
``_fused_step``, ``plant_pre_step`` then ``mooring_step`` from Python).

Both run the same compiled functions on the same arguments in the same order, so every logged row,
every measurement (with its noise and the true state), every event and the plant's state after
the run are equal to the bit (``np.array_equal``, on any machine): through a storm with a riser,
faults due inside a control period (line break, thruster failure, buoy loss), lines near their
strength (the overload check in Python, with and without a break), a diverging FEM and vessel
(each status of the pre-step and the health check, at the first and at a later step of a call),
outer steps of changing length and off the block grid of the environment sums, no environment,
and a closed PID loop. Winches and a turning current keep the per-step path.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

import tapm_opt
from tapm_opt.config import schema
from tapm_opt.interfaces import ThrusterCommand
from tapm_opt.plant import fem_kernel
from tapm_opt.plant.fem import SimulationDiverged
from tapm_opt.plant.simulator import Plant

pytestmark = pytest.mark.skipif(not fem_kernel.AVAILABLE, reason="numba is not installed")


@pytest.fixture(scope="module")
def fpso():
    return tapm_opt.load_scenario("fpso")


@pytest.fixture
def spy(monkeypatch):
    """Records every plant_steps call (steps asked, steps taken, status, near, suspect) and counts
    the plant_pre_step calls made from Python."""
    rec = {"multi": [], "pre": 0}
    multi, pre = fem_kernel.plant_steps, fem_kernel.plant_pre_step

    def steps(*a):
        out = multi(*a)
        rec["multi"].append((a[4].shape[0], out[0], out[1], out[10], out[11]))
        return out

    def pre_step(*a):
        rec["pre"] += 1
        return pre(*a)

    monkeypatch.setattr(fem_kernel, "plant_steps", steps)
    monkeypatch.setattr(fem_kernel, "plant_pre_step", pre_step)
    return rec


def _cmd(n, k):
    """A thrust and azimuth that change from one control period to the next."""
    return ThrusterCommand(np.full(n, 3e5 * (1.0 + math.sin(k / 23.0))), np.linspace(-2.5, 2.5, n) + 0.01 * k)


def _measurement(p):
    m = p.measure(truth=True)
    parts = [np.atleast_1d(np.asarray(getattr(m, k), dtype=float)).ravel()
             for k in ("t", "position", "heading", "tensions", "t_position", "t_heading", "t_tensions",
                       "thruster_f", "thruster_alpha", "thruster_failed", "tau_thr")]
    if m.riser_angles is not None:
        parts += [m.riser_angles, [m.t_riser_angles]]
    tr = m.truth
    return np.concatenate(parts + [tr.eta, tr.nu, tr.tau_env])


def _state(p):
    """The plant's state that the next step reads, and the last step's outputs."""
    m, fem, th = p.mooring, p.mooring.fem, p.thrusters
    arrays = [p.eta, p.nu, p._eta_wf, p._tau_moor, p._rate, fem.r, fem.v, m._r_fl, m._vc, th._f, th._alpha,
              fem.L, fem.node_mass, fem.active] + [p.loads[k] for k in ("tau_wind", "tau_drift", "tau_moor", "tau_thr")]
    if p._riser_angles is not None:
        arrays.append(p._riser_angles)
    scalars = (p.t, fem.t, m.dt, p._steps, p._blk_j, p._n_sub, p._fault_i, tuple(p.events), tuple(th._failed))
    return arrays, scalars


def _assert_same_plants(a, b):
    (xa, sa), (xb, sb) = _state(a), _state(b)
    assert sa == sb
    for u, v in zip(xa, xb):
        assert np.array_equal(u, v, equal_nan=True)


def _run(make, periods, *, dt=1.0, cmd=None, multi=True, spy=None, log_start=True):
    """``periods`` calls of Plant.step (``dt`` one number or one per call), the log row and the
    measurement before the first (``log_start``) and after each; the exception's text if the
    plant diverged."""
    p = make()
    p._multi_step = multi
    n = len(p.thrusters.ids)
    rows, meas, err = ([p.sample_row()], [_measurement(p)], None) if log_start else ([], [], None)
    dts = dt if isinstance(dt, (list, tuple)) else [dt] * periods
    if spy is not None:
        spy["multi"].clear()
        spy["pre"] = 0
    try:
        with np.errstate(all="ignore"):
            for k in range(periods):
                p.step(dts[k % len(dts)], _cmd(n, k) if cmd is None else cmd)
                rows.append(p.sample_row())
                meas.append(_measurement(p))
    except SimulationDiverged as exc:
        err = (str(exc), exc.time)
    calls = None if spy is None else (list(spy["multi"]), spy["pre"])
    return p, np.array(rows), np.array(meas), err, calls


def _compare(make, periods, spy, **kw):
    """The run with the multi-step call and with one fused step at a time: equal to the bit.
    Returns the plant_steps calls and the plant_pre_step count of the first, and its plant."""
    pm, rm, mm, em, (calls, pre) = _run(make, periods, multi=True, spy=spy, **kw)
    ps, rs, ms, es, (calls_s, pre_s) = _run(make, periods, multi=False, spy=spy, **kw)
    assert calls_s == [] and pre_s > 0   # the forced per-step path never calls plant_steps
    assert em == es
    assert rm.shape == rs.shape and np.array_equal(rm, rs, equal_nan=True)
    assert np.array_equal(mm, ms, equal_nan=True)
    _assert_same_plants(pm, ps)
    return calls, pre, pm


def _runs(calls, alone=(), start=0):
    """{first outer step: steps taken} of the plant_steps calls, the steps in ``alone`` taken on
    their own in between."""
    out, i = {}, start
    for _, k, _, _, _ in calls:
        while i in alone:
            i += 1
        out[i] = k
        i += k
    return out


def test_a_storm_with_faults_inside_the_periods_is_bit_identical(fpso, spy):
    """400 s of storm with its riser; a line breaks at 123.45 s and a thruster fails at 250.05 s,
    each inside a control period: the compiled call stops before the fault's step, which the
    per-step path takes with the fault, and the rest of the period is one call again."""
    faults = [schema.Fault(kind="line_break", time=123.45, line=fpso.lines[3].id),
              schema.Fault(kind="thruster_failure", time=250.05, thruster=fpso.thrusters[2].id)]
    calls, pre, p = _compare(lambda: Plant(fpso, sea_state="storm", seed=1, segments=10, faults=faults), 400, spy)
    assert p.riser is not None and [e for _, e in p.events] == [f"line {fpso.lines[3].id} broke",
                                                                f"thruster {fpso.thrusters[2].id} failed"]
    assert pre == 2                                              # only the two fault steps on their own
    assert sum(k for _, k, _, _, _ in calls) == 4000 - 2
    assert all(st == 0 and not near and not sus for _, _, st, near, sus in calls)
    runs = _runs(calls, [1235, 2501])
    assert runs[1230] == 5 and 1235 not in runs and runs[1236] == 4   # the break at the step from 123.5 s
    assert runs[2500] == 1 and 2501 not in runs and runs[2502] == 8   # the failure at the step from 250.1 s
    assert sum(1 for k in runs.values() if k == 10) > 350


def test_steps_near_a_lines_strength_are_finished_in_python(fpso, spy):
    """Lines set just above their tension: each step that finds one near its strength ends the
    call; the overload check (a break, or none) and the load are the per-step path's."""
    def make(factor):
        def build():
            p = Plant(fpso, sea_state="storm", seed=5, segments=10)
            T = np.maximum(p.mooring.fairlead_tension(), p.mooring.anchor_tension())
            p.strength = factor * T
            return p
        return build

    calls, _, p = _compare(make(1.01), 20, spy)   # lines break from overload
    assert any("overload" in e for _, e in p.events)
    assert any(near for _, _, _, near, _ in calls)
    calls, _, p = _compare(make(1.03), 40, spy)   # near their strength, some steps without a break
    assert any(near and k < n for n, k, _, near, _ in calls)


@pytest.mark.parametrize("case", ["fem_blows_up", "vessel_at_first_step", "vessel_at_later_step", "fast_nodes"])
def test_a_diverging_plant_is_reported_as_by_the_per_step_path(fpso, spy, case):
    """The same exception, at the same time, with the plant in the same state: the FEM stepped
    at 30x its stable step (a non-finite node: status 2 at a later step of a call), a vessel
    pushed off at once (status 1 at the first step) or after a step (status 1 later), a large
    push whose lines race (the health check on the 20th step ends a call; the lines may not break
    from overload there, or fpso's chain-wire-chain lines all break within 1.4 s instead). At 12
    segments (2 / 9 / 1): at 10 (2 / 7 / 1) the FEM at 30x its stable step blows up within the
    first step of the call, which the per-step path reports alike but which is not this case."""
    def make():
        p = Plant(fpso, sea_state="storm", seed=1, segments=12,
                  break_on_overload="never" if case in ("vessel_at_later_step", "fast_nodes") else None)
        p.step(0.3 if case != "fem_blows_up" else 0.1)
        if case == "fem_blows_up":
            p._dt_stable *= 30.0
            p._h_last = None
        else:
            p._tau_moor = np.array([{"vessel_at_first_step": 1e18, "vessel_at_later_step": 1e15,
                                     "fast_nodes": 3e11}[case], 0.0, 0.0])
        return p

    calls, _, p = _compare(make, 60, spy)
    stop = calls[-1]
    want = {"fem_blows_up": (2, True), "vessel_at_first_step": (1, False), "vessel_at_later_step": (1, True),
            "fast_nodes": (0, True)}[case]
    assert (stop[2], stop[1] > 0) == want, stop
    if case == "fast_nodes":
        assert stop[4] and stop[1] < stop[0] and p._steps % 20 == 0


def test_a_node_set_non_finite_from_outside_is_reported_alike(fpso, spy):
    def make():
        p = Plant(fpso, sea_state="storm", seed=1, segments=4)
        p.step(0.2)
        r = p.mooring.fem.r.copy()
        r[3, 2] = math.nan
        p.mooring.fem.r = r
        return p

    calls, _, _ = _compare(make, 3, spy, log_start=False)   # the sensors refuse the state
    assert calls[-1][1:3] == (0, 2)


@pytest.mark.parametrize("outer_dt", [0.1, 1.0 / 3.0, 0.07])
def test_outer_steps_of_changing_length_and_off_the_block_grid_are_bit_identical(fpso, spy, outer_dt):
    """Plant.step with a different dt each call, outer steps whose times drift off ``t0 + i h``:
    the calls cover the steps the environment's block holds, a new block as the per-step path
    starts it."""
    dts = [1.0, 0.5, 1.0 / 3.0, 0.13, 2.0, 0.1, 0.05, 0.37, 0.01]
    calls, _, p = _compare(lambda: Plant(fpso, sea_state="storm", seed=6, segments=4, outer_dt=outer_dt), 60, spy,
                        dt=dts)
    assert p._steps == sum(k for _, k, _, _, _ in calls) > 0


@pytest.mark.parametrize("kw", [{"sea_state": "none"}, {"sea_state": "normal", "wave_frequency": False}],
                         ids=["no_environment", "no_wave_frequency"])
def test_without_environment_or_wave_frequency_it_is_bit_identical(fpso, spy, kw):
    brk = [schema.Fault(kind="line_break", time=30.55, line=fpso.lines[0].id)]
    calls, _, p = _compare(lambda: Plant(fpso, seed=2, segments=8, faults=brk, **kw), 60, spy)
    assert len(p.events) == 1 and calls


def test_a_buoy_loss_inside_a_period_is_bit_identical(spy):
    """A buoy comes off at 20.35 s: the step takes the stable step anew (more substeps), the
    calls after it run with the new count."""
    from test_buoy_loss import UPPER, with_faults

    sc = with_faults(UPPER, {"kind": "buoy_loss", "line": "3", "joint": 1, "time": 20.35})
    calls, _, p = _compare(lambda: Plant(sc, sea_state="normal", seed=3, segments=8), 40, spy)
    assert [e for _, e in p.events] == ["line 3 lost its buoy at joint 1"]
    runs = _runs(calls, [204])
    assert runs[200] == 4 and 204 not in runs and runs[205] == 5    # the step from 20.4 s takes the fault


def test_winches_and_a_turning_current_keep_the_per_step_path(spy):
    aamo4 = tapm_opt.load_scenario("aamo4")
    w = np.array([0.2, -0.2, 0.1, 0.0])
    for make, winch in ((lambda: Plant(aamo4, seed=7, segments=8), w),
                        (lambda: Plant(aamo4, sea_state="tidal_rotating", seed=6, segments=8), None)):
        res = []
        for multi in (True, False):
            p = make()
            p._multi_step = multi
            spy["multi"].clear()
            rows = []
            for k in range(15):
                p.step(1.0, None, winch)
                rows.append(p.sample_row())
            assert spy["multi"] == []
            res.append(np.array(rows))
        assert np.array_equal(res[0], res[1])


def test_the_closed_pid_loop_is_bit_identical(fpso, spy):
    from tapm_opt.models.system import System
    from tapm_opt.studies.closed_loop import DEFAULT_ESTIMATOR, ClosedLoopSettings, run_closed_loop
    from tapm_opt.studies.controllers import build_controller

    system = System.from_scenario(fpso)
    brk = [schema.Fault(kind="line_break", time=60.0, line=fpso.lines[1].id)]
    out = []
    for multi in (True, False):
        ctrl = build_controller(system, {"type": "pid"}, where="--option", dt_control=1.0,
                                estimator=DEFAULT_ESTIMATOR, winch=None)
        plant = Plant(system, sea_state="storm", seed=0, segments=10, faults=brk)
        plant._multi_step = multi
        spy["multi"].clear()
        out.append(run_closed_loop(plant, ctrl, ClosedLoopSettings(duration=150.0, dt_control=1.0, dt_log=1.0),
                                   system=system))
        assert bool(spy["multi"]) == multi
    assert out[0].channels == out[1].channels
    assert np.array_equal(out[0].time, out[1].time) and np.array_equal(out[0].data, out[1].data)


def test_plant_steps_equals_its_plain_python_loop(fpso):
    """plant_steps compiled and its loop run as plain Python (calling the same compiled
    plant_pre_step and mooring_step)."""
    p = Plant(fpso, sea_state="storm", seed=3, segments=6)
    p.step(1.0, ThrusterCommand(np.full(len(fpso.thrusters), 4.0e5), np.full(len(fpso.thrusters), 0.4)))
    args = []
    real = fem_kernel.plant_steps

    def grab(*a):
        args.append([x.copy() if isinstance(x, np.ndarray) else x for x in a])
        return real(*a)

    fem_kernel.plant_steps = grab
    try:
        p.step(2.0, None)
    finally:
        fem_kernel.plant_steps = real
    assert len(args) == 2   # the block of environment sums ends at 1.5 s: two calls
    for a in args:
        a1 = [x.copy() if isinstance(x, np.ndarray) else x for x in a]
        a2 = [x.copy() if isinstance(x, np.ndarray) else x for x in a]
        o1, o2 = real(*a1), real.py_func(*a2)
        assert o1[0] == o2[0] == a[4].shape[0] and o1[1] == o2[1] == 0
        for x1, x2 in zip(o1, o2):
            assert np.array_equal(x1, x2)
        for x1, x2 in zip(a1, a2):   # the arrays written in place: thrusts, azimuths, node current
            if isinstance(x1, np.ndarray):
                assert np.array_equal(x1, x2)
    assert sum(a[4].shape[0] for a in args) == 20
