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
"""

from __future__ import annotations

import argparse
import time

import numpy as np

import tapm_opt
from tapm_opt.control.allocation import ThrustAllocator
from tapm_opt.design.capability import capability
from tapm_opt.design.loads import mean_environmental_load
from _machine import machine_info  # noqa: E402  (benchmarks/ is on sys.path when run)


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
    a = ap.parse_args()
    print(machine_info())
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


if __name__ == "__main__":
    main()
