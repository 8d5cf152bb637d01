"""Time per call of the QP thrust allocation (tapm_opt.control.allocation.ThrustAllocator.allocate),
DAQP path against OSQP path and against a raw ``daqp.solve`` of the same QP.

Printed figures, not a timed test. Run from the repository root::

    python benchmarks/bench_allocation.py [--calls 5000] [--warmup 500] [--loop-calls 6000] [--lp-repeats 200]

Two demand sets, dt = 0.1 s; the variants take turns in blocks of 50 calls (the order rotating
from block to block), so that a change of machine load hits every variant alike and no variant
runs with the caches another one left behind on every call:

* fixed demand set: a slowly varying tau_cmd (periods 1.5 to 15 min, within capacity) for 4, 6
  and 8 azimuths (built from the fpso scenario's thrusters); ``--warmup`` calls from rest (the
  start-up, also reported), then ``--calls`` timed calls;
* closed-loop demand: ``--loop-calls`` calls on fpso's six azimuths, without and with forbidden
  sectors (A2: 160..200 deg, F2: 340..20 deg): what a DP controller asks for in closed loop
  (:func:`closed_loop_demand`): a start from rest, wave-frequency motion and measurement noise on
  a mean load whose direction turns, a rate-limited reversal of the demand (every azimuth turns
  about 180 deg at its rate limit) and a storm beyond capacity (saturation). Every call timed.

Reported per variant: median, p90 and p99 wall time of one ``allocate`` call (Python included),
the solver's own time (``result.solve_time``: DAQP update + solve wall time, OSQP solve + polish),
the iterations and the statuses (over all calls). The reference workload, timed in the same
process after each DAQP block on the data each of its calls solved: ``daqp.solve`` from scratch
(setup + solve, the Python call included) of the same QP, with the polygon sides the DAQP path
used, and with the whole polygon (the QP as the OSQP path states it). The ratios of the medians make the figures
comparable between machines. Target: <= 20 us median per DAQP call (fpso's six azimuths,
closed-loop demand).

Thrust capacity: ``ThrusterSet.max_tau()`` on the fpso scenario (6 ``linprog`` solves, on a new
``ThrusterSet`` each time since the result is cached per set), each call followed by 20 warm
``allocate`` calls of fpso's six azimuths in the same process, and the ratio of the medians.

A calibration line gives the cost of one numpy ufunc on 6 floats and of an empty Python call on
this machine, and a noise line the tail a fixed ~100 us workload shows (on a shared VM the p99 is
set by preemption, not by the allocator).
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import time
import timeit

import daqp
import numpy as np
import osqp

from tapm_opt import load_scenario
from tapm_opt.control.allocation import ThrustAllocator
from tapm_opt.models.system import ThrusterSet
from _machine import machine_info as _machine_info  # noqa: E402  (benchmarks/ is on sys.path when run)

DEG = math.pi / 180.0


def machine_info() -> str:
    return _machine_info(f"osqp {osqp.__version__}, daqp (Model API)")


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


def sector_thrusters() -> list:
    """fpso's six azimuths, A2 forbidden 160..200 deg and F2 340..20 deg."""
    th = list(load_scenario("fpso").thrusters)
    th[1] = dataclasses.replace(th[1], forbidden_sectors=((160 * DEG, 200 * DEG),))
    th[4] = dataclasses.replace(th[4], forbidden_sectors=((340 * DEG, 20 * DEG),))
    return th


def demand(n_calls: int, dt: float) -> np.ndarray:
    """Fixed demand set: slowly varying tau_cmd (X, Y, N), periods 1.5 to 15 min, within every
    set's capacity."""
    t = np.arange(n_calls) * dt
    return np.stack([1.2e6 * np.sin(2 * math.pi * t / 600.0) + 3e5 * np.sin(2 * math.pi * t / 97.0),
                     8e5 * np.cos(2 * math.pi * t / 900.0) + 2e5 * np.sin(2 * math.pi * t / 131.0),
                     4e7 * np.sin(2 * math.pi * t / 420.0 + 1.0)], axis=1)


