"""The ``tapm report``, ``tapm study run``, ``tapm study verify`` and ``tapm compare`` commands."""

from __future__ import annotations

import math
import sys
from pathlib import Path

import click

from ..config.loader import log_size_issues
from .._text import terminal_text
from ._common import check_issues, cli, load, out_path


@cli.command()
@click.argument("study_dir", metavar="DIR", type=click.Path())
@click.option("--html", "out_html", type=click.Path(dir_okay=False), default=None, callback=out_path("file"),
              help="HTML file (default DIR/report.html).")
@click.option("--md", "out_md", type=click.Path(dir_okay=False), default=None, callback=out_path("file"),
              help="Markdown file (default DIR/report.md).")
def report(study_dir: str, out_html: str | None, out_md: str | None) -> None:
    """Write the HTML and Markdown report of the study results in DIR (saved results only); of a
    tapm tune run, the controllers' fronts compared."""
    from ..report import write_report
    from ..report.tuning import is_tuning_dir, write_tuning_report

    if not study_dir.strip():
        raise click.BadParameter(f"{study_dir!r} is empty: give the study directory", param_hint="DIR")
    if is_tuning_dir(study_dir):   # a tapm tune run: the fronts compared
        html, md = write_tuning_report(study_dir, out_html=out_html, out_md=out_md)
    else:
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
              callback=out_path("dir", "study directory"), help="Study output directory.")
@_workers_option
@click.option("--scheduler", default=None, help="Dask distributed scheduler address (tcp://host:port); needs the 'dask' extra.")
@click.option("--no-progress", is_flag=True, help="No progress bar.")
def study_run(study_file: str, out_dir: str, workers: int | None, scheduler: str | None, no_progress: bool) -> None:
    """Run every case of STUDY.toml not yet finished in OUT (re-running resumes), then the KPI table.

    Exit status 0 when every case finished, 1 when any case failed (each failed case has
    OUT/cases/<id>/error.json), 2 for a bad study file or option, or when another run is writing
    into OUT.
    """
    from ..studies.study import load_study, run_study

    if not study_file.strip():
        raise click.BadParameter(f"{study_file!r} is empty: give the study file", param_hint="STUDY.toml")
    st = load_study(study_file)
    summary = run_study(st, out_dir, workers=workers, scheduler=scheduler, progress=not no_progress,
                        announce=True)   # the case count before anything is written, with or without the bar
    click.echo(str(summary))
    if st.verification is not None:
        _echo_verification(Path(out_dir))
    _exit_if_failed(summary)


def _echo_verification(out: Path, res=None) -> None:
    """One line per limit state (rows, passed, failed), the warnings, and the files written."""
    import json

    from ..studies.verification_study import VERIFICATION_CSV, VERIFICATION_JSON

    if res is None:
        try:
            data = json.loads((out / VERIFICATION_JSON).read_text(encoding="utf-8"))
        except (OSError, ValueError):
            return
        rows, warnings = data.get("rows", []), data.get("warnings", [])
    else:
        rows, warnings = res.rows, res.warnings
    parts = []
    for ls in ("ULS", "ALS", "FLS"):
        sel = [r for r in rows if r.get("limit_state") == ls]
        if sel:
            n_p = sum(r.get("verdict") == "pass" for r in sel)
            n_f = sum(r.get("verdict") == "fail" for r in sel)
            parts.append(f"{ls} {len(sel)} rows ({n_p} pass, {n_f} fail)" if (n_p or n_f) else f"{ls} {len(sel)} rows")
    click.echo(f"verification: {'; '.join(parts) or 'no rows'} -> {out / VERIFICATION_CSV}")
    for w in warnings:
        click.echo(f"  warning: {terminal_text(str(w))}", err=True)


@study.command("verify")
@click.argument("study_dir", metavar="DIR", type=click.Path(file_okay=False))
@click.option("--study", "study_file", type=click.Path(dir_okay=False), default=None,
              help="Take the [verification] table from this study file (default DIR/study.toml, the file as run).")
