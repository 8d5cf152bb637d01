"""The ``tapm`` command.

User mistakes (a bad scenario, a missing file, an impossible option) end with a one-line
``error: ...`` message and a non-zero exit code; ``--verbose`` adds the traceback.
"""

from __future__ import annotations

import math
import os
import sys
import time
import traceback
import warnings
from pathlib import Path

import click
import numpy as np

from . import __version__
from ._io import atomic_write_text, csv_text
from .config import builtin_scenarios, load_scenario
from .config.loader import fem_size_issues, log_size_issues
from .errors import ScenarioError, TapmError

EXIT_USER_ERROR = 2


class _State:
    verbose = False


def _load(name_or_path: str):
    return load_scenario(name_or_path)


def _out_path(kind: str, what: str | None = None):
    """Callback of an ``--out`` option naming a file (``kind="file"``) or a directory to write
    (``what`` names it in messages): the path must not be empty, and its nearest existing ancestor
    must be a writable directory."""
    what = what or ("directory" if kind == "dir" else "file")

    def check(ctx: click.Context, param: click.Parameter, value: str | None) -> str | None:
        if value is None:
            return None
        if not str(value).strip():
            raise click.BadParameter(f"{value!r} is empty: give the {what} to write", ctx=ctx, param=param)
        p = Path(value)
        for anc in (p, *p.parents) if kind == "dir" else p.parents:
            if not anc.exists():
                continue
            if not anc.is_dir():
                raise click.BadParameter(f"{value!r}: cannot create the {what}: {str(anc)!r} is a file, not a "
                                         "directory", ctx=ctx, param=param)
            if not os.access(anc, os.W_OK | os.X_OK):
                raise click.BadParameter(f"{value!r}: cannot create the {what}: no write access to {str(anc)!r}",
                                         ctx=ctx, param=param)
            break
        return value

    return check


def _check_issues(issues) -> None:
    """Raise the first plausibility issue of an option as a click error naming the option."""
    if issues:
        iss = issues[0]
        raise click.BadParameter(str(iss.message).removeprefix("= "), param_hint=f"'{iss.path}'")


@click.group(context_settings={"help_option_names": ["-h", "--help"]})
@click.option("--verbose", "-v", is_flag=True, help="Show tracebacks and extra detail.")
@click.version_option(__version__, prog_name="tapm")
def cli(verbose: bool) -> None:
    """tapm_opt — control design workbench for thruster-assisted position mooring."""
    _State.verbose = verbose


# ------------------------------------------------------------------------------------------
# tapm scenario ...
# ------------------------------------------------------------------------------------------


@cli.group()
def scenario() -> None:
    """List, show and validate scenarios."""


@scenario.command("list")
def scenario_list() -> None:
    """List the built-in scenarios."""
    for name in builtin_scenarios():
        sc = load_scenario(name)
        click.echo(f"{name:8s} {sc.meta.description}")


@scenario.command("validate")
@click.argument("files", nargs=-1, required=True)
def scenario_validate(files: tuple[str, ...]) -> None:
    """Check scenario FILES; print every problem found. Exit status 1 if any is invalid."""
    bad = 0
    for f in files:
        try:
            sc = load_scenario(f)
        except ScenarioError as exc:
            bad += 1
            n = len(exc.issues)
            click.echo(f"{f}: INVALID ({n} problem{'s' if n != 1 else ''})")
            for issue in exc.issues:
                click.echo(f"  - {issue}")
            continue
        click.echo(f"{f}: OK — {sc.name}: {len(sc.lines)} lines, {len(sc.thrusters)} thrusters, "
                   f"{len(sc.sea_states)} sea states")
    if bad:
        sys.exit(1)


@scenario.command("show")
@click.argument("name")
def scenario_show(name: str) -> None:
    """Print a summary of scenario NAME (built-in name or TOML file)."""
    from .models.mooring import MooringModel

    sc = _load(name)
    env, v, tur = sc.environment, sc.vessel, sc.turret
    click.echo(f"Scenario {sc.name}: {sc.meta.description}")
    for s in sc.meta.sources:
        click.echo(f"  source: {s}")
    click.echo(f"Environment: depth {env.water_depth:g} m, rho_w {env.water_density:g} kg/m3, g {env.gravity:g} m/s2")
    click.echo(f"Vessel {v.name}: Lpp {v.length_pp:g} m, B {v.breadth:g} m, T {v.draught:g} m; "
               f"M diag [{', '.join(f'{x:.3g}' for x in np.diag(v.M))}]")
    click.echo(f"Turret: {tur.mode}, at ({tur.position[0]:g}, {tur.position[1]:g}) m in {{B}}, "
               f"fairlead radius {tur.fairlead_radius:g} m, depth {tur.fairlead_depth:g} m")
    model = MooringModel.from_scenario(sc)
    sol = model.solve_lines(np.zeros(3))
    click.echo(f"Lines ({len(sc.lines)}), at the field zero point:")
    click.echo(f"  {'id':>6} {'type':>10} {'L [m]':>8} {'XF [m]':>8} {'T [kN]':>9} {'H [kN]':>9} {'T/MBS':>6} regime")
    _, _, XF = model.spans(np.zeros(3))
    for i, ln in enumerate(sc.lines):
        click.echo(f"  {ln.id:>6} {ln.type:>10} {ln.length:8.1f} {XF[i]:8.1f} {sol.TF[i] / 1e3:9.1f} "
                   f"{sol.HF[i] / 1e3:9.1f} {sol.TF[i] / model.MBS[i]:6.3f} {sol.regime_names()[i]}")
    tau0 = model.force(np.zeros(3))
    click.echo(f"Net mooring load at the field zero point: X {tau0[0] / 1e3:.3g} kN, Y {tau0[1] / 1e3:.3g} kN, "
               f"N {tau0[2] / 1e3:.3g} kN m")
    if sc.thrusters:
        click.echo(f"Thrusters ({len(sc.thrusters)}):")
        for t in sc.thrusters:
            click.echo(f"  {t.id:>6} {t.kind:8s} at ({t.position[0]:g}, {t.position[1]:g}) m, "
                       f"max {t.max_thrust / 1e3:.0f} kN")
    for s in sc.sea_states:
        click.echo(f"Sea state {s.id}: Hs {s.Hs:g} m, Tp {s.Tp:g} s, wind {s.wind_speed:g} m/s, "
                   f"current {s.current_speed:g} m/s")
    if sc.riser is not None:
        click.echo(f"Riser: length {sc.riser.length:g} m, top tension {sc.riser.top_tension / 1e3:.0f} kN")
    for f in sc.faults:
        target = f.line if f.kind == "line_break" else f.thruster
        click.echo(f"Fault: {f.kind} of {target} at t = {f.time:g} s")
    if sc.limits.safe_radius is not None:
        click.echo(f"Limits: safe radius {sc.limits.safe_radius:g} m, alert radius {sc.limits.alert_radius} m")


