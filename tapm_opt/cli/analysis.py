"""The ``tapm lines``, ``tapm plant forced-motion``, ``tapm setpoint`` and ``tapm gains`` commands."""

from __future__ import annotations

import math
from pathlib import Path

import click
import numpy as np

from .._io import atomic_write_text, csv_text
from ..config.loader import fem_size_issues, log_size_issues
from ._common import check_issues, cli, key_values, load, out_path, parse_floats


@cli.command()
@click.argument("scenario_name", metavar="SCENARIO", default="fpso")
@click.option("--out", type=click.Path(dir_okay=False), default=None, callback=out_path("file"),
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
    from ..models.characteristics import line_characteristics, offset_curves
    from ..models.mooring import MooringModel

    sc = load(scenario_name)
    dirs_deg = parse_floats(directions, "--directions")
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
    from ..models.catenary import regime_name

    rows = []
    for i, lid in enumerate(chars.line_ids):
        for j in range(chars.XF.shape[1]):
            rows.append((lid, float(chars.XF[i, j]), float(chars.H[i, j]), float(chars.V[i, j]),
                         float(chars.T[i, j]), regime_name(chars.regime[i, j])))
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
@click.option("--waves", is_flag=True,
              help="Add the sea state's wave-frequency motion of the hull (the scenario's vessel.wave_motion: "
                   "surge, sway and yaw, or all six degrees of freedom) to the forced motion.")
@click.option("--seed", type=int, default=0, show_default=True, help="Seed of the waves (--waves), as the plant's.")
@click.option("--out", type=click.Path(dir_okay=False), default=None, callback=out_path("file"),
              help="CSV file with columns t, x, y, psi, T1..Tn (s, m, m, rad, N).")
def plant_forced_motion(scenario_name: str, dof: str, amplitude: float, period: float, duration: float,
                        segments: int | None, dt_out: float, sea_state: str | None, waves: bool, seed: int,
                        out: str | None) -> None:
    """Settle the lines of SCENARIO at rest, then move the vessel as amplitude*sin(2 pi t/period).

    Prints the FEM step used, how settling converged, the equivalent linear mooring damping of
    the DOF (energy dissipated per cycle, cycles after the first), and per line the tension range
    of the first cycle (start-up) and of the cycles after it, with the dynamic/quasi-static
    tension amplification.
    """
    from ..plant.forced_motion import forced_motion

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
    if waves and (sea_state is None or sea_state == "none"):
        raise click.BadParameter("--waves needs --sea-state (the sea state whose waves move the hull)")
    sc = load(scenario_name)
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
    check_issues(fem_size_issues(sc, segments, where="--segments"))
    check_issues(log_size_issues(sc, duration, dt_out, where="--duration", dt_name="--dt-out",
                                  channels=4 + len(sc.lines)))
    amp = math.radians(amplitude) if dof == "yaw" else amplitude
    res = forced_motion(sc, dof=dof, amplitude=amp, period=period, duration=duration, segments=segments,
                        dt_out=dt_out, sea_state=sea_state, waves=waves, seed=seed)
    unit = "N m s/rad" if dof == "yaw" else "N s/m"
    st = res.settle
    where = "still water"
    if res.sea_state:
        where = f"{res.sea_state} current" + (f" and waves ({sc.vessel.wave_motion.model} hull motion, seed {seed})"
                                              if waves else "")
    click.echo(f"{sc.name}: forced {dof}, amplitude {amplitude:g} {'deg' if dof == 'yaw' else 'm'}, period {period:g} s, "
               f"duration {duration:g} s, {where}; FEM step {res.dt:.4g} s")
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

    from ..design.setpoint import static_setpoint

    sc = load(scenario_name)
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
    wp = parse_floats(working_point, "--from")
    if wp.shape != (2,):
        raise click.BadParameter(f"{working_point!r} must be two numbers X,Y [m]", param_hint="'--from'")
    from ..control.setpoint_opt import SetpointOptions

    opts = SetpointOptions.from_mapping(key_values(options, "--option"), where="--option")
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
@click.option("--out", "out_dir", type=click.Path(file_okay=False), required=True, callback=out_path("dir"),
              help="Directory for gains.csv/.md/.json.")
@click.option("--sea-states", default=None, help="Sea-state ids, comma-separated (default: all of the scenario's).")
@click.option("--broken", default="each", show_default=True,
              help="'each' (intact plus every single line broken), 'none' (intact only), or line ids, comma-separated.")
@click.option("--headings", default="0", show_default=True,
              help="Headings [deg], comma-separated; 'weathervane' adds the heading where the mean load has no yaw moment.")
@click.option("--designs", default=None, metavar="TUNE_DIR",
              help="A tapm tune run that tuned a PID per sea state and mooring condition ([tuning] per = "
                   "[\"sea_state\", \"condition\"]): those conditions take its tuned design (docs/tuning.md).")
def gains(scenario_name: str, out_dir: str, sea_states: str | None, broken: str, headings: str,
          designs: str | None) -> None:
    """Gain tables of SCENARIO: PID (pole placement) and LQR gains per condition.

    A condition is a sea-state class x mooring intact or one line broken x heading; each is
    linearised at the offset equilibrium under that condition's mean environmental load. Every row
    records closed-loop poles, natural periods, damping ratios and stability margins. With
    --designs, the PID of each sea state and mooring condition a tuning run tuned takes the tuned
    periods, damping and integral ratio (the other conditions keep their class's design).
    """
    from ..design.gains import gain_table, write_gain_tables

    sc = load(scenario_name)
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
    row_designs = None
    if designs is not None:
        from ..studies.tuning import gain_designs

        row_designs = gain_designs(designs)
        known = {s.id for s in sc.sea_states}
        lost = sorted({k[0] for k in row_designs} - known)
        if lost:
            raise click.BadParameter(f"{designs!r} tuned sea states scenario {sc.name!r} lacks: {', '.join(lost)}",
                                     param_hint="'--designs'")
        if ss is None:
            ss = sorted({k[0] for k in row_designs}, key=[s.id for s in sc.sea_states].index)
        if broken == "each":
            br = sorted({k[1] for k in row_designs} - {"intact"})
    table = gain_table(sc, sea_states=ss, broken=br, headings=tuple(hs), row_designs=row_designs)
    paths = write_gain_tables(table, out_dir)
    n = len(table.rows)
    stable = sum(1 for r in table.rows if r.pid.stable)
    click.echo(f"{sc.name}: {n} conditions, {stable} with a stable PID loop"
               + (f"; {sum((r.condition.sea_state, r.condition.broken) in row_designs for r in table.rows)} with "
                  f"the tuned PID design" if row_designs else ""))
    for p in paths:
        click.echo(f"wrote {p}")
