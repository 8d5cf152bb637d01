"""The ``tapm simulate`` command: one controller in closed loop against the FEM plant."""

from __future__ import annotations

import math
from pathlib import Path

import click

from .._io import atomic_write_text
from .._text import terminal_text
from ..config.loader import fem_size_issues, log_size_issues
from ._common import ControllerKindChoice, check_issues, cli, key_values, load, out_path


@cli.command()
@click.argument("scenario_name", metavar="SCENARIO")
@click.option("--controller", type=ControllerKindChoice(), default="pid", show_default=True,
              help="A registered controller kind: pid (the TAPM PID modes), mpc (nonlinear MPC: real-time iteration, "
                   "DAQP; --option solver=sqp for the converged SQP), lmpc (linear MPC, DAQP; --option "
                   "qp_solver=piqp|osqp for the sparse QP), or an installed one (docs/controllers.md).")
@click.option("--duration", type=float, default=3600.0, show_default=True, help="Simulated time [s].")
@click.option("--out", "out_dir", type=click.Path(file_okay=False), required=True,
              callback=out_path("dir", "run directory"), help="Run directory to write.")
@click.option("--sea-state", default=None, help="Sea state id (default: the scenario's first), or 'none'.")
@click.option("--seed", type=click.IntRange(min=0), default=0, show_default=True,
              help="Seed of waves, wind and sensor noise (a whole number >= 0).")
@click.option("--segments", type=click.IntRange(2, 1000), default=None, help="FEM segments per line.")
@click.option("--dt-control", type=float, default=1.0, show_default=True,
              help="Control/allocation period [s], >= 0.01; the run is logged every control step, at least 1 s apart.")
@click.option("--setpoint", type=click.Choice(["fixed", "chasing", "quadratic", "reliability", "unified", "fatigue"]),
              default="fixed", show_default=True,
              help="Fixed setpoint (turret at its field-zero-point position), setpoint chasing (survey eq. 38), "
                   "the optimum of the quadratic (eq. 34), reliability-index (eq. 36) or unified riser + mooring "
                   "cost, or fatigue-aware chasing (survey 4.2.4, docs/fatigue_setpoint.md).")
@click.option("--setpoint-option", "setpoint_options", multiple=True, metavar="KEY=VALUE",
              help="Option of the optimal or fatigue-aware setpoints, e.g. --setpoint-option period=60 (repeatable).")
@click.option("--heading", type=click.Choice(["chasing", "fixed"]), default=None,
              help="Weather-optimal heading (bow into the estimated mean environmental force) or fixed north "
                   "[default: chasing; fixed with --winch tension, whose changing line lengths the estimated "
                   "environmental force does not know].")
