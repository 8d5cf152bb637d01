"""Throughput of the numeric elastic catenary (tapm_opt.models.catenary.solve).

Printed figures, not a timed test. Run from the repository root::

    python benchmarks/bench_catenary.py [--n 10000] [--repeats 9]

Reports microseconds per line solve for one vectorised call over N configurations that span
every regime (the regime mix is printed), the median over the repeats, and the time of one call
with scalar inputs for reference. Target: <= 5 us per solve (vectorised).
"""

from __future__ import annotations

import argparse
import os
import platform
import sys
import time

import casadi
import numpy as np

from tapm_opt.models import catenary as cat
from _machine import machine_info  # noqa: E402  (benchmarks/ is on sys.path when run)




def configurations(n: int, seed: int = 0):
    """n line configurations (L = 1000 m) drawn to cover every regime."""
    rng = np.random.default_rng(seed)
    L = np.full(n, 1000.0)
    kind = rng.choice(6, size=n, p=[0.15, 0.35, 0.30, 0.05, 0.05, 0.10])
    XF = rng.uniform(0.0, 1.05, n) * L
    ZF = rng.uniform(0.0, 1.05, n) * L
    EA = 10.0 ** rng.uniform(7.0, 12.0, n)
    w = rng.uniform(50.0, 2000.0, n)
    CB = np.where(rng.random(n) < 0.4, rng.uniform(0.1, 1.0, n), 0.0)
    # steer the draws toward each regime (the solver decides the regime, printed below)
    d = np.hypot(XF, ZF)
    taut = kind == 2                      # close to or beyond the straight length: suspended
    XF[taut] *= (rng.uniform(0.97, 1.01, taut.sum()) * L[taut] / np.maximum(d[taut], 1e-9))
    ZF[taut] *= (rng.uniform(0.97, 1.01, taut.sum()) * L[taut] / np.maximum(d[taut], 1e-9))
    td = kind == 1                        # moderately slack: touching down
    XF[td] *= (rng.uniform(0.90, 0.99, td.sum()) * L[td] / np.maximum(d[td], 1e-9))
    ZF[td] *= (rng.uniform(0.90, 0.99, td.sum()) * L[td] / np.maximum(d[td], 1e-9))
    vert = kind == 3
    XF[vert] = 0.0
    # beyond the self-weight stretch L + w L^2 / (2 EA): the anchor lifts (else: slack)
    ZF[vert] = L[vert] + w[vert] * L[vert] ** 2 / (2 * EA[vert]) + rng.uniform(0.0, 0.01, vert.sum()) * L[vert]
    bed = kind == 4
    ZF[bed] = 0.0
    XF[bed] = rng.uniform(1.0, 1.01, bed.sum()) * L[bed]
    w[kind == 5] = 0.0
    return XF, ZF, L, EA, w, CB


def timeit(fn, repeats: int) -> np.ndarray:
    out = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        out.append(time.perf_counter() - t0)
    return np.array(out)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=10_000, help="configurations per vectorised call")
    ap.add_argument("--repeats", type=int, default=9, help="repeats (>= 7); the median is reported")
    args = ap.parse_args(argv)
    repeats = max(args.repeats, 7)
    print(machine_info())
    print()
    XF, ZF, L, EA, w, CB = configurations(args.n)
    sol = cat.solve(XF, ZF, L, EA, w, CB=CB)  # warm-up, and the regime mix
    names, counts = np.unique(sol.regime_names(), return_counts=True)
    mix = ", ".join(f"{nm} {c / args.n:.0%}" for nm, c in zip(names, counts))
    fr = np.mean((sol.regime == cat.TOUCHDOWN) & (CB > 0))
    print(f"regime mix of {args.n} configurations: {mix} (touchdown with friction {fr:.0%}); "
          f"Newton iterations {sol.iterations}")

    t = timeit(lambda: cat.solve(XF, ZF, L, EA, w, CB=CB), repeats)
    per = t / args.n * 1e6
    print(f"vectorised: {np.median(per):.2f} us per solve (median of {repeats}; min {per.min():.2f}, "
          f"max {per.max():.2f}); {np.median(t) * 1e3:.1f} ms per call of {args.n}  [target <= 5 us]")

    reg = (sol.regime == cat.TOUCHDOWN) | (sol.regime == cat.SUSPENDED)
    t = timeit(lambda: cat.solve(XF[reg], ZF[reg], L[reg], EA[reg], w[reg], CB=CB[reg]), repeats)
    print(f"vectorised, regular regimes only (Newton, n = {reg.sum()}): "
          f"{np.median(t) / reg.sum() * 1e6:.2f} us per solve")

    idx = np.flatnonzero(sol.regime == cat.TOUCHDOWN)[:200]
    n_scalar = idx.size

    def scalar_calls():
        for i in idx:
            cat.solve(float(XF[i]), float(ZF[i]), float(L[i]), float(EA[i]), float(w[i]), CB=float(CB[i]))

    t = timeit(scalar_calls, repeats) / n_scalar * 1e6
    print(f"scalar inputs (one touchdown configuration per call): {np.median(t):.1f} us per call "
          f"(median of {repeats} x {n_scalar} calls)")


if __name__ == "__main__":
    sys.exit(main())
