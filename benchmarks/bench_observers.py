"""Per-update cost of the DP observers against the low-pass estimator; optionally their closed-loop KPIs.

Printed figures, not a timed test. Run from the repository root::

    python benchmarks/bench_observers.py [--scenario fpso] [--sea-state storm] [--duration 600] [--repeats 5]
    python benchmarks/bench_observers.py --kpis [--kpi-duration 1800] [--seeds 3 4 5] [--segments N]

Timing: one closed loop (PID, the low-pass estimator in the loop, ``dt_control`` 1 s) records the
measurements the estimators see; then ``LowPassEstimator``, ``PassiveObserver`` and ``EKFObserver``
(each ``from_scenario`` with the sea state; no detector or monitor) are fed the same recorded
measurements in the same process, ``--repeats`` passes each after a warm-up pass (the load
evaluator built, the discretisation cached). Median and p90 of ``update`` per call [us], and the
ratio to the low-pass estimator's median. Every estimator builds its ``Estimate`` (about 15 us of
the figure).

``--kpis``: the closed loop of the brief for each estimator — fpso (or ``--scenario``), PID
(``build_controller(system, "pid")``), sea state ``--sea-state`` (default storm), ``--kpi-duration``
(default 1800 s), plant seeds ``--seeds`` (default 3), each estimator with the tension-drop detector and the reliability
monitor as the runner's default has — and a table of ``case_kpis`` (max / mean turret offset,
time outside the safe circle, max utilisation, thrust energy) plus the LF position RMS error of the
estimate against the plant's truth after 300 s.
"""

from __future__ import annotations

import argparse
import sys
import time

import numpy as np

import tapm_opt
from tapm_opt.estimation.detection import TensionDropDetector
from tapm_opt.estimation.lowpass import LowPassEstimator
from tapm_opt.estimation.observer import EKFObserver, PassiveObserver
from tapm_opt.estimation.reliability import monitor_for
from tapm_opt.models.system import System
from tapm_opt.plant.simulator import Plant
from tapm_opt.studies.closed_loop import ClosedLoopSettings, run_closed_loop
from tapm_opt.studies.controllers import build_controller
from tapm_opt.studies.kpis import case_kpis
from _machine import machine_info  # noqa: E402  (benchmarks/ is on sys.path when run)


class Recorder:
    """An estimator wrapper that keeps every measurement it is given."""

    def __init__(self, est):
        self.est, self.measurements = est, []

    def update(self, t, m):
        self.measurements.append(m)
        return self.est.update(t, m)

    def reset(self):
        self.est.reset()


def makers(system, sea_state, *, with_parts=False):
    sc = system.scenario

    def parts():
        return {"detector": TensionDropDetector(system.lines), "monitor": monitor_for(sc)} if with_parts else {}

    return {
        "LowPassEstimator": lambda: LowPassEstimator(system.lines, **parts()),
        "PassiveObserver": lambda: PassiveObserver.from_scenario(system, sea_state, **parts()),
        "EKFObserver": lambda: EKFObserver.from_scenario(system, sea_state, **parts()),
    }


def timing(system, sea_state, duration, repeats, segments):
    plant = Plant(system, sea_state=sea_state, seed=1, segments=segments)
    rec = Recorder(LowPassEstimator(system.lines))
    run_closed_loop(plant, build_controller(system, "pid"), ClosedLoopSettings(duration=duration, dt_control=1.0),
                    system=system, estimator=rec)
    ms = rec.measurements
    out = {}
    pc = time.perf_counter
    for name, make in makers(system, sea_state).items():
        est = make()
        for m in ms:               # warm-up pass
            est.update(m.t, m)
        samples = np.empty((repeats, len(ms)))
        for r in range(repeats):
            est.reset()
            row = samples[r]
            for k, m in enumerate(ms):
                t0 = pc()
                est.update(m.t, m)
                row[k] = pc() - t0
        per = np.median(samples, axis=0)[1:]    # the first update (initialisation) left out
        out[name] = (float(np.median(per) * 1e6), float(np.percentile(per, 90) * 1e6))
    base = out["LowPassEstimator"][0]
    print(f"{len(ms)} recorded measurements ({duration:g} s, sea state {sea_state}), {repeats} passes; us per update\n")
    print(f"{'estimator':<18} | {'median':>8} | {'p90':>8} | ratio to LowPassEstimator (median)")
    for name, (med, p90) in out.items():
        print(f"{name:<18} | {med:8.1f} | {p90:8.1f} | {med / base:.2f}x")
    return out