def _type_values(items: tuple[str, ...], option: str) -> dict[str, float]:
    """``TYPE=NUMBER`` option values as a dict (click.BadParameter on a malformed one)."""
    out: dict[str, float] = {}
    for item in items:
        name, sep, val = item.rpartition("=")
        try:
            num = float(val)
        except ValueError:
            num = math.nan
        if not sep or not name.strip() or not (math.isfinite(num) and num > 0):
            raise click.BadParameter(f"{item!r} must look like TYPE=NEWTONS with a positive number, e.g. chain=1.2e7",
                                     param_hint=f"'{option}'")
        out[name.strip()] = num
    return out


@scenario.command("import-moordyn")
@click.argument("file", metavar="FILE", type=click.Path(dir_okay=False))
@click.option("--vessel", required=True, metavar="SCENARIO",
              help="Scenario (built-in name or TOML file) giving the vessel, turret position/mode/angle, thrusters, "
                   "sea states, riser, sensors and limits.")
@click.option("--out", required=True, type=click.Path(dir_okay=False), callback=_out_path("file"),
              help="Scenario TOML file to write.")
@click.option("--mbs", "mbs", multiple=True, metavar="TYPE=NEWTONS",
              help="Breaking strength of MoorDyn line type TYPE [N] (repeatable; required for every line type used: "
                   "MoorDyn files carry none).")
@click.option("--mbs-cov", type=click.FloatRange(0.0, 1.0), default=0.05, show_default=True,
              help="MBS_std as a fraction of MBS.")
@click.option("--name", default=None, help="Scenario name (default: the stem of --out).")
def scenario_import_moordyn(file: str, vessel: str, out: str, mbs: tuple[str, ...], mbs_cov: float,
                            name: str | None) -> None:
    """Build a scenario from MoorDyn v2 input FILE and a vessel scenario.

    From FILE: line types, lines, anchors, fairleads, water depth, water density and gravity.
    From --vessel: everything else. Fairleads become turret angles and radii about the vessel's
    centre of turret. Conventions: docs/moordyn.md.
    """
    from .config.moordyn import import_moordyn

    res = import_moordyn(file, vessel, mbs=_type_values(mbs, "--mbs"), mbs_cov=mbs_cov,
                         name=name or Path(out).stem)
    atomic_write_text(out, res.toml)
    sc = res.scenario
    click.echo(f"wrote {out}: scenario {sc.name}, {len(sc.lines)} lines, {len(sc.line_types)} line types, depth "
               f"{sc.environment.water_depth:g} m, fairleads at radius {sc.turret.fairlead_radius:g} m and depth "
               f"{sc.turret.fairlead_depth:g} m (mooring from {Path(file).name}, the rest from {vessel})")
    for note in res.notes:
        click.echo(f"  note: {note}")


@scenario.command("export-moordyn")
@click.argument("scenario_name", metavar="SCENARIO")
@click.option("--out", required=True, type=click.Path(dir_okay=False), callback=_out_path("file"),
              help="MoorDyn v2 input file to write.")
@click.option("--segments", type=click.IntRange(2, 1000), default=None,
              help="Segments of every line (default: the scenario's).")
def scenario_export_moordyn(scenario_name: str, out: str, segments: int | None) -> None:
    """Write the mooring of SCENARIO as a MoorDyn v2 input file.

    One coupled body at the centre of turret carries the fairleads; anchors are fixed points.
    Conventions (frames, diameter, drag, damping, seabed, time step): docs/moordyn.md.
    """
    from .config.moordyn import export_moordyn

    sc = _load(scenario_name)
    info = export_moordyn(sc, out, segments=segments)
    click.echo(f"wrote {out}: {info.n_lines} lines of {sc.name}; dtM {info.dtM:g} s ({info.scheme}), "
               f"kBot {info.kBot:.4g} Pa/m, cBot {info.cBot:.4g} Pa s/m")
    for note in info.notes:
        click.echo(f"  note: {note}")


# ------------------------------------------------------------------------------------------
# tapm lines
# ------------------------------------------------------------------------------------------


def _parse_floats(text: str, what: str) -> np.ndarray:
    try:
        vals = np.array([float(x) for x in text.split(",") if x.strip()])
    except ValueError:
        raise click.BadParameter(f"{what} must be comma-separated numbers, got {text!r}") from None
    if vals.size == 0 or not np.all(np.isfinite(vals)):
        raise click.BadParameter(f"{what} must be finite numbers, got {text!r}")
    return vals


@cli.command()
@click.argument("scenario_name", metavar="SCENARIO", default="fpso")
@click.option("--out", type=click.Path(dir_okay=False), default=None, callback=_out_path("file"),
              help="CSV of line characteristics; offsets and stiffness go beside it (*_offsets.csv, *_stiffness.csv).")
@click.option("--range", "half_range", type=float, default=None,
              help="Half range of anchor distance / offset [m] (default: 10 % of water depth).")
@click.option("--points", type=click.IntRange(2, 2001), default=41, show_default=True, help="Points per curve.")
@click.option("--directions", default="0,45,90,135,180,225,270,315", show_default=True,
              help="Offset directions from north [deg], comma-separated.")
