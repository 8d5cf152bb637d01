"""Cost of the composite-line quasi-static solve against the homogeneous catenary, in one process.

Printed figures, not a timed test. Run from the repository root::

    python benchmarks/bench_composite.py [--n 257] [--repeats 7]

Three workloads, each as a ratio to its homogeneous counterpart run in the same process (the
machine is shared, so only ratios are meaningful):

1. one vectorised solve of ``n`` fairlead distances of fpso's line as its chain-wire-chain
   sections with a buoy (``models.composite.solve``) against the equivalent homogeneous line
   (``models.catenary.solve``), and the composite solve without its continuation start;
2. the mooring model's load tables (``MooringModel.load_evaluator``: adaptive Hermite tables of
   every distinct line, checked to 1e-9) of the composite fpso against fpso;
3. one evaluation of the tabulated load at a pose (the control loop's path), composite against
   homogeneous — the tables make the composite lines as cheap as the homogeneous ones;
4. equilibria of fpso's chain-wire-chain mooring under eight mean loads (``MooringModel.equilibrium``,
   the path of gain tables, capability and setpoints), each line's solve started from its last
   solution (``composite.WarmStart``) against started afresh every time.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from _machine import machine_info  # noqa: E402
from test_composite import composite_fpso  # noqa: E402

from tapm_opt.config import load_scenario  # noqa: E402
from tapm_opt.models import catenary, composite  # noqa: E402
from tapm_opt.models.mooring import MooringModel  # noqa: E402


def median_time(fn, repeats: int) -> float:
    out = []
    for _ in range(repeats):
        t = time.perf_counter()
        fn()
        out.append(time.perf_counter() - t)
    return float(np.median(out))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=257, help="fairlead distances per solve")
    ap.add_argument("--repeats", type=int, default=7)
    a = ap.parse_args()
    print(machine_info())
    homo = MooringModel.from_scenario(load_scenario("fpso_equivalent"))
    comp = MooringModel.from_scenario(composite_fpso(buoy=True))
    line = comp.composite[0]
    XF = np.linspace(1900.0, 2030.0, a.n)
    t_c = median_time(lambda: composite.solve(XF, comp.ZF[0], line, h_A=comp.h_A[0]), a.repeats)
    t_h = median_time(lambda: catenary.solve(XF, homo.ZF[0], homo.L[0], homo.EA[0], homo.w[0]), a.repeats)
    t_n = median_time(lambda: composite.solve(XF, comp.ZF[0], line, h_A=comp.h_A[0], continuation=False), a.repeats)
    print(f"1. solve of {a.n} distances: composite {t_c * 1e3:.2f} ms, homogeneous {t_h * 1e3:.2f} ms, "
          f"ratio {t_c / t_h:.1f} ({t_c / a.n * 1e6:.0f} us per composite configuration); without the "
          f"continuation start {t_n * 1e3:.2f} ms ({t_n / t_c:.1f} x)")

    def tables(sc_model):
        m = MooringModel(**{f: getattr(sc_model, f) for f in (
            "line_ids", "anchors", "p_T", "p_cot_B", "turret_angle", "turret_mode", "ZF", "L", "EA", "w", "CB",
            "MBS", "h_A", "MBS_std", "composite")})
        return m.load_evaluator()

    reps = max(1, a.repeats // 3)
    t_tc = median_time(lambda: tables(comp), reps)
    t_th = median_time(lambda: tables(homo), reps)
    ev_c, ev_h = tables(comp), tables(homo)
    print(f"2. load tables: composite {t_tc:.2f} s ({ev_c.n_nodes} nodes), homogeneous {t_th:.3f} s "
          f"({ev_h.n_nodes} nodes), ratio {t_tc / t_th:.0f}")
    eta = np.array([12.0, -7.0, 0.03])
    ev_c(eta), ev_h(eta)
    n_ev = 20000
    t_ec = median_time(lambda: [ev_c(eta) for _ in range(n_ev)], 3) / n_ev
    t_eh = median_time(lambda: [ev_h(eta) for _ in range(n_ev)], 3) / n_ev
    print(f"3. tabulated load per call: composite {t_ec * 1e6:.2f} us, homogeneous {t_eh * 1e6:.2f} us, "
          f"ratio {t_ec / t_eh:.2f}")

    fpso = load_scenario("fpso")
    loads = [2.5e6 * np.array([np.cos(b), np.sin(b), 0.0]) for b in np.linspace(0.0, np.pi, 8)]

    def equilibria():
        m = MooringModel.from_scenario(fpso)
        return [m.equilibrium(tau, psi=0.0) for tau in loads]

    keep = composite.WarmStart.start

    def cold():
        composite.WarmStart.start = lambda self, *args: None
        try:
            return equilibria()
        finally:
            composite.WarmStart.start = keep

    e_w, e_c = equilibria(), cold()
    diff = max(float(np.max(np.abs(x - y))) for x, y in zip(e_w, e_c))
    t_w, t_0 = [], []
    for _ in range(reps):      # interleaved
        t_0.append(median_time(cold, 1))
        t_w.append(median_time(equilibria, 1))
    print(f"4. eight equilibria of fpso: warm start {np.median(t_w):.2f} s, afresh {np.median(t_0):.2f} s, "
          f"ratio {np.median(t_0) / np.median(t_w):.1f}; poses agree to {diff:.1e}")


if __name__ == "__main__":
    main()
