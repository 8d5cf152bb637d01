"""Line-break detection on the fpso FEM plant: the tension-residual CUSUM against the tension drop.

Printed figures, not a timed test. Run from the repository root::

    python benchmarks/bench_detection.py [--quick] [--seed 1] [--workers 2] [--estimator ekf|lowpass|passive]

Closed loop of ``run_closed_loop`` with the PID (``build_controller(scenario, "pid")``, default
settings: fixed setpoint and heading, 1 s control step) and the loop's estimator (``--estimator``,
default the loop's: the EKF) with ``detector=...``; the FEM plant with fpso's 20 segments per line and seed ``--seed``.

* Intact runs, 3 simulated hours (``--quick``: 30 min) in each of the sea states calm, normal and
  storm, with :class:`~tapm_opt.estimation.detection.TensionResidualDetector` as the estimator's
  detector and :class:`~tapm_opt.estimation.detection.TensionDropDetector` fed the same
  measurements alongside (its detections are counted, not acted on). Per sea state: false alarms
  of each detector (a detection of a line the plant had not broken by then), the residual test's
  threshold h, its largest statistic and the margin h - max g, the deepest intact residual relative
  to the design shift (``worst_drop``; the statistic grows only above 0.5), the drop detector's
  closest approach (smallest measured tension over its threshold, 20 % of pretension), the mean
  measured tension of every line, and the residual detector's time per update.
* Break runs in the storm: each line (``--quick``: lines 1, 4, 9, 12) broken at 600 s, run to
  700 s, once with each detector as the estimator's: detection delay, whether the first line
  detected after the break is the broken one, and detections of other lines.

At most ``--workers`` processes (default 2).
"""

from __future__ import annotations

import argparse
import math
import time
from concurrent.futures import ProcessPoolExecutor
from typing import Any

import numpy as np

import tapm_opt
from tapm_opt.config.schema import Fault
from tapm_opt.estimation.detection import TensionDropDetector, TensionResidualDetector
from tapm_opt.estimation.lowpass import LowPassEstimator
from tapm_opt.estimation.observer import EKFObserver, PassiveObserver
from tapm_opt.models.system import System
from tapm_opt.plant.simulator import Plant
from tapm_opt.studies.closed_loop import DEFAULT_ESTIMATOR, ESTIMATOR_KINDS, ClosedLoopSettings, run_closed_loop
from tapm_opt.studies.controllers import build_controller
from tapm_opt.studies.kpis import break_times
from _machine import machine_info  # noqa: E402  (benchmarks/ is on sys.path when run)

SCENARIO = "fpso"
T_BREAK = 600.0
T_END = 700.0


class Alongside:
    """The estimator's detector ``primary`` (its answer is used) with ``other`` fed the same
    measurements (its detections only recorded); times ``primary.update`` [s per call]."""

    def __init__(self, primary: Any, other: Any):
        self.primary, self.other = primary, other
        self.times: list[float] = []
        self.min_ratio = math.inf   # smallest measured tension / the drop detector's threshold

    @property
    def events(self) -> list[dict]:
        return self.primary.events

    @property
    def broken(self) -> frozenset:
        return self.primary.broken

    def reset(self) -> None:
        self.primary.reset()
        self.other.reset()
        self.times.clear()
        self.min_ratio = math.inf

    def update(self, t, tensions, eta=None):
        self.other.update(t, tensions, eta)
        if isinstance(self.other, TensionDropDetector):
            keep = [i for i, lid in enumerate(self.other.line_ids) if lid not in self.other.broken]
            if keep:
                self.min_ratio = min(self.min_ratio, float(np.min(np.asarray(tensions)[keep] / self.other.threshold[keep])))
        w0 = time.perf_counter()
        out = self.primary.update(t, tensions, eta)
        self.times.append(time.perf_counter() - w0)
        return out


