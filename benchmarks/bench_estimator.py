"""Mooring-load evaluation in the low-pass estimator: exact catenary vs tabulated evaluator.

Printed figures, not a timed test. Run from the repository root::

    python benchmarks/bench_estimator.py [--scenario fpso] [--calls 3000] [--repeats 3]

On one scenario (default ``fpso``, 12 lines) it times, per call from Python, on the same poses:

* ``MooringModel.force(eta)`` — the elastic catenary of every line solved numerically;
* ``MooringModel.force_fast(eta)`` and the evaluator object ``MooringModel.load_evaluator()``
  called directly — the tabulated characteristics (numba kernel), and the evaluator's numpy path;

over two pose sets: a slowly moving closed-loop-like sequence (low-frequency surge/sway/yaw
excursions up to ~60 m plus 1 m wave-frequency motion, one pose per 0.5 s control step) and
random poses (body origin uniform in a 100 m disc, any heading). Median and p90 per call (the
median of ``--repeats`` passes over the poses), the ratio exact / fast, and the whole
``LowPassEstimator.update`` per call on the slow sequence, with the tabulated load (the default)
and with the exact ``force`` (a model object that offers ``force`` only). Before timing, the
fast load is checked against ``force`` on every timed pose (largest difference printed), so a fast
wrong answer cannot pass for a result. Target: <= 30 us per mooring-load call, Python included.
"""

from __future__ import annotations

import argparse
import sys
import time

import numpy as np

import tapm_opt
from tapm_opt.estimation.lowpass import LowPassEstimator
from tapm_opt.interfaces import Measurement
from tapm_opt.models.mooring import MooringModel
from _machine import machine_info  # noqa: E402  (benchmarks/ is on sys.path when run)


def slow_poses(n: int, dt: float = 0.5) -> np.ndarray:
    """A closed-loop-like pose sequence: LF excursions (periods 150-600 s) plus WF motion (10 s)."""
    t = np.arange(n) * dt
    x = 45.0 * np.sin(2 * np.pi * t / 300.0) + 15.0 * np.sin(2 * np.pi * t / 150.0 + 0.4) + 1.0 * np.sin(2 * np.pi * t / 10.0)
    y = 30.0 * np.cos(2 * np.pi * t / 400.0) - 10.0 + 0.6 * np.sin(2 * np.pi * t / 9.0 + 1.0)
    psi = 0.25 * np.sin(2 * np.pi * t / 600.0) + 0.01 * np.sin(2 * np.pi * t / 11.0)
    return np.stack([x, y, psi], axis=1)