def lines(scenario_name: str, out: str | None, half_range: float | None, points: int, directions: str) -> None:
    """Line characteristics, restoring curves and stiffness of SCENARIO (default: fpso).

    Writes, per line, H, V, T against the horizontal anchor-fairlead distance (eq. 25); the
    system's restoring load and line tensions against offsets in the given directions (heading
    0); and the stiffness matrix at the field zero point.
    """
    from .models.characteristics import line_characteristics, offset_curves
    from .models.mooring import MooringModel

    sc = _load(scenario_name)
    dirs_deg = _parse_floats(directions, "--directions")
    if np.any(np.abs(dirs_deg) > 360.0):
        raise click.BadParameter(f"--directions = {directions!r}: each direction must be within [-360, 360] deg")
    half = 0.1 * sc.environment.water_depth if half_range is None else half_range
    if not (math.isfinite(half) and half > 0):
        raise click.BadParameter(f"--range = {half_range} must be a positive number of metres")
    longest = max(ln.length for ln in sc.lines)
    if half > longest:
        raise click.BadParameter(f"--range = {half:g} m must be at most the longest line's length, {longest:g} m "
                                 "(an offset beyond it tears every line)")
    model = MooringModel.from_scenario(sc)
    chars = line_characteristics(model, half_range=half, n_points=points)
    offs = np.linspace(0.0, half, points)
    curves = offset_curves(model, np.radians(dirs_deg), offs)
    K = model.stiffness(np.zeros(3))

    M = sc.vessel.M
    click.echo(f"{sc.name}: {model.n_lines} lines; stiffness K = -d tau_moor/d eta at the field zero point")
    labels = ("X [N/m]", "Y [N/m]", "N [N m/rad]")
    for i in range(3):
        click.echo(f"  {labels[i]:>12} " + " ".join(f"{K[i, j] + 0.0:14.6g}" for j in range(3)))
    for i, dof in enumerate(("surge", "sway", "yaw")):
        if K[i, i] > 0:
            click.echo(f"  {dof} natural period 2*pi*sqrt(M/K) = {2 * np.pi * np.sqrt(M[i, i] / K[i, i]):.1f} s")
        else:
            click.echo(f"  {dof}: no restoring stiffness")
    sol0 = model.solve_lines(np.zeros(3))
    click.echo("  pretension [kN]: " + ", ".join(f"{i}:{t / 1e3:.0f}" for i, t in zip(model.line_ids, sol0.TF)))

    if out is None:
        return
    path = Path(out)
    from .models.catenary import REGIMES

    rows = []
    for i, lid in enumerate(chars.line_ids):
        for j in range(chars.XF.shape[1]):
            rows.append((lid, float(chars.XF[i, j]), float(chars.H[i, j]), float(chars.V[i, j]),
                         float(chars.T[i, j]), REGIMES[int(chars.regime[i, j])]))
    text_lines = csv_text(["line", "XF_m", "H_N", "V_N", "T_N", "regime"], rows,
                          comments=[f"tapm lines {sc.name}: fairlead tensions against horizontal anchor-fairlead distance"])
    rows = []
    for a, d in enumerate(dirs_deg):
        for b, r in enumerate(offs):
            rows.append((float(d), float(r), *map(float, curves.tau[a, b]), *map(float, curves.T[a, b])))
    text_off = csv_text(["direction_deg", "offset_m", "X_N", "Y_N", "N_Nm", *[f"T_{i}_N" for i in curves.line_ids]],
                        rows, comments=[f"tapm lines {sc.name}: mooring load in {{B}} (heading 0) against offset"])
    text_k = csv_text(["row", "x_N_per_m", "y_N_per_m", "psi_N_per_rad"],
                      [(n, *map(float, K[i])) for i, n in enumerate(("X", "Y", "N"))],
                      comments=[f"tapm lines {sc.name}: stiffness K = -d tau_moor / d eta at the field zero point"])
    off_path = path.with_name(path.stem + "_offsets.csv")
    k_path = path.with_name(path.stem + "_stiffness.csv")
    for p, t in ((path, text_lines), (off_path, text_off), (k_path, text_k)):
        atomic_write_text(p, t)
        click.echo(f"wrote {p}")


# ------------------------------------------------------------------------------------------
# tapm plant ...
# ------------------------------------------------------------------------------------------


@cli.group()
def plant() -> None:
    """The FEM mooring plant: forced-motion analysis."""


@plant.command("forced-motion")
@click.argument("scenario_name", metavar="SCENARIO")
@click.option("--dof", type=click.Choice(["surge", "sway", "yaw"]), default="surge", show_default=True,
              help="Degree of freedom to move.")
@click.option("--amplitude", type=float, required=True,
              help="Motion amplitude: metres for surge/sway, degrees for yaw.")
@click.option("--period", type=float, required=True, help="Motion period [s].")
@click.option("--duration", type=float, required=True, help="Simulated time after settling [s].")
@click.option("--segments", type=click.IntRange(2, 1000), default=None,
              help="FEM segments per line (default: the scenario's).")
@click.option("--dt-out", type=float, default=1.0, show_default=True, help="Output interval [s].")
@click.option("--sea-state", "sea_state", default=None,
              help="Sea state whose current profile acts on the lines (default: still water).")
@click.option("--out", type=click.Path(dir_okay=False), default=None, callback=_out_path("file"),
              help="CSV file with columns t, x, y, psi, T1..Tn (s, m, m, rad, N).")