def study_verify(study_dir: str, study_file: str | None) -> None:
    """Limit-state checks (ULS, ALS, FLS; DNV-OS-E301) of the study run in DIR from its stored
    results: writes DIR/verification.csv and DIR/verification.json.

    `tapm study run` does this itself for a study file with a [verification] table; this command
    recomputes it on an existing directory (after editing the table, or for a study run without
    one: pass --study FILE with the table), without running any case.
    """
    from ..studies.verification_study import read_verification_table, verify_study

    if not study_dir.strip():
        raise click.BadParameter(f"{study_dir!r} is empty: give the study directory", param_hint="DIR")
    table = read_verification_table(study_dir, study_file)
    if table is None:
        where = study_file or str(Path(study_dir) / "study.toml")
        raise click.BadParameter(f"{where} has no [verification] table (docs/verification.md)",
                                 param_hint="'--study'" if study_file else "DIR")
    res = verify_study(study_dir, table, source=study_file or str(Path(study_dir) / "study.toml"))
    _echo_verification(Path(study_dir), res)


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
              callback=out_path("dir", "study directory"),
              help="Output directory (results, KPI tables, report).")
@_workers_option
@click.option("--duration", type=float, default=None, help="Override the study's duration [s].")
@click.option("--sea-state", "sea_state", default=None,
              help="Sea state id of SCENARIO (default: 'storm'; a scenario without one: its most severe, largest Hs).")
@click.option("--designs", "designs", default="shipped", show_default=True, metavar="shipped|defaults|DIR",
              help="The controllers' tunings: the designs tuned for SCENARIO and shipped in the package, the "
                   "registry's defaults, or a tapm tune run's directory (its tuned/<controller>.toml).")
def compare(scenario_name: str, out_dir: str, workers: int | None, duration: float | None,
            sea_state: str | None, designs: str) -> None:
    """The main job: MPC against PID in a storm with a line break half-way, and the report.

    Runs the default study (tapm_opt/studies/builtin/mpc_vs_pid.toml, also studies/mpc_vs_pid.toml)
    on SCENARIO (default: the built-in fpso) in its sea state 'storm' (or --sea-state; a scenario
    with no 'storm' runs in its most severe sea state, the one with the largest Hs, and the output
    says which), with each controller at the design tuned for SCENARIO and shipped in the package
    (tapm tune studies/mpc_vs_pid.toml; --designs), writes OUT/report.html and OUT/report.md and
    prints the headline KPIs. Re-running resumes. Exit status 1 when any case failed.
    """
    import tomllib

    from ..report import write_report
    from ..studies.shipped import DesignChoiceError, compare_designs
    from ..studies.study import run_study, study_from_dict

    path = Path(__file__).parent.parent / "studies" / "builtin" / "mpc_vs_pid.toml"
    data = tomllib.loads(path.read_text(encoding="utf-8"))
    data.pop("tuning", None)   # the study's tuning settings are tapm tune's, not the run's
    if duration is not None:
        if not (math.isfinite(duration) and duration > 0):
            raise click.BadParameter(f"--duration = {duration} must be a positive number of seconds")
        data["study"]["duration"] = duration
    sc = load(scenario_name)
    if duration is not None:
        check_issues(log_size_issues(sc, duration, float(data["study"].get("dt_log", 1.0)), where="--duration",
                                      dt_name="the study's dt_log"))
    sid, note = _compare_sea_state(sc, sea_state)
    if note:
        click.echo(note)
    try:
        chosen, design_note = compare_designs(designs, sc.name, [e["name"] for e in data["controllers"]])
    except DesignChoiceError as exc:
        raise click.BadParameter(str(exc), param_hint="'--designs'") from None
    for e in data["controllers"]:
        if e["name"] in chosen:
            e["design"] = str(chosen[e["name"]])
    click.echo(design_note)
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
    from ..studies.store import load_study_results

    rows = [r for r in load_study_results(out) if r.id in ids and r.status == "finished"]
    if not rows:
        return
    click.echo(f"  {'case':42s} {'offset max':>10} {'outside safe':>12} {'T/MBS max':>9} {'lines δ min':>11} "
               f"{'riser δ min':>11} {'energy':>10}")
    nan = float("nan")
    for r in rows:
        k, labels = r.kpis, r.labels
        name = terminal_text(f"{labels.get('controller')}, {labels.get('sea_state')}, {labels.get('condition')}")
        click.echo(f"  {name[:42]:42s} {k.get('offset_max', nan):8.1f} m {k.get('time_outside_safe', nan):10.0f} s "
                   f"{k.get('util_max', nan):9.3f} {k.get('delta_min', nan):11.2f} "
                   f"{k.get('riser_delta_min', nan):11.2f} {k.get('thrust_energy', nan) / 3.6e9:6.2f} MWh")
