"""Evaluation time of the symbolic mooring load tau_moor(eta) and its Jacobian (CasADi).

Printed figures, not a timed test. Run from the repository root::

    python benchmarks/bench_mooring_symbolic.py [--calls 3000]

For an 8-line turret mooring (the built-in ``ren8`` scenario if present, else aamo4 with 8 lines
at 45 deg steps) it builds, once, a CasADi Function eta -> (tau_moor, d tau_moor / d eta) for
each kind of ``MooringModel.force_function`` ("catenary", "characteristic", "linear") and times
single calls from Python with a new pose each call (median and 90th percentile over >= 2000
calls). The time of a trivial CasADi Function call is printed as the Python call floor, and the
time per evaluation inside CasADi (one call of ``F.map`` over 500 poses) without that overhead.
Target: <= 50 us for "catenary".
"""

from __future__ import annotations

import argparse
import copy
import math
import os
import platform
import sys
import time

import casadi as ca
import numpy as np

import tapm_opt
from tapm_opt.config import builtin_scenarios, scenario_from_dict, scenario_to_dict
from tapm_opt.models.mooring import MooringModel
from _machine import machine_info  # noqa: E402  (benchmarks/ is on sys.path when run)




def eight_line_scenario():
    """``ren8`` if it exists, else aamo4 with 8 equal lines at 45 deg steps."""
    if "ren8" in builtin_scenarios():
        return tapm_opt.load_scenario("ren8"), "ren8 (built-in)"
    d = copy.deepcopy(scenario_to_dict(tapm_opt.load_scenario("aamo4")))
    ref = d["vessel"].get("reference_point")
    if ref is not None and not all(math.isfinite(v) for v in ref):
        del d["vessel"]["reference_point"]
    proto = d["lines"][0]
    d["lines"] = []
    for i in range(8):
        a = math.radians(45.0 * i)
        ln = copy.deepcopy(proto)
        ln.update(id=str(i + 1), anchor=[2000.0 * math.cos(a), 2000.0 * math.sin(a), proto["anchor"][2]],
                  fairlead_angle_deg=45.0 * i)
        d["lines"].append(ln)
    d["meta"]["name"] = "aamo8"
    return scenario_from_dict(d), "aamo4 with 8 lines at 45 deg"


def time_calls(fn, poses) -> np.ndarray:
    out = np.empty(len(poses))
    for k, eta in enumerate(poses):
        t0 = time.perf_counter()
        fn(eta)
        out[k] = time.perf_counter() - t0
    return out * 1e6


def _once(fn, arg) -> float:
    t0 = time.perf_counter()
    fn(arg)
    return time.perf_counter() - t0


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--calls", type=int, default=3000, help="timed calls per kind (>= 2000)")
    args = ap.parse_args(argv)
    n = max(args.calls, 2000)
    print(machine_info())
    sc, label = eight_line_scenario()
    m = MooringModel.from_scenario(sc)
    print(f"scenario: {label}; {m.n_lines} lines, turret {m.turret_mode}; "
          f"regimes at the field zero point: {', '.join(sorted(set(m.solve_lines(np.zeros(3)).regime_names())))}")
    print()
    rng = np.random.default_rng(0)
    poses = [np.array(p) for p in rng.uniform([-30.0, -30.0, -0.5], [30.0, 30.0, 0.5], size=(n, 3))]

    eta = ca.MX.sym("eta", 3)
    floor_fn = ca.Function("floor", [eta], [eta, ca.DM.eye(3)])
    floor_fn(poses[0])
    t = time_calls(floor_fn, poses)
    print(f"{'trivial Function (Python call floor)':40s} median {np.median(t):7.1f} us   p90 {np.percentile(t, 90):7.1f} us")

    results, mapped = {}, {}
    for kind in ("catenary", "characteristic", "linear"):
        t0 = time.perf_counter()
        f = m.force_function(kind)
        tau = f(eta)
        F = ca.Function(f"tau_and_jac_{kind}", [eta], [tau, ca.jacobian(tau, eta)], ["eta"], ["tau", "J"])
        build = time.perf_counter() - t0
        F(poses[0])  # warm-up
        t = time_calls(F, poses)
        results[kind] = t
        target = "  [target <= 50 us]" if kind == "catenary" else ""
        print(f"{'tau_moor + Jacobian, ' + kind:40s} median {np.median(t):7.1f} us   "
              f"p90 {np.percentile(t, 90):7.1f} us   ({n} calls; built in {build * 1e3:.0f} ms){target}")
        # the same work without the per-call Python overhead: one call of F.map over 500 poses
        Fm = F.map(500)
        P = np.column_stack(poses[:500])
        Fm(P)
        tm = np.array([_once(Fm, P) for _ in range(7)]) / 500 * 1e6
        mapped[kind] = np.median(tm)

    print("\nper evaluation inside CasADi (F.map over 500 poses, one call; median of 7): "
          + ", ".join(f"{k} {v:.1f} us" for k, v in mapped.items()))

    # the catenary Function against the numeric model on the timed poses (a benchmark of wrong
    # answers is worthless)
    f = m.force_function("catenary")
    err = max(np.abs(np.array(f(p)).ravel() - m.force(p)).max() / max(np.abs(m.force(p)).max(), 1.0)
              for p in poses[:50])
    print(f"\ncheck: catenary Function vs numeric force on 50 of the poses, max relative error {err:.1e}")


if __name__ == "__main__":
    sys.exit(main())
