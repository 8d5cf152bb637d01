"""The ``tapm capability`` command (registered in :mod:`tapm_opt.cli`).

Computation: :func:`tapm_opt.design.capability.capability`; files and figures:
:func:`tapm_opt.report.capability.write_capability`; method: ``docs/capability.md``.
"""

from __future__ import annotations

import json
import math
import os

import click

__all__ = ["capability"]


def _out_dir(ctx: click.Context, param: click.Parameter, value: str | None) -> str | None:
    """``--out``: the check of every ``tapm`` command's output directory (``cli._out_path``),
    imported when called (``tapm_opt.cli`` imports this module)."""
    from ._common import out_path

    return out_path("dir")(ctx, param, value)


@click.command("capability")
@click.argument("scenario_name", metavar="SCENARIO")
@click.option("--out", "out_dir", type=click.Path(file_okay=False), required=True, callback=_out_dir,
              help="Directory for capability.csv, capability.json and the polar plots.")
@click.option("--level", type=click.Choice(["1", "2"]), default="1", show_default=True,
              help="1: wind, waves and current collinear (DNV-ST-0111 Level 1); 2: wind and current keep the base "
                   "sea state's directions relative to its waves.")
@click.option("--heading", type=click.Choice(["weathervane", "fixed"]), default="weathervane", show_default=True,
              help="Heading with thrust: bow into the environment (weathervane) or --fixed-heading. Mooring alone "
                   "always weathervanes.")
@click.option("--fixed-heading", "fixed_heading", type=float, default=0.0, show_default=True,
              help="Heading of --heading fixed [deg].")
@click.option("--condition", type=click.Choice(["all", "intact", "all-single-line", "thruster-failure"]),
              default="all", show_default=True,
              help="Cases besides mooring alone and intact: every single line broken, the worst single thruster "
                   "failure, or both (all).")
@click.option("--sea-state", "sea_state", default=None,
              help="Base sea state (JONSWAP gamma, current profile, Level 2 spreads; default the scenario's first).")
@click.option("--directions", default=None,
              help="Environment directions [deg, coming from], comma-separated (default 0-350 in 10 deg steps).")
@click.option("--design-direction", "design_direction", type=float, default=None,
              help="Centre of the ±30 deg sector of A and C [deg, coming from] (default: the base sea state's waves).")
@click.option("--workers", type=click.IntRange(1, 64), default=None,
              help="Processes over the cases (default: 2, or 1 on a single CPU).")
@click.option("--json", "as_json", is_flag=True, help="Print one JSON object instead of text.")
def capability(scenario_name: str, out_dir: str, level: str, heading: str, fixed_heading: float, condition: str,
               sea_state: str | None, directions: str | None, design_direction: float | None, workers: int | None,
               as_json: bool) -> None:
    """Thruster-assisted mooring capability envelopes of SCENARIO, DNV-ST-0111 style.

    For every direction and case (mooring alone; thrusters with the mooring intact; each single
    line broken; the worst single thruster failure) the largest Beaufort row of the standard's
    table, and the limiting wind speed between rows, for which a quasi-static equilibrium exists
    with the turret inside the safe circle, the lines within DNV-OS-E301 ULS/ALS and the riser
    within its angles, the thrust allocation supplying the rest (dynamic allowance 1.25). Writes
    OUT/capability.csv, capability.json (the numbers A, B, C, D), capability.png and
    capability_cases.png. Method: docs/capability.md.
    """
    from ._common import load, parse_floats
    from ..design.capability import CapabilityOptions, capability as compute
    from ..report.capability import write_capability

    sc = load(scenario_name)
    if sea_state is not None and sea_state not in [s.id for s in sc.sea_states]:
        raise click.BadParameter(f"{sea_state!r} is not a sea state of scenario {sc.name!r}; its sea states: "
                                 f"{', '.join(s.id for s in sc.sea_states) or 'none'}", param_hint="'--sea-state'")
    if sea_state is None and not sc.sea_states:
        raise click.BadParameter(f"scenario {sc.name!r} defines no sea state (the base of the environments)",
                                 param_hint="SCENARIO")
    for name, v in (("--fixed-heading", fixed_heading), ("--design-direction", design_direction)):
        if v is not None and not (math.isfinite(v) and abs(v) <= 360.0):
            raise click.BadParameter(f"{v!r} must be a finite angle in [-360, 360] deg", param_hint=f"'{name}'")
    dirs = None
    if directions is not None:
        vals = parse_floats(directions, "--directions")
        if any(abs(d) > 360.0 for d in vals):
            raise click.BadParameter(f"{directions!r}: each direction must be within [-360, 360] deg",
                                     param_hint="'--directions'")
        if len({round(float(d) % 360.0, 9) for d in vals}) != len(vals):
            raise click.BadParameter(f"{directions!r} repeats a direction", param_hint="'--directions'")
        dirs = tuple(float(d) for d in vals)
    if sc.limits.safe_radius is None:
        raise click.BadParameter(f"scenario {sc.name!r} has no limits.safe_radius: the capability needs the safe "
                                 "circle", param_hint="SCENARIO")
    if not sc.thrusters:
        raise click.BadParameter(f"scenario {sc.name!r} has no thrusters: every case but mooring alone needs them",
                                 param_hint="SCENARIO")
    kw = {} if dirs is None else {"directions_deg": dirs}
    opts = CapabilityOptions(level=int(level), heading=heading, condition=condition, fixed_heading_deg=fixed_heading,
                             sea_state=sea_state, design_direction_deg=design_direction,
                             workers=workers or min(2, os.cpu_count() or 1), **kw)
    res = compute(sc, opts)
    paths = write_capability(res, out_dir)
    n = res.numbers
    if as_json:
        cases = []
        for c in res.cases:
            j = int(c.wind_speed.argmin())
            cases.append({"name": c.name, "lowest_beaufort": int(c.beaufort.min()),
                          "lowest_wind_speed": float(c.wind_speed[j]),
                          "at_direction_deg": float(res.directions_deg[j])})
        click.echo(json.dumps({"scenario": res.scenario, "numbers": n, "cases": cases,
                               "worst_thruster": res.info.get("worst_thruster"),
                               "files": [str(p) for p in paths], "elapsed_s": res.info["elapsed_s"]}, indent=2))
        return

    def f(x):
        return "-" if x is None else str(x)

    n_cases = len(res.cases) + max(len(res.thruster_cases) - 1, 0)
    click.echo(f"{res.scenario}: capability, Level {level}, heading {heading}"
               + (f" {fixed_heading:g} deg" if heading == "fixed" else "")
               + f", {len(res.directions_deg)} directions, {n_cases} cases in {res.info['elapsed_s']:.1f} s")
    click.echo(f"  A {f(n['A'])}  B {f(n['B'])}  C {f(n['C'])}"
               + (f" ({n['C_case']})" if n["C_case"] else "") + f"  D {f(n['D'])}"
               + (f" ({n['D_case']})" if n["D_case"] else "")
               + f"  (mooring alone: {f(n['mooring_A'])}, {f(n['mooring_B'])}; design direction "
               f"{res.design_direction_deg:g} deg)")
    for c in res.cases:
        j = int(c.wind_speed.argmin())
        click.echo(f"  {c.name:14s} lowest Beaufort {int(c.beaufort.min()):3d}, {c.wind_speed[j]:5.1f} m/s from "
                   f"{res.directions_deg[j]:5.0f} deg ({c.limit[j]})")
    for p in paths:
        click.echo(f"wrote {p}")
