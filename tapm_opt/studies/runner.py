"""Running a whole study into a directory: :func:`run_study`, its progress bar and KPI tables.

:func:`run_study` locks the study directory (:func:`tapm_opt.studies.store.study_lock`: one run
at a time), writes ``study.toml`` and ``study.json``, skips the finished cases, runs the others on
local processes or a Dask cluster (:mod:`tapm_opt.studies.executors`; each case is one
:func:`~tapm_opt.studies.jobs.run_case`) and writes ``kpis.csv`` and ``kpis.md``
(:func:`write_tables`), and with a ``[verification]`` table ``verification.csv`` and
``verification.json`` (:func:`write_study_verification`). The layout is in
:mod:`tapm_opt.studies.store`.
"""

from __future__ import annotations

import os
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from .._io import atomic_write_text
from . import executors, store
from .spec import Study
from .store import StudyRunError

__all__ = ["StudySummary", "run_study", "write_study_verification", "write_tables"]


@dataclass(frozen=True)
class StudySummary:
    """What :func:`run_study` did.

    Attributes
    ----------
    out_dir : Path
    finished : tuple of str
        Ids of the cases run to completion now.
    failed : tuple of str
        Ids of the cases that raised (each has ``error.json``).
    skipped : tuple of str
        Ids of the cases already finished before (not run again).
    wall_time : float
        Wall-clock time of :func:`run_study` [s].
    errors : dict
        ``{id: "Type: message"}`` of the failed cases.
    """

    out_dir: Path
    finished: tuple[str, ...]
    failed: tuple[str, ...]
    skipped: tuple[str, ...]
    wall_time: float
    errors: dict = field(default_factory=dict)

    @property
    def success(self) -> bool:
        """True when no case failed."""
        return not self.failed

    @property
    def n_cases(self) -> int:
        """Cases of the study: finished now, failed and finished before."""
        return len(self.finished) + len(self.failed) + len(self.skipped)

    def __str__(self) -> str:
        return (f"{len(self.finished)} finished, {len(self.failed)} failed, {len(self.skipped)} already done "
                f"in {self.wall_time:.1f} s -> {self.out_dir}")


class _Progress:
    """tqdm bar (cases done, ETA) with the number running and failed; or nothing."""

    def __init__(self, total: int, initial: int, enabled: bool, name: str):
        self.failed = 0
        self.running = 0
        self.bar = None
        if enabled:
            from tqdm.auto import tqdm

            self.bar = tqdm(total=total, initial=initial, desc=name, unit="case", dynamic_ncols=True,
                            smoothing=0.0)
            self._post(refresh=True)

    def _post(self, refresh: bool) -> None:
        if self.bar is not None:
            self.bar.set_postfix_str(f"running {self.running}, failed {self.failed}", refresh=refresh)

    def set_running(self, n: int) -> None:
        self.running = n
        self._post(refresh=True)

    def done(self, failed: bool, running: int) -> None:
        """One more case done (``failed`` or not); ``running`` cases still under way."""
        self.failed += int(failed)
        self.running = running
        self._post(refresh=False)
        if self.bar is not None:
            self.bar.update(1)

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()


