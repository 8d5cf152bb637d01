"""Two parts of an MPC step, each against its reference in the same process (ratios, since the
machine is shared).

Printed figures, not a timed test. Run from the repository root::

    python benchmarks/bench_mpc_parts.py [--repeats 3] [--scenario fpso]

1. **Line characteristics at the centre pose** (``mooring_parameters``, the ``moor`` parameters of
   ``mooring="characteristic"``): the tabulated catenary (``TabulatedMooringLoad.characteristics``)
   against the catenary solve of every line (``MooringModel.characteristics``), alternated over the
   poses of the benchmark trajectory of ``bench_mpc.py``; median time per call and the largest
   difference of the tensions (relative) and slopes (relative to the largest exact slope).
2. **The linear MPC's QP in piqp**: the QPs of the benchmark trajectory (``LinearMPC`` with the
   study defaults, N = 20, N = 50, N = 50 with 8 moves), recorded once, then solved by piqp with
   its default KKT solver (``sparse_ldlt``) and with the one the MPC uses
   (``tapm_opt.control.mpc.PIQP_KKT_SOLVER``), set up once and updated per QP as in the MPC,
   the two alternated ``--repeats`` times; median per QP (set-up excluded), iterations, the largest
   difference between the two solutions, and the ratio.
3. **The linear MPC's step with the condensed QP in DAQP** (``LinearMPC(qp_solver="daqp")``,
   ``tapm_opt.control.mpc_condensed``) against the sparse QP in piqp (the default): two controllers
   on the benchmark trajectory, their ``update()`` timed alternately step by step, the DAQP one
   handed piqp's previous plan before each step so that both solve the same QP (N = 20, N = 20 with
   5 moves, N = 50 with 8 moves; ``--repeats`` passes over the trajectory); median ``update()``,
   the ratio, and the largest difference of the first moves (relative to the single-DOF maxima)
   and of the costs.
"""

from __future__ import annotations

import argparse
import sys
import time

import numpy as np
import piqp

import tapm_opt
from tapm_opt.control.mpc import PIQP_KKT_SOLVER, LinearMPC, MPCSettings
from tapm_opt.models.system import as_system
from tapm_opt.studies.controllers import MPC_DEAD_BAND, MPC_DEFAULTS
from _machine import machine_info  # noqa: E402  (benchmarks/ is on sys.path when run)
from bench_mpc import MOVE_BLOCKS, trajectory  # noqa: E402


def characteristics(scenario, repeats: int) -> None:
    model = as_system(scenario).lines
    table = model.load_evaluator()
    ests, sp = trajectory(34, 5.0)
    poses = [e.eta for e in ests]
    times = {"catenary": [], "table": []}
    for _ in range(repeats):
        for name, fn in (("catenary", model.characteristics), ("table", table.characteristics)):
            for eta in poses:
                t0 = time.perf_counter()
                fn(eta)
                times[name].append(time.perf_counter() - t0)
    err_T, err_k = 0.0, 0.0
    for eta in poses:
        a, b = model.characteristics(eta), table.characteristics(eta)
        err_T = max(err_T, float(np.max(np.abs(a[[0, 3]] - b[[0, 3]]) / np.abs(a[[0, 3]]))))
        err_k = max(err_k, float(np.max(np.abs(a[[1, 4]] - b[[1, 4]]) / np.max(np.abs(a[[1, 4]])))))
    c, t = np.median(times["catenary"]), np.median(times["table"])
    print(f"line characteristics, {model.n_lines} lines, {len(poses)} poses x {repeats}: catenary "
          f"{c * 1e6:.0f} us, table {t * 1e6:.1f} us per call (table / catenary {t / c:.3f}); "
          f"largest difference: tensions {err_T:.1e} relative, slopes {err_k:.1e} of the largest slope "
          f"({table.exact_calls} poses beyond the tables)")


def record_qps(scenario, settings: MPCSettings, n: int) -> list[dict]:
    """The piqp QP data of ``n`` steps of ``LinearMPC`` on the benchmark trajectory."""
    ctrl = LinearMPC(scenario, settings)
    qps = []
    solve = ctrl._solve_piqp

    def recording(t):
        Hx, Ax, Gx, q, g_eq, g_in = ctrl._data[:6]
        qps.append(dict(P=ctrl._csc(0, Hx), c=q.copy(), A=ctrl._csc(1, Ax), b=ctrl._b_eq - g_eq,
                        G=ctrl._csc(2, Gx), h_l=ctrl._lb_in - g_in, h_u=ctrl._ub_in - g_in,
                        x_l=ctrl._prob.lbz.copy(), x_u=ctrl._prob.ubz.copy()))
        return solve(t)

    ctrl._solve_piqp = recording
    ests, sp = trajectory(n, settings.dt)
    for est in ests:
        ctrl.update(est.t, est, sp)
    return qps