@click.option("--true-state", is_flag=True, help="Give the controller the true LF state (no estimator).")
@click.option("--option", "options", multiple=True, metavar="KEY=VALUE",
              help="Controller option, e.g. --option horizon=30 --option solver=ipopt (repeatable); "
                   "estimator=ekf|passive|lowpass (default ekf), detector=tension|drop|bank|none (default tension), "
                   "redundancy=none|vote (sensor voting, docs/sensor_faults.md) and "
                   "current=known|estimated|estimated_tensions (docs/current_estimation.md) choose the estimation.")
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

    from ..models.system import System
    from ..studies.closed_loop import ClosedLoopSettings
    from ..studies.recipe import run_case_on

    if not (math.isfinite(duration) and duration > 0):
        raise click.BadParameter(f"--duration = {duration} must be a positive number of seconds")
    if not (math.isfinite(dt_control) and 0.01 <= dt_control <= duration):
        raise click.BadParameter(f"--dt-control = {dt_control:g} s must be between 0.01 s (100 Hz, faster than any "
                                 f"position-control loop) and --duration = {duration:g} s")
    dt_log = dt_control * max(1, math.ceil(1.0 / dt_control - 1e-9))  # every control step, >= 1 s apart
    spec: dict = {"type": controller, **key_values(options, "--option")}
    if "design" in spec:   # a tuned design file: its kind unless --controller is given
        from ..design.registry import ControllerSpecError, load_design, merge_design

        if click.get_current_context().get_parameter_source("controller") != click.core.ParameterSource.COMMANDLINE:
            spec.pop("type")
        try:
            spec = merge_design(spec, load_design(spec["design"], "--option design"), "--controller")
        except ControllerSpecError as exc:
            raise click.BadParameter(str(exc), param_hint="'--option design'") from None
        controller = spec["type"]
    # estimation is the runner's: --option estimator=... / detector=... / redundancy=... / current=...
    estimation = {k: str(spec.pop(k)) for k in ("estimator", "detector", "redundancy", "current") if k in spec}
    from ..studies.closed_loop import ClosedLoopError

    w_opts = key_values(winch_options, "--winch-option")
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
    sp_opts = key_values(setpoint_options, "--setpoint-option")
    if sp_opts and setpoint not in ("quadratic", "reliability", "unified", "fatigue"):
        raise click.BadParameter(f"--setpoint-option is for the optimal setpoints (quadratic, reliability, unified) "
                                 f"and fatigue-aware chasing, not --setpoint {setpoint}")
    if sp_opts and setpoint == "fatigue":
        from ..control.fatigue_setpoint import FatigueOptions

        FatigueOptions.from_mapping(sp_opts, where="--setpoint-option")
    elif sp_opts:
        from ..control.setpoint_opt import SetpointOptions

        SetpointOptions.from_mapping(sp_opts, where="--setpoint-option")
    sc = load(scenario_name)
    if sea_state is not None and sea_state != "none" and sea_state not in [s.id for s in sc.sea_states]:
        raise click.BadParameter(f"{sea_state!r} is not a sea state of scenario {sc.name!r}; its sea states: "
                                 f"{', '.join(s.id for s in sc.sea_states) or 'none'} (or 'none')",
                                 param_hint="'--sea-state'")
    check_issues(fem_size_issues(sc, segments, where="--segments"))
    check_issues(log_size_issues(sc, duration, dt_log, where="--duration", dt_name="every control step, >= 1 s apart"))
    system = System.from_scenario(sc)  # built once: controller, plant and runner share it
    settings = ClosedLoopSettings(duration=duration, dt_control=dt_control, dt_log=dt_log, true_state=true_state,
                                  setpoint=setpoint, heading=heading, setpoint_options=sp_opts or None, **estimation,
                                  **winching)
    try:
        run = run_case_on(system, spec, settings, sea_state=sea_state, seed=seed, segments=segments,
                          where="--option", meta={"controller_spec": {**spec, **estimation}})
    except ClosedLoopError as exc:   # e.g. --winch tension on a scenario without winches
        raise click.BadParameter(str(exc), param_hint="'--winch'") from None
    res, k = run.result, dict(run.kpis)
    k["utilisation_max"] = k.get("util_max", math.nan)   # the summary's name since its first version
    out = Path(out_dir)
    res.save(out / "result.npz")
    summary = {"scenario": sc.name, "controller": spec, **estimation,
               **({"winch": winch, "winch_options": w_opts} if winch != "none" else {}),
               "sea_state": run.sea_state, "seed": seed, "duration": duration, "kpis": k,
               "diagnostics": res.meta.get("diagnostics", {}), "events": run.events, "wall_time": run.wall_time,
               "settle": {"time": run.settle_time, "wall_time": run.settle_wall_time}}
    click.echo(f"{terminal_text(sc.name)}, {controller}, {run.sea_state} sea, {duration:g} s (wall "
               f"{run.wall_time:.1f} s, of which {run.settle_wall_time:.1f} s settling the lines)")
    for t, what in run.events:   # line breaks and thruster failures, as the plant logged them
        click.echo(f"  t = {t:.1f} s: {terminal_text(what)}")
    click.echo(f"  offset max {k['offset_max']:.1f} m, mean {k['offset_mean']:.1f} m; outside safe circle "
               f"{k['time_outside_safe']:.0f} s; heading error max {k['heading_error_max']:.1f} deg")
    n_broken = int(k.get("lines_broken", 0) or 0)
    click.echo(f"  max tension {k['T_max'] / 1e3:.0f} kN ({100 * k['utilisation_max']:.1f} % MBS); "
               f"thrust energy {k['thrust_energy'] / 3.6e9:.3f} MWh"
               + (f"; {n_broken} line{'s' if n_broken != 1 else ''} broken" if n_broken else ""))
    if winch != "none":
        click.echo(f"  winch control: thrust/command {k.get('thrust_to_command_ratio', float('nan')):.3f}, "
                   f"winch energy {k.get('winch_energy', 0.0) / 3.6e9:.4f} MWh")
    if "solver_time_median" in k:
        click.echo(f"  solver: median {1e3 * k['solver_time_median']:.1f} ms, max {1e3 * k['solver_time_max']:.1f} ms, "
                   f"{int(k['solver_failures'])} failures")
    atomic_write_text(out / "summary.json", json.dumps(summary, indent=2, default=float))
    click.echo(f"wrote {out / 'result.npz'} and {out / 'summary.json'}")
