"""Per-step solve time of the MPC controllers (tapm_opt.control.mpc).

Printed figures, not a timed test. Run from the repository root::

    python benchmarks/bench_mpc.py [--steps 32] [--horizons 20 50] [--budget 20] [--no-fatrop]

Scenario: ``--scenario`` (default ``fpso``, 12 lines, six azimuths); ``ren8`` (8 catenary lines) gets
the six azimuths of ``fpso`` copied in if it has no thrusters and a 50 m safe radius if it has none.
Settings: the study defaults of ``tapm_opt.studies.controllers`` (``MPCSettings`` with
``MPC_DEFAULTS`` and the dead band ``MPC_DEAD_BAND`` x safe radius), ``decision="tau"``.

The state moves slowly and is prescribed (not a closed loop, so every path sees the same states):
radius 28 -> 44 m along a fixed bearing at 0.1 m/s, crossing the dead band, heading drifting by
0.05 deg per step, a constant environmental load of 0.5 MN. After 2 warm-up steps, 32 warm-started
steps are timed -- fewer (at least 5, marked *) where that would take more than ``--budget`` seconds,
none where a warm-up step takes more than ``--skip-above`` seconds (said so in the output), which keeps
the run to about 5 minutes. Paths: LinearMPC (piqp, OSQP, the condensed QP in DAQP);
NonlinearMPC with the "characteristic" and the "catenary" mooring x solver sqp, rti (one SQP
iteration per step), ipopt, fatrop, and the rti with its Gauss-Newton QP condensed for DAQP
(``qp_solver="daqp"``, ``tapm_opt.control.mpc_condensed``). Per path: build
time (for LinearMPC incl. the QP set-up in its first update), median / p95 / max of the wall time of
``update()`` (what the control loop sees: parameters, solve, first move), the solver call alone,
iterations, failed solves (fallbacks), and for the NLP paths the split of the solver's time between
the QP solver, the Hessian of the Lagrangian, the Jacobians, f/g and the rest (IPOPT: its linear
algebra) from ``nlpsol.stats()``.

``--move-blocks`` adds the linear MPC (piqp, DAQP) and the nonlinear SQP and RTI paths with move blocking
(``MPCSettings.move_blocks``): ``MOVE_BLOCKS[N]``, 5 moves at N = 20 and 8 at N = 50 (other horizons:
blocks doubling from 1 step).

Targets: nonlinear MPC <= 3 ms median and <= 10 ms p95 at N = 20 on the fastest path (plain CasADi +
IPOPT takes about 17 ms on a comparable problem here); linear MPC <= 1 ms median at N = 50.
"""

from __future__ import annotations

import argparse
import copy
import sys
import time

import numpy as np

import tapm_opt
from tapm_opt.config import scenario_from_dict, scenario_to_dict
from tapm_opt.control.estimate import Estimate, Setpoint
from tapm_opt.control.mpc import LinearMPC, MPCSettings, NonlinearMPC
from tapm_opt.geometry import rot_z
from _machine import machine_info  # noqa: E402  (benchmarks/ is on sys.path when run)

TARGET_NMPC_N20 = 3e-3  # [s] median, fastest nonlinear path (p95 <= 10 ms)
TARGET_LMPC_N50 = 1e-3  # [s] median, linear MPC

#: Move blocks of ``--move-blocks`` per horizon (the thrust held over each block).
MOVE_BLOCKS = {20: (1, 1, 2, 4, 12), 50: (1, 1, 2, 4, 6, 8, 12, 16)}


def move_blocks(N: int) -> tuple[int, ...]:
    """``MOVE_BLOCKS[N]``, or blocks of 1, 1, 2, 4, ... steps with the remainder last."""
    if N in MOVE_BLOCKS:
        return MOVE_BLOCKS[N]
    out, b = [], 1
    while sum(out) + b < N:
        out.append(b)
        b = b * 2 if len(out) > 1 else 1
    return tuple(out + [N - sum(out)])


def ren8_with_thrusters():
    """(scenario, description): ren8, given fpso's thrusters if it has none and a 50 m safe radius if
    it has none."""
    d = copy.deepcopy(scenario_to_dict(tapm_opt.load_scenario("ren8")))
    what = "ren8"
    if not d.get("thrusters"):
        d["thrusters"] = copy.deepcopy(scenario_to_dict(tapm_opt.load_scenario("fpso"))["thrusters"])
        d["meta"]["name"] = "ren8_fpso_thrusters"
        what += " + fpso's thrusters"
    else:
        what += " (its own thrusters)"
    limits = d.setdefault("limits", {})
    if limits.get("safe_radius") is None:
        limits["safe_radius"] = 50.0
        what += " + safe radius 50 m"
    return scenario_from_dict(d), what


