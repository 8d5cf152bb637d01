"""The ``tapm scenario`` commands: list, show, validate, import-moordyn, export-moordyn."""

from __future__ import annotations

import math
import sys
from pathlib import Path

import click
import numpy as np

from .._io import atomic_write_text
from ..config import builtin_scenarios, load_scenario
from ..errors import ScenarioError
from ._common import cli, load, out_path


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
    """Check scenario FILES; print every problem found. Exit status 1 if any is invalid.

    After the file checks, engineering checks on the mooring and thrusters (pretension against MBS,
    lines straight under their fairlead, balance at the field zero point, thrust capacity, unit
    slips): an error makes the file INVALID, a warning is printed and the file stays valid.
    """
    from .._text import terminal_text
    from ..models.sanity import engineering_issues

    bad = 0
    for f in files:
        name = terminal_text(f)
        try:
            sc = load_scenario(f)
        except ScenarioError as exc:
            bad += 1
            n = len(exc.issues)
            click.echo(f"{name}: INVALID ({n} problem{'s' if n != 1 else ''})")
            for issue in exc.issues:
                click.echo(f"  - {terminal_text(issue)}")
            continue
        found = engineering_issues(sc)
        errors = [i for i in found if i.severity == "error"]
        warns = [i for i in found if i.severity != "error"]
        if errors:
            bad += 1
            n = len(errors)
            click.echo(f"{name}: INVALID ({n} problem{'s' if n != 1 else ''})")
            for issue in errors:
                click.echo(f"  - {terminal_text(issue)}")
        else:
            click.echo(f"{name}: OK — {terminal_text(sc.name)}: {len(sc.lines)} lines, {len(sc.thrusters)} thrusters, "
                       f"{len(sc.sea_states)} sea states" + (f"; {len(warns)} warning{'s' if len(warns) != 1 else ''}"
                                                             if warns else ""))
        for issue in warns:
            click.echo(f"  - warning: {terminal_text(issue)}")
    if bad:
        sys.exit(1)


@scenario.command("show")
@click.argument("name")
def scenario_show(name: str) -> None:
    """Print a summary of scenario NAME (built-in name or TOML file)."""
    from .._text import terminal_text as tt
    from ..models.mooring import MooringModel

    sc = load(name)
    env, v, tur = sc.environment, sc.vessel, sc.turret
    click.echo(f"Scenario {tt(sc.name)}: {tt(sc.meta.description)}")
    for s in sc.meta.sources:
        click.echo(f"  source: {tt(s)}")
    click.echo(f"Environment: depth {env.water_depth:g} m, rho_w {env.water_density:g} kg/m3, g {env.gravity:g} m/s2")
    click.echo(f"Vessel {tt(v.name)}: Lpp {v.length_pp:g} m, B {v.breadth:g} m, T {v.draught:g} m; "
               f"M diag [{', '.join(f'{x:.3g}' for x in np.diag(v.M))}]")
    click.echo(f"Turret: {tur.mode}, at ({tur.position[0]:g}, {tur.position[1]:g}) m in {{B}}, "
               f"fairlead radius {tur.fairlead_radius:g} m, depth {tur.fairlead_depth:g} m")
    model = MooringModel.from_scenario(sc)
    sol = model.solve_lines(np.zeros(3))
    click.echo(f"Lines ({len(sc.lines)}), at the field zero point:")
    click.echo(f"  {'id':>6} {'type':>10} {'L [m]':>8} {'XF [m]':>8} {'T [kN]':>9} {'H [kN]':>9} {'T/MBS':>6} regime")
    _, _, XF = model.spans(np.zeros(3))
    for i, ln in enumerate(sc.lines):
        click.echo(f"  {tt(ln.id):>6} {tt(ln.type):>10} {ln.length:8.1f} {XF[i]:8.1f} {sol.TF[i] / 1e3:9.1f} "
                   f"{sol.HF[i] / 1e3:9.1f} {sol.TF[i] / model.MBS[i]:6.3f} {sol.regime_names()[i]}")
    tau0 = model.force(np.zeros(3))
    click.echo(f"Net mooring load at the field zero point: X {tau0[0] / 1e3:.3g} kN, Y {tau0[1] / 1e3:.3g} kN, "
               f"N {tau0[2] / 1e3:.3g} kN m")
    if sc.thrusters:
        click.echo(f"Thrusters ({len(sc.thrusters)}):")
        for t in sc.thrusters:
            click.echo(f"  {tt(t.id):>6} {t.kind:8s} at ({t.position[0]:g}, {t.position[1]:g}) m, "
                       f"max {t.max_thrust / 1e3:.0f} kN")
    for s in sc.sea_states:
        click.echo(f"Sea state {tt(s.id)}: Hs {s.Hs:g} m, Tp {s.Tp:g} s, wind {s.wind_speed:g} m/s, "
                   f"current {s.current_speed:g} m/s")
    if sc.riser is not None:
        click.echo(f"Riser: length {sc.riser.length:g} m, top tension {sc.riser.top_tension / 1e3:.0f} kN")
    for f in sc.faults:
        if f.kind == "buoy_loss":
            at = f"joint {f.joint}" if f.joint is not None else f"point {tt(f.point)}"
            click.echo(f"Fault: buoy_loss at {at} of line {tt(f.line)} at t = {f.time:g} s")
            continue
        target = f.line if f.kind == "line_break" else f.thruster
        click.echo(f"Fault: {f.kind} of {tt(target)} at t = {f.time:g} s")
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
@click.option("--out", required=True, type=click.Path(dir_okay=False), callback=out_path("file"),
              help="Scenario TOML file to write.")
