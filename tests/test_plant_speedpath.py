"""The plant's fast outer step against its references.

* The environment's block sums (``WaveField.block``, ``Wind.block``: a block of outer-step times
  at once, by angle sums) against the scalar-time sums of every step (``WaveField._sums``,
  ``Wind.speed``), to a few units in the last place of the phases.
* A plant stepped on the block sums against the same plant stepped on the scalar-time sums (the
  original per-step formulas), over a few hundred outer steps with a heading change, a line break
  and a riser, and with outer steps of changing length and off the block grid.
* The fused compiled outer step (``fem_kernel.plant_pre_step``, then ``mooring_step``) against
  its numpy path (bit for bit where the machine allows, ``_bitwise``) and against the same
  functions run as plain Python (the numba-less fallback), and the plant run without numba.
* Bad input still raises the same typed errors on the fast path.
"""

from __future__ import annotations

import dataclasses
import importlib.util
import math
import sys

import numpy as np
import pytest

import tapm_opt
from tapm_opt.config import schema
from tapm_opt.interfaces import ThrusterCommand
from tapm_opt.plant import fem_kernel
from tapm_opt.plant.environment import Environment, PlantError
from tapm_opt.plant.fem import SimulationDiverged
from tapm_opt.plant.simulator import Plant, run_open_loop

from _bitwise import assert_same

compiled_only = pytest.mark.skipif(not fem_kernel.AVAILABLE, reason="numba is not installed")


@pytest.fixture(scope="module")
def fpso():
    return tapm_opt.load_scenario("fpso")


def _turning_cmd(n):
    """Thrusters that push and turn the vessel (a heading change of about a degree in 30 s)."""
    return lambda t: ThrusterCommand(np.full(n, 6.0e5), np.full(n, 1.2 if t < 15.0 else -1.2))


def _scalar_sums(plant):
    """Plant._env_sums on the scalar-time sums of every step (the original per-step formulas)."""
    env = plant.env

    def sums(t0, t1, h):
        S, C = env.waves._sums(t1)
        w = env.waves
        th = t1 * w.omega + w.phase
        vg = np.concatenate([np.cos(th), np.sin(th)]) @ w._Wv   # the heave, roll and pitch sums on the grid
        if vg.size:   # brought in by the start-up ramp (WaveField.ramp), as the block does
            vg = vg.reshape(fem_kernel.N_HEADINGS, -1).copy()
            vg[:, :3] *= float(w.ramp(t1)[0])
            vg = vg.ravel()
        return (env.wind.speed(t0), float(env.waves._sums(t0)[1][1]), float(S[0]), float(S[1]), float(C[0]), vg)

    return sums


@pytest.mark.parametrize("t0", [0.0, 0.1, 599.9, 3600.0])
@pytest.mark.parametrize("h", [0.1, 0.07, 0.25])
def test_block_sums_equal_the_scalar_sums_of_every_step(fpso, t0, h):
    env = Environment(fpso, "storm", seed=11)
    n = 300
    S, C = env.waves.block(t0, h, n)
    V = env.wind.block(t0, h, n)
    assert S.shape == (n, 3) and C.shape == (n, 4) and len(V) == n and all(type(v) is float for v in V)
    w = env.waves
    scale_s, scale_c = np.abs(w._Ws).sum(axis=1), np.abs(w._Wc).sum(axis=1)
    scale_v = env.wind.amplitude.sum()
    tol = 1e-15 * 64 * max(1.0, t0 + n * h)   # a few ulp of the phases omega t
    for j in range(n):
        t = t0 + j * h
        s, c = w._sums(t)
        assert np.all(np.abs(S[j] - s) <= tol * scale_s), (t, S[j] - s)
        assert np.all(np.abs(C[j] - c) <= tol * scale_c), (t, C[j] - c)
        assert abs(V[j] - env.wind.speed(t)) <= tol * scale_v
    assert not np.array_equal(S[0], S[1])   # the sums do change along the block


