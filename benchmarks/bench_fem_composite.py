"""FEM step cost per node on composite lines against homogeneous lines of the same size, in one process.

Printed figures, not a timed test. Run from the repository root::

    python benchmarks/bench_fem_composite.py [--segments 40] [--steps 4000] [--repeats 7]

Two line systems of the same size: ``fpso_equivalent`` (12 homogeneous lines of ``--segments`` segments) and
the same 12 lines as chain-wire-chain composite lines (300 m chain, 1900 m wire, 100 m chain from
the anchor up, the segments shared so the longest is shortest) with a 353 kN buoy at the lower joint and a 20 t
clump at the upper one (24 joint nodes with their own drag, added mass and weight). Both are
settled at the field zero point and stepped along the same surging and yawing fairlead path;
for each kernel ("numba", the compiled kernel, and "numpy", the reference path) the time of
``FEMLines.advance`` in batches of 64 steps is divided by steps x nodes: nanoseconds per node and
step (median of the repeats, min-max in brackets, the two systems alternating in every repeat).
The figure of interest is the ratio composite / homogeneous per node (the goal: no slower per node
than a homogeneous line). The stable steps of the two systems are printed too: a composite line's
step is set by its stiffest section (here the short top chain), which changes the cost per
simulated second, not per node-step.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _machine import machine_info  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from test_fem_composite import composite_fpso as _test_composite_fpso  # noqa: E402

import tapm_opt  # noqa: E402
from tapm_opt.plant.mooring_fem import MooringFEM  # noqa: E402

ZERO = np.zeros(3)


def composite_fpso():
    """fpso's 12 lines as chain-wire-chain with a buoy and a clump (the tests' scenario)."""
    return _test_composite_fpso(lower="buoy", upper="clump")


class Run:
    """FEMLines.advance of a settled line system on one kernel in batches of 64 along a path;
    ``__call__`` returns ns per node and step."""

    def __init__(self, sc, segments: int, steps: int):
        self.m = m = MooringFEM(sc, segments=segments)
        m.initialise(ZERO)
        m.settle(ZERO)
        self.r0, self.v0 = m.fem.r.copy(), m.fem.v.copy()
        t = np.arange(1, steps + 1) * m.dt
        eta = np.column_stack([4.0 * np.sin(0.3 * t), 1.0 * np.sin(0.2 * t), 0.02 * np.sin(0.25 * t)])
        eta_dot = np.column_stack([1.2 * np.cos(0.3 * t), 0.2 * np.cos(0.2 * t), 0.005 * np.cos(0.25 * t)])
        self.r_seq, self.v_seq = m.fairlead_states(eta, eta_dot)
        self.vc = np.zeros((m.fem.n_nodes, 3))
        self.steps = steps

    def __call__(self, kernel: str) -> float:
        fem, n = self.m.fem, self.steps
        fem.kernel = kernel
        fem.r, fem.v = self.r0.copy(), self.v0.copy()
        t0 = time.perf_counter()
        for i in range(0, n, 64):
            fem.advance(self.m.dt, self.r_seq[i:i + 64], self.v_seq[i:i + 64], self.vc)
        ns = (time.perf_counter() - t0) / (n * fem.n_nodes) * 1e9
        fem.check_health()
        return ns


def stats(v):
    v = np.asarray(v, dtype=float)
    return float(np.median(v)), float(v.min()), float(v.max())


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--segments", type=int, default=40, help="segments per line (both systems)")
    ap.add_argument("--steps", type=int, default=4000, help="FEM steps per timed run (numba; numpy runs a quarter)")
    ap.add_argument("--repeats", type=int, default=7)
    a = ap.parse_args(argv)
    print(machine_info())
    runs = {"homogeneous": Run(tapm_opt.load_scenario("fpso_equivalent"), a.segments, a.steps),
            "composite": Run(composite_fpso(), a.segments, a.steps)}
    h, c = runs["homogeneous"].m.fem, runs["composite"].m.fem
    assert h.n_nodes == c.n_nodes
    print(f"fpso, 12 lines x {a.segments} segments, {h.n_nodes} nodes each; composite: sections "
          f"{c.lines.sections[0]['segments'].tolist()} per line, {c.joint_node.size} joint nodes")
    print(f"  stable step: homogeneous {h.stable_dt(0.9) * 1e3:.3f} ms, composite {c.stable_dt(0.9) * 1e3:.3f} ms "
          f"(safety 0.9)")
    for kernel in ("numba", "numpy"):
        for r in runs.values():  # warm-up (compiles or loads the kernel)
            r.steps, full = min(r.steps, 128), r.steps
            r(kernel)
            r.steps = full if kernel == "numba" else max(full // 4, 64)
        out = {k: [] for k in runs}
        for _ in range(a.repeats):
            for k, r in runs.items():
                out[k].append(r(kernel))
        s = {k: stats(v) for k, v in out.items()}
        ratio = s["composite"][0] / s["homogeneous"][0]
        ratio_min = s["composite"][1] / s["homogeneous"][1]
        print(f"  {kernel:5}: ns per node-step  homogeneous {s['homogeneous'][0]:8.2f} "
              f"[{s['homogeneous'][1]:.2f}-{s['homogeneous'][2]:.2f}]  composite {s['composite'][0]:8.2f} "
              f"[{s['composite'][1]:.2f}-{s['composite'][2]:.2f}]  ratio {ratio:.3f} (medians), "
              f"{ratio_min:.3f} (minima)")
        for r in runs.values():
            r.steps = a.steps
    return 0


if __name__ == "__main__":
    sys.exit(main())