def kpis(system, sea_state, duration, segments, seeds):
    sc = system.scenario
    rows = []
    for seed in seeds:
        for name, make in makers(system, sea_state, with_parts=True).items():
            plant = Plant(system, sea_state=sea_state, seed=seed, segments=segments)
            w0 = time.perf_counter()
            res = run_closed_loop(plant, build_controller(system, "pid"), ClosedLoopSettings(duration=duration),
                                  system=system, estimator=make())
            wall = time.perf_counter() - w0
            k = case_kpis(res, sc)
            w = res.time >= 300.0
            err = np.hypot(res["x_hat"][w] - res["x"][w], res["y_hat"][w] - res["y"][w])
            rows.append((seed, name, k, float(np.sqrt(np.mean(err ** 2))), wall))
    print(f"\nclosed loop: {sc.name} {sea_state}, PID, {duration:g} s, dt_control 1 s\n")
    print(f"{'seed':>4} | {'estimator':<18} | {'offset_max':>10} | {'offset_mean':>11} | {'t_out_safe':>10} | "
          f"{'util_max':>8} | {'energy':>9} | {'LF rms err':>10} | wall")
    print(f"{'':>4} | {'':<18} | {'m':>10} | {'m':>11} | {'s':>10} | {'-':>8} | {'MWh':>9} | {'m':>10} | s")
    for seed, name, k, rms, wall in rows:
        print(f"{seed:4d} | {name:<18} | {k['offset_max']:10.2f} | {k['offset_mean']:11.2f} | "
              f"{k.get('time_outside_safe', 0.0):10.0f} | {k.get('util_max', float('nan')):8.3f} | "
              f"{k['thrust_energy'] / 3.6e9:9.3f} | {rms:10.3f} | {wall:.0f}")
    if len(seeds) > 1:
        for name in dict.fromkeys(r[1] for r in rows):
            sel = [r for r in rows if r[1] == name]
            print(f"mean | {name:<18} | {np.mean([r[2]['offset_max'] for r in sel]):10.2f} | "
                  f"{np.mean([r[2]['offset_mean'] for r in sel]):11.2f} | "
                  f"{np.mean([r[2].get('time_outside_safe', 0.0) for r in sel]):10.0f} | "
                  f"{np.mean([r[2].get('util_max', np.nan) for r in sel]):8.3f} | "
                  f"{np.mean([r[2]['thrust_energy'] for r in sel]) / 3.6e9:9.3f} | "
                  f"{np.mean([r[3] for r in sel]):10.3f} |")
    return rows


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenario", default="fpso", help="built-in scenario name or TOML path")
    ap.add_argument("--sea-state", default="storm", help="sea state id")
    ap.add_argument("--duration", type=float, default=600.0, help="recorded run for the timing [s]")
    ap.add_argument("--repeats", type=int, default=5, help="timed passes over the recording")
    ap.add_argument("--segments", type=int, default=None, help="FEM segments per line (default: the lines' own)")
    ap.add_argument("--kpis", action="store_true", help="also run the closed-loop KPI comparison")
    ap.add_argument("--kpi-duration", type=float, default=1800.0, help="closed-loop KPI run [s]")
    ap.add_argument("--seeds", type=int, nargs="+", default=[3], help="plant seeds of the KPI runs")
    args = ap.parse_args(argv)
    print(machine_info())
    system = System.from_scenario(tapm_opt.load_scenario(args.scenario))
    timing(system, args.sea_state, args.duration, max(args.repeats, 1), args.segments or 10)
    if args.kpis:
        kpis(system, args.sea_state, args.kpi_duration, args.segments, args.seeds)
    return 0


if __name__ == "__main__":
    sys.exit(main())