def test_block_rotation_tables_are_reused_and_extended(fpso):
    env = Environment(fpso, "storm", seed=2)
    a = env.waves.block(5.0, 0.1, 16)[0]
    b = env.waves.block(5.0, 0.1, 64)[0]   # a longer table for the same step: the same first rows
    assert np.array_equal(a, b[:16])
    assert set(env.waves._rot_cache) == {0.1}


def _pair(fpso, duration, *, patch_ref, compiled=True, **kw):
    """The same open-loop run stepped on the block sums and on the scalar sums of every step."""
    kw.setdefault("segments", 8)
    run_kw = {k: kw.pop(k) for k in ("thruster_cmd", "dt_log") if k in kw}
    out = []
    for ref in (False, True):
        p = Plant(fpso, **kw)
        p.compiled = compiled
        if ref:
            p._env_sums = patch_ref(p)
        out.append((run_open_loop(p, duration, **run_kw), p))
    return out


def _close(a, b):
    """The largest difference of two logs, each column relative to its scale (tensions, loads and
    positions have their own)."""
    scale = np.maximum(np.max(np.abs(a), axis=0), 1e-12)
    return np.max(np.abs(a - b) / scale)


@pytest.mark.parametrize("compiled", [True, False], ids=["compiled", "numpy"])
def test_plant_on_block_sums_follows_the_scalar_sums_through_a_turn_and_a_break(fpso, compiled):
    if compiled and not fem_kernel.AVAILABLE:
        pytest.skip("numba is not installed")
    brk = [schema.Fault(kind="line_break", time=20.0, line=fpso.lines[2].id)]
    (rb, pb), (rr, pr) = _pair(fpso, 30.0, patch_ref=_scalar_sums, compiled=compiled, sea_state="storm", seed=4,
                               faults=brk, thruster_cmd=_turning_cmd(len(fpso.thrusters)), dt_log=0.5)
    psi = rb.data[:, rb.channels.index("psi")]
    assert np.ptp(psi) > math.radians(0.5)             # the heading changed
    assert pb.events == pr.events and len(pb.events) == 1
    assert pb.riser is not None and "riser_top_angle" in rb.channels
    assert rb.channels == rr.channels and np.array_equal(rb.time, rr.time)
    assert _close(rb.data, rr.data) < 1e-9


@pytest.mark.parametrize("outer_dt", [1.0 / 3.0, 0.07])
def test_off_grid_and_changing_outer_steps_follow_the_scalar_sums(fpso, outer_dt):
    """Outer steps whose times drift off ``t0 + i h`` (round(t + 1/3, 9)) get the sums at their
    own times; steps of changing length start new blocks."""
    plants = []
    for ref in (False, True):
        p = Plant(fpso, sea_state="storm", seed=6, segments=4, outer_dt=outer_dt)
        if ref:
            p._env_sums = _scalar_sums(p)
        plants.append(p)
    cmd = ThrusterCommand(np.full(len(fpso.thrusters), 3.0e5), None)
    rows = [[], []]
    for dt in (1.0, 0.5, 1.0 / 3.0, 0.13, 2.0) * 8:
        for k, p in enumerate(plants):
            p.step(dt, cmd)
            rows[k].append(p.sample_row())
    assert plants[0].t == plants[1].t
    assert _close(np.array(rows[0]), np.array(rows[1])) < 1e-9


