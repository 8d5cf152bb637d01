"""The ``tapm capability`` command (registered in :mod:`tapm_opt.cli`).

Computation: :func:`tapm_opt.design.capability.capability` (Levels 1 and 2) and
:func:`tapm_opt.studies.capability_level3.capability_level3` (Level 3, the time domain); files and
figures: :func:`tapm_opt.report.capability.write_capability` and
:func:`~tapm_opt.report.capability.write_level3`; method: ``docs/capability.md``.
"""

from __future__ import annotations

import json
import math
import os

import click

from ._common import ControllerKindChoice

__all__ = ["capability"]


def _out_dir(ctx: click.Context, param: click.Parameter, value: str | None) -> str | None:
    """``--out``: the check of every ``tapm`` command's output directory (``cli._out_path``),
    imported when called (``tapm_opt.cli`` imports this module)."""
    from ._common import out_path

    return out_path("dir")(ctx, param, value)


@click.command("capability")
@click.argument("scenario_name", metavar="SCENARIO")
@click.option("--out", "out_dir", type=click.Path(file_okay=False), default=None, callback=_out_dir,
              help="Directory for the files (Levels 1, 2: capability.csv, capability.json and the polar plots; "
                   "Level 3: capability_level3_<controller>.csv, .json, .png). Without it nothing is written.")
@click.option("--level", type=click.Choice(["1", "2", "3"]), default="1", show_default=True,
              help="1: wind, waves and current collinear (DNV-ST-0111 Level 1); 2: wind and current keep the base "
                   "sea state's directions relative to its waves; 3: the time domain, the controller in the loop on "
                   "the FEM plant (environments as Level 1).")
@click.option("--heading", type=click.Choice(["weathervane", "fixed"]), default=None,
              help="Heading with thrust: bow into the environment (weathervane) or --fixed-heading. Default by the "
                   "turret: weathervane for a free turret, fixed for a locked one (a spread mooring cannot turn "
                   "into the weather; weathervane is refused). Mooring alone: a free turret weathervanes, a locked "
                   "one's heading is where the lines hold it.")
@click.option("--fixed-heading", "fixed_heading", type=float, default=0.0, show_default=True,
              help="Heading of --heading fixed [deg].")
@click.option("--condition", type=click.Choice(["all", "intact", "all-single-line", "thruster-failure"]),
              default=None,
              help="Cases besides mooring alone and intact: every single line broken, the worst single thruster "
                   "failure, or both (all; the default of Levels 1, 2). Level 3: intact only.")
@click.option("--sea-state", "sea_state", default=None,
              help="Base sea state (JONSWAP gamma, current profile, Level 2 spreads; default the scenario's first).")
@click.option("--directions", default=None,
              help="Environment directions [deg, coming from], comma-separated (default 0-350 in 10 deg steps).")
@click.option("--design-direction", "design_direction", type=float, default=None,
              help="Centre of the ±30 deg sector of A and C [deg, coming from] (default: the base sea state's waves).")
@click.option("--table", type=click.Choice(["extended", "standard"]), default="extended", show_default=True,
              help="Environment table: the standard's Beaufort 0-11 with the extension 12-15 (rows beyond the "
                   "standard's, docs/capability.md), or the standard's alone.")
@click.option("--losses", is_flag=True,
              help="Apply DNV-ST-0111's Level 1 thrust losses (the factor 0.9 and the thruster-thruster interaction "
                   "sectors) to the thrusters.")
@click.option("--thruster-diameter", "thruster_diameter", type=float, default=None,
              help="Propeller diameter [m] of the interaction sectors of --losses (default: each thruster's from "
                   "its thrust).")
@click.option("--controller", type=ControllerKindChoice(), default=None,
              help="Level 3: the controller in the loop (a registered kind; default pid).")
@click.option("--duration", type=float, default=None,
              help="Level 3: checked length of each run [s] after the warm-up (default 10800, 3 hours).")
@click.option("--warmup", type=float, default=None,
              help="Level 3: start of each run left out of the statistics [s] (default 300).")
@click.option("--seeds", type=int, default=None,
              help="Level 3: runs per table row, plant seeds 1..N; a row passes when all do (default 1).")
@click.option("--segments", type=int, default=None,
              help="Level 3: FEM segments per line (default each line's own).")
