"""Optimal setpoints and the reliability monitor: cost per call against the catenary of the lines.

Printed figures, not a timed test. Run from the repository root::

    python benchmarks/bench_setpoint.py [--scenario fpso] [--sea-state normal] [--solves 20]

Times, in one process, on the scenario's lines and riser:

* the reference workload: ``MooringModel.force(eta)`` — the elastic catenary of every line solved
  numerically (one call);
* ``SetpointProblem.solve`` of each method (``quadratic``, ``reliability``, ``unified``) from the
  field zero point (cold: every start) and warm-started from its optimum (the layer's re-solve);
* ``ReliabilityMonitor.update`` with every line's tension and the two riser angles, over a
  synthetic hour sampled at 1 s;

and prints each as a median and as a ratio to the reference, so the figures travel between
machines of different speed.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

import tapm_opt
from tapm_opt.control.setpoint_opt import SetpointProblem, WorkingPoint
from tapm_opt.design.loads import mean_environmental_load
from tapm_opt.estimation.reliability import monitor_for
from tapm_opt.models.riser import RiserModel
from tapm_opt.models.system import System
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
    ap.add_argument("--sea-state", default="normal")
    ap.add_argument("--solves", type=int, default=20)
    a = ap.parse_args()
    print(machine_info())
    sc = tapm_opt.load_scenario(a.scenario)
    system = System.from_scenario(sc)
    riser = RiserModel.from_scenario(sc, a.sea_state) if sc.riser is not None else None
    eta = np.array([-15.0, 3.0, 0.05])
    ref = median_time(lambda: system.lines.force(eta), 200)
    print(f"reference: MooringModel.force, {system.lines.n_lines} lines: {1e3 * ref:.3f} ms per call")
    tau = np.asarray(mean_environmental_load(sc, a.sea_state, 0.0).total, float)
    wp = WorkingPoint(p=np.zeros(2), psi=0.0, tau_env=tau, ksigma_lines=np.full(system.lines.n_lines, 2e5),
                      ksigma_riser=np.radians([0.05, 0.1]), v_c=np.zeros(2) if riser is None else riser.v_c,
                      r_lf=6.0)
    for method in ("quadratic", "reliability", "unified"):
        prob = SetpointProblem(system, riser, method)
        p_opt, _ = prob.solve(wp)
        cold = median_time(lambda: prob.solve(wp), a.solves)
        warm = median_time(lambda: prob.solve(wp.at(p_opt), starts=(p_opt,), warm=True), a.solves)
        print(f"{method:12s} solve: cold {1e3 * cold:8.1f} ms ({cold / ref:7.0f} x reference), "
              f"warm {1e3 * warm:8.1f} ms ({warm / ref:7.0f} x reference); optimum {np.round(p_opt, 2)} m")
    mon = monitor_for(sc)
    rng = np.random.default_rng(0)
    T0 = np.asarray(system.lines.tensions(np.zeros(3)), float)
    t = np.arange(0.0, 3600.0, 1.0)
    X = T0[None, :] * (1 + 0.02 * np.sin(2 * np.pi * t[:, None] / 10.0 + rng.random(T0.size)))
    if sc.riser is not None:
        X = np.hstack([X, np.full((t.size, 2), np.radians(2.0))])
    w = []
    for ti, xi in zip(t, X):
        t0 = time.perf_counter()
        mon.update(ti, xi)
        w.append(time.perf_counter() - t0)
    m = float(np.median(w))
    print(f"ReliabilityMonitor.update, {mon.m} signals: {1e6 * m:.1f} us per sample ({m / ref:.3f} x reference)")


if __name__ == "__main__":
    main()