def trajectory(n: int, dt: float):
    """(Estimate, Setpoint) of a slowly moving state, n steps."""
    bearing = np.radians(30.0)
    speed = 0.1  # [m/s] radial
    b_E = 0.5e6 * np.array([np.cos(bearing), np.sin(bearing), 0.0])  # [N] environmental load in {E}
    out = []
    for k in range(n):
        t = k * dt
        r = 28.0 + speed * t
        psi = np.radians(2.0 + 0.05 * k)
        eta = np.array([r * np.cos(bearing), r * np.sin(bearing), psi])
        nu = rot_z(psi).T @ np.array([speed * np.cos(bearing), speed * np.sin(bearing), 0.0])
        nu[2] = np.radians(0.05) / dt
        out.append(Estimate(t, eta, nu, rot_z(psi).T @ b_E))
    return out, Setpoint(np.zeros(3))


def _stats(ctrl) -> dict:
    try:
        return dict(ctrl._solver.stats())  # diagnosis only: where the solver's time goes
    except AttributeError:
        return {}


def run_case(scenario, settings, cls, steps: int, *, budget: float, skip_above: float):
    """Build, 2 warm-up steps, then ``steps`` timed steps (fewer if a step is slow: at most ``budget``
    seconds of timed steps, at least 5; none if a warm-up step takes more than ``skip_above`` s)."""
    t0 = time.perf_counter()
    if isinstance(cls, tuple):  # (the MPC class, its QP solver)
        cls, qp = cls
        ctrl = cls(scenario, settings, qp_solver=qp)
    else:
        ctrl = cls(scenario, settings)
    build = time.perf_counter() - t0
    ests, sp = trajectory(steps + 2, settings.dt)
    warm = []
    for est in ests[:2]:
        t1 = time.perf_counter()
        ctrl.update(est.t, est, sp)
        warm.append(time.perf_counter() - t1)
    if cls is LinearMPC:
        build += warm[0]  # the QP solver is set up at the first update
    first = ctrl.diagnostics[0]
    if warm[1] > skip_above:
        return {"skipped": f"a warm-up step took {warm[1]:.1f} s (> {skip_above:.0f} s) -- not timed"}
    n = steps if warm[1] * steps <= budget else max(5, int(budget / warm[1]))
    wall = []
    split = dict.fromkeys(("QP", "hess", "jac", "f/g", "total"), 0.0)
    for est in ests[2:2 + n]:
        t1 = time.perf_counter()
        ctrl.update(est.t, est, sp)
        wall.append(time.perf_counter() - t1)
        st = _stats(ctrl)
        if st:
            split["QP"] += st.get("t_wall_QP", 0.0)
            split["hess"] += st.get("t_wall_nlp_hess_l", 0.0)
            split["jac"] += sum(st.get(k, 0.0) for k in ("t_wall_nlp_jac_g", "t_wall_nlp_jac_fg", "t_wall_nlp_grad_f",
                                                         "t_wall_nlp_grad"))
            split["f/g"] += sum(st.get(k, 0.0) for k in ("t_wall_nlp_f", "t_wall_nlp_g", "t_wall_nlp_fg"))
            split["total"] += ctrl.diagnostics[-1].solve_time
    diag = ctrl.diagnostics[2:]
    return {
        "build": build, "first": first, "n": n, "wall": np.array(wall), "solve": np.array([d.solve_time for d in diag]),
        "its": np.array([d.iterations for d in diag]), "fail": int(sum(not d.success for d in diag)),
        "status": sorted({d.status for d in diag if not d.success}), "split": split if split["total"] else None,
    }