@click.option("--heading-tolerance", "heading_tolerance", type=float, default=None,
              help="Level 3: largest heading error allowed [deg] (default 5).")
@click.option("--failed-line", "failed_line", default=None, metavar="ID",
              help="Level 3: the system after the loss of line ID (plant and controllers without it from the "
                   "start; compared with Level 1's case 'line ID' after the failure). Default: intact.")
@click.option("--riser/--no-riser", default=None,
              help="Check the riser's angles (default: Levels 1, 2 yes; Level 3 no: turret offset and line "
                   "tensions only).")
@click.option("--workers", type=click.IntRange(1, 64), default=None,
              help="Processes over the cases (Levels 1, 2) or the directions (Level 3) (default: 2, or 1 on a "
                   "single CPU).")
@click.option("--json", "as_json", is_flag=True, help="Print one JSON object instead of text.")
def capability(scenario_name: str, out_dir: str | None, level: str, heading: str | None, fixed_heading: float,
               condition: str | None, sea_state: str | None, directions: str | None, design_direction: float | None,
               table: str, losses: bool, thruster_diameter: float | None, controller: str | None,
               duration: float | None, warmup: float | None, seeds: int | None, segments: int | None,
               heading_tolerance: float | None, failed_line: str | None, riser: bool | None, workers: int | None,
               as_json: bool) -> None:
    """Thruster-assisted mooring capability envelopes of SCENARIO, DNV-ST-0111 style.

    Levels 1 and 2: for every direction and case (mooring alone; thrusters with the mooring intact;
    each single line broken; the worst single thruster failure) the largest Beaufort row of the
    table, and the limiting wind speed between rows, for which a quasi-static equilibrium exists
    with the turret inside the safe circle, the lines within DNV-OS-E301 ULS/ALS and the riser
    within its angles, the thrust allocation supplying the rest (dynamic allowance 1.25). Writes
    OUT/capability.csv, capability.json (the numbers A, B, C, D), capability.png and
    capability_cases.png.

    Level 3: for every direction the strongest row in which the closed loop with --controller on
    the FEM plant keeps the turret inside the safe circle and every fairlead tension below
    limits.tension_utilisation x MBS for --duration seconds (after --warmup); with --failed-line,
    the same after the loss of that line. Writes OUT/capability_level3_<controller>.csv, .json and
    .png (capability_level3_<controller>_line<ID>.* after a line's loss). Method:
    docs/capability.md.
    """
    from ._common import load, parse_floats

    sc = load(scenario_name)
    lv = int(level)
    if sea_state is not None and sea_state not in [s.id for s in sc.sea_states]:
        raise click.BadParameter(f"{sea_state!r} is not a sea state of scenario {sc.name!r}; its sea states: "
                                 f"{', '.join(s.id for s in sc.sea_states) or 'none'}", param_hint="'--sea-state'")
    if sea_state is None and not sc.sea_states:
        raise click.BadParameter(f"scenario {sc.name!r} defines no sea state (the base of the environments)",
                                 param_hint="SCENARIO")
    for name, v in (("--fixed-heading", fixed_heading), ("--design-direction", design_direction)):
        if v is not None and not (math.isfinite(v) and abs(v) <= 360.0):
            raise click.BadParameter(f"{v!r} must be a finite angle in [-360, 360] deg", param_hint=f"'{name}'")
    if thruster_diameter is not None and not (math.isfinite(thruster_diameter) and thruster_diameter > 0):
        raise click.BadParameter(f"{thruster_diameter!r} must be a positive number of metres",
                                 param_hint="'--thruster-diameter'")
    if thruster_diameter is not None and not losses:
        raise click.BadParameter("is the diameter of the interaction sectors of --losses: give --losses too",
                                 param_hint="'--thruster-diameter'")
    level3_only = {"--controller": controller, "--duration": duration, "--warmup": warmup, "--seeds": seeds,
                   "--segments": segments, "--heading-tolerance": heading_tolerance, "--failed-line": failed_line}
    if lv != 3:
        for name, v in level3_only.items():
            if v is not None:
                raise click.BadParameter(f"is an option of --level 3 (the time domain), not of --level {lv}",
                                         param_hint=f"'{name}'")
    else:
        if condition not in (None, "intact"):
            raise click.BadParameter(f"{condition!r}: Level 3 computes one case, intact or after --failed-line ID "
                                     "(give --condition intact or leave it out)", param_hint="'--condition'")
        # the Level 3 options themselves are checked by Level3Options and the scenario's lines (_level3)
    dirs = None
    if directions is not None:
        vals = parse_floats(directions, "--directions")
        if any(abs(d) > 360.0 for d in vals):
            raise click.BadParameter(f"{directions!r}: each direction must be within [-360, 360] deg",
                                     param_hint="'--directions'")
        if len({round(float(d) % 360.0, 9) for d in vals}) != len(vals):
            raise click.BadParameter(f"{directions!r} repeats a direction", param_hint="'--directions'")
        dirs = tuple(float(d) for d in vals)
    from ..design.capability import CapabilityError, CapabilityOptions, resolve_options

    try:   # the heading by the turret, a weathervane on a locked turret refused (one rule, the options')
        heading = resolve_options(sc, CapabilityOptions(heading=heading)).heading
    except CapabilityError as exc:
        raise click.BadParameter(str(exc), param_hint="'--heading'") from None
    if sc.limits.safe_radius is None:
        raise click.BadParameter(f"scenario {sc.name!r} has no limits.safe_radius: the capability needs the safe "
                                 "circle", param_hint="SCENARIO")
    if not sc.thrusters:
        raise click.BadParameter(f"scenario {sc.name!r} has no thrusters: every case but mooring alone needs them",
                                 param_hint="SCENARIO")
    kw = {} if dirs is None else {"directions_deg": dirs}
    n_workers = workers or min(2, os.cpu_count() or 1)
    if lv == 3:
        _level3(sc, out_dir, as_json, heading=heading, fixed_heading_deg=fixed_heading, sea_state=sea_state,
                table=table, losses=losses, thruster_diameter=thruster_diameter, controller=controller or "pid",
                duration=duration, warmup=warmup, seeds=seeds, segments=segments,
                heading_tolerance=heading_tolerance, failed_line=failed_line, riser=bool(riser),
                workers=n_workers, **kw)
        return
    from ..design.capability import capability as compute
    from ..report.capability import capability_files, write_capability

    opts = CapabilityOptions(level=lv, heading=heading, condition=condition or "all", fixed_heading_deg=fixed_heading,
                             sea_state=sea_state, design_direction_deg=design_direction, table=table, losses=losses,
                             thruster_diameter=thruster_diameter, riser=True if riser is None else riser,
                             workers=n_workers, **kw)
    res = compute(sc, opts)
    if out_dir is not None:
        paths = write_capability(res, out_dir)
    else:
        capability_files(res)   # the figures are drawn either way (a failure shows without --out too)
        paths = []
    n = res.numbers
    if as_json:
        cases = []
        for c in res.cases:
            j = int(c.wind_speed.argmin())
            cases.append({"name": c.name, "lowest_beaufort": int(c.beaufort.min()),
                          "lowest_wind_speed": float(c.wind_speed[j]),
                          "at_direction_deg": float(res.directions_deg[j])})
        click.echo(json.dumps({"scenario": res.scenario, "level": lv, "numbers": n, "cases": cases,
                               "worst_thruster": res.info.get("worst_thruster"),
                               "losses": bool(losses), "table": table,
                               "files": [str(p) for p in paths], "elapsed_s": res.info["elapsed_s"]}, indent=2))
        return

    def f(x):
        return "-" if x is None else str(x)

    n_cases = len(res.cases) + max(len(res.thruster_cases) - 1, 0)
    click.echo(f"{res.scenario}: capability, Level {level}, heading {heading}"
               + (f" {fixed_heading:g} deg" if heading == "fixed" else "")
               + f", {len(res.directions_deg)} directions, {n_cases} cases in {res.info['elapsed_s']:.1f} s"
               + (", with DNV-ST-0111 Level 1 thrust losses" if losses else ", no thrust losses")
               + f", {table} table")
    click.echo(f"  A {f(n['A'])}  B {f(n['B'])}  C {f(n['C'])}"
               + (f" ({n['C_case']})" if n["C_case"] else "") + f"  D {f(n['D'])}"
               + (f" ({n['D_case']})" if n["D_case"] else "")
               + f"  (mooring alone: {f(n['mooring_A'])}, {f(n['mooring_B'])}; design direction "
               f"{res.design_direction_deg:g} deg)")
    for c in res.cases:
        j = int(c.wind_speed.argmin())
        click.echo(f"  {c.name:14s} lowest Beaufort {int(c.beaufort.min()):3d}, {c.wind_speed[j]:5.1f} m/s from "
                   f"{res.directions_deg[j]:5.0f} deg ({c.limit[j]})")
    if table == "extended" and any(int(c.beaufort.max()) > 11 for c in res.cases):
        click.echo("  (Beaufort above 11: the table's extension, beyond the standard's rows; docs/capability.md)")
    for p in paths:
        click.echo(f"wrote {p}")


