"""Speed of the compiled FEM kernel against the numpy path, in the same process.

Printed figures, not a timed test. Run from the repository root::

    python benchmarks/bench_fem_kernel.py [--repeats 5] [--steps 4000] [--plant-duration 60]
                                          [--compile-time]

For ``aamo4`` (4 lines x 20 segments, 84 nodes) and ``fpso`` (12 lines x 20 segments, 252 nodes),
with the kernel "numpy" (the vectorised reference) and "numba" (``tapm_opt.plant.fem_kernel``),
microseconds per FEM step (median of the repeats, min-max in brackets) of

* ``FEMLines.step``: one call per step, the fairleads on a surging/yawing path (positions and
  velocities computed beforehand), still water;
* ``FEMLines.advance``: the same steps in batches (of the plant's substep count and of 64);
* ``MooringFEM.step``: one call per step including the fairlead kinematics and the current look-up,
  and ``MooringFEM.advance`` in batches of the plant's substep count (vectorised kinematics);
* the plant path: ``Plant(scenario, sea_state="none")`` + ``plant.step(duration)``, wall time per
  FEM substep (the whole outer step: vessel, thrusters, mooring load, tension checks, divided by
  its substeps), and the part of it spent in the substeps (``MooringFEM.advance``: kinematics +
  kernel);
* ``forced_motion`` (surge, A = 20 m, T = 100 s, 300 s, dt_out 1 s): real-time factor of the whole
  call and of the stepping loop (whole call minus a separately timed set-up), and the loop's
  microseconds per FEM step;

and the ratio numpy / numba of each (of the medians, and of the minima: the least disturbed
repeats, on a shared machine). The numba and numpy states are compared after each timed
run (largest relative difference printed), so a fast wrong answer cannot pass for a result.
``--compile-time`` also runs two fresh processes on a temporary numba cache directory, the first
with it empty (cold compile), the second with it filled by the first (cache load), and prints the
time of their first FEM step.
"""

from __future__ import annotations

import argparse
import math
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _machine import machine_info  # noqa: E402

import tapm_opt  # noqa: E402
from tapm_opt.plant.fem import KERNELS, set_default_kernel  # noqa: E402
from tapm_opt.plant.forced_motion import forced_motion  # noqa: E402
from tapm_opt.plant.mooring_fem import MooringFEM  # noqa: E402
from tapm_opt.plant.simulator import Plant  # noqa: E402

SCENARIOS = ("aamo4", "fpso")
SURGE = dict(dof="surge", amplitude=20.0, period=100.0, duration=300.0, dt_out=1.0, segments=20)
ZERO = np.zeros(3)


def stats(values):
    v = np.asarray(values, dtype=float)
    return float(np.median(v)), float(v.min()), float(v.max())


def fmt(s):
    return f"{s[0]:8.2f} [{s[1]:.2f}-{s[2]:.2f}]"


class Kernel:
    """``with Kernel("numpy"):`` builds every FEMLines on that kernel."""

    def __init__(self, kernel: str):
        self.kernel = kernel

    def __enter__(self):
        self.previous = set_default_kernel(self.kernel)

    def __exit__(self, *exc):
        set_default_kernel(self.previous)


def settled(name: str) -> MooringFEM:
    """The scenario's lines settled at the field zero point (20 segments, the scenario's own)."""
    m = MooringFEM(tapm_opt.load_scenario(name))
    m.initialise(ZERO)
    m.settle(ZERO)
    return m


def path(m: MooringFEM, n: int):
    """Fairlead positions and velocities (n, n_lines, 3) on a surging and yawing path."""
    t = np.arange(1, n + 1) * m.dt
    eta = np.column_stack([4.0 * np.sin(0.3 * t), 1.0 * np.sin(0.2 * t), 0.02 * np.sin(0.25 * t)])
    eta_dot = np.column_stack([1.2 * np.cos(0.3 * t), 0.2 * np.cos(0.2 * t), 0.005 * np.cos(0.25 * t)])
    return eta, eta_dot


def interleaved(runs: dict, repeats: int) -> dict:
    """Median/min/max of each ``runs[k]()`` (a time per step), the kernels alternating in every
    repeat so that both see the same load on a shared machine."""
    out = {k: [] for k in runs}
    for _ in range(repeats):
        for k, run in runs.items():
            out[k].append(run())
    return {k: stats(v) for k, v in out.items()}