def solve_all(qps: list[dict], kkt: str) -> tuple[list[float], list[int], list[np.ndarray]]:
    """piqp with KKT solver ``kkt``, set up on the first QP and updated for each next one."""
    s = piqp.SparseSolver()
    s.settings.verbose = False
    s.settings.kkt_solver = getattr(piqp.KKTSolver, kkt)
    d = qps[0]
    s.setup(d["P"], d["c"], d["A"], d["b"], d["G"], d["h_l"], d["h_u"], d["x_l"], d["x_u"])
    s.solve()
    times, its, xs = [], [], []
    for d in qps[1:]:
        t0 = time.perf_counter()
        s.update(**d)
        status = s.solve()
        times.append(time.perf_counter() - t0)
        if status != piqp.Status.PIQP_SOLVED:
            raise RuntimeError(f"piqp ({kkt}) returned {status.name}")
        its.append(int(s.result.info.iter))
        xs.append(np.array(s.result.x))
    return times, its, xs


def qp_solvers(scenario, repeats: int) -> None:
    base = dict(MPC_DEFAULTS, dead_band=MPC_DEAD_BAND * scenario.limits.safe_radius)
    for N, blocks in ((20, None), (50, None), (50, MOVE_BLOCKS[50])):
        qps = record_qps(scenario, MPCSettings(horizon=N, move_blocks=blocks, **base), 34)
        res = {k: ([], [], None) for k in ("sparse_ldlt", PIQP_KKT_SOLVER)}
        ratios = []
        for _ in range(repeats):
            per = {}
            for kkt in res:
                t, it, xs = solve_all(qps, kkt)
                res[kkt][0].extend(t)
                res[kkt][1].extend(it)
                res[kkt] = (res[kkt][0], res[kkt][1], xs)
                per[kkt] = np.median(t)
            ratios.append(per[PIQP_KKT_SOLVER] / per["sparse_ldlt"])
        dz = max(float(np.max(np.abs(a - b))) for a, b in zip(res["sparse_ldlt"][2], res[PIQP_KKT_SOLVER][2]))
        d = qps[0]
        what = f"N = {N}" + (f", {len(blocks)} moves" if blocks else "")
        print(f"linear MPC QP, {what} ({d['P'].shape[0]} variables, {d['A'].shape[0]} equality and "
              f"{d['G'].shape[0]} inequality rows), {len(qps) - 1} QPs x {repeats}:")
        for kkt, (t, it, _) in res.items():
            print(f"    {kkt:24s} median {np.median(t) * 1e3:6.2f} ms, {np.median(it):.0f} iterations")
        print(f"    {PIQP_KKT_SOLVER} / sparse_ldlt: {np.median(ratios):.2f} (per repeat "
              f"{', '.join(f'{r:.2f}' for r in ratios)}); largest solution difference {dz:.1e}")


def condensed_daqp(scenario, repeats: int) -> None:
    base = dict(MPC_DEFAULTS, dead_band=MPC_DEAD_BAND * scenario.limits.safe_radius)
    scale = as_system(scenario).thrusters.max_tau()
    for N, blocks in ((20, None), (20, MOVE_BLOCKS[20]), (50, MOVE_BLOCKS[50])):
        s = MPCSettings(horizon=N, move_blocks=blocks, **base)
        ests, sp = trajectory(34, s.dt)
        times = {"piqp": [], "daqp": []}
        du, dc, ratios = 0.0, 0.0, []
        for _ in range(repeats):
            a, b = LinearMPC(scenario, s, qp_solver="piqp"), LinearMPC(scenario, s, qp_solver="daqp")
            per = {"piqp": [], "daqp": []}
            for k, est in enumerate(ests):
                u = {}
                for name, c in (("piqp", a), ("daqp", b)):
                    t0 = time.perf_counter()
                    u[name] = c.update(est.t, est, sp)
                    if k >= 2:
                        per[name].append(time.perf_counter() - t0)
                du = max(du, float(np.max(np.abs(u["piqp"] - u["daqp"]) / scale)))
                dc = max(dc, abs(b.last_step().cost / a.last_step().cost - 1))
                b._u_prev, b._z = a._u_prev.copy(), a._z.copy()
            for name in per:
                times[name].extend(per[name])
            ratios.append(np.median(per["daqp"]) / np.median(per["piqp"]))
        cq = b._daqp.cq
        what = f"N = {N}" + (f", {len(blocks)} moves" if blocks else "")
        print(f"linear MPC step, {what}: condensed QP {cq.nU} variables, {cq.m} rows ({len(cq.groups)} soft); "
              f"{len(ests) - 2} steps x {repeats}:")
        for name, t in times.items():
            print(f"    {name:5s} update() median {np.median(t) * 1e3:6.2f} ms")
        print(f"    daqp / piqp: {np.median(ratios):.2f} (per repeat {', '.join(f'{r:.2f}' for r in ratios)}); "
              f"largest difference: first moves {du:.1e} of the maxima, costs {dc:.1e} relative")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--scenario", default="fpso")
    args = ap.parse_args(argv)
    print(machine_info(f"piqp {piqp.__version__}" if hasattr(piqp, "__version__") else ""))
    scenario = tapm_opt.load_scenario(args.scenario)
    characteristics(scenario, args.repeats)
    qp_solvers(scenario, args.repeats)
    condensed_daqp(scenario, args.repeats)
    return 0


if __name__ == "__main__":
    sys.exit(main())
