"""What the budgeted dead band after a line break costs an MPC step.

Printed figures, not a timed test. Run from the repository root::

    python benchmarks/bench_dead_band.py [--steps 200] [--repeats 5] [--line 9]

Two linear MPCs with the study defaults (``build_controller(system, {"type": "lmpc"})``: dead
band 30 m, damaged 22.5 m), one with ``dead_band_budget`` on (the default) and one with it off
(``dead_band_damaged`` after any break, no budget to work out), are stepped in the same process,
alternately, through the same ``--steps`` estimates: fpso in its design storm's mean load at a
heading of 0.33 rad, the turret 28-36 m down-weather moving slowly, line ``--line`` reported
broken. ``--repeats`` passes after a warm-up pass (the damaged mooring's tabulated load built, the
QP set up). Printed: the median ``update`` per call [ms] of each and their ratio, and the median of
``budgeted_dead_band`` alone [us] on the same data (the budget's share of a step). With a lee or
side line (the default, 9) both hold 22.5 m and solve the same QPs, so the ratio is the budget's
overhead; with a weather line (1-4) the budget keeps 30 m and the two solve different problems.
"""

from __future__ import annotations

import argparse
import sys
import time

import numpy as np

import tapm_opt
from tapm_opt.control.mpc import budgeted_dead_band
from tapm_opt.design.loads import mean_environmental_load
from tapm_opt.geometry import body_from_turret, rot_z
from tapm_opt.interfaces import Estimate, Setpoint
from tapm_opt.models.system import System
from tapm_opt.studies.controllers import build_controller
from _machine import machine_info  # noqa: E402  (benchmarks/ is on sys.path when run)

PSI = 0.33


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=200)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--line", default="9")
    a = ap.parse_args()
    system = System.from_scenario(tapm_opt.load_scenario("fpso"))
    b_E = rot_z(PSI) @ mean_environmental_load(system.scenario, "storm", PSI).total
    tau_B = rot_z(PSI).T @ b_E
    e = b_E[:2] / np.hypot(*b_E[:2])
    ests = []
    for k in range(a.steps):
        r = 32.0 + 4.0 * np.sin(2 * np.pi * k / 60.0)
        xy = body_from_turret(r * e, PSI, system.p_cot_B)
        ests.append(Estimate(t=5.0 * k, eta=np.array([xy[0], xy[1], PSI]), nu=np.zeros(3), tau_env=tau_B,
                             broken_lines=frozenset([a.line])))
    sp = Setpoint(eta_d=np.zeros(3))
    ctrls = {"budget": build_controller(system, {"type": "lmpc"}),
             "no budget": build_controller(system, {"type": "lmpc", "dead_band_budget": False})}
    times = {k: [] for k in ctrls}
    for rep in range(a.repeats + 1):
        for c in ctrls.values():
            c.reset()
        for est in ests:
            for name, c in ctrls.items():
                t0 = time.perf_counter()
                c.update(est.t, est, sp)
                if rep:
                    times[name].append(time.perf_counter() - t0)
    damaged = system.lines.without([a.line])
    tb = []
    for _ in range(a.repeats * a.steps):
        t0 = time.perf_counter()
        budgeted_dead_band(system.lines, damaged, b_E, PSI, 22.5, 30.0)
        tb.append(time.perf_counter() - t0)
    print(machine_info())
    radius = ctrls["budget"].last_step().dead_band
    print(f"fpso storm mean load, line {a.line} broken: budgeted radius {radius:.2f} m")
    for name, ts in times.items():
        print(f"  LinearMPC.update, {name:9s}: median {1e3 * np.median(ts):.3f} ms over {len(ts)} calls")
    ratio = np.median(times["budget"]) / np.median(times["no budget"])
    print(f"  ratio budget / no budget: {ratio:.3f}")
    print(f"  budgeted_dead_band alone: median {1e6 * np.median(tb):.1f} us "
          f"({100 * np.median(tb) / np.median(times['budget']):.1f} % of a step)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