def fmt_ms(a: np.ndarray) -> str:
    return f"{np.median(a) * 1e3:8.2f} {np.percentile(a, 95) * 1e3:8.2f} {np.max(a) * 1e3:9.2f}"


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=32, help="timed steps per path (>= 30)")
    ap.add_argument("--horizons", type=int, nargs="+", default=[20, 50])
    ap.add_argument("--no-fatrop", action="store_true", help="do not try fatrop")
    ap.add_argument("--scenario", default="fpso",
                    help="built-in scenario (default fpso); 'ren8' gets fpso's thrusters and a 50 m safe radius")
    ap.add_argument("--budget", type=float, default=20.0, help="seconds of timed steps per path at most")
    ap.add_argument("--move-blocks", action="store_true",
                    help="also time the linear MPC and the nonlinear SQP with move blocking (MOVE_BLOCKS)")
    ap.add_argument("--skip-above", type=float, default=5.0, help="do not time a path whose warm-up step is slower")
    args = ap.parse_args(argv)
    steps = max(args.steps, 30)
    t_start = time.perf_counter()
    print(machine_info())
    if args.scenario == "ren8":
        sc, what = ren8_with_thrusters()
    else:
        sc, what = tapm_opt.load_scenario(args.scenario), args.scenario
    kinds = ", ".join(sorted({t.kind for t in sc.thrusters}))
    print(f"scenario {what}: {len(sc.lines)} lines, {len(sc.thrusters)} thrusters ({kinds}), "
          f"safe radius {sc.limits.safe_radius} m; {steps} timed steps after 2 warm-up steps")
    from tapm_opt.studies.controllers import MPC_DEAD_BAND, MPC_DEFAULTS

    base = dict(MPC_DEFAULTS, dead_band=MPC_DEAD_BAND * sc.limits.safe_radius)
    print(f"settings: the study defaults, MPCSettings + {base} (dt = {MPCSettings().dt} s)\n")

    paths = []
    for N in args.horizons:
        for qp in ("piqp", "osqp", "daqp"):
            paths.append((N, f"LMPC characteristic {qp}", (LinearMPC, qp), dict(mooring="characteristic")))
        for moor in ("characteristic", "catenary"):
            for solver in ("sqp", "rti", "ipopt", "fatrop"):
                if solver == "fatrop" and args.no_fatrop:
                    continue
                paths.append((N, f"NMPC {moor:14s} {solver}", NonlinearMPC, dict(mooring=moor, solver=solver)))
        paths.append((N, "NMPC characteristic rti daqp", (NonlinearMPC, "daqp"),
                      dict(mooring="characteristic", solver="rti")))
        if args.move_blocks:
            mb = move_blocks(N)
            for qp in ("piqp", "daqp"):
                paths.append((N, f"LMPC characteristic {qp}, {len(mb)} moves", (LinearMPC, qp),
                              dict(mooring="characteristic", move_blocks=mb)))
            for solver in ("sqp", "rti"):
                paths.append((N, f"NMPC characteristic {solver}, {len(mb)} moves", NonlinearMPC,
                              dict(mooring="characteristic", solver=solver, move_blocks=mb)))
            paths.append((N, f"NMPC characteristic rti daqp, {len(mb)} moves", (NonlinearMPC, "daqp"),
                          dict(mooring="characteristic", solver="rti", move_blocks=mb)))

    hdr = (f"{'N':>3} {'path':38s} {'build s':>8} {'median':>8} {'p95':>8} {'max':>9}   "
           f"{'solver':>8} {'its med':>7} {'its max':>7} {'fail':>4}  {'n':>3}   solver time: QP/hess/jac/f,g/rest")
    print("wall time of update() per step [ms]; 'solver' = median of the solver call alone [ms]")
    print(hdr)
    print("-" * len(hdr))
    results, notes = {}, []
    for N, name, cls, kw in paths:
        settings = MPCSettings(horizon=N, **base, **kw)
        r = run_case(sc, settings, cls, steps, budget=args.budget, skip_above=args.skip_above)
        if "skipped" in r:
            print(f"{N:3d} {name:38s} {r['skipped']}")
            notes.append(f"N = {N}, {name.split()[1]} {name.split()[2]}: {r['skipped']}")
            continue
        results[(N, name)] = r
        sp_txt = ""
        if r["split"]:
            t = r["split"]
            rest = t["total"] - t["QP"] - t["hess"] - t["jac"] - t["f/g"]
            sp_txt = " / ".join(f"{100 * v / t['total']:.0f}%" for v in (t["QP"], t["hess"], t["jac"], t["f/g"], rest))
        fail = f"{r['fail']:4d}"
        star = "*" if r["n"] < steps else " "
        print(f"{N:3d} {name:38s} {r['build']:8.2f} {fmt_ms(r['wall'])}   {np.median(r['solve']) * 1e3:8.2f} "
              f"{int(np.median(r['its'])):7d} {int(np.max(r['its'])):7d} {fail}  {r['n']:3d}{star}  {sp_txt}")
        if r["fail"]:
            notes.append(f"N = {N}, {name.split()[1]} {name.split()[2]}: {r['fail']} of {r['n']} solves failed "
                         f"(fallback to the shifted plan): {', '.join(r['status'])}")
        if not r["first"].success:
            notes.append(f"N = {N}, {name.split()[1]} {name.split()[2]}: the first (cold) solve failed: "
                         f"{r['first'].status}")
        sys.stdout.flush()
    print(f"* fewer timed steps: a step took longer than {args.budget:.0f} s / {steps} (time budget per path)")
    for n in notes:
        print("note:", n)
    print()
    nl20 = [(np.median(r["wall"]), name) for (N, name), r in results.items() if N == 20 and "NMPC" in name]
    if nl20:
        best, who = min(nl20)
        print(f"fastest nonlinear path at N = 20: {who.strip()} {best * 1e3:.2f} ms median  "
              f"[target <= {TARGET_NMPC_N20 * 1e3:.0f} ms; plain CasADi + IPOPT ~17 ms on a comparable problem]")
    lm50 = [(np.median(r["wall"]), name) for (N, name), r in results.items() if N == 50 and "LMPC" in name]
    if lm50:
        best, who = min(lm50)
        print(f"fastest linear MPC path at N = 50: {who.strip()} {best * 1e3:.2f} ms median  "
              f"[target <= {TARGET_LMPC_N50 * 1e3:.0f} ms]")
    print(f"\nwhole benchmark: {time.perf_counter() - t_start:.0f} s")


if __name__ == "__main__":
    sys.exit(main())