class FEMRun:
    """FEMLines.step (block None) or FEMLines.advance in batches of ``block``, or the same through
    MooringFEM (``mooring=True``: poses in, fairlead kinematics included), from the settled state
    ``state0``; ``__call__`` returns us per step."""

    def __init__(self, m: MooringFEM, state0, kernel: str, n: int, block: int | None = None, mooring: bool = False):
        self.m, self.kernel, self.n, self.block, self.mooring = m, kernel, n, block, mooring
        self.r0, self.v0 = state0
        self.eta, self.eta_dot = path(m, n)
        self.r_seq, self.v_seq = m.fairlead_states(self.eta, self.eta_dot)
        self.vc = np.zeros((m.fem.n_nodes, 3))
        self()  # warm-up (loads the compiled kernel)

    def __call__(self) -> float:
        m, fem, n, b = self.m, self.m.fem, self.n, self.block
        fem.kernel = self.kernel
        fem.r, fem.v = self.r0.copy(), self.v0.copy()
        t0 = time.perf_counter()
        if self.mooring and b is None:
            for i in range(n):
                m.step(self.eta[i], self.eta_dot[i])
        elif self.mooring:
            for i in range(0, n, b):
                m.advance(self.eta[i:i + b], self.eta_dot[i:i + b])
        elif b is None:
            for i in range(n):
                fem.step(m.dt, self.r_seq[i], self.v_seq[i], self.vc)
        else:
            for i in range(0, n, b):
                fem.advance(m.dt, self.r_seq[i:i + b], self.v_seq[i:i + b], self.vc)
        us = (time.perf_counter() - t0) / n * 1e6
        self.state = np.concatenate([fem.r, fem.v])
        return us


class PlantRun:
    """Plant(scenario, sea_state="none") on one kernel; ``__call__`` steps it ``duration`` seconds
    and returns us per FEM substep; ``fem_part`` collects the us per substep spent in
    MooringFEM.advance (the substeps: fairlead kinematics + kernel)."""

    def __init__(self, name: str, kernel: str, duration: float):
        with Kernel(kernel):
            self.p = Plant(tapm_opt.load_scenario(name), sea_state="none")
        self.duration, self.fem_part, self.spent = duration, [], 0.0
        m = self.p.mooring
        advance = m.advance

        def timed_advance(eta_seq, eta_dot_seq):
            t0 = time.perf_counter()
            out = advance(eta_seq, eta_dot_seq)
            self.spent += time.perf_counter() - t0
            return out

        m.advance = timed_advance
        self.p.step(1.0)  # warm-up

    def __call__(self) -> float:
        p = self.p
        s0, self.spent = p._steps, 0.0
        t0 = time.perf_counter()
        p.step(self.duration)
        wall = time.perf_counter() - t0
        n_sub = (p._steps - s0) * p._n_sub
        self.fem_part.append(self.spent / n_sub * 1e6)
        self.row = p.sample_row()
        return wall / n_sub * 1e6


class ForcedRun:
    """forced_motion (SURGE) on one kernel; ``__call__`` returns the whole call's wall time [s]
    and stores the set-up time (construction, initialisation, settling) timed after it."""

    def __init__(self, name: str, kernel: str):
        self.sc, self.kernel, self.setup = tapm_opt.load_scenario(name), kernel, []

    def __call__(self) -> float:
        with Kernel(self.kernel):
            t0 = time.perf_counter()
            self.res = forced_motion(self.sc, **SURGE)
            whole = time.perf_counter() - t0
            t0 = time.perf_counter()
            plant = MooringFEM(self.sc, segments=SURGE["segments"])
            every = int(math.ceil(SURGE["dt_out"] / plant.dt - 1e-9))
            plant.dt = SURGE["dt_out"] / every
            plant.initialise(ZERO)
            plant.settle(ZERO)
            self.setup.append(time.perf_counter() - t0)
        return whole


def rel(a, b) -> float:
    a, b = np.asarray(a, float), np.asarray(b, float)
    return float(np.max(np.abs(a - b)) / max(float(np.max(np.abs(a))), 1e-300))


COMPILE_PROBE = """
import time
t0 = time.perf_counter()
import numpy as np, tapm_opt
from tapm_opt.plant.mooring_fem import MooringFEM
m = MooringFEM(tapm_opt.load_scenario("aamo4"))
m.initialise(np.zeros(3))
t1 = time.perf_counter()
m.step(np.zeros(3), np.zeros(3))
t2 = time.perf_counter()
m.step(np.zeros(3), np.zeros(3))
t3 = time.perf_counter()
print(f"{t1 - t0:.3f} {t2 - t1:.3f} {1e6 * (t3 - t2):.0f}")
"""


