"""Speed of the FEM mooring plant: real-time factors of forced motion and of the full plant.

Printed figures, not a timed test. Run from the repository root::

    python benchmarks/bench_plant.py [--repeats 3] [--plant-duration 600] [--closed-loop]

Real-time factor (RTF) = simulated seconds per wall-clock second, one process, one thread of
Python (numpy may use more for large arrays; these arrays are small). Reported:

* aamo4 forced surge (``forced_motion``; 20 segments, amplitude 20 m, period 100 s, 300 s,
  dt_out 1 s): (a) the whole call including the catenary initialisation and settling, (b) the
  time-stepping loop alone (whole call minus a separately timed set-up: construction,
  initialisation, settling), the FEM step, and the largest tension difference against a run at
  half the step (safety 0.45 instead of 0.9) as a fraction of the peak tension;
* fpso full plant (``Plant`` + ``run_open_loop``; default sea state, 20 segments per line,
  600 s, log every 1 s): construction (settling) and run separately;
* scaling of the forced-motion loop with segments (10, 20, 40 on aamo4) and with lines (aamo4 4,
  ren8 8, fpso 12 lines at 20 segments), with the cost per node and FEM step.

With ``--closed-loop`` only: the PID closed loop of ``tapm simulate fpso --controller pid
--sea-state normal --duration 600`` (the same plant, controller and settings, in this process) at 20
and 10 segments per line, as the CLI's figure (plant construction with settling + run) and the run
alone, with the compiled outer step (``Plant.compiled``, the default) and with the numpy outer step
alternated in each repeat, and their ratio (the numpy step's time over the compiled one's, per
repeat, then the median: the ratio is steadier than either time on a shared machine).

Targets: aamo4 forced motion >= 250x real time, fpso full plant >= 100x, PID closed loop >= 400x.
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_catenary import machine_info  # noqa: E402

import tapm_opt  # noqa: E402
from tapm_opt.plant.forced_motion import forced_motion  # noqa: E402
from tapm_opt.plant.mooring_fem import MooringFEM  # noqa: E402
from tapm_opt.plant.simulator import Plant, run_open_loop  # noqa: E402

SURGE = dict(dof="surge", amplitude=20.0, period=100.0, duration=300.0, dt_out=1.0)
TARGET_FORCED = 250.0
TARGET_PLANT = 100.0
TARGET_CLOSED = 400.0


def closed_loop_times(segments: int, duration: float, compiled: bool) -> tuple[float, float]:
    """(construction + run, run) wall times [s] of the fpso PID closed loop in the normal sea state."""
    from tapm_opt.models.system import System
    from tapm_opt.studies.closed_loop import DEFAULT_ESTIMATOR, ClosedLoopSettings, run_closed_loop
    from tapm_opt.studies.controllers import build_controller

    system = System.from_scenario(tapm_opt.load_scenario("fpso"))
    ctrl = build_controller(system, {"type": "pid"}, where="--option", dt_control=1.0,
                            estimator=DEFAULT_ESTIMATOR, winch=None)
    settings = ClosedLoopSettings(duration=duration, dt_control=1.0, dt_log=1.0)
    t0 = time.perf_counter()
    plant = Plant(system, sea_state="normal", seed=0, segments=segments)
    plant.compiled = compiled
    t1 = time.perf_counter()
    run_closed_loop(plant, ctrl, settings, system=system)
    t2 = time.perf_counter()
    return t2 - t0, t2 - t1


def closed_loop_section(duration: float, repeats: int) -> None:
    """Print the PID closed-loop real-time factors, compiled and numpy outer step (module docstring)."""
    closed_loop_times(10, 20.0, True)  # warm-up: compile or load the kernels
    print(f"fpso PID closed loop, normal sea, {duration:g} s simulated, median of {repeats} "
          f"(alternating compiled / numpy outer step):")
    print(f"  {'segments':>8} {'outer step':>10} {'CLI wall RTF':>13} {'run RTF':>8} {'numpy/compiled':>15}")
    for seg in (20, 10):
        times = {True: [], False: []}
        for _ in range(repeats):
            for compiled in (True, False):
                times[compiled].append(closed_loop_times(seg, duration, compiled))
        ratio = float(np.median([n[1] / c[1] for c, n in zip(times[True], times[False])]))
        for compiled in (True, False):
            wall = float(np.median([t[0] for t in times[compiled]]))
            run = float(np.median([t[1] for t in times[compiled]]))
            mark = f"[target >= {TARGET_CLOSED:.0f}x]" if compiled else ""
            print(f"  {seg:>8} {'compiled' if compiled else 'numpy':>10} {duration / wall:>12.0f}x "
                  f"{duration / run:>7.0f}x {ratio if compiled else 1.0:>14.2f}x {mark}")


def median_time(fn, repeats: int):
    """Median wall time [s] of ``fn()`` over ``repeats`` calls, and the last return value."""
    times, out = [], None
    for _ in range(repeats):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return float(np.median(times)), float(np.min(times)), float(np.max(times)), out


def setup_only(sc, *, segments: int, safety: float = 0.9, dt_out: float = 1.0):
    """The set-up part of ``forced_motion``: construction, step choice, initialisation, settling."""
    plant = MooringFEM(sc, segments=segments, safety=safety)
    every = int(math.ceil(dt_out / plant.dt - 1e-9))
    plant.dt = dt_out / every
    plant.initialise(np.zeros(3))
    plant.settle(np.zeros(3))
    return plant


def forced_figures(sc, segments: int, repeats: int, safety: float = 0.9):
    """(whole-call time, set-up time, result) for the standard forced surge."""
    t_all, lo, hi, res = median_time(lambda: forced_motion(sc, segments=segments, safety=safety, **SURGE), repeats)
    t_set, _, _, plant = median_time(lambda: setup_only(sc, segments=segments, safety=safety), repeats)
    return t_all, t_set, res, plant, (lo, hi)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=3, help="repeats of each forced-motion timing (median)")
    ap.add_argument("--plant-duration", type=float, default=600.0, help="simulated time of the fpso plant run [s]")
    ap.add_argument("--closed-loop", action="store_true",
                    help="time only the PID closed loop (20 and 10 segments, compiled and numpy outer step)")
    args = ap.parse_args(argv)
    reps = max(1, args.repeats)
    print(machine_info())
    if hasattr(os, "getloadavg"):
        print("load average (1, 5, 15 min): " + ", ".join(f"{v:.2f}" for v in os.getloadavg())
              + "  (figures scale with it on a shared machine)")
    print()
    if args.closed_loop:
        closed_loop_section(args.plant_duration, reps)
        return None

    aamo4 = tapm_opt.load_scenario("aamo4")
    forced_motion(aamo4, segments=10, dof="surge", amplitude=1.0, period=10.0, duration=10.0)  # warm-up

    # -- aamo4 forced motion ---------------------------------------------------------------
    dur = SURGE["duration"]
    t_all, t_set, ref, plant, (lo, hi) = forced_figures(aamo4, 20, reps)
    t_loop = t_all - t_set
    n_steps = int(round(dur / ref.dt))
    print(f"aamo4 forced surge, 20 segments, A = 20 m, T = 100 s, {dur:g} s simulated, dt_out 1 s "
          f"(median of {reps}):")
    print(f"  FEM step {ref.dt * 1e3:.2f} ms ({n_steps} steps), {plant.fem.n_nodes} nodes, settling "
          f"{ref.settle.time:.0f} s simulated")
    print(f"  (a) whole call      {t_all:6.2f} s  -> {dur / t_all:6.0f}x real time  "
          f"(min {dur / hi:.0f}x, max {dur / lo:.0f}x)  [target >= {TARGET_FORCED:.0f}x]")
    print(f"      of which set-up (construct, initialise, settle) {t_set:.2f} s")
    print(f"  (b) stepping loop   {t_loop:6.2f} s  -> {dur / t_loop:6.0f}x real time  "
          f"({t_loop / n_steps * 1e6:.1f} us per FEM step)")
    half = forced_motion(aamo4, segments=20, safety=0.45, **SURGE)
    d_dt = float(np.max(np.abs(half.T - ref.T)) / np.max(ref.T))
    print(f"  convergence: half step ({half.dt * 1e3:.2f} ms) changes the tension history by at most "
          f"{d_dt:.2%} of the peak ({np.max(ref.T) / 1e6:.3f} MN)  [converged to 1 %: "
          f"{'yes' if d_dt < 0.01 else 'NO'}]; damping {ref.damping:.4g} vs {half.damping:.4g} N s/m")
    print()

    # -- fpso full plant -------------------------------------------------------------------
    fpso = tapm_opt.load_scenario("fpso")
    pdur = args.plant_duration
    t0 = time.perf_counter()
    p = Plant(fpso, segments=20, seed=1)
    t_build = time.perf_counter() - t0
    t0 = time.perf_counter()
    res = run_open_loop(p, pdur, dt_log=1.0)
    t_run = time.perf_counter() - t0
    ok = bool(np.all(np.isfinite(res.data)))
    print(f"fpso full plant, sea state {p.sea_state.id!r} (Hs {p.sea_state.Hs:g} m, current "
          f"{p.sea_state.current_speed:g} m/s), {len(fpso.lines)} lines x 20 segments, {pdur:g} s simulated:")
    print(f"  outer step {p.outer_dt:g} s, FEM step {p.fem_dt * 1e3:.2f} ms, {p.mooring.fem.n_nodes} nodes; "
          f"all channels finite: {ok}")
    print(f"  construction incl. settling {t_build:.2f} s (settled {p.settle_info.time:.0f} s simulated)")
    print(f"  run                {t_run:6.2f} s  -> {pdur / t_run:6.0f}x real time  [target >= {TARGET_PLANT:.0f}x]")
    print(f"  run + construction {t_run + t_build:6.2f} s  -> {pdur / (t_run + t_build):6.0f}x real time")
    print()

    # -- scaling ---------------------------------------------------------------------------
    print(f"scaling of forced surge (A = 20 m, T = 100 s, {dur:g} s; median of {reps}):")
    print(f"  {'case':<22} {'lines':>5} {'seg':>4} {'nodes':>6} {'FEM dt ms':>9} {'whole RTF':>10} "
          f"{'loop RTF':>9} {'us/step':>8} {'ns/node-step':>13}")
    cases = [("aamo4", 10), ("aamo4", 20), ("aamo4", 40), ("ren8", 20), ("fpso", 20)]
    for name, seg in cases:
        sc = aamo4 if name == "aamo4" else tapm_opt.load_scenario(name)
        t_all, t_set, r, pl, _ = forced_figures(sc, seg, reps)
        t_loop = t_all - t_set
        n = int(round(dur / r.dt))
        nodes = pl.fem.n_nodes
        print(f"  {name + ' ' + str(seg) + ' seg':<22} {len(sc.lines):>5} {seg:>4} {nodes:>6} {r.dt * 1e3:>9.2f} "
              f"{dur / t_all:>9.0f}x {dur / t_loop:>8.0f}x {t_loop / n * 1e6:>8.1f} "
              f"{t_loop / n / nodes * 1e9:>13.0f}")


if __name__ == "__main__":
    sys.exit(main())
