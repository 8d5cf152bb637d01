"""The closed loop's overhead over the plant it steps: fpso's storm, PID and the MPCs.

Printed figures, not a timed test. Run from the repository root::

    python benchmarks/bench_loop_overhead.py [--duration 1800] [--repeats 3] [--kinds pid,lmpc,mpc]
    python benchmarks/bench_loop_overhead.py --profile pid      # cProfile of one closed loop

Method. One process; fpso (12 lines, six azimuths), sea state ``storm``, seed 1, 10 FEM segments
per line, ``--duration`` seconds (default 1800), heading ``chasing``, the default estimator (the
EKF with the statistical tension test and the reliability monitor), ``dt_control = dt_log = 1 s``.

- **plant alone**: a ``Plant`` built like the case recipe builds it (``studies.recipe.run_case_on``:
  ``Plant(system, sea_state="storm", seed=1, segments=10)``), stepped the way ``run_closed_loop``
  steps it — ``plant.step(dt_control, cmd)`` once per control period (ten 0.1 s outer steps, each
  with its FEM substeps) and ``plant.sample_row()`` once per ``dt_log`` (the plant's share of
  the loop's logging) — with one fixed thruster command (every thruster at 30 % of its
  largest thrust, at its initial azimuth), on the plant's default path: the outer steps of a
  control period in one compiled call (``fem_kernel.plant_steps``).
- **FEM kernel**: the time inside the FEM kernel alone (the compiled ``fem_kernel.mooring_step``:
  an outer step's FEM substeps, fairlead kinematics and mooring load in one call), timed around
  each call from Python. ``plant_steps`` calls it from compiled code, where it cannot be timed
  apart, so this is a second run of the same plant, the same steps and the same command with the
  per-outer-step path forced (``Plant._multi_step = False``: ``plant_pre_step`` then
  ``mooring_step`` from Python for every outer step; the same numbers): the kernel's own time for
  those steps, as before the multi-step call. The loops' ratios to it are printed too.
- **closed loop**: a ``Plant`` built the same way, the controller from
  ``tapm_opt.design.build(system, kind)`` at the registry's defaults (``--shipped``: at fpso's shipped
  tuned designs, what ``tapm compare`` runs), and ``run_closed_loop``
  with the default estimator, setpoint layer and allocator, timed around the call (so the
  estimator's and the result's construction count; the plant's construction and settling and
  the controller's construction do not, as they do not in the plant-alone figure).

The machine is shared, so the runs interleave — plant, pid, lmpc, mpc, plant, pid, ... — and
medians are printed with their spread. The figures to compare are the ratios loop / plant alone
and loop / FEM kernel (targets, against the FEM kernel: PID <= 2, lmpc and mpc <= 3), and the tuning trials per core-hour of a one-case trial
(3600 / wall of the closed loop over ``--duration`` seconds).
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _machine import machine_info  # noqa: E402

SCENARIO, SEA_STATE, SEED, SEGMENTS = "fpso", "storm", 1, 10


def _plant(system):
    from tapm_opt.plant.simulator import Plant

    return Plant(system, sea_state=SEA_STATE, seed=SEED, segments=SEGMENTS)


def _step_plant(plant, settings) -> float:
    """Wall time of ``plant`` stepped as the closed loop steps it, with one fixed command."""
    from tapm_opt.interfaces import ThrusterCommand

    th = plant.thrusters
    f_max = np.asarray(th.limits.f_max, float)
    cmd = ThrusterCommand(f=0.3 * f_max, alpha=th.alpha.copy())
    n_steps = int(round(settings.duration / settings.dt_control))
    log_every = int(round(settings.dt_log / settings.dt_control))
    rows = []
    w0 = time.perf_counter()
    for step in range(n_steps + 1):
        if step % log_every == 0:
            rows.append(plant.sample_row())
        if step == n_steps:
            break
        plant.step(settings.dt_control, cmd)
    return time.perf_counter() - w0


def plant_alone(system, settings) -> tuple[float, float]:
    """Wall time of the plant stepped as the closed loop steps it (its default path, the outer
    steps of a control period in one compiled call), and of the FEM kernel in the same steps
    (``fem_kernel.mooring_step``, the compiled substeps of every outer step, timed on a second run
    with the per-outer-step path forced)."""
    from tapm_opt.plant import fem_kernel

    wall = _step_plant(_plant(system), settings)
    plant = _plant(system)
    plant._multi_step = False   # mooring_step called from Python, once per outer step
    inner = fem_kernel.mooring_step
    fem_time = [0.0]

    def timed(*a, **k):
        w = time.perf_counter()
        out = inner(*a, **k)
        fem_time[0] += time.perf_counter() - w
        return out

    fem_kernel.mooring_step = timed   # the kernel's time, timed apart: its wrapper adds ~0.3 us a call
    try:
        _step_plant(plant, settings)
    finally:
        fem_kernel.mooring_step = inner
    return wall, fem_time[0]


#: The shipped fpso design of each kind (``--shipped``): what ``tapm compare`` runs.
SHIPPED = {"pid": "PID", "lmpc": "MPC", "mpc": "NMPC"}
_use_shipped = False


def _spec(kind: str):
    if not _use_shipped:
        return kind
    from tapm_opt.studies.shipped import shipped_designs

    return {"design": str(shipped_designs(SCENARIO)[SHIPPED[kind]])}


def closed_loop(system, settings, kind: str) -> tuple[float, float, dict]:
    from tapm_opt.design import build
    from tapm_opt.studies import run_closed_loop

    ctrl = build(system, _spec(kind), dt_control=settings.dt_control)
    plant = _plant(system)
    w0 = time.perf_counter()
    res = run_closed_loop(plant, ctrl, settings, system=system)
    wall = time.perf_counter() - w0
    return wall, float(res.meta["wall_time"]), res.meta["diagnostics"]


def _fmt(xs: list[float]) -> str:
    return f"{statistics.median(xs):7.3f} s ({min(xs):.3f}-{max(xs):.3f})"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--duration", type=float, default=1800.0, help="simulated seconds per run")
    ap.add_argument("--repeats", type=int, default=3, help="interleaved rounds (medians are printed)")
    ap.add_argument("--kinds", default="pid,lmpc,mpc", help="controller kinds, comma-separated")
    ap.add_argument("--profile", metavar="KIND", help="cProfile one closed loop of KIND instead")
    ap.add_argument("--sort", default="tottime", help="cProfile sort key (with --profile)")
    ap.add_argument("--shipped", action="store_true",
                    help="the controllers at fpso's shipped tuned designs (what tapm compare runs), not the registry's "
                         "defaults")
    args = ap.parse_args()
    global _use_shipped
    _use_shipped = bool(args.shipped)

    import tapm_opt
    from tapm_opt.models.system import System
    from tapm_opt.studies import ClosedLoopSettings

    print(machine_info())
    system = System.from_scenario(tapm_opt.load_scenario(SCENARIO))
    settings = ClosedLoopSettings(duration=args.duration, heading="chasing")
    kinds = [k for k in args.kinds.split(",") if k]
    print(f"{SCENARIO}, {SEA_STATE}, seed {SEED}, {SEGMENTS} segments, {args.duration:g} s, heading chasing, "
          f"estimator {settings.estimator}, detector {settings.detector}")

    # warm-up: compiled kernels loaded, CasADi functions built once per process where cached
    plant_alone(system, ClosedLoopSettings(duration=20.0, heading="chasing"))
    for k in ([args.profile] if args.profile else kinds):
        closed_loop(system, ClosedLoopSettings(duration=20.0, heading="chasing"), k)

    if args.profile:
        import cProfile
        import pstats

        from tapm_opt.design import build
        from tapm_opt.studies import run_closed_loop

        ctrl = build(system, _spec(args.profile), dt_control=settings.dt_control)
        plant = _plant(system)
        pr = cProfile.Profile()
        pr.enable()
        run_closed_loop(plant, ctrl, settings, system=system)
        pr.disable()
        pstats.Stats(pr).sort_stats(args.sort).print_stats(45)
        return

    plant_t: list[float] = []
    fem_t: list[float] = []
    loop_t: dict[str, list[float]] = {k: [] for k in kinds}
    inner_t: dict[str, list[float]] = {k: [] for k in kinds}
    ratio: dict[str, list[float]] = {k: [] for k in kinds}
    ratio_fem: dict[str, list[float]] = {k: [] for k in kinds}
    ctrl_med: dict[str, list[float]] = {k: [] for k in kinds}
    for r in range(args.repeats):
        w, f = plant_alone(system, settings)
        plant_t.append(w)
        fem_t.append(f)
        print(f"round {r + 1}: plant alone {w:.3f} s (FEM kernel {f:.3f} s)", end="", flush=True)
        for k in kinds:
            wall, inner, diag = closed_loop(system, settings, k)
            loop_t[k].append(wall)
            inner_t[k].append(inner)
            ratio[k].append(wall / w)
            ratio_fem[k].append(wall / f)
            ctrl_med[k].append(diag.get("controller_time_median", 0.0) * diag.get("controller_calls", 0))
            print(f", {k} {wall:.3f} s", end="", flush=True)
        print()

    p = statistics.median(plant_t)
    print(f"\nplant alone            {_fmt(plant_t)}   real-time factor {args.duration / p:6.0f}x")
    print(f"  FEM kernel in it     {_fmt(fem_t)}   {statistics.median(fem_t) / p:.2f} of the plant; "
          f"plant alone / FEM kernel {p / statistics.median(fem_t):.2f}")
    targets = {"pid": 2.0}
    for k in kinds:
        w = statistics.median(loop_t[k])
        rs, rf = ratio[k], ratio_fem[k]
        print(f"{k:5s} closed loop       {_fmt(loop_t[k])}   real-time factor {args.duration / w:6.0f}x   "
              f"trials of {args.duration:g} s per core-hour {3600 / w:6.0f}")
        print(f"      loop / plant alone {statistics.median(rs):.2f} ({min(rs):.2f}-{max(rs):.2f});   "
              f"loop / FEM kernel {statistics.median(rf):.2f} ({min(rf):.2f}-{max(rf):.2f}; target <= "
              f"{targets.get(k, 3.0):g})")
        print(f"      loop alone (meta wall_time) {statistics.median(inner_t[k]):.3f} s; "
              f"controller calls ~{statistics.median(ctrl_med[k]):.3f} s (median call x calls)")


if __name__ == "__main__":
    main()
