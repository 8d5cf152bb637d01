"""What the hull's six-degree-of-freedom wave-frequency motion costs the plant and the PID loop.

Printed figures, not a timed test. Run from the repository root::

    python benchmarks/bench_wave_motion.py [--repeats 5] [--duration 600] [--sea-state storm]

fpso's PID closed loop (``build_controller(system, {"type": "pid"})``, the default estimator, the
plant's compiled outer steps, 1 s control and log) and its open-loop plant (``run_open_loop``) in
one process, with ``vessel.wave_motion.model`` "horizontal" (surge, sway and yaw only), "six_dof"
(the closed-form heave, roll and pitch) and "table" (all six from an RAO table, a CSV written
from the closed form and the parametric horizontal RAOs), interleaved — horizontal, six_dof,
table, horizontal, ... — so that the machine's load falls on all alike. Reported: the median
real-time factor of each and the median, over the repeats, of each model's run time over the
horizontal one's in the same repeat (the ratio is steadier than the times on a shared machine).

Target (the six-degree-of-freedom issue): the PID loop's real-time factor drops by no more than
10 % with six_dof.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_catenary import machine_info

import tapm_opt
from tapm_opt.models import rao as rao_mod
from tapm_opt.plant.environment import N_HEADINGS, Environment
from tapm_opt.plant.simulator import Plant, run_open_loop

MODELS = ("horizontal", "six_dof", "table")


def scenarios(tmp: Path, sea_state: str) -> dict[str, object]:
    """fpso with each wave-motion model (the table written to ``tmp``)."""
    sc = tapm_opt.load_scenario("fpso")
    wm = sc.vessel.wave_motion
    six = dataclasses.replace(sc, vessel=dataclasses.replace(sc.vessel, wave_motion=dataclasses.replace(
        wm, model="six_dof")))
    w = Environment(six, sea_state, seed=0).waves
    v, g = sc.vessel, sc.environment.gravity
    hull = rao_mod.HullMotionParams(length_pp=v.length_pp, breadth=v.breadth, draught=v.draught,
                                    block_coefficient=wm.block_coefficient,
                                    waterplane_coefficient=(1 + 2 * wm.block_coefficient) / 3, GM_T=wm.GM_T,
                                    roll_period=wm.roll_period, roll_damping=wm.roll_damping)
    omega = np.linspace(0.1, 3.0, 146)
    beta = 2 * math.pi / N_HEADINGS * np.arange(N_HEADINGS)
    H = np.zeros((omega.size, beta.size, 6), complex)
    H[:, :, 2:5] = rao_mod.closed_form_rao(omega[:, None], beta[None, :], hull, g=g)
    H[:, :, [0, 1, 5]] = w.horizontal_rao(omega[:, None], beta[None, :])   # the parametric surge, sway, yaw
    path = tmp / "fpso_rao.csv"
    rao_mod.write_rao_csv(rao_mod.RAOTable(omega=omega, beta=beta, H=H), path)
    table = dataclasses.replace(sc, vessel=dataclasses.replace(sc.vessel, wave_motion=dataclasses.replace(
        wm, model="table", rao_file=str(path))))
    return {"horizontal": sc, "six_dof": six, "table": table}


def closed_loop_time(sc, sea_state: str, duration: float) -> float:
    """Wall time [s] of the PID closed loop's run (the plant built and settled before the clock)."""
    from tapm_opt.models.system import System
    from tapm_opt.studies.closed_loop import (
        DEFAULT_ESTIMATOR,
        ClosedLoopSettings,
        run_closed_loop,
    )
    from tapm_opt.studies.controllers import build_controller

    system = System.from_scenario(sc)
    ctrl = build_controller(system, {"type": "pid"}, where="--option", dt_control=1.0,
                            estimator=DEFAULT_ESTIMATOR, winch=None)
    settings = ClosedLoopSettings(duration=duration, dt_control=1.0, dt_log=1.0)
    plant = Plant(system, sea_state=sea_state, seed=0)
    t0 = time.perf_counter()
    run_closed_loop(plant, ctrl, settings, system=system)
    return time.perf_counter() - t0


def open_loop_time(sc, sea_state: str, duration: float) -> float:
    """Wall time [s] of the open-loop plant's run (built and settled before the clock)."""
    plant = Plant(sc, sea_state=sea_state, seed=0)
    t0 = time.perf_counter()
    run_open_loop(plant, duration)
    return time.perf_counter() - t0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--duration", type=float, default=600.0)
    ap.add_argument("--sea-state", default="storm")
    a = ap.parse_args()
    print(machine_info())
    with tempfile.TemporaryDirectory() as tmp:
        scs = scenarios(Path(tmp), a.sea_state)
        for sc in scs.values():   # warm-up: compile or load the kernels for each model
            closed_loop_time(sc, a.sea_state, 20.0)
        for name, fn in (("PID closed loop", closed_loop_time), ("open-loop plant", open_loop_time)):
            times: dict[str, list[float]] = {m: [] for m in MODELS}
            for _ in range(a.repeats):
                for m in MODELS:
                    times[m].append(fn(scs[m], a.sea_state, a.duration))
            print(f"\nfpso {name}, sea state {a.sea_state}, {a.duration:g} s simulated, median of {a.repeats} "
                  "(interleaved):")
            print(f"  {'model':>10} {'RTF':>8} {'time / horizontal':>18}")
            for m in MODELS:
                rtf = a.duration / float(np.median(times[m]))
                ratio = float(np.median([t / h for t, h in zip(times[m], times["horizontal"])]))
                print(f"  {m:>10} {rtf:>7.0f}x {ratio:>17.3f}")


if __name__ == "__main__":
    main()