def plant_forced_motion(scenario_name: str, dof: str, amplitude: float, period: float, duration: float,
                        segments: int | None, dt_out: float, sea_state: str | None, out: str | None) -> None:
    """Settle the lines of SCENARIO at rest, then move the vessel as amplitude*sin(2 pi t/period).

    Prints the FEM step used, how settling converged, the equivalent linear mooring damping of
    the DOF (energy dissipated per cycle, cycles after the first), and per line the tension range
    of the first cycle (start-up) and of the cycles after it, with the dynamic/quasi-static
    tension amplification.
    """
    from .plant.forced_motion import forced_motion

    for name, val in (("--amplitude", amplitude), ("--period", period), ("--duration", duration), ("--dt-out", dt_out)):
        if not (math.isfinite(val) and val > 0):
            raise click.BadParameter(f"{name} = {val} must be a positive number")
    if period < 1.0:
        raise click.BadParameter(f"--period = {period:g} s must be >= 1 s (vessel motions are slower; the FEM does "
                                 "not resolve faster ones)")
    if dt_out > duration:
        raise click.BadParameter(f"--dt-out = {dt_out:g} s must not exceed --duration = {duration:g} s")
    if dt_out > period / 10.0:
        raise click.BadParameter(f"--dt-out = {dt_out:g} s must be at most --period / 10 = {period / 10.0:g} s (the "
                                 "tension range is read from the output samples, ten or more per cycle)")
    sc = _load(scenario_name)
    if dof == "yaw" and amplitude > 180.0:
        raise click.BadParameter(f"--amplitude = {amplitude:g} deg must be at most 180 deg for yaw")
    if dof != "yaw":
        longest = max(ln.length for ln in sc.lines)
        if amplitude > longest:
            raise click.BadParameter(f"--amplitude = {amplitude:g} m must be at most the longest line's length, "
                                     f"{longest:g} m (a larger motion tears every line)")
        if 2 * math.pi * amplitude / period > 10.0:
            raise click.BadParameter(f"--amplitude = {amplitude:g} m at --period = {period:g} s moves the vessel at "
                                     f"{2 * math.pi * amplitude / period:.3g} m/s, above 10 m/s (20 knots)")
    _check_issues(fem_size_issues(sc, segments, where="--segments"))
    _check_issues(log_size_issues(sc, duration, dt_out, where="--duration", dt_name="--dt-out",
                                  channels=4 + len(sc.lines)))
    amp = math.radians(amplitude) if dof == "yaw" else amplitude
    res = forced_motion(sc, dof=dof, amplitude=amp, period=period, duration=duration, segments=segments,
                        dt_out=dt_out, sea_state=sea_state)
    unit = "N m s/rad" if dof == "yaw" else "N s/m"
    st = res.settle
    click.echo(f"{sc.name}: forced {dof}, amplitude {amplitude:g} {'deg' if dof == 'yaw' else 'm'}, period {period:g} s, "
               f"duration {duration:g} s, {res.sea_state + ' current' if res.sea_state else 'still water'}; "
               f"FEM step {res.dt:.4g} s")
    click.echo(f"  settled in {st.time:.0f} s simulated (fastest node {1e3 * st.max_speed:.2g} mm/s, tension change "
               f"{st.tension_change:.1g} per check); wall time {res.wall_time:.1f} s including "
               f"{st.wall_time:.1f} s of settling")
    if res.cycles_analysed >= 1:
        click.echo(f"  equivalent linear damping ({res.cycles_analysed} cycles after the first): "
                   f"{res.damping:.4g} {unit}; energy per cycle {res.energy_per_cycle:.4g} J")
        span = f"cycles 2-{res.cycles_analysed + 1}"
    else:
        click.echo("  damping not estimated: the duration must cover at least two periods")
        span = "whole run"
    click.echo(f"  line  start-up T_min/T_max [kN]  {span}: T_min [kN]  T_max [kN]  dyn/qs amplification")
    for i, lid in enumerate(res.line_ids):
        amp_i = res.amplification[i]
        amp_txt = f"{amp_i:.3f}" if np.isfinite(amp_i) else "n/a"
        click.echo(f"  {lid:>4}  {res.T_startup[i, 0] / 1e3:10.1f} {res.T_startup[i, 1] / 1e3:10.1f}   "
                   f"{res.T_range[i, 0] / 1e3:10.1f}  {res.T_range[i, 1] / 1e3:10.1f}  {amp_txt}")
    if out is not None:
        header, data = res.table()
        atomic_write_text(out, csv_text(header, (tuple(map(float, row)) for row in data)))
        click.echo(f"wrote {out}")


# ------------------------------------------------------------------------------------------
# tapm simulate
# ------------------------------------------------------------------------------------------


@cli.command()
@click.argument("scenario_name", metavar="SCENARIO")
@click.option("--controller", type=click.Choice(["pid", "mpc", "lmpc"]), default="pid", show_default=True,
              help="PID modes, nonlinear MPC, or linear MPC (piqp; --option qp_solver=osqp|daqp).")
@click.option("--duration", type=float, default=3600.0, show_default=True, help="Simulated time [s].")
@click.option("--out", "out_dir", type=click.Path(file_okay=False), required=True,
              callback=_out_path("dir", "run directory"), help="Run directory to write.")
@click.option("--sea-state", default=None, help="Sea state id (default: the scenario's first), or 'none'.")
@click.option("--seed", type=click.IntRange(min=0), default=0, show_default=True,
              help="Seed of waves, wind and sensor noise (a whole number >= 0).")
@click.option("--segments", type=click.IntRange(2, 1000), default=None, help="FEM segments per line.")
@click.option("--dt-control", type=float, default=1.0, show_default=True,
              help="Control/allocation period [s], >= 0.01; the run is logged every control step, at least 1 s apart.")
@click.option("--setpoint", type=click.Choice(["fixed", "chasing", "quadratic", "reliability", "unified"]),
              default="fixed", show_default=True,
              help="Fixed setpoint (turret at its field-zero-point position), setpoint chasing (survey eq. 38), or "
                   "the optimum of the quadratic (eq. 34), reliability-index (eq. 36) or unified riser + mooring cost.")
@click.option("--setpoint-option", "setpoint_options", multiple=True, metavar="KEY=VALUE",
              help="Option of the optimal setpoints, e.g. --setpoint-option period=60 (repeatable).")
@click.option("--heading", type=click.Choice(["chasing", "fixed"]), default=None,
              help="Weather-optimal heading (bow into the estimated mean environmental force) or fixed north "
                   "[default: chasing; fixed with --winch tension, whose changing line lengths the estimated "
                   "environmental force does not know].")
@click.option("--true-state", is_flag=True, help="Give the controller the true LF state (no estimator).")
@click.option("--option", "options", multiple=True, metavar="KEY=VALUE",
              help="Controller option, e.g. --option horizon=30 --option solver=ipopt (repeatable); "
                   "estimator=ekf|passive|lowpass (default ekf) and detector=tension|drop|bank|none (default tension) "
                   "choose the estimation.")
@click.option("--winch", type=click.Choice(["none", "tension"]), default="none", show_default=True,
              help="Line-tension control: none, or the passivity-based tension controller (the winches drive the "
                   "mooring force toward the DP command, the thrusters supply the rest; docs/controllers.md). "
                   "'tension' needs detector=none (set unless --option detector=... is given).")
@click.option("--winch-option", "winch_options", multiple=True, metavar="KEY=VALUE",
              help="Option of the tension controller, e.g. --winch-option kc=2.5e-7 --winch-option ki=1e-9 "
                   "(kc, ki, T_max_fraction, T_min_fraction, geometry; repeatable).")
