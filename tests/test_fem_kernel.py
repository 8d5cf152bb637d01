"""Tests of the compiled FEM kernel (tapm_opt.plant.fem_kernel) against the numpy reference path.

The two implementations of ``FEMLines.step`` / ``FEMLines.advance`` must give the same positions,
velocities and tensions to 1e-12 (relative to the largest value) over a few hundred steps of lines
that exercise every term: internal damping, seabed contact with Coulomb friction, a depth-varying
current, settling damping, a line that breaks and a winch that changes a line's length. The same
for the plant and the forced-motion analysis run on either kernel; the batched advance against
single steps; the block-held current against a current evaluated every step; the array semantics
of the state; the fallback without numba.
"""

from __future__ import annotations

import copy
import dataclasses
import functools
import importlib.util
import math
import sys
import warnings

import numpy as np
import pytest

import tapm_opt
from tapm_opt.config import Fault, scenario_from_dict, scenario_to_dict
from tapm_opt.errors import ModelError
from tapm_opt.plant import fem as fem_module
from tapm_opt.plant.fem import KERNELS, FEMLines, set_default_kernel
from tapm_opt.plant.forced_motion import forced_motion
from tapm_opt.plant.mooring_fem import MooringFEM, line_set_from_scenario
from tapm_opt.plant.simulator import Plant, ThrusterCommand

ZERO = np.zeros(3)
TOL = 1e-12


@functools.lru_cache(maxsize=None)
def scenario(name: str):
    return tapm_opt.load_scenario(name)