def closed_loop_demand(n_calls: int, dt: float, cap: np.ndarray, seed: int = 0) -> np.ndarray:
    """tau_cmd (X, Y, N) as a DP controller commands it in closed loop, relative to the capacity
    ``cap`` (``ThrusterSet.max_tau()``), over ``n_calls`` steps of dt:

    * a mean load of 25-45 % of capacity whose direction turns slowly (wind and current veering),
      reached from rest over the first 30 s;
    * at 30 % of the run the mean demand reverses (a setpoint step): the controller output moves
      at most 4 % of capacity per second, and the azimuths turn about 180 deg at their rate limit;
    * from 60 % to 75 % of the run a storm asks for 1.4 x capacity (saturation, the slack takes
      the rest), then back;
    * wave-frequency motion (9.5 s period, 12 % of capacity, amplitude modulated) and measurement
      noise through the derivative gain (2 % of capacity per step, white).
    """
    rng = np.random.default_rng(seed)
    t = np.arange(n_calls) * dt
    T = n_calls * dt
    mag = 0.35 + 0.1 * np.sin(2 * math.pi * t / 400.0)
    mag = np.where((t > 0.6 * T) & (t < 0.75 * T), 1.4, mag)
    heading = 0.4 + 1.2 * np.sin(2 * math.pi * t / (1.3 * T)) + np.where(t > 0.3 * T, math.pi, 0.0)
    target = mag[:, None] * np.stack([np.cos(heading), np.sin(heading), 0.5 * np.sin(heading + 1.0)], axis=1)
    target *= np.minimum(t / 30.0, 1.0)[:, None]
    mean = np.empty_like(target)
    m, step = np.zeros(3), 0.04 * dt                       # rate limit of the controller output
    for k in range(n_calls):
        m += np.clip(target[k] - m, -step, step)
        mean[k] = m
    wave = 0.12 * (1.0 + 0.5 * np.sin(2 * math.pi * t / 137.0))[:, None] * np.stack(
        [np.sin(2 * math.pi * t / 9.5), np.sin(2 * math.pi * t / 9.5 + 1.3), 0.5 * np.sin(2 * math.pi * t / 9.5 + 2.1)], axis=1)
    noise = 0.02 * rng.standard_normal((n_calls, 3))
    return (mean + wave * np.minimum(t / 30.0, 1.0)[:, None] + noise) * cap


VARIANTS = {"daqp": dict(solver="daqp"), "osqp": dict(solver="osqp")}
BLOCK = 50          # calls per variant in turn


class RawQP:
    """The QP of a DAQP allocator's calls, for ``daqp.solve`` from scratch: the constant data
    once, the data that changes per call (balance rows of A, bounds) as snapshots."""

    def __init__(self, al: ThrustAllocator):
        self.H = np.diag(al._Pd)
        self.f = np.zeros(self.H.shape[0])
        self.A, self.bu, self.bl = al._A.copy(), al._bu.copy(), al._bl.copy()
        self.nv, self.rows_two = al._nv, 3 + 2 * al._naz
        self.sense = [v[3].copy() for v in al._views]

    def snapshot(self, al: ThrustAllocator) -> tuple:
        """What the allocator's last call solved (its buffers hold it)."""
        return al._k_last, al._A[:3].copy(), al._bu[:self.nv + 3].copy(), al._bl[:self.nv + 3].copy()

    def problem(self, snap: tuple, full: bool) -> tuple:
        """daqp.solve's arguments: the sides that call used, or the whole polygon."""
        k, A3, bu, bl = snap
        A, BU, BL = self.A.copy(), self.bu.copy(), self.bl.copy()
        A[:3], BU[:self.nv + 3], BL[:self.nv + 3] = A3, bu, bl
        rows = A.shape[0] if full or k != 0 else self.rows_two
        return (self.H, self.f, A[:rows].copy(), BU[:self.nv + rows].copy(), BL[:self.nv + rows].copy(),
                self.sense[1 if rows == A.shape[0] else 0].copy())


def run(thrusters, taus: np.ndarray, dt: float) -> dict[str, tuple]:
    """Every variant on the same demand in blocks of BLOCK calls, the order of the variants
    rotating from block to block so that a change of machine load hits every variant alike; after
    each DAQP block the raw ``daqp.solve`` of each of its calls' QP, timed one by one."""
    als = {name: ThrustAllocator(thrusters, dt=dt, **kw) for name, kw in VARIANTS.items()}
    raw = RawQP(als["daqp"])
    out = {name: ([], [], [], {}) for name in als}
    raw_used, raw_full, two_sides = [], [], []
    names = list(als)
    for b, k0 in enumerate(range(0, len(taus), BLOCK)):
        block = taus[k0:k0 + BLOCK]
        for name in names[b % len(names):] + names[:b % len(names)]:
            al = als[name]
            wall, solver_t, iters, status = out[name]
            snaps = []
            for tau in block:
                t0 = time.perf_counter()
                res = al.allocate(tau)
                t1 = time.perf_counter()
                wall.append(t1 - t0)
                solver_t.append(res.solve_time)
                iters.append(res.iterations)
                status[res.status] = status.get(res.status, 0) + 1
                if name == "daqp":
                    snaps.append(None if res.fallback else raw.snapshot(al))
            for snap in snaps:
                two_sides.append(snap is not None and snap[0] == 0)
                for full, dest in ((False, raw_used), (True, raw_full)):
                    if snap is None:
                        dest.append(math.nan)
                        continue
                    args = raw.problem(snap, full)
                    t0 = time.perf_counter()
                    _, _, flag, _ = daqp.solve(*args)
                    t1 = time.perf_counter()
                    dest.append(t1 - t0 if flag > 0 else math.nan)
    res = {name: (np.array(w) * 1e6, np.array(o) * 1e6, np.array(i), st) for name, (w, o, i, st) in out.items()}
    res["raw"] = (np.array(raw_used) * 1e6, np.array(raw_full) * 1e6, np.array(two_sides))
    return res