@compiled_only
def test_fused_step_runs_and_equals_the_numpy_path_through_a_turn_and_a_break(fpso, monkeypatch):
    calls = []
    real, multi = fem_kernel.plant_pre_step, fem_kernel.plant_steps

    def counted(*a):
        calls.append(1)
        return real(*a)

    def counted_steps(*a):   # plant_pre_step called from compiled code, once per outer step taken
        out = multi(*a)
        calls.extend([1] * out[0])
        return out

    monkeypatch.setattr(fem_kernel, "plant_pre_step", counted)
    monkeypatch.setattr(fem_kernel, "plant_steps", counted_steps)
    brk = [schema.Fault(kind="line_break", time=12.0, line=fpso.lines[0].id)]
    res = []
    for compiled in (True, False):
        p = Plant(fpso, sea_state="storm", seed=9, segments=8, faults=brk)
        p.compiled = compiled
        res.append((run_open_loop(p, 25.0, thruster_cmd=_turning_cmd(len(fpso.thrusters)), dt_log=0.5), p))
    (rc, pc), (rn, pn) = res
    assert len(calls) == 250   # every outer step of the compiled plant is fused, none of the numpy one
    assert pc.events == pn.events
    assert_same(rc.data, rn.data)
    assert pc.loads.keys() == pn.loads.keys()
    for k in pc.loads:
        assert_same(pc.loads[k], pn.loads[k])


@compiled_only
def test_fused_kernel_equals_its_plain_python_fallback(fpso, monkeypatch):
    """plant_pre_step compiled and as the plain Python function the module holds without numba
    (called from Python on the per-step path, ``Plant._multi_step`` False)."""
    p = Plant(fpso, sea_state="storm", seed=3, segments=6)
    p._multi_step = False
    p.step(1.0, ThrusterCommand(np.full(len(fpso.thrusters), 4.0e5), np.full(len(fpso.thrusters), 0.4)))
    args = []

    def grab(*a):
        args.append([x.copy() if isinstance(x, np.ndarray) else x for x in a])
        return real(*a)

    real = fem_kernel.plant_pre_step
    monkeypatch.setattr(fem_kernel, "plant_pre_step", grab)
    p.step(0.5, None)
    assert len(args) == 5
    for a in args:
        a1 = [x.copy() if isinstance(x, np.ndarray) else x for x in a]
        a2 = [x.copy() if isinstance(x, np.ndarray) else x for x in a]
        s1, out1 = real(*a1)
        s2, out2 = real.py_func(*a2)
        assert s1 == s2 == 0
        assert_same(out1, out2)
        for x1, x2 in zip(a1, a2):   # the arrays written in place: thrusts, azimuths, node current
            if isinstance(x1, np.ndarray):
                assert_same(x1, x2)


@compiled_only
@pytest.mark.parametrize("kind, depths, factors", [("uniform", (), ()), ("linear", (), (0.3,)),
                                                   ("piecewise", (0.0, 500.0, 1000.0), (1.0, 0.75, 0.15)),
                                                   ("piecewise", (100.0, 400.0, 1500.0), (0.9, 0.2, 0.0)),
                                                   ("piecewise", (200.0,), (0.5,))])
def test_compiled_current_at_the_nodes_is_the_profile(fpso, kind, depths, factors):
    from tapm_opt.models.environment import CurrentProfile

    ss = dataclasses.replace(fpso.sea_state("storm"), current_profile=kind, current_profile_depths=depths,
                             current_profile_factors=factors)
    prof = CurrentProfile(ss, 1000.0)
    z = np.concatenate([[-5.0, -0.0, 0.0, 1000.0, 1200.0], depths, np.linspace(-50.0, 1100.0, 257)])
    r = np.zeros((z.size, 3))
    r[:, 2] = z
    vc = np.full((z.size, 3), np.nan)
    code = {"uniform": fem_kernel.CURRENT_UNIFORM, "linear": fem_kernel.CURRENT_LINEAR,
            "piecewise": fem_kernel.CURRENT_PIECEWISE}[kind]
    ok = fem_kernel._current_at_nodes(r, vc, code, bool(prof._interp_clamps), np.array(prof._depths, dtype=float),
                                      np.array(prof._factors, dtype=float), float(prof.water_depth),
                                      np.array(prof.surface))
    assert ok
    assert np.array_equal(vc, prof.velocity_unchecked(z))
    r[3, 2] = np.nan
    assert not fem_kernel._current_at_nodes(r, vc, code, False, np.zeros(1), np.zeros(1), 1000.0, np.ones(3))


