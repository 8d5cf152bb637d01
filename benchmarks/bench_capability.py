"""Capability envelopes (``tapm capability``): wall time of a whole run against reference workloads.

Printed figures, not a timed test. Run from the repository root::

    python benchmarks/bench_capability.py [--scenario fpso] [--heading weathervane] [--workers 2]
                                          [--condition all] [--repeats 1]

Times, in one process:

* the reference workloads: one ``mean_environmental_load`` (the mean wind, drift and current load
  of one environment at one heading) and one ``ThrustAllocator.allocate`` (DAQP, 6 azimuths, from
  rest with no rate limit binding) — medians of 200 calls;
* ``capability(...)`` with every case of ``--condition`` (default: mooring alone, intact, every
  single line, every single thruster) over the 36 directions, with ``--workers`` processes and with
  one (the single-process run also counts the environments evaluated, the load evaluations and
  the allocation calls);

and prints each run as seconds and as a ratio to the references, so the figures travel between
machines of different speed. Target: the fpso run with every case in under 2 minutes on 2 cores.

With ``--level3`` it times the time-domain capability instead (``tapm capability --level 3``):
``capability_level3`` over ``--directions`` with ``--controller`` and runs of ``--duration`` s
(default 600 s after a 100 s warm-up, ``--segments`` 10), against the reference workload of one
closed-loop run of the same controller and length in the scenario's first sea state, in the same
process; it prints the Level 3 wall time as a number of reference runs next to the number of runs
the search made (the difference is the two Level 1 envelopes, the building of each direction's
System and the worker processes)::

    python benchmarks/bench_capability.py --level3 --controller pid --directions 0,60
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from _machine import machine_info  # benchmarks/ is on sys.path when run

import tapm_opt
from tapm_opt.control.allocation import ThrustAllocator
from tapm_opt.design.capability import capability
from tapm_opt.design.loads import mean_environmental_load


def median_time(fn, n: int) -> float:
    ts = []
    for _ in range(n):
        t0 = time.perf_counter()
        fn()
        ts.append(time.perf_counter() - t0)
    return float(np.median(ts))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenario", default="fpso")
    ap.add_argument("--heading", default="weathervane", choices=("weathervane", "fixed"))
    ap.add_argument("--condition", default="all")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--repeats", type=int, default=1)
    ap.add_argument("--level3", action="store_true", help="time the time-domain capability (module docstring)")
    ap.add_argument("--controller", default="pid")
    ap.add_argument("--directions", default="0,60")
    ap.add_argument("--duration", type=float, default=600.0)
    ap.add_argument("--segments", type=int, default=10)
    a = ap.parse_args()
    print(machine_info())
    if a.level3:
        level3(a)
        return
    sc = tapm_opt.load_scenario(a.scenario)
    ss = sc.sea_state()
    ref_load = median_time(lambda: mean_environmental_load(sc, ss, 0.3), 200)
    alloc = ThrustAllocator(sc.thrusters, dt=1e6)
    tau = np.array([2.0e6, 1.0e6, 5.0e7])

    def one_allocation() -> None:
        alloc.reset()
        alloc.allocate(tau)

    ref_alloc = median_time(one_allocation, 200)
    print(f"reference: mean_environmental_load {1e3 * ref_load:.3f} ms, ThrustAllocator.allocate "
          f"{1e6 * ref_alloc:.1f} us ({len(sc.thrusters)} thrusters)")
    for workers in dict.fromkeys((a.workers, 1)):
        for k in range(a.repeats):
            t0 = time.perf_counter()
            res = capability(sc, heading=a.heading, condition=a.condition, workers=workers)
            wall = time.perf_counter() - t0
            n_cases = len(res.cases) + max(len(res.thruster_cases) - 1, 0)
            print(f"capability {a.scenario}, heading {a.heading}, condition {a.condition}: {n_cases} cases x "
                  f"{len(res.directions_deg)} directions, workers {workers}: {wall:.1f} s "
                  f"({wall / ref_load:,.0f} x one load, {wall / ref_alloc:,.0f} x one allocation); "
                  f"A {res.numbers['A']} B {res.numbers['B']} C {res.numbers['C']} D {res.numbers['D']}")
            cnt = res.info.get("counts")
            if cnt:
                print(f"  counts: {cnt['environments']} environments, {cnt['load_calls']} load evaluations "
                      f"({cnt['load_calls'] * ref_load:.1f} s at the reference), {cnt['allocations']} allocation "
                      f"calls ({cnt['allocations'] * ref_alloc:.1f} s); {wall / max(cnt['environments'], 1) * 1e3:.2f} "
                      "ms per environment")


def level3(a: argparse.Namespace) -> None:
    """``--level3``: the Level 3 search against one closed-loop run of the same length."""
    import math

    from tapm_opt.geometry import body_from_turret, ssa
    from tapm_opt.models.system import System
    from tapm_opt.plant.simulator import Plant
    from tapm_opt.studies.capability_level3 import capability_level3
    from tapm_opt.studies.closed_loop import ClosedLoopSettings, run_closed_loop
    from tapm_opt.studies.controllers import build_controller

    sc = tapm_opt.load_scenario(a.scenario)
    warmup = 100.0
    system = System.from_scenario(sc)

    def reference() -> float:
        t0 = time.perf_counter()
        psi = float(ssa(sc.sea_state().wave_direction + math.pi))   # bow into the first sea state's waves
        bx, by = body_from_turret((0.0, 0.0), psi, sc.turret.position)
        plant = Plant(system, seed=1, segments=a.segments, eta0=(bx, by, psi), faults=())
        run_closed_loop(plant, build_controller(system, a.controller),
                        ClosedLoopSettings(duration=warmup + a.duration, eta_d=(0.0, 0.0, psi)), system=system)
        return time.perf_counter() - t0

    reference()                                   # compiled kernels and caches warm
    ref = [reference() for _ in range(2)]
    dirs = tuple(float(d) for d in a.directions.split(","))
    for k in range(a.repeats):
        t0 = time.perf_counter()
        res = capability_level3(sc, controller=a.controller, directions_deg=dirs, duration=a.duration, warmup=warmup,
                                segments=a.segments, workers=a.workers)
        wall = time.perf_counter() - t0
        r = float(np.median(ref))
        print(f"reference: one {a.controller} closed-loop run of {warmup:g} + {a.duration:g} s, {a.segments} "
              f"segments: {r:.2f} s (runs {', '.join(f'{x:.2f}' for x in ref)})")
        print(f"capability_level3 {a.scenario}, {a.controller}, directions {a.directions}, workers {a.workers}: "
              f"{wall:.1f} s = {wall / r:.1f} reference runs for {res.info['runs']} runs of the search "
              f"({res.info['runs'] / max(a.workers, 1):.1f} per worker); Beaufort {res.beaufort.tolist()}, "
              f"Level 1 {res.level1.case('intact').beaufort.tolist()}")


if __name__ == "__main__":
    main()
