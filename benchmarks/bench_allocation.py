"""Time per call of the QP thrust allocation (tapm_opt.control.allocation.ThrustAllocator.allocate).

Printed figures, not a timed test. Run from the repository root::

    python benchmarks/bench_allocation.py [--calls 5000] [--warmup 500] [--lp-repeats 200]

For 4, 6 and 8 azimuth thrusters (built from the fpso scenario's thrusters), a control loop at
dt = 0.1 s with a slowly varying tau_cmd: after ``--warmup`` calls (the start-up from rest, also
reported), ``--calls`` timed calls. Reports the median, p90 and p99 wall time of one ``allocate`` call
(Python included), OSQP's own solve + polish time (``result.solve_time``), the ADMM iterations and
the statuses. Variants: the default; without polishing; and the Python path before its
optimisation (every call through the ``osqp.OSQP.update``/``solve`` wrapper). Target: <= 50 us
median per call including Python.

Thrust capacity: ``ThrusterSet.max_tau()`` on the fpso scenario (6 ``linprog`` solves, on a new
``ThrusterSet`` each time since the result is cached per set), each call followed by 20 warm
``allocate`` calls of fpso's six azimuths in the same process, and the ratio of the medians.

A calibration line gives the cost of one numpy ufunc on 6 floats and of an empty Python call on
this machine, to compare figures between machines, and a noise line the tail a fixed ~100 us
workload shows (on a shared VM the p99 is set by preemption, not by the allocator).
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import os
import platform
import time
import timeit

import numpy as np
import osqp

from tapm_opt import load_scenario
from tapm_opt.control.allocation import ThrustAllocator
from tapm_opt.models.system import ThrusterSet
from _machine import machine_info as _machine_info  # noqa: E402  (benchmarks/ is on sys.path when run)


def machine_info() -> str:
    return _machine_info(f"osqp {osqp.__version__}")


def calibration() -> str:
    a, b = np.random.default_rng(0).random(6), np.random.default_rng(1).random(6)
    n = 200_000
    ufunc = min(timeit.repeat(lambda: np.add(a, b), number=n, repeat=3)) / n
    call = min(timeit.repeat(lambda: None, number=n, repeat=3)) / n
    return f"calibration: numpy ufunc on 6 floats {ufunc * 1e6:.2f} us, empty Python call {call * 1e6:.3f} us"


def noise_floor(n: int) -> str:
    """p99 of a fixed ~100 us numpy workload: what this machine adds to any tail (preemption)."""
    a = np.random.default_rng(0).random(6)
    w = []
    for _ in range(n):
        t0 = time.perf_counter()
        for _ in range(100):
            np.add(a, a)
        w.append(time.perf_counter() - t0)
    w = np.array(w) * 1e6
    return (f"noise floor: a fixed workload of median {np.median(w):.0f} us has p99 {np.percentile(w, 99):.0f} us, "
            f"max {w.max():.0f} us, {np.mean(w > 1000) * 100:.2f} % of runs > 1 ms")


def thruster_sets() -> dict[int, list]:
    """4, 6 and 8 azimuths: fpso's six (A1-A3 aft, F1-F3 forward), its four outer ones, and the
    six plus two amidships."""
    th = list(load_scenario("fpso").thrusters)
    mid = [dataclasses.replace(th[0], id="M1", position=(0.0, -22.0)),
           dataclasses.replace(th[0], id="M2", position=(0.0, 22.0))]
    return {4: [th[0], th[2], th[3], th[5]], 6: th, 8: th + mid}


def demand(n_calls: int, dt: float) -> np.ndarray:
    """Slowly varying tau_cmd (X, Y, N), periods 1.5 to 15 min, within every set's capacity."""
    t = np.arange(n_calls) * dt
    return np.stack([1.2e6 * np.sin(2 * math.pi * t / 600.0) + 3e5 * np.sin(2 * math.pi * t / 97.0),
                     8e5 * np.cos(2 * math.pi * t / 900.0) + 2e5 * np.sin(2 * math.pi * t / 131.0),
                     4e7 * np.sin(2 * math.pi * t / 420.0 + 1.0)], axis=1)


VARIANTS = {"default": {}, "no polishing": dict(osqp_settings=dict(polishing=False)),
            "before: osqp wrapper": dict(wrapper=True)}