def _estimator(kind: str, system: System, sea_state: str, detector: Any) -> Any:
    """The loop's estimator of ``kind`` (ClosedLoopSettings.estimator) with ``detector``."""
    if kind == "lowpass":
        return LowPassEstimator(system.lines, detector=detector)
    cls = EKFObserver if kind == "ekf" else PassiveObserver
    return cls.from_scenario(system, sea_state=system.scenario.sea_state(sea_state), detector=detector)


def _run(sea_state: str, duration: float, seed: int, detector: Any, faults=(), estimator: str = DEFAULT_ESTIMATOR) -> Any:
    sc = tapm_opt.load_scenario(SCENARIO)
    system = System.from_scenario(sc)
    plant = Plant(sc, sea_state=sea_state, seed=seed, faults=list(faults))
    est = _estimator(estimator, system, sea_state, detector)
    return run_closed_loop(plant, build_controller(sc, {"type": "pid"}), ClosedLoopSettings(duration=duration),
                           system=system, estimator=est)


def _false_alarms(events: list[dict], breaks: dict[str, float]) -> int:
    return sum(1 for e in events if not (e["line"] in breaks and e["t"] >= breaks[e["line"]]))


def intact_job(args: tuple[str, float, int]) -> dict:
    sea_state, duration, seed, estimator = args
    lines = System.from_scenario(tapm_opt.load_scenario(SCENARIO)).lines
    res_det, drop_det = TensionResidualDetector(lines), TensionDropDetector(lines)
    both = Alongside(res_det, drop_det)
    w0 = time.perf_counter()
    r = _run(sea_state, duration, seed, both, estimator=estimator)
    brk = break_times(r)
    T = r.group("T_fairlead")
    return {"sea_state": sea_state, "duration": duration, "wall": time.perf_counter() - w0, "plant_breaks": brk,
            "fa_residual": _false_alarms(res_det.events, brk), "fa_drop": _false_alarms(drop_det.events, brk),
            "h": res_det.threshold, "peak": float(np.max(res_det.peak)),
            "worst_drop": float(np.nanmax(res_det.worst_drop)),
            "worst_line": res_det.line_ids[int(np.nanargmax(res_det.worst_drop))],
            "sigma": res_det.sigma.tolist(), "bias": res_det.bias.tolist(),
            "drop_min_ratio": both.min_ratio, "samples": res_det.samples,
            "exact_calls": res_det._predict.exact_calls,
            "us_median": 1e6 * float(np.median(both.times)), "us_p99": 1e6 * float(np.percentile(both.times, 99)),
            "T_mean": T.mean(axis=0).tolist(), "line_ids": list(lines.line_ids)}