def simulate(scenario_name: str, controller: str, duration: float, out_dir: str, sea_state: str | None, seed: int,
             segments: int | None, dt_control: float, setpoint: str, setpoint_options: tuple[str, ...], heading: str,
             true_state: bool, options: tuple[str, ...], winch: str, winch_options: tuple[str, ...]) -> None:
    """Run CONTROLLER in closed loop against the FEM plant of SCENARIO and save the run.

    Writes OUT/result.npz (all channels, labelled; numpy.load reads it) and OUT/summary.json
    (settings, key figures, controller diagnostics), and prints the key figures.
    """
    import json

    from .models.system import System
    from .plant.simulator import Plant
    from .studies.closed_loop import DEFAULT_ESTIMATOR, ClosedLoopSettings, run_closed_loop
    from .studies.controllers import build_controller
    from .studies.kpis import basic_kpis

    if not (math.isfinite(duration) and duration > 0):
        raise click.BadParameter(f"--duration = {duration} must be a positive number of seconds")
    if not (math.isfinite(dt_control) and 0.01 <= dt_control <= duration):
        raise click.BadParameter(f"--dt-control = {dt_control:g} s must be between 0.01 s (100 Hz, faster than any "
                                 f"position-control loop) and --duration = {duration:g} s")
    dt_log = dt_control * max(1, math.ceil(1.0 / dt_control - 1e-9))  # every control step, >= 1 s apart
    spec: dict = {"type": controller, **_key_values(options, "--option")}
    # estimation is the runner's: --option estimator=... / detector=... choose its default estimator
    estimation = {k: str(spec.pop(k)) for k in ("estimator", "detector") if k in spec}
    from .studies.closed_loop import ClosedLoopError

    w_opts = _key_values(winch_options, "--winch-option")
    if w_opts and winch != "tension":
        raise click.BadParameter("--winch-option is for --winch tension", param_hint="'--winch-option'")
    if winch == "tension":
        estimation.setdefault("detector", "none")  # the detectors assume the nominal line lengths
    if heading is None:   # chasing reads tau_env, which assumes the nominal line lengths too
        heading = "fixed" if winch == "tension" else "chasing"
    winching = {"winch": winch, "winch_options": w_opts or None} if winch != "none" else {}
    try:
        ClosedLoopSettings(true_state=true_state, **estimation)
    except ClosedLoopError as exc:
        raise click.BadParameter(str(exc), param_hint="'--option'") from None
    try:
        ClosedLoopSettings(true_state=true_state, **estimation, **winching)
    except ClosedLoopError as exc:
        raise click.BadParameter(str(exc), param_hint="'--winch-option'" if w_opts else "'--winch'") from None
    sp_opts = _key_values(setpoint_options, "--setpoint-option")
    if sp_opts and setpoint not in ("quadratic", "reliability", "unified"):
        raise click.BadParameter(f"--setpoint-option is for the optimal setpoints (quadratic, reliability, unified), "
                                 f"not --setpoint {setpoint}")
    if sp_opts:
        from .control.setpoint_opt import SetpointOptions

        SetpointOptions.from_mapping(sp_opts, where="--setpoint-option")
    sc = _load(scenario_name)
    if sea_state is not None and sea_state != "none" and sea_state not in [s.id for s in sc.sea_states]:
        raise click.BadParameter(f"{sea_state!r} is not a sea state of scenario {sc.name!r}; its sea states: "
                                 f"{', '.join(s.id for s in sc.sea_states) or 'none'} (or 'none')",
                                 param_hint="'--sea-state'")
    _check_issues(fem_size_issues(sc, segments, where="--segments"))
    _check_issues(log_size_issues(sc, duration, dt_log, where="--duration", dt_name="every control step, >= 1 s apart"))
    system = System.from_scenario(sc)  # built once: controller, runner and estimator share it
    ctrl = build_controller(system, spec, where="--option", dt_control=dt_control,
                            estimator=estimation.get("estimator", DEFAULT_ESTIMATOR),
                            winch=(w_opts or {}) if winch == "tension" else None)
    settings = ClosedLoopSettings(duration=duration, dt_control=dt_control, dt_log=dt_log, true_state=true_state,
                                  setpoint=setpoint, heading=heading, setpoint_options=sp_opts or None, **estimation,
                                  **winching)
    w0 = time.perf_counter()
    plant = Plant(system, sea_state=sea_state, seed=seed, segments=segments)
    try:
        res = run_closed_loop(plant, ctrl, settings, system=system,
                              meta={"controller_spec": {**spec, **estimation}, "seed": seed})
    except ClosedLoopError as exc:   # e.g. --winch tension on a scenario without winches
        raise click.BadParameter(str(exc), param_hint="'--winch'") from None
    out = Path(out_dir)
    res.save(out / "result.npz")
    k = basic_kpis(res, sc)
    summary = {"scenario": sc.name, "controller": spec, **estimation,
               **({"winch": winch, "winch_options": w_opts} if winch != "none" else {}),
               "sea_state": plant.sea_state.id if plant.sea_state else "none",
               "seed": seed, "duration": duration, "kpis": k, "diagnostics": res.meta.get("diagnostics", {}),
               "events": plant.events}
    wall = time.perf_counter() - w0
    summary["wall_time"] = wall
    summary["settle"] = {"time": plant.settle_info.time, "wall_time": plant.settle_info.wall_time}
    click.echo(f"{sc.name}, {controller}, {summary['sea_state']} sea, {duration:g} s (wall {wall:.1f} s, of which "
               f"{plant.settle_info.wall_time:.1f} s settling the lines)")
    click.echo(f"  offset max {k['offset_max']:.1f} m, mean {k['offset_mean']:.1f} m; outside safe circle "
               f"{k['time_outside_safe']:.0f} s; heading error max {k['heading_error_max']:.1f} deg")
    click.echo(f"  max tension {k['T_max'] / 1e3:.0f} kN ({100 * k['utilisation_max']:.1f} % MBS); "
               f"thrust energy {k['thrust_energy'] / 3.6e9:.3f} MWh")
    if winch != "none":
        from .studies.kpis import case_kpis

        kw = case_kpis(res, sc)
        k.update({n: kw[n] for n in ("thrust_to_command_ratio", "winch_energy") if n in kw})
        click.echo(f"  winch control: thrust/command {k.get('thrust_to_command_ratio', float('nan')):.3f}, "
                   f"winch energy {k.get('winch_energy', 0.0) / 3.6e9:.4f} MWh")
    if "solver_time_median" in k:
        click.echo(f"  solver: median {1e3 * k['solver_time_median']:.1f} ms, max {1e3 * k['solver_time_max']:.1f} ms, "
                   f"{int(k['solver_failures'])} failures")
    atomic_write_text(out / "summary.json", json.dumps(summary, indent=2, default=float))
    click.echo(f"wrote {out / 'result.npz'} and {out / 'summary.json'}")


