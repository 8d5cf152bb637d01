"""The ``tapm tune`` command: every controller of a study tuned by optimisation on its cases
(:mod:`tapm_opt.studies.tuning`, ``docs/tuning.md``)."""

from __future__ import annotations

import click

from ._common import cli, out_path


@cli.command()
@click.argument("study_file", metavar="STUDY.toml", type=click.Path(dir_okay=False))
@click.option("--out", "out_dir", type=click.Path(file_okay=False), required=True,
              callback=out_path("dir", "tuning directory"), help="Tuning output directory.")
@click.option("--trials", type=click.IntRange(1, 100_000), default=None,
              help="Finished trials per controller (default: the study's [tuning] trials, else 30).")
@click.option("--workers", type=click.IntRange(0, 64), default=1, show_default=True,
              help="Local worker processes, each running trials on the shared storage (0: in this process).")
@click.option("--scheduler", default=None,
              help="Dask scheduler address (tcp://host:port): the workers' trial loops run there instead.")
@click.option("--storage", default=None, metavar="URL",
              help="optuna storage (a database URL); default sqlite:///OUT/tuning.db. Several runs on one "
                   "storage share the trials.")
def tune(study_file: str, out_dir: str, trials: int | None, workers: int, scheduler: str | None,
         storage: str | None) -> None:
    """Tune every [[controllers]] of STUDY.toml over its kind's search space on all the study's cases.

    Objectives and constraints from the study's [tuning] table (default: the largest turret offset,
    worst over the cases, and the thrust energy, summed, both minimised). Writes OUT/trials.csv,
    OUT/front.csv, OUT/tuned/<controller>.toml (the selected design: [[controllers]] design = "..."
    or tapm simulate --option design=...) and, with [tuning] verify_seeds, OUT/verify.csv. A rerun
    continues: no finished trial is lost or repeated. Watch it live with
    optuna-dashboard sqlite:///OUT/tuning.db.
    """
    from ..studies.tuning import tune_study

    if scheduler is not None:
        from ..studies.executors import check_scheduler

        check_scheduler(scheduler)
    tune_study(study_file, out_dir, trials=trials, workers=workers, scheduler=scheduler, storage=storage,
               echo=click.echo)