def break_job(args: tuple[str, str, int]) -> dict:
    line, kind, seed, estimator = args
    lines = System.from_scenario(tapm_opt.load_scenario(SCENARIO)).lines
    det = TensionResidualDetector(lines) if kind == "residual" else TensionDropDetector(lines)
    r = _run("storm", T_END, seed, det, [Fault(kind="line_break", line=line, time=T_BREAK)], estimator=estimator)
    brk = break_times(r)
    log = r.meta["estimator_log"]
    after = [e for e in log if e["t"] >= T_BREAK]
    mine = [e for e in after if e["line"] == line]
    return {"line": line, "kind": kind, "plant_breaks": brk,
            "delay": (mine[0]["t"] - brk.get(line, T_BREAK)) if mine else math.nan,
            "isolated": bool(after) and after[0]["line"] == line,
            "others": [e["line"] for e in log if e["line"] != line],
            "statistic": mine[0].get("statistic") if mine else None}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="30 min intact runs and 4 of the 12 line breaks")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--sea-states", default="calm,normal,storm", help="comma-separated sea states of the intact runs")
    ap.add_argument("--estimator", choices=ESTIMATOR_KINDS, default=DEFAULT_ESTIMATOR,
                    help="the loop's estimator that carries the detectors (default: the loop's default)")
    a = ap.parse_args(argv)
    print(machine_info())
    lines = System.from_scenario(tapm_opt.load_scenario(SCENARIO)).lines
    ids = list(lines.line_ids)
    duration = 1800.0 if a.quick else 3 * 3600.0
    breaks = ["1", "4", "9", "12"] if a.quick else ids
    intact = [(ss, duration, a.seed, a.estimator) for ss in a.sea_states.split(",")]
    brk = [(lid, kind, a.seed, a.estimator) for lid in breaks for kind in ("residual", "drop")]
    w0 = time.perf_counter()
    with ProcessPoolExecutor(max(1, min(a.workers, 2))) as ex:
        fi = [ex.submit(intact_job, j) for j in intact]
        fb = [ex.submit(break_job, j) for j in brk]
        ri = [f.result() for f in fi]
        rb = [f.result() for f in fb]
    wall = time.perf_counter() - w0

    print(f"\nscenario {SCENARIO}, PID, estimator {a.estimator}, seed {a.seed}; TensionResidualDetector defaults "
          f"(h = {ri[0]['h']:.2f}), TensionDropDetector defaults (20 % of pretension for 5 s)")
    print(f"\nintact runs, {duration / 3600:g} h each")
    print(f"{'sea state':<10}{'false alarms res/drop':>23}{'max g':>8}{'h - max g':>11}{'worst drop/shift':>18}"
          f"{'(line)':>8}{'drop: min T/thr':>17}{'us/update med/p99':>20}{'plant breaks':>14}")
    for r in ri:
        print(f"{r['sea_state']:<10}{r['fa_residual']:>13d} / {r['fa_drop']:<7d}{r['peak']:>8.2f}"
              f"{r['h'] - r['peak']:>11.2f}{r['worst_drop']:>18.3f}{r['worst_line']:>8}{r['drop_min_ratio']:>17.2f}"
              f"{r['us_median']:>12.1f} / {r['us_p99']:<6.1f}{len(r['plant_breaks']):>12d}")
    for r in ri:
        print(f"  {r['sea_state']}: {r['samples']} samples tested, {r['exact_calls']} beyond the tension tables "
              f"(exact catenary), run {r['wall']:.0f} s wall")
        print(f"  {r['sea_state']}: mean tension [kN] " + " ".join(f"{lid}:{T / 1e3:.0f}" for lid, T in
                                                             zip(r["line_ids"], r["T_mean"])))
        print(f"  {r['sea_state']}: residual s_i [kN] " + " ".join(f"{v / 1e3:.0f}" for v in r["sigma"])
              + "; b_i [kN] " + " ".join(f"{v / 1e3:.0f}" for v in r["bias"]))
    print(f"\nline breaks in the storm at {T_BREAK:g} s, run to {T_END:g} s")
    print(f"{'line':<6}{'delay residual [s]':>20}{'delay drop [s]':>16}{'isolated res/drop':>19}{'other detections':>18}")
    by = {(r["line"], r["kind"]): r for r in rb}
    for lid in breaks:
        x, y = by[(lid, "residual")], by[(lid, "drop")]
        oth = ",".join(x["others"] + [f"{o}(drop)" for o in y["others"]]) or "-"
        print(f"{lid:<6}{x['delay']:>20.1f}{y['delay']:>16.1f}{'yes' if x['isolated'] else 'NO':>12} / "
              f"{'yes' if y['isolated'] else 'NO':<5}{oth:>18}")
    dr = np.array([by[(lid, "residual")]["delay"] for lid in breaks])
    dd = np.array([by[(lid, "drop")]["delay"] for lid in breaks])
    print(f"delay residual: max {np.nanmax(dr):.1f} s, mean {np.nanmean(dr):.1f} s; drop: max {np.nanmax(dd):.1f} s, "
          f"mean {np.nanmean(dd):.1f} s; all detected within 30 s and isolated: "
          f"{bool(np.all(dr <= 30) and all(by[(lid, 'residual')]['isolated'] for lid in breaks))}")
    print(f"\nwall time {wall:.0f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