def run_study(study: Study, out_dir: str | Path, *, workers: int | None = None, scheduler: Any = None,
              progress: bool = True, announce: bool | None = None) -> StudySummary:
    """Run every case of ``study`` that is not finished in ``out_dir`` and write the tables.

    Parameters
    ----------
    study : Study
        From :func:`~tapm_opt.studies.spec.load_study`.
    out_dir : path
        Study run directory (layout: :mod:`tapm_opt.studies.store`); created if needed. Finished
        cases found there are skipped, so running the same study again resumes it; failed or
        interrupted cases are run again.
    workers : int, optional
        Local worker processes (default ``os.cpu_count()``, at most one per case to run); ``0`` runs
        the cases one after the other in this process (for debugging). Ignored with ``scheduler``.
    scheduler : str or dask.distributed.Client or cluster, optional
        Run the cases on a Dask cluster instead: a scheduler address (``"tcp://host:8786"``), a
        ``Client``, or a cluster object (``LocalCluster``). The workers only compute: they send
        each case's result back and this process writes ``out_dir``, so they need no shared file
        system. Needs the ``dask`` extra (``pip install 'tapm_opt[dask]'``).
    progress : bool
        Show a progress bar (done / running / failed, ETA) on stderr.
    announce : bool, optional
        Before anything is written, print one line on stderr with the number of cases, how many
        are finished already and how many will run (default: as ``progress``).

    Returns
    -------
    StudySummary
        A failed case does not raise: see ``failed``, ``errors`` and ``success``.

    Raises
    ------
    StudyRunError
        Bad ``workers`` or ``scheduler``, ``out_dir`` not a directory or not writable, or Dask
        missing; nothing is written then.
    StudyBusyError
        Another run (another process, even on another machine sharing the directory) is running
        into ``out_dir``; the message names the directory and that run's pid.

    Notes
    -----
    Local workers are started with ``spawn`` (a fork would copy the parent's threads and solver
    state), so a script that calls ``run_study`` must guard it with ``if __name__ == "__main__":``.
    They end when this process ends, however it ends (``kill -9`` included), and an interrupted
    call (``KeyboardInterrupt``) kills them before it raises. Every file is written atomically, so
    killing the run at any point keeps every case finished so far. A case that raises gets
    ``error.json`` (type, message, traceback); the other cases go on. At the end ``kpis.csv`` and
    ``kpis.md`` list every finished case and every failed one (with its error), and a study with a
    ``[verification]`` table gets ``verification.csv`` and ``verification.json``
    (:func:`write_study_verification`).
    """
    t0 = time.perf_counter()
    if not isinstance(study, Study):
        raise TypeError(f"study must be a Study (from load_study), got {type(study).__name__}")
    if workers is not None and (not isinstance(workers, int) or isinstance(workers, bool) or workers < 0):
        raise StudyRunError(f"workers = {workers!r} must be a whole number >= 0 (0: run in this process)")
    out = Path(out_dir)
    if out.exists() and not out.is_dir():
        raise StudyRunError(f"output {out} exists and is not a directory")
    client, own_client = executors.dask_client(scheduler) if scheduler is not None else (None, False)
    try:
        try:
            out.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise StudyRunError(f"cannot create the study directory {out}: {exc.strerror or exc}") from None
        with store.study_lock(out):
            outcomes, todo, skipped = _run_locked(study, out, workers, client, progress,
                                                  progress if announce is None else announce)
    finally:
        if own_client:
            client.close()
    finished = tuple(c.id for c in todo if outcomes.get(c.id, {}).get("status") == "finished")
    failed = tuple(c.id for c in todo if outcomes.get(c.id, {}).get("status") == "failed")
    return StudySummary(out_dir=out, finished=finished, failed=failed, skipped=tuple(skipped),
                        wall_time=time.perf_counter() - t0, errors={cid: outcomes[cid]["error"] for cid in failed})


def _run_locked(study: Study, out: Path, workers: int | None, client: Any, progress: bool, announce: bool):
    """The body of :func:`run_study`, under the directory lock: (outcomes, cases run, ids skipped)."""
    from .. import __version__

    # resume: finished cases of this code version are not run again (a case run by another version
    # is, so one study never mixes results of two versions)
    skipped = [c.id for c in study.cases if store.is_finished(store.case_dir(out, c.id), version=__version__)]
    todo = [c for c in study.cases if c.id not in set(skipped)]
    if announce:   # say what is about to happen before the first file is written
        n = len(study.cases)
        sys.stderr.write(f"study {study.name}: {n} case{'' if n == 1 else 's'}"
                         + (f", {len(skipped)} already finished" if skipped else "")
                         + f", {len(todo)} to run -> {out}\n")
        sys.stderr.flush()
    if study.text:
        atomic_write_text(out / store.STUDY_TOML, study.text)
    store.write_json(out / store.STUDY_JSON, store.study_json(
        study.name, study.description, None if study.path is None else str(study.path), study.cases, __version__))
    bar = _Progress(len(study.cases), len(skipped), progress, study.name)
    outcomes: dict[str, dict] = {}
    try:
        if not todo:
            pass
        elif client is not None:
            executors.run_dask(todo, out, client, bar, outcomes)
        elif workers == 0:
            executors.run_inline(todo, out, bar, outcomes)
        else:
            executors.run_local(todo, out, workers or os.cpu_count() or 1, bar, outcomes)
    finally:
        bar.close()
    write_tables(study, out)
    if study.verification is not None:
        write_study_verification(study, out)
    write_study_capability(study, out, workers=min(2, workers or os.cpu_count() or 1))   # (or removes old ones)
    return outcomes, todo, skipped


def write_study_verification(study: Study, out_dir: str | Path) -> Any:
    """The limit-state checks a study's ``[verification]`` table asks for, from the stored results
    of its finished cases, into ``DIR/verification.csv`` and ``DIR/verification.json``
    (:func:`tapm_opt.studies.verification_study.verify_study`; the study writes data, the report
    draws). Returns the :class:`~tapm_opt.studies.verification_study.Verification` (None when
    the study asks for none)."""
    if study.verification is None:
        return None
    from .verification_study import verify_study

    return verify_study(out_dir, study.verification,
                        source=str(study.path) if study.path is not None else study.name)