def random_poses(n: int, radius: float = 100.0, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    r = radius * np.sqrt(rng.random(n))
    a = rng.uniform(-np.pi, np.pi, n)
    return np.stack([r * np.cos(a), r * np.sin(a), rng.uniform(-np.pi, np.pi, n)], axis=1)


def per_call(fn, args_list, repeats: int) -> np.ndarray:
    """Seconds per call of fn(*args) for every element, the median over ``repeats`` passes."""
    out = np.empty((repeats, len(args_list)))
    pc = time.perf_counter
    for r in range(repeats):
        row = out[r]
        for k, args in enumerate(args_list):
            t0 = pc()
            fn(*args)
            row[k] = pc() - t0
    return np.median(out, axis=0)


def stats(ts: np.ndarray) -> tuple[float, float]:
    return float(np.median(ts) * 1e6), float(np.percentile(ts, 90) * 1e6)


class ExactOnly:
    """A mooring model that offers ``force`` only: the estimator then calls the exact catenary."""

    def __init__(self, model: MooringModel):
        self.force = model.force


def measurements(poses: np.ndarray, n_lines: int, dt: float = 0.5) -> list[Measurement]:
    out = []
    for k, eta in enumerate(poses):
        t = k * dt
        out.append(Measurement(t=t, position=eta[:2], heading=float(eta[2]), tensions=np.zeros(n_lines),
                               t_position=t, t_heading=t, t_tensions=t, tau_thr=np.array([1e5, -2e5, 1e6])))
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenario", default="fpso", help="built-in scenario name or TOML path")
    ap.add_argument("--calls", type=int, default=3000, help="poses per set (>= 500)")
    ap.add_argument("--repeats", type=int, default=3, help="passes over the poses; the median per call is kept")
    args = ap.parse_args(argv)
    n = max(args.calls, 500)
    repeats = max(args.repeats, 1)
    print(machine_info())
    sc = tapm_opt.load_scenario(args.scenario)
    model = MooringModel.from_scenario(sc)
    t0 = time.perf_counter()
    ev = model.load_evaluator()
    t_build = time.perf_counter() - t0
    t0 = time.perf_counter()
    ev_np = model.load_evaluator(kernel="numpy")
    t_build_np = time.perf_counter() - t0
    print(f"scenario {args.scenario}: {model.n_lines} lines, turret {model.turret_mode}; {ev!r}")
    print(f"evaluator built in {t_build * 1e3:.0f} ms (tables + numba kernel load/compile; tables alone "
          f"{t_build_np * 1e3:.0f} ms); tables cover offsets up to {ev.max_offset:g} m at any heading; "
          f"largest checked table error {ev.max_error:.2f} x rtol\n")

    sets = {"slow sequence": slow_poses(n), "random, 100 m disc": random_poses(n)}
    # correctness on every timed pose first
    for name, poses in sets.items():
        worst_f, worst_n, worst_rel = 0.0, 0.0, 0.0
        for eta in poses:
            a, b = ev(eta), model.force(eta)
            d = np.abs(a - b)
            worst_f, worst_n = max(worst_f, d[:2].max()), max(worst_n, d[2])
            worst_rel = max(worst_rel, d[:2].max() / model.solve_lines(eta).HF.max())
            np.testing.assert_allclose(ev_np(eta), a, rtol=0, atol=1e-9 * np.abs(b).max())
        print(f"check, {name}: |fast - force| <= {worst_f:.3g} N (X, Y), {worst_n:.3g} N m (N); "
              f"{worst_rel:.2g} of the largest line tension's horizontal component; "
              f"{ev.exact_calls} pose(s) beyond the tables")
    print()

    rows = []
    for name, poses in sets.items():
        eta_args = [(np.array(e),) for e in poses]
        t_exact = per_call(model.force, eta_args, repeats)
        t_fast = per_call(model.force_fast, eta_args, repeats)
        t_ev = per_call(ev, eta_args, repeats)
        t_np = per_call(ev_np, eta_args, repeats)
        rows.append((name, stats(t_exact), stats(t_fast), stats(t_ev), stats(t_np)))
    w = max(len(r[0]) for r in rows)
    print(f"{'poses':<{w}} | {'model.force':>15} | {'force_fast':>15} | {'evaluator(eta)':>15} | "
          f"{'numpy path':>15} | ratio")
    print(f"{'':<{w}} | {'median / p90 us':>15} | {'median / p90 us':>15} | {'median / p90 us':>15} | "
          f"{'median / p90 us':>15} | force / force_fast (median)")
    for name, e, f, v, p in rows:
        print(f"{name:<{w}} | {e[0]:7.1f} /{e[1]:6.1f} | {f[0]:7.2f} /{f[1]:6.2f} | {v[0]:7.2f} /{v[1]:6.2f} | "
              f"{p[0]:7.1f} /{p[1]:6.1f} | {e[0] / f[0]:.0f}x")

    # the whole estimator step, on the slow sequence
    ms = measurements(sets["slow sequence"], model.n_lines)
    res = {}
    for label, m in (("tabulated (default)", model), ("exact force", ExactOnly(model))):
        samples = []
        for _ in range(repeats):
            est = LowPassEstimator(m)
            est.update(ms[0].t, ms[0])  # builds / fetches the evaluator
            ts = np.empty(len(ms) - 1)
            pc = time.perf_counter
            for k, meas in enumerate(ms[1:]):
                t0 = pc()
                est.update(meas.t, meas)
                ts[k] = pc() - t0
            samples.append(ts)
        res[label] = stats(np.median(np.array(samples), axis=0))
    print()
    for label, (med, p90) in res.items():
        print(f"LowPassEstimator.update, {label}: median {med:.1f} us, p90 {p90:.1f} us per call")
    print(f"ratio exact / tabulated (median): {res['exact force'][0] / res['tabulated (default)'][0]:.0f}x")
    worst = max(max(r[2][0], r[3][0]) for r in rows)
    print(f"\ntarget <= 30 us per mooring-load call: {'met' if worst <= 30.0 else 'NOT met'} "
          f"(largest median {worst:.2f} us)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