def run(thrusters, taus: np.ndarray, warmup: int, dt: float) -> dict[str, tuple]:
    """All variants on the same demand, calls interleaved (k-th call of each variant in turn, the
    order rotating) so that a change of machine load hits every variant alike."""
    als = {}
    for name, kw in VARIANTS.items():
        kw = dict(kw)
        wrapper = kw.pop("wrapper", False)
        als[name] = ThrustAllocator(thrusters, dt=dt, **kw)
        if wrapper:  # the Python path before its optimisation: osqp.OSQP.update()/solve() each call
            als[name]._raw = None
    out = {name: ([], [], [], {}) for name in als}
    names = list(als)
    for k, tau in enumerate(taus):
        for name in names[k % len(names):] + names[:k % len(names)]:
            t0 = time.perf_counter()
            res = als[name].allocate(tau)
            t1 = time.perf_counter()
            wall, osqp_t, iters, status = out[name]
            wall.append(t1 - t0)
            osqp_t.append(res.solve_time)
            iters.append(res.iterations)
            if k >= warmup:
                status[res.status] = status.get(res.status, 0) + 1
    return {name: (np.array(w) * 1e6, np.array(o) * 1e6, np.array(i), st) for name, (w, o, i, st) in out.items()}


def capacity_lp(repeats: int, taus: np.ndarray, warmup: int, dt: float, burst: int = 20) -> str:
    """Median time of ``ThrusterSet.max_tau()`` (fpso, a new set each call: the result is cached
    per set) against one warm ``allocate`` call (fpso's six azimuths): each LP call is followed by
    ``burst`` allocate calls of the control loop, timed one by one."""
    sc = load_scenario("fpso")
    al = ThrustAllocator(list(sc.thrusters), dt=dt)
    for tau in taus[:warmup]:
        al.allocate(tau)
    ThrusterSet.from_scenario(sc).max_tau()  # first call: imports and HiGHS start-up
    lp, rows, alloc = [], [], []
    k = warmup
    for _ in range(repeats):
        ts = ThrusterSet.from_scenario(sc)
        t0 = time.perf_counter()
        ts._hull_rows()  # diagnosis only: the constraint rows max_tau builds before its LPs
        t1 = time.perf_counter()
        cap = ThrusterSet.from_scenario(sc).max_tau()
        lp.append(time.perf_counter() - t1)
        rows.append(t1 - t0)
        for _ in range(burst):
            t2 = time.perf_counter()
            al.allocate(taus[k])
            alloc.append(time.perf_counter() - t2)
            k = k + 1 if k + 1 < len(taus) else warmup
    lp_m, rows_m, al_m = (float(np.median(v)) * 1e6 for v in (lp, rows, alloc))
    return (f"thrust capacity: ThrusterSet.max_tau() on fpso (6 linprog solves) median {lp_m / 1e3:.2f} ms "
            f"(p90 {np.percentile(lp, 90) * 1e3:.2f} ms; of which hull rows {rows_m / 1e3:.2f} ms) "
            f"= {lp_m / al_m:.0f} x one allocate call of fpso's six azimuths (median {al_m:.1f} us; "
            f"{repeats} LP calls, each followed by {burst} allocate calls); "
            f"max_tau = {np.array2string(cap, precision=4)}")


def line(label: str, wall, osqp_t, iters) -> str:
    return (f"  {label:24s} call median {np.median(wall):7.1f} us  p90 {np.percentile(wall, 90):7.1f} us  "
            f"p99 {np.percentile(wall, 99):7.1f} us | "
            f"OSQP solve+polish median {np.median(osqp_t):6.1f} us  p99 {np.percentile(osqp_t, 99):7.1f} us | "
            f"iterations median {np.median(iters):4.0f}  p99 {np.percentile(iters, 99):5.0f}")


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--calls", type=int, default=5000, help="timed calls per case (>= 5000)")
    ap.add_argument("--warmup", type=int, default=500, help="untimed calls first (start-up from rest)")
    ap.add_argument("--lp-repeats", type=int, default=200, help="timed ThrusterSet.max_tau() calls")
    args = ap.parse_args(argv)
    calls = max(args.calls, 5000)
    dt = 0.1
    print(machine_info())
    print(calibration())
    print(noise_floor(calls))
    print(f"control loop: dt = {dt} s, {args.warmup} warm-up calls from rest, then {calls} timed calls, "
          "slowly varying tau_cmd; default OSQP settings unless noted")
    taus = demand(args.warmup + calls, dt)
    ss = slice(args.warmup, None)
    for n, ths in thruster_sets().items():
        print(f"{n} azimuth thrusters:")
        for name, (wall, osqp_t, iters, status) in run(ths, taus, args.warmup, dt).items():
            print(line(name, wall[ss], osqp_t[ss], iters[ss]), f"| {status}")
            if name == "default":
                start = slice(0, min(200, args.warmup))
                print(line("  start-up from rest", wall[start], osqp_t[start], iters[start]),
                      f"| max {wall[start].max():.0f} us, {iters[start].max()} iterations")
    print(capacity_lp(max(args.lp_repeats, 20), taus, args.warmup, dt))


if __name__ == "__main__":
    main()