def write_study_capability(study: Study, out_dir: str | Path, *, workers: int = 1) -> Path | None:
    """The capability envelopes a study's ``[capability]`` table asks for, of its scenario, into
    ``DIR/capability``, where the report finds them and draws their figures (the study writes data,
    the report draws): Levels 1 and 2 as ``capability.csv`` and ``capability.json``
    (:mod:`tapm_opt.design.capability`); Level 3 (``level = 3``) as
    ``capability_level3_<controller>.csv`` and ``.json`` per controller of its ``controllers``
    (:mod:`tapm_opt.studies.capability_level3`). Each is stamped (``study_capability.json``,
    ``study_capability_level3_<controller>.json``) with its resolved options (the study's, with every
    default of this version filled in, the environment table's rows included), the scenario and the
    version (for Level 3 also the controller's registry defaults, which it runs), and not
    recomputed while they are the same; the files of an earlier ``[capability]`` table that this one
    no longer asks for (or of any, when the study has none) are removed. Returns the folder (None
    when the study asks for none)."""
    import dataclasses
    import json

    from .. import __version__
    from .._io import atomic_write_bytes
    from ..config import scenario_from_dict
    from ..design.capability import CapabilityOptions, capability, resolve_options
    from ..design.registry import kind
    from .capability_level3 import (
        capability_level3,
        level3_file_stem,
        study_level3_options,
    )

    d = Path(out_dir) / "capability"
    tab = study.capability if study.scenario is not None else None
    jobs = []   # (file stem, resolved options, computation): files <stem>.csv, .json, stamp study_<stem>.json
    if tab is not None and tab.get("level") == 3:
        sc3 = scenario_from_dict(study.scenario, source=f"study {study.name}")
        for opt in (o.resolved(sc3) for o in study_level3_options(tab)):
            # the controller runs at its registry defaults: they are part of what was computed
            jobs.append((level3_file_stem(opt.controller, opt.failed_line),
                         {**opt.settings(), "controller_defaults": kind(opt.controller).defaults()},
                         lambda opt=opt: capability_level3(
                             scenario_from_dict(study.scenario, source=f"study {study.name}"),
                             dataclasses.replace(opt, workers=max(1, workers)))))
    elif tab is not None:
        # the heading resolved by the scenario's turret (design.capability.resolve_options), as computed
        resolved = resolve_options(scenario_from_dict(study.scenario, source=f"study {study.name}"),
                                   CapabilityOptions(**tab))
        jobs = [("capability", {**resolved.settings(), "table": [dataclasses.asdict(r) for r in resolved.table]},
                 lambda: capability(scenario_from_dict(study.scenario, source=f"study {study.name}"),
                                    {**tab, "workers": max(1, workers)}))]
    wanted = {stem for stem, *_ in jobs}
    stamps = ([d / "study_capability.json", *d.glob("study_capability_level3_*.json")] if d.is_dir() else [])
    for stamp_file in sorted(p for p in stamps if p.is_file()):   # an earlier table's files (the study's own)
        stem = stamp_file.name[len("study_"):-len(".json")]
        if stem not in wanted:
            for f in (d / f"{stem}.csv", d / f"{stem}.json", stamp_file):
                f.unlink(missing_ok=True)
    if not jobs:
        return None
    for stem, options, compute in jobs:
        stamp = {"options": options, "scenario": study.scenario, "tapm_opt_version": __version__}
        try:
            old = json.loads((d / f"study_{stem}.json").read_text())
        except (OSError, ValueError):
            old = None
        if old == json.loads(json.dumps(stamp)) and all((d / f"{stem}.{x}").is_file() for x in ("csv", "json")):
            continue
        res = compute()
        d.mkdir(parents=True, exist_ok=True)
        for name, blob in res.data_files().items():
            atomic_write_bytes(d / name, blob)
        store.write_json(d / f"study_{stem}.json", stamp)
    return d


def write_tables(study: Study, out_dir: str | Path) -> tuple[Path, Path]:
    """Write ``kpis.csv`` and ``kpis.md`` of a study run.

    Parameters
    ----------
    study : Study
        The study; its cases give the rows and their order.
    out_dir : path
        The study run directory.

    Returns
    -------
    (Path, Path)
        The CSV and Markdown files: one row per finished or failed case of ``study``, in study
        order (:func:`tapm_opt.studies.kpis.kpi_table`); a failed case has an ``error`` entry
        (``"Type: message"``) instead of KPIs.
    """
    from .kpis import kpi_table

    out = Path(out_dir)
    ids = {c.id for c in study.cases}
    rows = []
    for r in store.load_study_results(out):
        if r.id not in ids:
            continue
        if r.status == "finished":
            rows.append({"id": r.id, "name": r.name, "labels": r.labels, "kpis": r.kpis})
        elif r.status == "failed":
            err = r.error or {}
            rows.append({"id": r.id, "name": r.name, "labels": r.labels,
                         "kpis": {"error": f"{err.get('type', 'Error')}: {err.get('message', '')}".strip()}})
    csv_text, md_text = kpi_table(rows)
    return atomic_write_text(out / store.KPIS_CSV, csv_text), atomic_write_text(out / store.KPIS_MD, md_text)