def _key_values(items: tuple[str, ...], flag: str) -> dict:
    """``KEY=VALUE`` options as a dict (values by :func:`_parse_value`)."""
    out: dict = {}
    for opt in items:
        if "=" not in opt:
            raise click.BadParameter(f"{flag} {opt!r} must look like KEY=VALUE")
        k, v = opt.split("=", 1)
        out[k.strip()] = _parse_value(v.strip())
    return out


def _parse_value(text: str):
    """A --option value: number, list of numbers (comma-separated), true/false, or text."""
    low = text.lower()
    if low in ("true", "false"):
        return low == "true"
    try:
        if "," in text:
            return [float(x) for x in text.split(",")]
        val = float(text)
        return int(val) if val.is_integer() and "." not in text and "e" not in low else val
    except ValueError:
        return text


# ------------------------------------------------------------------------------------------
# tapm gains
# ------------------------------------------------------------------------------------------


@cli.command()
@click.argument("scenario_name", metavar="SCENARIO")
@click.option("--sea-state", "sea_state", required=True, help="Sea state id of the scenario.")
@click.option("--method", type=click.Choice(["quadratic", "reliability", "unified"]), required=True,
              help="Quadratic thrust + offset cost (survey eq. 34), thrust + failure probability (eq. 36), or the "
                   "unified riser + mooring reliability cost (reliability-setpoint-riser-mooring §2.2).")
@click.option("--broken", default="", help="Comma-separated ids of lines known broken.")
@click.option("--heading", "heading", default="weathervane", show_default=True,
              help="Heading [deg], or 'weathervane' (where the mooring balances the mean yaw moment).")
@click.option("--from", "working_point", default="0,0", show_default=True, metavar="X,Y",
              help="Present turret offset [m]: the working point of the closed form and the solver's start.")
@click.option("--option", "options", multiple=True, metavar="KEY=VALUE",
              help="Setpoint option, e.g. --option w_bottom=20 (repeatable).")
@click.option("--json", "as_json", is_flag=True, help="Print one JSON object instead of text.")
def setpoint(scenario_name: str, sea_state: str, method: str, broken: str, heading: str, working_point: str,
             options: tuple[str, ...], as_json: bool) -> None:
    """Print the optimal turret setpoint of SCENARIO in a sea state and every reliability index there.

    The mean environmental load and the wave-frequency allowance k sigma come from the scenario
    (quasi-static, over 3 hours); for --method unified also the closed-form optimum of the
    reliability paper and its distance to the numeric one.
    """
    import json

    from .design.setpoint import static_setpoint

    sc = _load(scenario_name)
    if sea_state not in [s.id for s in sc.sea_states]:
        raise click.BadParameter(f"{sea_state!r} is not a sea state of scenario {sc.name!r}; its sea states: "
                                 f"{', '.join(s.id for s in sc.sea_states) or 'none'}", param_hint="'--sea-state'")
    ids = [ln.id for ln in sc.lines]
    bl = [b.strip() for b in broken.split(",") if b.strip()]
    for b in bl:
        if b not in ids:
            raise click.BadParameter(f"{b!r} is not a line of scenario {sc.name!r}; lines: {', '.join(ids)}",
                                     param_hint="'--broken'")
    if heading.strip().lower() == "weathervane":
        psi = None
    else:
        try:
            psi = math.radians(float(heading))
        except ValueError:
            psi = math.nan
        if not math.isfinite(psi):
            raise click.BadParameter(f"{heading!r} must be a heading in degrees or 'weathervane'",
                                     param_hint="'--heading'")
    wp = _parse_floats(working_point, "--from")
    if wp.shape != (2,):
        raise click.BadParameter(f"{working_point!r} must be two numbers X,Y [m]", param_hint="'--from'")
    from .control.setpoint_opt import SetpointOptions

    opts = SetpointOptions.from_mapping(_key_values(options, "--option"), where="--option")
    res = static_setpoint(sc, sea_state, method, broken=bl, heading=psi, working_point=wp, options=opts)
    if as_json:
        click.echo(json.dumps(res.as_json(), indent=2))
        return
    x, y = res.setpoint
    click.echo(f"{sc.name}, {res.sea_state} sea, {method} setpoint"
               + (f", line(s) {', '.join(res.broken)} broken" if res.broken else "")
               + f"; heading {math.degrees(res.heading):.1f} deg")
    click.echo(f"  setpoint (turret offset): x = {x:.2f} m, y = {y:.2f} m (|p| = {math.hypot(x, y):.2f} m); "
               f"thrust needed {100 * res.info['F_T']:.1f} % of capacity")
    worst = min(res.delta_lines, key=res.delta_lines.get) if res.delta_lines else None
    click.echo("  line delta: " + ", ".join(f"{k} {v:.2f}" for k, v in res.delta_lines.items())
               + (f"  (lowest: line {worst})" if worst else ""))
    if res.delta_riser_top is not None:
        click.echo(f"  riser delta: top {res.delta_riser_top:.2f}, bottom {res.delta_riser_bottom:.2f}")
    if res.closed_form is not None:
        cx, cy = res.closed_form
        ix, iy = res.closed_form_iterated
        nx, ny = res.numeric
        click.echo(f"  the paper's unified cost as printed: numeric optimum x = {nx:.2f} m, y = {ny:.2f} m; closed form "
                   f"one step from {wp[0]:g},{wp[1]:g}: x = {cx:.2f} m, y = {cy:.2f} m ({res.distance:.2f} m from it); "
                   f"iterated: x = {ix:.2f} m, y = {iy:.2f} m ({res.distance_iterated:.2f} m)")


@cli.command()
@click.argument("scenario_name", metavar="SCENARIO")
@click.option("--out", "out_dir", type=click.Path(file_okay=False), required=True, callback=_out_path("dir"),
              help="Directory for gains.csv/.md/.json.")
@click.option("--sea-states", default=None, help="Sea-state ids, comma-separated (default: all of the scenario's).")
@click.option("--broken", default="each", show_default=True,
              help="'each' (intact plus every single line broken), 'none' (intact only), or line ids, comma-separated.")
@click.option("--headings", default="0", show_default=True,
              help="Headings [deg], comma-separated; 'weathervane' adds the heading where the mean load has no yaw moment.")