def _level3(sc, out_dir: str | None, as_json: bool, **kw) -> None:
    """``--level 3``: :func:`~tapm_opt.studies.capability_level3.capability_level3`, its text or
    JSON summary and its files."""
    from ..design.capability import CapabilityError
    from ..report.capability import level3_files, write_level3
    from ..studies.capability_level3 import (
        Level3Options,
        capability_level3,
        check_failed_line,
    )

    given = {k: v for k, v in kw.items() if v is not None}
    try:   # the options' own checks, each error named as its command-line option
        opts = Level3Options(**given)
        check_failed_line(sc, opts)
    except CapabilityError as exc:
        field = str(exc).split(" ", 1)[0]
        raise click.BadParameter(str(exc), param_hint=f"'--{field.replace('_', '-')}'") from None

    def progress(line: str) -> None:
        if not as_json:
            click.echo(f"  {line}", err=True)

    res = capability_level3(sc, opts, progress=progress)
    if out_dir is not None:
        paths = write_level3(res, out_dir)
    else:
        level3_files(res)
        paths = []
    b1 = res.level1.case(opts.case).beaufort
    b0 = res.level1_bound.case(opts.case).beaufort
    if as_json:
        click.echo(json.dumps({"scenario": res.scenario, "level": 3, "controller": opts.controller,
                               "case": opts.case,
                               "directions": [{"direction_deg": d.direction_deg, "beaufort": d.beaufort,
                                               "wind_speed": d.wind_speed, "limit_above": d.limit,
                                               "level1_beaufort": int(b1[i]), "level1_bound_beaufort": int(b0[i]),
                                               "runs": len(d.tested)}
                                              for i, d in enumerate(res.directions)],
                               "files": [str(p) for p in paths], "elapsed_s": res.info["elapsed_s"]}, indent=2))
        return
    click.echo(f"{res.scenario}: capability, Level 3 (time domain), controller {opts.controller}, case "
               f"{opts.case}" + (" (the system after the failure)" if opts.failed_line is not None else "") + ", heading "
               f"{opts.heading}, {len(res.directions)} directions, {res.info['runs']} runs of "
               f"{opts.warmup:g} + {opts.duration:g} s in {res.info['elapsed_s']:.1f} s"
               + (", thrusters with the Level 1 losses" if opts.losses else ""))
    click.echo("  direction  Level 3 (wind)        L1 / bound  deciding run: offset, T/MBS (line), heading error, "
               "energy   row above: what failed")
    for i, d in enumerate(res.directions):
        s = d.decided
        run = ("-" if s is None else
               f"{s.offset_max:5.1f} m, {s.util_max:.3f} ({s.util_line}), {s.heading_error_max:.1f} deg, "
               f"{s.thrust_energy / 3.6e9:.2f} MWh")
        above = d.limit if d.above is None else f"BF {d.above.number}: {d.above.detail}"
        if opts.seeds > 1:   # each seed's largest offset: how far the maxima spread
            for lab, r in (("", s), ("above ", d.above)):
                if r is not None and len(r.offset_by_seed) > 1:
                    above += f"; {lab}offset by seed " + ", ".join(f"{v:.1f}" for v in r.offset_by_seed) + " m"
        click.echo(f"  {d.direction_deg:6.0f} deg  BF {d.beaufort:3d} ({d.wind_speed:4.1f} m/s)  "
                   f"{int(b1[i]):4d} / {int(b0[i]):2d}   {run}   {above}")
    for p in paths:
        click.echo(f"wrote {p}")