def rel_diff(a: np.ndarray, b: np.ndarray) -> float:
    """Largest difference relative to the largest magnitude of ``a``."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    return float(np.max(np.abs(a - b)) / max(float(np.max(np.abs(a))), 1e-300))


def current_field(z: np.ndarray) -> np.ndarray:
    """A sheared current: 1.2 m/s at the surface falling to 0.2 m/s at 1000 m, toward +x+y."""
    s = 1.2 - 1.0e-3 * np.clip(z, 0.0, 1000.0)
    return np.column_stack([0.8 * s, 0.6 * s, np.zeros_like(s)])


@pytest.fixture(scope="module", autouse=True)
def numba_kernel_compiled():
    """numba is installed and the default kernel is the compiled one; the kernel is loaded once for
    the module (compiled on the first run on a machine, then loaded from numba's disk cache)."""
    sc = scenario("aamo4")
    m = MooringFEM(sc, segments=4)
    m.initialise(ZERO)
    assert m.fem.kernel == "numba"
    m.step(ZERO, ZERO)


def twin_lines(name: str, *, friction: float):
    """The scenario's lines on both kernels, placed on the catenary, with seabed friction
    ``friction`` on every other line (on every section of a composite line, whose sections carry
    their own friction); the MooringFEM that gives the fairlead kinematics."""
    sc = scenario(name)
    ls = line_set_from_scenario(sc)
    mu = np.where(np.arange(len(ls.ids)) % 2 == 0, friction, 0.0)
    sections = ls.sections if ls.sections is None else tuple(
        None if s is None else dict(s, mu=np.full_like(s["mu"], mu[j])) for j, s in enumerate(ls.sections))
    ls = dataclasses.replace(ls, mu=mu, sections=sections)
    env = sc.environment
    m = MooringFEM(sc)
    fems = {k: FEMLines(ls, np.array(sc.anchors), water_depth=env.water_depth, rho_w=env.water_density, kernel=k)
            for k in KERNELS}
    ref = fems["numpy"]
    m.fem = ref
    m.initialise(ZERO)
    free = ~ref.fixed
    depth = ref.depth
    if not np.any(ref.r[free, 2] > depth - 0.05):  # lines hanging free (aamo4): raise the seabed
        depth = float(np.max(ref.r[free, 2])) - 0.05  # under the lowest nodes, 5 cm into them
    for f in fems.values():
        f.r, f.v, f.anchors, f.depth = ref.r.copy(), ref.v.copy(), ref.anchors.copy(), depth
    return m, fems


def drive(m: MooringFEM, fem: FEMLines, *, n_steps: int = 300, block: int = 1, seen=None):
    """Run ``n_steps`` steps with a moving vessel and a sheared current: settling damping for the
    first 40 steps, line 2 breaks at step 100, line 1 pays out 30 m (winch) at step 150. Steps go
    in blocks of ``block`` through ``advance`` (the current held over a block), or one by one
    through ``step`` when ``block == 1``. Returns the tensions of the last step."""
    dt = m.dt
    T = None
    i = 0
    while i < n_steps:
        n = min(block, n_steps - i, *(e - i for e in (40, 100, 150) if e > i))
        t = (i + np.arange(1, n + 1)) * dt
        eta = np.column_stack([8.0 * np.sin(0.9 * t), 3.0 * np.sin(0.6 * t), 0.05 * np.sin(0.7 * t)])
        eta_dot = np.column_stack([7.2 * np.cos(0.9 * t), 1.8 * np.cos(0.6 * t), 0.035 * np.cos(0.7 * t)])
        r_seq, v_seq = m.fairlead_states(eta, eta_dot)
        vc = current_field(fem.r[:, 2])
        damping = 0.5 if i < 40 else 0.0
        if block == 1:
            T = fem.step(dt, r_seq[0], v_seq[0], vc, extra_damping=damping)
        else:
            T = fem.advance(dt, r_seq, v_seq, vc, extra_damping=damping)
        i += n
        if i == 100:
            fem.break_line(1)
        if i == 150:
            fem.L[0] += 30.0
            fem._update_lengths()
        if seen is not None:
            seen(fem)
    return T


def contact_and_friction(fem: FEMLines, record: dict) -> None:
    """Record how many nodes were on the seabed and sliding on a line with friction."""
    on = fem.r[:, 2] > fem.depth
    sliding = on & (fem._mu > 0) & (np.hypot(fem.v[:, 0], fem.v[:, 1]) > 1e-3)
    record["on"] = max(record.get("on", 0), int(on.sum()))
    record["sliding"] = max(record.get("sliding", 0), int(sliding.sum()))


# ------------------------------------------------------------------------------------------
# the kernel against the numpy path
# ------------------------------------------------------------------------------------------

@pytest.mark.parametrize("name", ["aamo4", "fpso"])
def test_numba_step_equals_numpy_step(name):
    """300 single steps with every force term active: equal to 1e-12 relative."""
    m, fems = twin_lines(name, friction=0.6)
    record: dict = {}
    out = {}
    for k, fem in fems.items():
        T = drive(m, fem, seen=(lambda f: contact_and_friction(f, record)) if k == "numpy" else None)
        out[k] = (fem.r, fem.v, T, fem.t)
    (r0, v0, T0, t0), (r1, v1, T1, t1) = out["numpy"], out["numba"]
    assert rel_diff(r0, r1) <= TOL
    assert rel_diff(v0, v1) <= TOL
    assert rel_diff(T0, T1) <= TOL
    assert t0 == t1
    # the run exercised what it claims to
    fem = fems["numba"]
    assert record["on"] > 0 and record["sliding"] > 0, record
    assert np.any(fem._c_int > 0)
    assert not fem.active[1]
    j = 1
    assert np.linalg.norm(fem.r[fem.fairlead_idx[j]] - m.fairlead_state(ZERO, ZERO)[0][j]) > 1.0  # fell free
    assert fem.L[0] == pytest.approx(float(scenario(name).line_arrays["L"][0]) + 30.0)
    assert float(np.max(np.abs(v1))) > 0.1


@pytest.mark.parametrize("name", ["aamo4", "fpso"])
def test_numba_advance_equals_numpy_advance_and_single_steps(name):
    """Blocks of 16 steps through ``advance``: the numba and numpy paths agree to 1e-12, and the
    numba advance equals the numba single steps given the same held current."""
    m, fems = twin_lines(name, friction=0.6)
    T = {k: drive(m, f, block=16) for k, f in fems.items()}
    assert rel_diff(fems["numpy"].r, fems["numba"].r) <= TOL
    assert rel_diff(fems["numpy"].v, fems["numba"].v) <= TOL
    assert rel_diff(T["numpy"], T["numba"]) <= TOL
    assert fems["numpy"].t == fems["numba"].t


def test_advance_returns_the_tensions_of_its_last_step():
    m, fems = twin_lines("aamo4", friction=0.0)
    a = fems["numba"]
    b = FEMLines(a.lines, a.anchors, water_depth=a.depth, rho_w=a.rho_w, kernel="numba")
    b.r, b.v = a.r.copy(), a.v.copy()
    r_seq, v_seq = m.fairlead_states(np.zeros((5, 3)), np.zeros((5, 3)))
    vc = np.zeros((a.n_nodes, 3))
    T = a.advance(m.dt, r_seq, v_seq, vc)
    for i in range(5):
        Ti = b.step(m.dt, r_seq[i], v_seq[i], vc)
    np.testing.assert_array_equal(T, Ti)
    np.testing.assert_array_equal(a.r, b.r)


@pytest.mark.parametrize("kernel", KERNELS)
def test_state_arrays_are_replaced_not_overwritten(kernel):
    """After a step ``r`` and ``v`` are new arrays; arrays held from before keep their values, and
    in-place edits of the current state are seen by the next step (both kernels)."""
    m = MooringFEM(scenario("aamo4"), segments=6)
    m.fem.kernel = kernel
    m.initialise(ZERO)
    fem = m.fem
    r_old, v_old = fem.r, fem.v
    r_copy = r_old.copy()
    m.step(np.array([1.0, 0.0, 0.0]), np.array([0.5, 0.0, 0.0]))
    assert fem.r is not r_old and fem.v is not v_old
    np.testing.assert_array_equal(r_old, r_copy)
    assert np.any(fem.r != r_old)
    fem.r[3, 1] += 1.0  # a user's in-place edit
    r_edit = fem.r.copy()
    fem.step(m.dt, fem.r[fem.fairlead_idx].copy(), np.zeros((4, 3)), np.zeros((fem.n_nodes, 3)))
    assert fem.r[3, 1] == pytest.approx(r_edit[3, 1], abs=0.1)
    assert fem.t == pytest.approx(2 * m.dt, rel=1e-15)


def test_winch_lengths_reach_the_kernel():
    """A length change through _update_lengths is seen by the compiled kernel at once (it reads
    the arrays, not copies): one step after paying out equals the numpy step."""
    m, fems = twin_lines("fpso", friction=0.0)
    r_fl, v_fl = m.fairlead_state(ZERO, ZERO)
    vc = np.zeros((fems["numpy"].n_nodes, 3))
    T = {}
    for k, f in fems.items():
        f.step(m.dt, r_fl, v_fl, vc)
        f.L[:] = f.L - 40.0
        f._update_lengths()
        T[k] = f.step(m.dt, r_fl, v_fl, vc)
    assert rel_diff(T["numpy"], T["numba"]) <= TOL
    assert rel_diff(fems["numpy"].v, fems["numba"].v) <= TOL


# ------------------------------------------------------------------------------------------
# users of the kernel: MooringFEM.advance, the plant, forced motion
# ------------------------------------------------------------------------------------------

def test_mooring_advance_equals_steps_in_still_water():
    """MooringFEM.advance over a pose sequence = MooringFEM.step pose by pose (still water)."""
    sc = scenario("fpso")
    ms = [MooringFEM(sc, segments=10) for _ in range(2)]
    for m in ms:
        m.initialise(ZERO)
        m.settle(ZERO, max_time=20.0, strict=False)
    t = np.arange(1, 61) * ms[0].dt
    eta = np.column_stack([5.0 * np.sin(t), 2.0 * np.sin(0.5 * t), 0.02 * np.sin(t)])
    eta_dot = np.column_stack([5.0 * np.cos(t), 1.0 * np.cos(0.5 * t), 0.02 * np.cos(t)])
    Ta = ms[0].advance(eta, eta_dot)
    for i in range(len(t)):
        Tb = ms[1].step(eta[i], eta_dot[i])
    assert rel_diff(Tb, Ta) <= TOL
    assert rel_diff(ms[1].fem.r, ms[0].fem.r) <= TOL
    assert rel_diff(ms[1].tau(eta[-1]), ms[0].tau(eta[-1])) <= TOL


@pytest.mark.parametrize("mode", ["free", "locked"])
def test_fairlead_states_equal_fairlead_state_pose_by_pose(mode):
    """The vectorised kinematics of MooringFEM.advance = fairlead_state at each pose, for a
    weathervaning and a locked turret off the vessel's origin; bad shapes are refused."""
    data = scenario_to_dict(scenario("fpso"))
    data["turret"]["mode"] = mode
    m = MooringFEM(scenario_from_dict(data), segments=4)
    assert np.any(m.geometry.p_cot_B != 0.0)
    t = np.linspace(0.0, 40.0, 9)
    eta = np.column_stack([30.0 * np.sin(0.1 * t), -20.0 * np.cos(0.07 * t), 0.4 * np.sin(0.05 * t)])
    eta_dot = np.column_stack([3.0 * np.cos(0.1 * t), 1.4 * np.sin(0.07 * t), 0.02 * np.cos(0.05 * t)])
    r, v = m.fairlead_states(eta, eta_dot)
    assert r.shape == v.shape == (len(t), m.fem.n_lines, 3)
    for i in range(len(t)):
        ri, vi = m.fairlead_state(eta[i], eta_dot[i])
        assert rel_diff(ri, r[i]) <= 1e-14 and rel_diff(vi, v[i]) <= 1e-14
    with pytest.raises(ModelError, match=r"expected \(n, 3\) or \(n, 6\) each"):
        m.fairlead_states(eta[:, :2], eta_dot[:, :2])


@pytest.mark.parametrize("name,sea_state", [("fpso", "normal"), ("aamo4", "tidal")])
def test_block_held_current_is_a_tiny_approximation(name, sea_state):
    """The current held over 0.1 s blocks (MooringFEM.advance, as the plant does) against the
    current re-evaluated every step (MooringFEM.step), vessel surging at up to 2 m/s for 30 s.

    fpso's 'normal' current is sheared (0.8 m/s, a piecewise profile over depth): the fairlead
    tensions and the load on the vessel differ by ~2.5e-5 of their size (bound 1e-4; a FEM step
    half as long changes the tensions by ~5e-4). aamo4's 'tidal' current is uniform over depth:
    holding it changes nothing (1e-12)."""
    from tapm_opt.plant.environment import CurrentProfile

    sc = scenario(name)
    current = CurrentProfile(sc.sea_state(sea_state), sc.environment.water_depth).velocity
    ms = [MooringFEM(sc, segments=10, current=current) for _ in range(2)]
    for m in ms:
        m.initialise(ZERO)
        m.settle(ZERO, max_time=20.0, strict=False)
    dt = ms[0].dt
    n_block = max(1, int(0.1 / dt))
    n = n_block * int(round(30.0 / (n_block * dt)))
    t = np.arange(1, n + 1) * dt
    eta = np.column_stack([10.0 * np.sin(0.2 * t), np.zeros(n), np.zeros(n)])
    eta_dot = np.column_stack([2.0 * np.cos(0.2 * t), np.zeros(n), np.zeros(n)])
    for i in range(0, n, n_block):
        ms[0].advance(eta[i:i + n_block], eta_dot[i:i + n_block])
    for i in range(n):
        ms[1].step(eta[i], eta_dot[i])
    T_block, T_step = ms[0].fairlead_tension(), ms[1].fairlead_tension()
    tau_block, tau_step = ms[0].tau(eta[-1]), ms[1].tau(eta[-1])
    d_T = float(np.max(np.abs(T_block - T_step) / T_step))
    d_tau = float(np.max(np.abs(tau_block - tau_step)) / np.max(np.abs(tau_step)))
    if name == "aamo4":
        assert d_T <= TOL and d_tau <= TOL, (d_T, d_tau)
    else:
        assert 1e-7 < d_T < 1e-4, d_T  # not identical (the nodes move through the shear) ...
        assert d_tau < 1e-4, d_tau      # ... but tiny


def _winch_variant():
    d = copy.deepcopy(scenario_to_dict(scenario("aamo4")))
    d["lines"][0].update(winch_max_rate=0.5, min_length=2240.0, max_length=2265.0)
    return scenario_from_dict(d)


@pytest.mark.parametrize("case", ["still water, winch, line break", "current, waves, wind"])
def test_plant_runs_agree_on_both_kernels(case):
    """The same plant run on the numba and the numpy kernel (settling included): every logged
    channel agrees to 1e-12 relative to its own range."""
    if case.startswith("still"):
        make = dict(scenario=_winch_variant(), sea_state="none",
                    faults=[Fault(kind="line_break", time=6.0, line="3")])
        winch, duration = [0.5, 0.0, 0.0, 0.0], 12.0
    else:
        make = dict(scenario=scenario("fpso"), sea_state="normal")
        winch, duration = None, 8.0
    rows = {}
    for k in KERNELS:
        previous = set_default_kernel(k)
        try:
            p = Plant(make["scenario"], sea_state=make["sea_state"], segments=10, seed=3, faults=make.get("faults"))
        finally:
            set_default_kernel(previous)
        assert p.mooring.fem.kernel == k
        cmd = ThrusterCommand(0.3 * p.thrusters.limits.f_max, None) if p.thrusters.n else None
        out = []
        for _ in range(int(duration / 0.5)):
            p.step(0.5, cmd, winch_cmd=winch)
            out.append(p.sample_row())
        rows[k] = np.array(out)
        rows[k + " events"] = p.events
    a, b = rows["numpy"], rows["numba"]
    scale = np.maximum(np.max(np.abs(a), axis=0), 1e-300)
    assert float(np.max(np.abs(a - b) / scale)) <= TOL
    assert rows["numpy events"] == rows["numba events"]
    if case.startswith("still"):
        assert rows["numba events"] and "line 3 broke" in rows["numba events"][0][1]


def test_forced_motion_agrees_on_both_kernels():
    """forced_motion (fpso sway in its 'normal' current, 2 cycles) on either kernel: outputs
    to 1e-12."""
    res = {}
    for k in KERNELS:
        previous = set_default_kernel(k)
        try:
            res[k] = forced_motion(scenario("fpso"), dof="sway", amplitude=8.0, period=20.0, duration=40.0,
                                   segments=10, dt_out=0.5, sea_state="normal")
        finally:
            set_default_kernel(previous)
    a, b = res["numpy"], res["numba"]
    np.testing.assert_array_equal(a.t, b.t)
    assert rel_diff(a.T, b.T) <= TOL
    assert rel_diff(a.force, b.force) <= TOL
    assert b.damping == pytest.approx(a.damping, rel=TOL)
    assert math.isfinite(b.damping) and b.damping > 0


# ------------------------------------------------------------------------------------------
# options, errors, fallback
# ------------------------------------------------------------------------------------------

def test_kernel_option_and_errors():
    sc = scenario("aamo4")
    m = MooringFEM(sc, segments=4)
    fem = m.fem
    assert fem.kernel == "numba"
    fem.kernel = "numpy"
    assert fem.kernel == "numpy"
    with pytest.raises(ModelError, match=r"kernel = 'fortran' must be one of 'numba', 'numpy'"):
        fem.kernel = "fortran"
    with pytest.raises(ModelError, match="kernel"):
        set_default_kernel("C")
    m.initialise(ZERO)
    for k in KERNELS:
        fem.kernel = k
        with pytest.raises(ModelError, match=r"expected \(n_steps, 4, 3\)"):
            fem.advance(m.dt, np.zeros((3, 5, 3)), np.zeros((3, 5, 3)), np.zeros((fem.n_nodes, 3)))
        with pytest.raises(ModelError, match="at least one step"):
            fem.advance(m.dt, np.zeros((0, 4, 3)), np.zeros((0, 4, 3)), np.zeros((fem.n_nodes, 3)))
    fem.kernel = "numba"
    with pytest.raises(ModelError, match=r"v_current has shape \(7, 3\)"):
        fem.step(m.dt, np.zeros((4, 3)), np.zeros((4, 3)), np.zeros((7, 3)))
    with pytest.raises(ModelError, match=r"fairlead_r has shape \(5, 3\)"):
        fem.step(m.dt, np.zeros((5, 3)), np.zeros((4, 3)), np.zeros((fem.n_nodes, 3)))


def test_uniform_current_vector_broadcasts_as_in_the_numpy_path():
    """A (3,) current (one velocity for every node) is accepted by both kernels alike."""
    m, fems = twin_lines("aamo4", friction=0.0)
    r_fl, v_fl = m.fairlead_state(ZERO, ZERO)
    for f in fems.values():
        f.step(m.dt, r_fl, v_fl, np.array([0.5, 0.2, 0.0]))
    assert rel_diff(fems["numpy"].v, fems["numba"].v) <= TOL


def test_without_numba_the_numpy_path_is_used_with_a_warning(monkeypatch):
    """If numba cannot be imported, importing the kernel module warns and FEMLines runs numpy."""
    path = fem_module.__file__.replace("fem.py", "fem_kernel.py")
    monkeypatch.setitem(sys.modules, "numba", None)  # makes ``import numba`` fail
    spec = importlib.util.spec_from_file_location("tapm_opt.plant._fem_kernel_without_numba", path)
    mod = importlib.util.module_from_spec(spec)
    with pytest.warns(RuntimeWarning, match="numba is not available.*numpy path"):
        spec.loader.exec_module(mod)
    assert mod.AVAILABLE is False
    monkeypatch.setitem(sys.modules, "tapm_opt.plant.fem_kernel", mod)
    monkeypatch.setattr(sys.modules["tapm_opt.plant"], "fem_kernel", mod, raising=False)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        m = MooringFEM(scenario("aamo4"), segments=4)
    assert m.fem.kernel == "numpy"
    m.initialise(ZERO)
    m.step(ZERO, ZERO)
    assert np.all(np.isfinite(m.fem.r))


@pytest.mark.parametrize("name", ["aamo4", "fpso"])
def test_fairlead_forces_along_the_path_equal_fairlead_forces(name):
    """advance(fairlead_force_out=...) gives, at the start of every step, the fairlead forces
    (tension, weight, drag with the current at the fairleads) on both kernels."""
    m, fems = twin_lines(name, friction=0.0)
    n = 25
    t = np.arange(1, n + 1) * m.dt
    eta = np.column_stack([8.0 * np.sin(0.9 * t), 3.0 * np.sin(0.6 * t), 0.05 * np.sin(0.7 * t)])
    eta_dot = np.column_stack([7.2 * np.cos(0.9 * t), 1.8 * np.cos(0.6 * t), 0.035 * np.cos(0.7 * t)])
    r_seq, v_seq = m.fairlead_states(eta, eta_dot)
    out = {}
    for k, fem in fems.items():
        fem.break_line(1)
        vc = current_field(fem.r[:, 2])
        ref = fem.fairlead_forces(vc[fem.fairlead_idx])
        out[k] = np.zeros((n, fem.n_lines, 3))
        fem.advance(m.dt, r_seq, v_seq, vc, fairlead_force_out=out[k])
        assert rel_diff(out[k][0], ref) < 1e-12
        assert np.all(out[k][:, 1] == 0.0)               # the broken line loads nothing
        assert np.ptp(out[k][:, 0, 0]) > 0.0             # the forces follow the motion
        last = fem.fairlead_forces(vc[fem.fairlead_idx])  # after the last step: not in the output
        assert rel_diff(out[k][-1], last) > 0.0
    assert rel_diff(out["numba"], out["numpy"]) < 1e-12
    with pytest.raises(ModelError, match="fairlead_force_out"):
        fems["numpy"].advance(m.dt, r_seq, v_seq, current_field(fems["numpy"].r[:, 2]),
                              fairlead_force_out=np.zeros((n - 1, fems["numpy"].n_lines, 3)))
