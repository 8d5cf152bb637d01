"""Forced motion of a scenario's mooring by one engine, as a whole process: the FEM plant or MoorDyn-C.

Printed figures, not a timed test. Run one engine per process, so whole-process timings of the
two can be compared (e.g. with ``/usr/bin/time``)::

    python benchmarks/moordyn_forced_motion.py aamo4 --dof surge --amplitude 10 --period 100 \\
        --duration 300 --engine moordyn [--segments 20] [--dt-out 1] [--csv out.csv]

Prints the machine, the engine's time step, the wall time of the whole call (export / set-up,
settling and motion) and of its set-up and settling, the real-time factor
``(simulated settling + motion) / wall time`` (settling included, as the task a user runs), the
equivalent linear damping of the DOF and each line's fairlead tension range over the cycles after
the first. ``--csv`` writes ``t, x, y, psi, T1..Tn`` (s, m, m, rad, N), the same columns for both
engines, for a comparison afterwards.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

T_START = time.perf_counter()

import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _machine import machine_info  # noqa: E402

import tapm_opt  # noqa: E402
from tapm_opt._io import atomic_write_text, csv_text  # noqa: E402


def compare(path: str, r, unit: str) -> None:
    """Print this run's fairlead tensions and damping against another engine's ``--csv``."""
    text = Path(path).read_text(encoding="utf-8")
    other = next((ln.split("engine ")[-1].strip() for ln in text.splitlines() if ln.startswith("#") and "engine " in ln),
                 "?")
    b_other = next((float(ln.split()[-1]) for ln in text.splitlines() if ln.startswith("# damping")), math.nan)
    data = np.loadtxt([ln for ln in text.splitlines() if ln and not ln.startswith("#")][1:], delimiter=",", ndmin=2)
    if data.shape != (len(r.t), 4 + len(r.line_ids)) or not np.allclose(data[:, 0], r.t):
        print(f"  cannot compare with {path}: other times or lines")
        return
    T_o = data[:, 4:]
    d = r.T - T_o
    mean = T_o.mean(axis=0)
    rms = np.sqrt((d * d).mean(axis=0)) / mean
    peak = np.abs(d).max(axis=0) / mean
    print(f"  against {other} ({path}): fairlead tension difference, relative to the mean tension of each line:")
    print(f"    RMS {100 * rms.max():.3f} % (largest line), {100 * rms.mean():.3f} % (mean over lines); "
          f"max {100 * peak.max():.3f} %")
    if math.isfinite(b_other) and math.isfinite(r.damping):
        print(f"    damping {r.damping:.5g} vs {b_other:.5g} {unit}: {100 * (r.damping / b_other - 1):+.2f} %")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("scenario", help="built-in scenario name or TOML file")
    ap.add_argument("--dof", choices=("surge", "sway", "yaw"), default="surge")
    ap.add_argument("--amplitude", type=float, required=True, help="m (surge, sway) or deg (yaw)")
    ap.add_argument("--period", type=float, required=True, help="s")
    ap.add_argument("--duration", type=float, required=True, help="simulated time after settling [s]")
    ap.add_argument("--engine", choices=("fem", "moordyn"), default="fem")
    ap.add_argument("--segments", type=int, default=None, help="segments of every line (default: the scenario's)")
    ap.add_argument("--dt-out", type=float, default=1.0, help="output interval [s]")
    ap.add_argument("--csv", default=None, help="write t, x, y, psi, T1..Tn here")
    ap.add_argument("--compare", default=None, metavar="CSV",
                    help="a --csv of the other engine (same scenario and motion): print the tension and damping differences")
    a = ap.parse_args(argv)

    sc = tapm_opt.load_scenario(a.scenario)
    amp = math.radians(a.amplitude) if a.dof == "yaw" else a.amplitude
    kw = dict(dof=a.dof, amplitude=amp, period=a.period, duration=a.duration, segments=a.segments, dt_out=a.dt_out)
    extra = ""
    if a.engine == "moordyn":
        from tapm_opt.plant.moordyn_reference import moordyn_forced_motion, moordyn_version

        extra = f"moordyn {moordyn_version()}"
    print(machine_info(extra))
    w0 = time.perf_counter()
    if a.engine == "fem":
        from tapm_opt.plant.forced_motion import forced_motion

        r = forced_motion(sc, **kw)
        wall = time.perf_counter() - w0
        settle_sim = r.settle.time
        settle_wall = getattr(r.settle, "wall_time", math.nan)
        step = f"FEM step {r.dt:.4g} s (symplectic Euler)"
    else:
        r = moordyn_forced_motion(sc, **kw)
        wall = time.perf_counter() - w0
        settle_sim = r.settle_time
        settle_wall = r.settle_wall_time
        step = (f"MoorDyn dtM {r.dtM:.4g} s ({r.scheme}), coupling step {r.dt:.4g} s; settling = initial condition "
                f"{r.meta['ic_time']:.0f} s + hold {r.meta['hold_time']:.0f} s")
    sim = settle_sim + a.duration
    unit = "N m s/rad" if a.dof == "yaw" else "N s/m"
    print(f"{sc.name}: {a.engine}, forced {a.dof} {a.amplitude:g} {'deg' if a.dof == 'yaw' else 'm'}, period "
          f"{a.period:g} s, duration {a.duration:g} s, {len(sc.lines)} lines x "
          f"{a.segments or sc.lines[0].segments} segments")
    print(f"  {step}")
    print(f"  wall time: {wall:.3f} s for the call ({settle_wall:.3f} s set-up and settling), {time.perf_counter() - T_START:.3f} s "
          "for the process so far (imports included)")
    print(f"  simulated: {settle_sim:.0f} s settling + {a.duration:g} s motion; real-time factor {sim / wall:.0f}x "
          f"(settling included), {a.duration / max(wall - settle_wall, 1e-9):.0f}x (motion alone)")
    if r.cycles_analysed >= 1:
        print(f"  equivalent linear damping ({r.cycles_analysed} cycles after the first): {r.damping:.5g} {unit}; "
              f"energy per cycle {r.energy_per_cycle:.5g} J")
    m = r.t >= (a.period if r.cycles_analysed >= 1 else 0.0) - 1e-9
    print("  line  T_mean [kN]  T_min [kN]  T_max [kN]")
    for i, lid in enumerate(r.line_ids):
        T = r.T[m, i]
        print(f"  {lid:>4}  {T.mean() / 1e3:11.2f}  {T.min() / 1e3:10.2f}  {T.max() / 1e3:10.2f}")
    if a.csv:
        header = ["t", "x", "y", "psi", *[f"T{i + 1}" for i in range(len(r.line_ids))]]
        data = np.column_stack([r.t, r.eta, r.T])
        atomic_write_text(a.csv, csv_text(header, (tuple(map(float, row)) for row in data),
                                          comments=[f"{sc.name} forced {a.dof}, engine {a.engine}",
                                                    f"damping {r.damping!r}"]))
        print(f"wrote {a.csv}")
    if a.compare:
        compare(a.compare, r, unit)
    print(f"process wall time {time.perf_counter() - T_START:.3f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