def gains(scenario_name: str, out_dir: str, sea_states: str | None, broken: str, headings: str) -> None:
    """Gain tables of SCENARIO: PID (pole placement) and LQR gains per condition.

    A condition is a sea-state class x mooring intact or one line broken x heading; each is
    linearised at the offset equilibrium under that condition's mean environmental load. Every row
    records closed-loop poles, natural periods, damping ratios and stability margins.
    """
    from .design.gains import gain_table, write_gain_tables

    sc = _load(scenario_name)
    ss = None if sea_states is None else [x.strip() for x in sea_states.split(",") if x.strip()]
    if ss is not None:
        known = [s.id for s in sc.sea_states]
        unknown = [x for x in ss if x not in known]
        if not ss or unknown:
            what = (f"names sea states scenario {sc.name!r} lacks: {', '.join(unknown)}" if unknown
                    else "names no sea state")
            raise click.BadParameter(f"{sea_states!r} {what}; its sea states: {', '.join(known) or 'none'}",
                                     param_hint="'--sea-states'")
    if broken == "each":
        br = "each"
    elif broken == "none":
        br = ()
    else:
        br = [x.strip() for x in broken.split(",") if x.strip()]
        if not br:
            raise click.BadParameter(f"{broken!r} names no line: give 'each', 'none' or line ids",
                                     param_hint="'--broken'")
    hs: list = []
    for h in headings.split(","):
        h = h.strip()
        if h == "weathervane":
            hs.append("weathervane")
        elif h:
            try:
                deg = float(h)
            except ValueError:
                raise click.BadParameter(f"--headings entry {h!r} is neither a number of degrees nor 'weathervane'") from None
            if not (math.isfinite(deg) and abs(deg) <= 360.0):
                raise click.BadParameter(f"--headings entry {h!r} must be a finite heading in [-360, 360] deg")
            hs.append(math.radians(deg))
    if not hs:
        raise click.BadParameter(f"--headings = {headings!r} names no heading")
    table = gain_table(sc, sea_states=ss, broken=br, headings=tuple(hs))
    paths = write_gain_tables(table, out_dir)
    n = len(table.rows)
    stable = sum(1 for r in table.rows if r.pid.stable)
    click.echo(f"{sc.name}: {n} conditions, {stable} with a stable PID loop")
    for p in paths:
        click.echo(f"wrote {p}")


# ------------------------------------------------------------------------------------------
# tapm report
# ------------------------------------------------------------------------------------------


@cli.command()
@click.argument("study_dir", metavar="DIR", type=click.Path())
@click.option("--html", "out_html", type=click.Path(dir_okay=False), default=None, callback=_out_path("file"),
              help="HTML file (default DIR/report.html).")
@click.option("--md", "out_md", type=click.Path(dir_okay=False), default=None, callback=_out_path("file"),
              help="Markdown file (default DIR/report.md).")
def report(study_dir: str, out_html: str | None, out_md: str | None) -> None:
    """Write the HTML and Markdown report of the study results in DIR (saved results only)."""
    from .report import write_report

    if not study_dir.strip():
        raise click.BadParameter(f"{study_dir!r} is empty: give the study directory", param_hint="DIR")
    html, md = write_report(study_dir, out_html=out_html, out_md=out_md)
    click.echo(f"wrote {html}")
    click.echo(f"wrote {md}")


# ------------------------------------------------------------------------------------------
# tapm study run, tapm compare
# ------------------------------------------------------------------------------------------


@cli.group()
def study() -> None:
    """Design studies: many closed-loop cases, in parallel, resumable."""


EXIT_CASES_FAILED = 1

_workers_option = click.option(
    "--workers", type=click.IntRange(0, 256), default=None,
    help="Local worker processes (default: CPU count; 0: one case after the other in this process).")


def _exit_if_failed(summary) -> None:
    """With failed cases: name them, say how many, and exit with status 1."""
    if summary.failed:
        for cid in summary.failed:
            click.echo(f"  failed: case {cid}: {summary.errors.get(cid, '')}", err=True)
        click.echo(f"error: {len(summary.failed)} of {summary.n_cases} cases failed (traceback in "
                   f"{Path(summary.out_dir) / 'cases' / '<id>' / 'error.json'}; re-running runs them again)", err=True)
        sys.exit(EXIT_CASES_FAILED)


@study.command("run")
@click.argument("study_file", metavar="STUDY.toml", type=click.Path(dir_okay=False))
@click.option("--out", "out_dir", type=click.Path(file_okay=False), required=True,
              callback=_out_path("dir", "study directory"), help="Study output directory.")
@_workers_option
@click.option("--scheduler", default=None, help="Dask distributed scheduler address (tcp://host:port); needs the 'dask' extra.")
@click.option("--no-progress", is_flag=True, help="No progress bar.")
def study_run(study_file: str, out_dir: str, workers: int | None, scheduler: str | None, no_progress: bool) -> None:
    """Run every case of STUDY.toml not yet finished in OUT (re-running resumes), then the KPI table.

    Exit status 0 when every case finished, 1 when any case failed (each failed case has
    OUT/cases/<id>/error.json), 2 for a bad study file or option, or when another run is writing
    into OUT.
    """
    from .studies.study import load_study, run_study

    if not study_file.strip():
        raise click.BadParameter(f"{study_file!r} is empty: give the study file", param_hint="STUDY.toml")
    st = load_study(study_file)
    summary = run_study(st, out_dir, workers=workers, scheduler=scheduler, progress=not no_progress)
    click.echo(str(summary))
    _exit_if_failed(summary)


def _compare_sea_state(sc, requested: str | None) -> tuple[str, str | None]:
    """The sea state of ``tapm compare`` and a note saying why when it is not the one asked for.

    ``requested`` if given; else ``storm``; else the scenario's most severe sea state: largest Hs,
    then largest wind speed, then largest current speed.
    """
    ids = [s.id for s in sc.sea_states]
    if requested is not None:
        if requested not in ids:
            raise click.BadParameter(f"{requested!r} is not a sea state of scenario {sc.name!r}; its sea states: "
                                     f"{', '.join(ids) or 'none'}", param_hint="'--sea-state'")
        return requested, None
    if "storm" in ids:
        return "storm", None
    if not ids:
        raise click.BadParameter(f"scenario {sc.name!r} defines no sea state", param_hint="SCENARIO")
    worst = max(sc.sea_states, key=lambda s: (s.Hs, s.wind_speed, s.current_speed))
    which = "its only sea state" if len(ids) == 1 else "its most severe sea state (largest Hs)"
    return worst.id, (f"scenario {sc.name} has no sea state 'storm': using {which}, {worst.id!r} (Hs {worst.Hs:g} m, "
                      f"Tp {worst.Tp:g} s, wind {worst.wind_speed:g} m/s, current {worst.current_speed:g} m/s)")