@compiled_only
def test_without_numba_the_plant_runs_its_numpy_path_with_the_same_results(fpso, monkeypatch):
    """The kernel module loaded with numba absent (as tests/test_fem_kernel.py does): the FEM and the
    plant run numpy, and the run agrees with the compiled fused one to round-off."""
    ref = run_open_loop(Plant(fpso, sea_state="storm", seed=1, segments=6), 5.0)
    path = fem_kernel.__file__
    monkeypatch.setitem(sys.modules, "numba", None)
    spec = importlib.util.spec_from_file_location("tapm_opt.plant._fem_kernel_without_numba_2", path)
    mod = importlib.util.module_from_spec(spec)
    with pytest.warns(RuntimeWarning, match="numba is not available"):
        spec.loader.exec_module(mod)
    assert mod.AVAILABLE is False
    monkeypatch.setitem(sys.modules, "tapm_opt.plant.fem_kernel", mod)
    monkeypatch.setattr(sys.modules["tapm_opt.plant"], "fem_kernel", mod, raising=False)
    p = Plant(fpso, sea_state="storm", seed=1, segments=6)
    assert p.mooring.fem.kernel == "numpy"
    res = run_open_loop(p, 5.0)
    assert np.all(np.isfinite(res.data))
    assert np.allclose(res.data, ref.data, rtol=1e-6, atol=1e-6)


@pytest.mark.parametrize("compiled", [True, False], ids=["compiled", "numpy"])
def test_bad_input_raises_the_same_typed_errors(fpso, compiled):
    p = Plant(fpso, sea_state="storm", seed=1, segments=4)
    p.compiled = compiled
    n = len(fpso.thrusters)
    with pytest.raises(PlantError, match="dt"):
        p.step(-1.0)
    with pytest.raises(PlantError, match="must be finite"):
        p.step(0.1, ThrusterCommand(np.full(n, math.nan), None))
    with pytest.raises(PlantError, match="shape"):
        p.step(0.1, ThrusterCommand(np.zeros(n + 1), None))
    p.step(0.2)
    # a vessel pushed off by an absurd load: the fast path reports it as the numpy path does
    p._tau_moor = np.array([1e18, 0.0, 0.0])
    with pytest.raises(SimulationDiverged, match="vessel state became unphysical"):
        p.step(0.1)


@pytest.mark.parametrize("compiled", [True, False], ids=["compiled", "numpy"])
def test_a_node_that_is_no_longer_finite_is_reported_as_diverged(fpso, compiled):
    if compiled and not fem_kernel.AVAILABLE:
        pytest.skip("numba is not installed")
    p = Plant(fpso, sea_state="storm", seed=1, segments=4)
    p.compiled = compiled
    p.step(0.2)
    r = p.mooring.fem.r.copy()
    r[3, 2] = math.nan
    p.mooring.fem.r = r
    with pytest.raises(SimulationDiverged, match="line"):
        p.step(0.1)


@compiled_only
def test_compiled_end_tensions_are_the_numpy_formulas(fpso):
    """FEMLines.end_tensions (compiled with the numba FEM) against the numpy path of
    fairlead_tension and anchor_tension on the same states, with a broken line."""
    p = Plant(fpso, sea_state="storm", seed=2, segments=6,
              faults=[schema.Fault(kind="line_break", time=1.0, line=fpso.lines[4].id)])
    fem = p.mooring.fem
    assert fem.kernel == "numba"
    for k in range(40):
        p.step(0.5, ThrusterCommand(np.full(len(fpso.thrusters), 5e5 * math.sin(k / 7)),
                                    np.full(len(fpso.thrusters), k / 20)))
        T_fl, T_an = fem.end_tensions()
        fn = fem._kernel_fn
        fem._kernel_fn = None   # the numpy path of the same methods
        try:
            assert_same(T_fl, fem.fairlead_tension())
            assert_same(T_an, fem.anchor_tension())
        finally:
            fem._kernel_fn = fn
    assert T_fl[4] == 0.0 and np.all(np.delete(T_fl, 4) > 0.0) and np.all(np.delete(T_an, 4) > 0.0)