def compile_times() -> None:
    def probe(env):
        out = subprocess.run([sys.executable, "-c", COMPILE_PROBE], env=env, capture_output=True, text=True,
                             check=True).stdout.split()
        return float(out[0]), float(out[1]), float(out[2])

    with tempfile.TemporaryDirectory() as d:
        cold = probe({**os.environ, "NUMBA_CACHE_DIR": d})
        loaded = probe({**os.environ, "NUMBA_CACHE_DIR": d})
    print("first FEM step in a new process (import + construction + initialisation before it):")
    for label, (setup, first, nxt) in (("empty numba cache (cold compile)", cold), ("cache filled (load)", loaded)):
        print(f"  {label:33s} {first:.2f} s (import and set-up before it {setup:.2f} s, next step {nxt:.0f} us)")


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=5, help="repeats of each timing (median)")
    ap.add_argument("--steps", type=int, default=4000, help="FEM steps per raw timing")
    ap.add_argument("--plant-duration", type=float, default=60.0, help="simulated time per plant timing [s]")
    ap.add_argument("--forced-repeats", type=int, default=3, help="repeats of the forced-motion timing")
    ap.add_argument("--compile-time", action="store_true", help="also time the cold compile and the cache load")
    args = ap.parse_args(argv)
    import numba

    print(machine_info(f"numba {numba.__version__}"))
    if args.compile_time:
        compile_times()
    reps, n = max(1, args.repeats), max(64, args.steps)
    for name in SCENARIOS:
        m = settled(name)
        state0 = (m.fem.r.copy(), m.fem.v.copy())
        print(f"\n{name}: {m.fem.n_lines} lines, {m.fem.n_nodes} nodes, FEM step {m.dt * 1e3:.2f} ms")
        print(f"  {'us per FEM step (median [min-max])':40s} {'numpy':>22s} {'numba':>22s}   ratio (of mins)"
              "  max rel. diff")
        plants = {k: PlantRun(name, k, args.plant_duration) for k in KERNELS}
        n_sub = plants["numba"].p._n_sub
        rows = []
        for label, kw in (("FEMLines.step", {}), (f"FEMLines.advance, batches of {n_sub}", dict(block=n_sub)),
                          ("FEMLines.advance, batches of 64", dict(block=64)),
                          ("MooringFEM.step", dict(mooring=True)),
                          (f"MooringFEM.advance, batches of {n_sub}", dict(mooring=True, block=n_sub))):
            runs = {k: FEMRun(m, state0, k, n, **kw) for k in KERNELS}
            res = interleaved(runs, reps)
            rows.append((label, res["numpy"], res["numba"], rel(runs["numpy"].state, runs["numba"].state)))
        res = interleaved(plants, reps)
        diff = rel(plants["numpy"].row, plants["numba"].row)
        rows.append((f"Plant.step per FEM substep ({n_sub} per 0.1 s)", res["numpy"], res["numba"], diff))
        rows.append(("  of which in the substeps (advance)", stats(plants["numpy"].fem_part),
                     stats(plants["numba"].fem_part), diff))
        for label, a, b, d in rows:
            print(f"  {label:40s} {fmt(a):>22s} {fmt(b):>22s} {a[0] / b[0]:6.1f}x ({a[1] / b[1]:4.1f}x)  {d:.1e}")
        forced = {k: ForcedRun(name, k) for k in KERNELS}
        fr = max(1, args.forced_repeats)
        whole = interleaved(forced, fr)
        res = forced["numba"].res
        n_steps = int(round(SURGE["duration"] / res.dt))
        d = max(rel(forced["numpy"].res.T, res.T), rel(forced["numpy"].res.force, res.force))
        print(f"  forced_motion, surge 300 s, FEM step {res.dt * 1e3:.2f} ms ({n_steps} steps), median of {fr}:")
        us = {}
        for k in KERNELS:
            t_whole, t_setup = whole[k][0], float(np.median(forced[k].setup))
            loop = max(t_whole - t_setup, 1e-9)
            us[k] = loop / n_steps * 1e6
            print(f"    {k:5s}: real-time factor {SURGE['duration'] / t_whole:6.0f}x whole call, "
                  f"{SURGE['duration'] / loop:6.0f}x stepping loop, {us[k]:6.1f} us per FEM step")
        print(f"    ratio (loop us per step) {us['numpy'] / us['numba']:.1f}x; max rel. diff of the tensions and "
              f"loads {d:.1e}")


if __name__ == "__main__":
    main()