@cli.command()
@click.argument("scenario_name", metavar="[SCENARIO]", default="fpso")
@click.option("--out", "out_dir", type=click.Path(file_okay=False), default="tapm_compare", show_default=True,
              callback=_out_path("dir", "study directory"),
              help="Output directory (results, KPI tables, report).")
@_workers_option
@click.option("--duration", type=float, default=None, help="Override the study's duration [s].")
@click.option("--sea-state", "sea_state", default=None,
              help="Sea state id of SCENARIO (default: 'storm'; a scenario without one: its most severe, largest Hs).")
def compare(scenario_name: str, out_dir: str, workers: int | None, duration: float | None,
            sea_state: str | None) -> None:
    """The main job: MPC against PID in a storm with a line break half-way, and the report.

    Runs the default study (tapm_opt/studies/builtin/mpc_vs_pid.toml, also studies/mpc_vs_pid.toml)
    on SCENARIO (default: the built-in fpso) in its sea state 'storm' (or --sea-state; a scenario
    with no 'storm' runs in its most severe sea state, the one with the largest Hs, and the output
    says which), writes OUT/report.html and OUT/report.md and prints the headline KPIs. Re-running
    resumes. Exit status 1 when any case failed.
    """
    import tomllib

    from .report import write_report
    from .studies.study import run_study, study_from_dict

    path = Path(__file__).parent / "studies" / "builtin" / "mpc_vs_pid.toml"
    data = tomllib.loads(path.read_text(encoding="utf-8"))
    if duration is not None:
        if not (math.isfinite(duration) and duration > 0):
            raise click.BadParameter(f"--duration = {duration} must be a positive number of seconds")
        data["study"]["duration"] = duration
    sc = _load(scenario_name)
    if duration is not None:
        _check_issues(log_size_issues(sc, duration, float(data["study"].get("dt_log", 1.0)), where="--duration",
                                      dt_name="the study's dt_log"))
    sid, note = _compare_sea_state(sc, sea_state)
    if note:
        click.echo(note)
    ss = sc.sea_state(sid)
    brk = data["conditions"][0]["line_break"]
    data["study"]["scenario"] = scenario_name
    data["sea_states"] = [{"id": sid}]
    data["study"]["description"] = (
        f"PID control modes vs linear and nonlinear MPC on {sc.name} in sea state {sid} (Hs {ss.Hs:g} m, Tp {ss.Tp:g} s, wind "
        f"{ss.wind_speed:g} m/s, current {ss.current_speed:g} m/s); line {brk['line']} breaks at "
        f"{brk['time_fraction'] * data['study']['duration']:g} s")
    st = study_from_dict(data, base_dir=Path.cwd(), source=str(path))
    summary = run_study(st, out_dir, workers=workers, progress=True)
    html, md = write_report(out_dir)
    click.echo(str(summary))
    _print_headlines(Path(out_dir), [c.id for c in st.cases])
    click.echo(f"report: {html}")
    click.echo(f"        {md}")
    _exit_if_failed(summary)


def _print_headlines(out: Path, ids: list[str]) -> None:
    from .studies.store import load_study_results

    rows = [r for r in load_study_results(out) if r.id in ids and r.status == "finished"]
    if not rows:
        return
    click.echo(f"  {'case':42s} {'offset max':>10} {'outside safe':>12} {'T/MBS max':>9} {'delta min':>9} {'energy':>10}")
    nan = float("nan")
    for r in rows:
        k, labels = r.kpis, r.labels
        name = f"{labels.get('controller')}, {labels.get('sea_state')}, {labels.get('condition')}"
        click.echo(f"  {name[:42]:42s} {k.get('offset_max', nan):8.1f} m {k.get('time_outside_safe', nan):10.0f} s "
                   f"{k.get('util_max', nan):9.3f} {k.get('delta_min', nan):9.2f} "
                   f"{k.get('thrust_energy', nan) / 3.6e9:6.2f} MWh")


from .cli_capability import capability as _capability_command  # noqa: E402

cli.add_command(_capability_command)

from .cli_estimate import estimate as _estimate_group  # noqa: E402

cli.add_command(_estimate_group)


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``tapm`` console script.

    Warnings raised on the way (e.g. numpy's on non-finite arithmetic) are held back: a failed
    command ends with its one-line error only (``--verbose`` shows them too); a command that
    succeeds prints each as one ``warning: ...`` line after its output.
    """
    with warnings.catch_warnings(record=True) as caught:
        code = _main(argv)
    if code == 0 or _State.verbose:
        for w in caught:
            click.echo(f"warning: {w.category.__name__}: {w.message} ({Path(w.filename).name}:{w.lineno})", err=True)
    return code


def _main(argv: list[str] | None) -> int:
    try:
        cli.main(args=argv, prog_name="tapm", standalone_mode=False)
    except click.exceptions.Abort:
        click.echo("aborted", err=True)
        return 130
    except click.exceptions.NoArgsIsHelpError as exc:
        exc.show()
        return exc.exit_code
    except click.UsageError as exc:  # one line naming the option and the value; --help has the usage
        where = f" (see '{exc.ctx.command_path} --help')" if exc.ctx is not None else ""
        click.echo(f"error: {exc.format_message()}{where}", err=True)
        return exc.exit_code
    except click.ClickException as exc:
        exc.show()
        return exc.exit_code
    except TapmError as exc:
        if _State.verbose:
            traceback.print_exc()
        msg = str(exc)
        click.echo(f"error: {msg}", err=True)
        return EXIT_USER_ERROR
    except OSError as exc:
        if _State.verbose:
            traceback.print_exc()
        click.echo(f"error: {exc}", err=True)
        return EXIT_USER_ERROR
    except MemoryError as exc:
        if _State.verbose:
            traceback.print_exc()
        click.echo(f"error: out of memory ({exc or 'MemoryError'}): ask for a shorter run or fewer FEM segments",
                   err=True)
        return EXIT_USER_ERROR
    except SystemExit as exc:
        return int(exc.code or 0)
    return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