def capacity_lp(repeats: int, taus: np.ndarray, warmup: int, dt: float, burst: int = 20) -> str:
    """Median time of ``ThrusterSet.max_tau()`` (fpso, a new set each call: the result is cached
    per set) against one warm ``allocate`` call (fpso's six azimuths, default solver): each LP call
    is followed by ``burst`` allocate calls of the control loop, timed one by one."""
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
            f"= {lp_m / al_m:.0f} x one allocate call of fpso's six azimuths (median {al_m:.1f} us, DAQP; "
            f"{repeats} LP calls, each followed by {burst} allocate calls); "
            f"max_tau = {np.array2string(cap, precision=4)}")


def line(label: str, wall, solver_t, iters) -> str:
    return (f"  {label:22s} call median {np.median(wall):7.1f} us  p90 {np.percentile(wall, 90):7.1f} us  "
            f"p99 {np.percentile(wall, 99):7.1f} us | "
            f"solver median {np.median(solver_t):6.1f} us  p99 {np.percentile(solver_t, 99):7.1f} us | "
            f"iterations median {np.median(iters):4.0f}  p99 {np.percentile(iters, 99):5.0f}  max {np.max(iters):5.0f}")


def report(res: dict, ss: slice) -> None:
    for name in VARIANTS:
        wall, solver_t, iters, status = res[name]
        print(line(name, wall[ss], solver_t[ss], iters[ss]), f"| {status}")
    raw_used, raw_full, two = (v[ss] for v in res["raw"])
    ok = np.isfinite(raw_used)
    d, o = np.median(res["daqp"][0][ss]), np.median(res["osqp"][0][ss])
    ru, rf = np.median(raw_used[ok]), np.median(raw_full[ok])
    print(f"  {'reference':22s} daqp.solve from scratch, same QP: median {ru:6.1f} us  p90 {np.percentile(raw_used[ok], 90):6.1f} us "
          f"(sides used: two on {np.mean(two[ok]) * 100:.0f} % of calls); whole polygon: median {rf:6.1f} us  "
          f"p90 {np.percentile(raw_full[ok], 90):6.1f} us")
    print(f"  {'ratios of medians':22s} daqp path / raw daqp.solve (same QP) {d / ru:.2f}, / raw (whole polygon) {d / rf:.2f}; "
          f"osqp path / daqp path {o / d:.1f}")


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--calls", type=int, default=5000, help="timed calls per case of the fixed demand set (>= 5000)")
    ap.add_argument("--warmup", type=int, default=500, help="untimed calls first (start-up from rest)")
    ap.add_argument("--loop-calls", type=int, default=6000, help="calls of the closed-loop demand (>= 3000)")
    ap.add_argument("--lp-repeats", type=int, default=200, help="timed ThrusterSet.max_tau() calls")
    args = ap.parse_args(argv)
    calls = max(args.calls, 5000)
    loop_calls = max(args.loop_calls, 3000)
    dt = 0.1
    print(machine_info())
    print(calibration())
    print(noise_floor(calls))
    ThrustAllocator(thruster_sets()[6]).allocate([1e5, 0.0, 0.0])   # compiled kernels loaded (or compiled)
    taus = demand(args.warmup + calls, dt)
    ss = slice(args.warmup, None)
    print(f"fixed demand set: dt = {dt} s, {args.warmup} warm-up calls from rest, then {calls} timed calls, "
          "slowly varying tau_cmd; default solver settings")
    for n, ths in thruster_sets().items():
        print(f"{n} azimuth thrusters:")
        res = run(ths, taus, dt)
        report(res, ss)
        start = slice(0, min(200, args.warmup))
        wall, solver_t, iters, _ = res["daqp"]
        print(line("daqp start from rest", wall[start], solver_t[start], iters[start]),
              f"| max {wall[start].max():.0f} us, {iters[start].max()} iterations")
    cap = ThrusterSet.from_scenario(load_scenario("fpso")).max_tau()
    loop = closed_loop_demand(loop_calls, dt, cap)
    print(f"closed-loop demand: dt = {dt} s, {loop_calls} calls from rest, all timed (start-up, reversal at 30 %, "
          "storm at 1.4 x capacity 60-75 %)")
    for label, ths in [("fpso, 6 azimuths", thruster_sets()[6]), ("fpso, 6 azimuths, sectors on A2 and F2", sector_thrusters())]:
        print(f"{label}:")
        report(run(ths, loop, dt), slice(None))
    print(capacity_lp(max(args.lp_repeats, 20), taus, args.warmup, dt))


if __name__ == "__main__":
    main()