@click.option("--mbs", "mbs", multiple=True, metavar="TYPE=NEWTONS",
              help="Breaking strength of MoorDyn line type TYPE [N] (repeatable; required for every line type used: "
                   "MoorDyn files carry none).")
@click.option("--mbs-cov", type=click.FloatRange(0.0, 1.0), default=0.05, show_default=True,
              help="MBS_std as a fraction of MBS.")
@click.option("--name", default=None, help="Scenario name (default: the stem of --out).")
@click.option("--riser", type=click.Choice(["auto", "keep", "adapt", "drop"]), default="auto", show_default=True,
              help="The vessel scenario's riser in FILE's water depth: kept, adapted (length and top tension scaled "
                   "to the new depth), dropped, or auto: kept at the same depth, else adapted.")
@click.option("--turret", type=click.Choice(["auto", "locked", "free"]), default="auto", show_default=True,
              help="MoorDyn's fairleads are hull-fixed: auto keeps the vessel's turret mode when they lie on one "
                   "circle about its centre of turret and locks the turret (spread mooring) otherwise.")
@click.option("--recentre", type=click.Choice(["auto", "no"]), default="auto", show_default=True,
              help="auto: move the mooring so the vessel sits at the field zero point (a vessel body off the file's "
                   "origin, or fairleads beyond the hull about the centre of turret); no: the file's coordinates.")
@click.option("--fixed-as-fairleads", is_flag=True, default=False,
              help="For a FILE with no vessel point (no coupled point or body): take the upper fixed point of each "
                   "line (or lines in series) between two fixed points as a fairlead on the vessel, the lower one as "
                   "its anchor.")
def scenario_import_moordyn(file: str, vessel: str, out: str, mbs: tuple[str, ...], mbs_cov: float,
                            name: str | None, riser: str, turret: str, recentre: str,
                            fixed_as_fairleads: bool) -> None:
    """Build a scenario from MoorDyn v2 input FILE and a vessel scenario.

    From FILE: line types, lines, anchors, fairleads, water depth, water density and gravity.
    From --vessel: everything else. Fairleads become turret angles and radii about the vessel's
    centre of turret. Conventions: docs/moordyn.md.
    """
    from ..models.moordyn_import import import_moordyn

    res = import_moordyn(file, vessel, mbs=_type_values(mbs, "--mbs"), mbs_cov=mbs_cov,
                         name=name or Path(out).stem, riser=riser, turret=turret, recentre=recentre,
                         fixed_as_fairleads=fixed_as_fairleads)
    atomic_write_text(out, res.toml)
    sc = res.scenario
    click.echo(f"wrote {out}: scenario {sc.name}, {len(sc.lines)} lines, {len(sc.line_types)} line types, depth "
               f"{sc.environment.water_depth:g} m, fairleads at radius {sc.turret.fairlead_radius:g} m and depth "
               f"{sc.turret.fairlead_depth:g} m (mooring from {Path(file).name}, the rest from {vessel})")
    for note in res.notes:
        click.echo(f"  note: {note}")


@scenario.command("export-moordyn")
@click.argument("scenario_name", metavar="SCENARIO")
@click.option("--out", required=True, type=click.Path(dir_okay=False), callback=out_path("file"),
              help="MoorDyn v2 input file to write.")
@click.option("--segments", type=click.IntRange(2, 1000), default=None,
              help="Segments of every line (default: the scenario's).")
def scenario_export_moordyn(scenario_name: str, out: str, segments: int | None) -> None:
    """Write the mooring of SCENARIO as a MoorDyn v2 input file.

    One coupled body at the centre of turret carries the fairleads; anchors are fixed points.
    Conventions (frames, diameter, drag, damping, seabed, time step): docs/moordyn.md.
    """
    from ..models.moordyn_import import export_moordyn   # free points start at the quasi-static equilibrium

    sc = load(scenario_name)
    info = export_moordyn(sc, out, segments=segments)
    click.echo(f"wrote {out}: {info.n_lines} lines of {sc.name}; dtM {info.dtM:g} s ({info.scheme}), "
               f"kBot {info.kBot:.4g} Pa/m, cBot {info.cBot:.4g} Pa s/m")
    for note in info.notes:
        click.echo(f"  note: {note}")
