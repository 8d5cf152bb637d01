"""Controllers designed by optimisation: each controller of a study tuned over its kind's search
space on the study's cases, for objectives and constraints from the KPI catalogue (``tapm tune``).

The pieces, each usable alone:

- :class:`Objective` and :class:`Constraint` — a KPI of the catalogue (:mod:`.kpi_catalogue`)
  aggregated over the cases (worst case for most KPIs, the sum for the extensive ones: energy,
  fuel), minimised or maximised as the catalogue says; a constraint ``kpi <= bound`` or
  ``kpi >= bound`` on the aggregate is a constraint of the search, not a weight.
- :func:`search_space` — the kind's :class:`~tapm_opt.design.registry.Dimension` s
  (``docs/controllers.md``), minus the options the study fixes, narrowed or fixed by the
  controller's ``tune`` table; :func:`spec_from_params` turns a trial's parameters back into a
  controller specification.
- :func:`optimise` — an optuna study per controller (multi-objective TPE by default, NSGA-II on
  request, both with constraints) in a storage that is the run's memory: an SQLite file by
  default, any database URL for several machines. Finished trials are committed as they end, so
  a run killed at any point loses none of them and a rerun (or a second ``tapm tune`` on the same
  storage at the same time) continues the same studies instead of repeating trials. The trials
  run on local processes, each a loop of optuna's ``optimize`` on the shared storage, or as tasks
  on a Dask cluster.
- :func:`front`, :func:`select` — the non-dominated finished trials that meet the constraints, and
  the design chosen from them (the knee, or a rule ``"min thrust_energy with offset_max <= 45"``).
- :func:`tune_study` — the whole job for a study file, writing ``trials.csv``, ``front.csv``,
  ``tuned/<controller>.toml`` and the held-out confirmation ``verify.csv`` (``docs/tuning.md``).

Why optuna: a maintained multi-objective optimiser with constraints, a storage that several
processes and machines share with transactions, heartbeats that fail the trials of a dead worker,
and a dashboard (``optuna-dashboard sqlite:///DIR/tuning.db``) — the run's memory and its view
without code of ours.
"""

from __future__ import annotations

import csv
import dataclasses
import io
import json
import math
import multiprocessing
import os
import re
import time
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Mapping, Sequence

import numpy as np

from .._io import atomic_write_text, toml_key, toml_value
from ..design.registry import DESIGN_FORMAT, kind as controller_kind
from .kpi_catalogue import KPIS
from .kpis import DELTA_S_DEFAULT
from .tuning_space import (ALWAYS_REPORTED, CONTEXT_KPIS, DEFAULT_OBJECTIVES, SUMMED_KPIS, Constraint, Objective, Param,
                           TuningError, TuningSettings, _num, default_params, parse_rule, search_space,
                           spec_from_params,
                           tuning_settings)

__all__ = ["TuningError", "Objective", "Constraint", "TuningSettings", "Param", "tuning_settings", "search_space",
           "spec_from_params", "optimise", "front", "select", "dominates", "hypervolume_2d", "tune_study",
           "DEFAULT_OBJECTIVES", "ALWAYS_REPORTED", "SUMMED_KPIS", "load_trials", "TrialRow", "write_design",
           "DESIGN_FORMAT", "format_kpi", "gain_designs"]

def _suggest(trial: Any, p: Param) -> Any:
    d = p.dim
    if d.choices is not None:
        return trial.suggest_categorical(p.name, list(d.choices))
    if d.integer:
        return trial.suggest_int(p.name, int(math.ceil(d.low)), int(math.floor(d.high)), log=d.log)
    return trial.suggest_float(p.name, float(d.low), float(d.high), log=d.log)


# ------------------------------------------------------------------------------------------
# the optimiser and its storage
# ------------------------------------------------------------------------------------------


def _storage(url: str) -> Any:
    """optuna's RDB storage at ``url`` with heartbeats (a dead worker's trial fails, its finished
    ones stay)."""
    import optuna
    from sqlalchemy.exc import ArgumentError, OperationalError

    kw: dict[str, Any] = {}
    if url.startswith("sqlite:"):
        kw["engine_kwargs"] = {"connect_args": {"timeout": 60}}
        path = url.split("sqlite:///", 1)[-1]
        if path and path != url and not Path(path).parent.is_dir():
            raise TuningError(f"--storage {url!r}: the folder {str(Path(path).parent)!r} does not exist")
    from sqlalchemy.exc import IntegrityError

    try:
        for attempt in range(5):
            try:
                return optuna.storages.RDBStorage(url, heartbeat_interval=HEARTBEAT, grace_period=GRACE, **kw)
            except (IntegrityError, OperationalError) as exc:
                # another process (a second run joining, a dashboard) created the new database's
                # tables at the same moment: they exist now, so open it again
                racing = isinstance(exc, IntegrityError) or "already exists" in str(exc)
                if attempt == 4 or not racing:
                    raise
                time.sleep(0.2 * (attempt + 1))
    except (ArgumentError, OperationalError, ImportError, ValueError, ModuleNotFoundError) as exc:
        raise TuningError(f"--storage {url!r} cannot be opened: {str(exc).splitlines()[0]}") from None
    except Exception as exc:  # noqa: BLE001 - any database driver's error, named
        raise TuningError(f"--storage {url!r} cannot be opened: {type(exc).__name__}: "
                          f"{str(exc).splitlines()[0] if str(exc) else ''}") from None


#: Seconds between a running trial's heartbeats, and after the last one before it counts as dead.
HEARTBEAT = 10
GRACE = 30


def _sampler(settings: TuningSettings, constraints: bool, worker: int = 0, resumed: int = 0) -> Any:
    """The sampler of one worker: seeded by the study's seed, the worker's number and ``resumed``
    (the trials the storage already holds, and the run's number on the storage), so a resumed or
    joining run draws new parameters instead of the first run's again; a fresh one-worker run is
    reproducible."""
    import optuna

    cf = _constraints_of if constraints else None
    seed = settings.seed + 7919 * worker + 104729 * resumed
    if settings.sampler == "nsga2":
        pop = settings.population or min(50, max(8, settings.trials // 4))
        return optuna.samplers.NSGAIISampler(population_size=pop, seed=seed, constraints_func=cf)
    n_startup = max(5, min(10, settings.trials // 3))
    return optuna.samplers.TPESampler(seed=seed, n_startup_trials=n_startup, multivariate=True,
                                      constraints_func=cf)


def _constraints_of(trial: Any) -> list[float]:
    return list(trial.user_attrs.get("constraints", []))


def _skip_repeat(trial: Any, values: Mapping[str, Any]) -> None:
    """Prune a trial whose parameters a finished or running trial of the study has already (two
    runs joining one storage at the same moment may draw the same ones): it is not run twice."""
    import optuna
    from optuna.trial import TrialState

    for t in trial.study.get_trials(deepcopy=False, states=(TrialState.COMPLETE, TrialState.RUNNING)):
        if t.number != trial.number and t.params == dict(values):
            raise optuna.TrialPruned(f"the same parameters as trial {t.number}")


@dataclass
class TrialEvaluator:
    """What a trial computes: ``evaluate(spec) -> list of per-case KPI dicts`` (picklable for the
    worker processes), the objectives and constraints read from them."""

    base_spec: dict
    params: list
    fixed: dict
    settings: TuningSettings
    evaluate: Callable[[dict], list]
    safe_radius: float | None = None

    def __call__(self, trial: Any) -> Any:
        values = {p.name: _suggest(trial, p) for p in self.params}
        _skip_repeat(trial, values)
        spec = spec_from_params(self.base_spec, self.params, values, self.fixed, safe_radius=self.safe_radius)
        trial.set_user_attr("spec", spec)
        t0 = time.perf_counter()
        try:
            per_case = self.evaluate(spec)
        except Exception as exc:
            trial.set_user_attr("error", f"{type(exc).__name__}: {str(exc).splitlines()[0] if str(exc) else ''}")
            raise
        trial.set_user_attr("wall_time", time.perf_counter() - t0)
        reported = reported_kpis(self.settings, per_case)
        trial.set_user_attr("kpis", reported)
        trial.set_user_attr("cases", per_case if len(json.dumps(per_case, default=float)) < 200_000 else [])
        cons = [c.violation(c.value(per_case)) for c in self.settings.constraints]
        trial.set_user_attr("constraints", cons)
        vals = [reported[o.kpi] for o in self.settings.objectives]
        if not all(math.isfinite(v) for v in vals):
            trial.set_user_attr("error", f"no finite value of {[o.kpi for o in self.settings.objectives]}: {vals}")
            raise TuningError(f"a case gave no finite value of {[o.kpi for o in self.settings.objectives]}: {vals}")
        return vals if len(vals) > 1 else vals[0]


@dataclass(frozen=True)
class WorkerJob:
    """One worker's loop: trials of ``study_name`` in ``storage`` until ``trials`` have finished."""

    storage: str
    study_name: str
    evaluator: TrialEvaluator
    trials: int
    worker: int = 0
    threads: int = 1


class _Budgeted:
    """The objective of a worker's loop: a trial runs only if fewer than ``n`` trials numbered
    before it have finished or are running; else it is pruned before it runs. Trial numbers are
    given out by the storage in order, so workers that start trials at the same moment cannot
    both take the last place of the budget."""

    def __init__(self, evaluator: Any, n: int):
        self.evaluator, self.n = evaluator, n

    def __call__(self, trial: Any) -> Any:
        import optuna
        from optuna.trial import TrialState

        ahead = [t for t in trial.study.get_trials(deepcopy=False, states=(TrialState.COMPLETE, TrialState.RUNNING))
                 if t.number < trial.number]
        if len(ahead) >= self.n:
            raise optuna.TrialPruned(f"the budget of {self.n} trials is taken by trials before it")
        return self.evaluator(trial)


class _Enough:
    """Stop a worker's loop once the finished trials and those still running elsewhere make
    ``n`` (so several workers do not overshoot the budget)."""

    def __init__(self, n: int):
        self.n = n

    def __call__(self, study: Any, trial: Any) -> None:
        if _count(study, ("COMPLETE", "RUNNING")) >= self.n:
            study.stop()


def _count(study: Any, states: Sequence[str]) -> int:
    from optuna.trial import TrialState

    return len(study.get_trials(deepcopy=False, states=tuple(TrialState[s] for s in states)))


def _check_failures(study: Any, trials: int) -> None:
    """Give up on a study whose trials keep failing (more failed than :func:`max_failures` allows):
    a :class:`TuningError` naming the count and the last failure's reason."""
    failed = [t for t in study.get_trials(deepcopy=False) if t.state.name == "FAIL"]
    if len(failed) > max_failures(trials):
        last = failed[-1]
        why = last.user_attrs.get("error") or last.system_attrs.get("fail_reason", "no reason recorded")
        raise TuningError(f"{study.study_name}: {len(failed)} trials failed (at most {max_failures(trials)} for "
                          f"{trials} trials); the last (trial {last.number}): {why}")


def max_failures(trials: int) -> int:
    """Failed trials a study may have before it is given up: 10, or the budget if larger."""
    return max(10, int(trials))


class _GiveUp:
    """A worker loop's callback: stop on too many failed trials (:func:`_check_failures`)."""

    def __init__(self, n: int):
        self.n = n

    def __call__(self, study: Any, trial: Any) -> None:
        if trial.state.name == "FAIL":
            try:
                _check_failures(study, self.n)
            except TuningError:
                study.stop()


def run_worker(job: WorkerJob) -> int:
    """Run trials until ``job.trials`` trials of the study have finished (counted over every
    worker of the storage). A trial left running by a worker that died (killed, its machine
    gone) is failed once its heartbeat is :data:`GRACE` seconds old, and the loop goes on until
    the budget is finished. Returns the trials this worker finished."""
    import warnings

    import optuna

    from .._parallel import limit_threads

    limit_threads(job.threads)
    optuna.logging.set_verbosity(optuna.logging.WARNING)
    warnings.filterwarnings("ignore", category=optuna.exceptions.ExperimentalWarning)
    storage = _storage(job.storage)
    ev = job.evaluator
    probe = optuna.load_study(study_name=job.study_name, storage=storage)
    held = len(probe.get_trials(deepcopy=False)) + 1000 * (int(probe.user_attrs.get("runs", 1)) - 1)
    study = optuna.load_study(study_name=job.study_name, storage=storage,
                              sampler=_sampler(ev.settings, bool(ev.settings.constraints), job.worker, held))
    before = _count(study, ("COMPLETE",))
    beaten: set[int] = set()
    while _count(study, ("COMPLETE",)) < job.trials:
        _check_failures(study, job.trials)
        if _count(study, ("COMPLETE", "RUNNING")) >= job.trials:
            _beat_once(study, storage, beaten)
            optuna.storages.fail_stale_trials(study)   # a dead worker's trial: failed after its grace
            time.sleep(min(HEARTBEAT, 2.0))
            continue
        study.optimize(_Budgeted(ev, job.trials), callbacks=[_Enough(job.trials), _GiveUp(job.trials)],
                       catch=(Exception,), gc_after_trial=False)
    return _count(study, ("COMPLETE",)) - before


def _beat_once(study: Any, storage: Any, beaten: set[int]) -> None:
    """One heartbeat for each running trial not seen running before (``beaten``, updated): a
    worker killed between starting a trial and its first heartbeat leaves a trial that optuna's
    ``fail_stale_trials`` never fails (it has no heartbeat to grow old), and a resumed run would
    wait for it for ever. With this beat it fails :data:`GRACE` seconds later; a live trial beats
    on its own, so one extra beat does not fail it."""
    from optuna.trial import TrialState

    if not hasattr(storage, "record_heartbeat"):
        return
    sid = storage.get_study_id_from_name(study.study_name)
    for t in study.get_trials(deepcopy=False, states=(TrialState.RUNNING,)):
        if t.number not in beaten:
            beaten.add(t.number)
            storage.record_heartbeat(storage.get_trial_id_from_study_id_trial_number(sid, t.number))


def _worker_entry(job: WorkerJob) -> int:   # a process pool's target (module level: picklable)
    return run_worker(job)


def create_study(storage_url: str, study_name: str, settings: TuningSettings, meta: Mapping[str, Any]) -> Any:
    """Create (or join) the optuna study of one controller; its settings must match a joined one's."""
    import warnings

    import optuna

    optuna.logging.set_verbosity(optuna.logging.WARNING)
    warnings.filterwarnings("ignore", category=optuna.exceptions.ExperimentalWarning)
    storage = _storage(storage_url)
    directions = ["minimize" if o.direction == "minimise" else "maximize" for o in settings.objectives]
    try:
        study = optuna.create_study(study_name=study_name, storage=storage, directions=directions,
                                    load_if_exists=True)
    except Exception as exc:  # noqa: BLE001
        raise TuningError(f"storage {storage_url!r}: the study {study_name!r} cannot be created or joined: "
                          f"{type(exc).__name__}: {exc}") from None
    sig = {"objectives": [o.label for o in settings.objectives], "constraints": [c.text for c in settings.constraints],
           **{k: v for k, v in meta.items()}}
    if not study.metric_names:
        study.set_metric_names([o.kpi for o in settings.objectives])   # the dashboard names the axes
    old = study.user_attrs.get("signature")
    runs = int(study.user_attrs.get("runs", 0))
    study.set_user_attr("runs", runs + 1)   # this run's number: its workers' seeds differ from other runs'
    if old is None:
        study.set_user_attr("signature", sig)
    elif old != sig:
        raise TuningError(f"storage {storage_url!r} holds a study {study_name!r} tuned for {old}, not {sig}: give "
                          "another --out or --storage, or the same study file")
    return study


def optimise(storage_url: str, study_name: str, evaluator: TrialEvaluator, *, trials: int, workers: int = 1,
             scheduler: Any = None, meta: Mapping[str, Any] | None = None,
             progress: Callable[[Any], None] | None = None, poll: float = 5.0) -> Any:
    """Run the trials of one controller until ``trials`` have finished; returns the optuna study.

    ``workers`` local processes (0: in this process) or, with ``scheduler``, as many tasks on the
    Dask cluster; each is a loop of trials on the shared storage. ``progress(study)`` is called
    every ``poll`` seconds and at the end.
    """
    study = create_study(storage_url, study_name, evaluator.settings, meta or {})
    if evaluator.settings.start_from_defaults and not study.get_trials(deepcopy=False):
        start = default_params(evaluator.base_spec["type"], evaluator.params, evaluator.safe_radius)
        if start is not None:   # a new run starts from the hand-picked default: its front can only be better
            study.enqueue_trial(start, user_attrs={"origin": "registry default"})
            if workers > 0 or scheduler is not None:
                # run here, before the workers start: two workers asking at once can both take one
                # waiting trial from the storage, and the second then cannot report it
                run_worker(WorkerJob(storage_url, study_name, evaluator, 1))
    if workers <= 0 and scheduler is None:
        run_worker(WorkerJob(storage_url, study_name, evaluator, trials))
        if progress:
            progress(study)
        return study
    from .._parallel import worker_threads

    n = max(1, workers)
    jobs = [WorkerJob(storage_url, study_name, evaluator, trials, worker=i, threads=worker_threads(n))
            for i in range(n)]
    if scheduler is not None:
        from .executors import dask_client

        client, owned = dask_client(scheduler)
        try:
            futs = [client.submit(run_worker, j, pure=False) for j in jobs]
            while not all(f.done() for f in futs):
                if progress:
                    progress(study)
                time.sleep(poll)
            for f in futs:
                f.result()
        finally:
            if owned:
                client.close()
    else:
        import concurrent.futures as cf

        from .executors import PARENT_POLL, USE_PDEATHSIG, _init_worker, _kill_workers

        ctx = multiprocessing.get_context("spawn")
        ex = cf.ProcessPoolExecutor(max_workers=n, mp_context=ctx, initializer=_init_worker,
                                    initargs=(os.getpid(), USE_PDEATHSIG, PARENT_POLL, worker_threads(n)))
        try:
            futs = [ex.submit(_worker_entry, j) for j in jobs]
            while True:
                done, _ = cf.wait(futs, timeout=poll)
                if progress:
                    progress(study)
                if len(done) == len(futs):
                    break
            for f in futs:
                f.result()
        except BaseException:
            _kill_workers(ex)
            raise
        ex.shutdown(wait=True)
    if progress:
        progress(study)
    return study


# ------------------------------------------------------------------------------------------
# fronts and selection
# ------------------------------------------------------------------------------------------


def dominates(a: Sequence[float], b: Sequence[float]) -> bool:
    """``a`` Pareto-dominates ``b`` (both in 'smaller is better' form)."""
    return all(x <= y for x, y in zip(a, b)) and any(x < y for x, y in zip(a, b))


@dataclass(frozen=True)
class TrialRow:
    """A trial as the outputs show it."""

    controller: str
    number: int
    state: str
    values: dict          # column -> aggregated KPI
    params: dict          # the sampled parameters
    spec: dict            # the controller specification
    feasible: bool
    objectives: tuple     # the objectives in 'smaller is better' form
    cases: list = field(default_factory=list)


def load_trials(study: Any, controller: str, settings: TuningSettings) -> list[TrialRow]:
    """Every trial of a controller's study as :class:`TrialRow`."""
    rows = []
    sign = [1.0 if o.direction == "minimise" else -1.0 for o in settings.objectives]
    for t in study.get_trials(deepcopy=False):
        kp = dict(t.user_attrs.get("kpis", {}))
        cons = list(t.user_attrs.get("constraints", []))
        feasible = t.state.name == "COMPLETE" and all(c <= 0 for c in cons)
        obj = tuple(s * float(kp.get(o.kpi, math.nan)) for s, o in zip(sign, settings.objectives))
        rows.append(TrialRow(controller, t.number, t.state.name, kp, dict(t.params), dict(t.user_attrs.get("spec", {})),
                             feasible, obj, list(t.user_attrs.get("cases", []))))
    return rows


def front(rows: Sequence[TrialRow]) -> list[TrialRow]:
    """The non-dominated finished trials among those that meet every constraint (every finished
    trial's if none does: then the caller says so)."""
    pool = [r for r in rows if r.state == "COMPLETE" and r.feasible and all(math.isfinite(v) for v in r.objectives)]
    if not pool:
        return []
    out = [r for r in pool if not any(dominates(o.objectives, r.objectives) for o in pool)]
    uniq: dict[tuple, TrialRow] = {}
    for r in sorted(out, key=lambda r: r.number):
        uniq.setdefault(r.objectives, r)
    return sorted(uniq.values(), key=lambda r: r.objectives)


def select(rows_front: Sequence[TrialRow], settings: TuningSettings) -> TrialRow | None:
    """The design chosen from a front: the knee (the point nearest the ideal point with each
    objective scaled to [0, 1] over the front), or the first rule of ``settings.select`` that a
    front design meets (:func:`select_with`)."""
    return select_with(rows_front, settings)[0]


def select_with(rows_front: Sequence[TrialRow], settings: TuningSettings) -> tuple[TrialRow | None, str | None]:
    """``(design, rule)``: the design :func:`select` chooses and the rule that chose it (None and
    None when no rule is met or the front is empty)."""
    if not rows_front:
        return None, None
    objectives = [o.kpi for o in settings.objectives]
    for text in settings.rules():
        rule = parse_rule(text, objectives)
        if rule is None:
            F = np.array([r.objectives for r in rows_front], dtype=float)
            lo, hi = F.min(axis=0), F.max(axis=0)
            span = np.where(hi > lo, hi - lo, 1.0)
            d = np.linalg.norm((F - lo) / span, axis=1)
            return rows_front[int(np.argmin(d))], text
        how, target, conds = rule
        ok = [r for r in rows_front if all(c.violation(_num(r.values.get(c.kpi))) <= 0 for c in conds)
              and math.isfinite(_num(r.values.get(target)))]
        if ok:
            key = (lambda r: _num(r.values.get(target)))
            return (min(ok, key=key) if how == "min" else max(ok, key=key)), text
    return None, None


def hypervolume_2d(points: Sequence[Sequence[float]], reference: Sequence[float]) -> float:
    """The area dominated by ``points`` (two objectives, both smaller-is-better) and bounded by
    ``reference``; points beyond the reference add nothing."""
    P = sorted((float(a), float(b)) for a, b in points if a < reference[0] and b < reference[1])
    area, best_b = 0.0, float(reference[1])
    for a, b in P:
        if b < best_b:
            area += (reference[0] - a) * (best_b - b)
            best_b = b
    return area


# ------------------------------------------------------------------------------------------
# outputs
# ------------------------------------------------------------------------------------------


def _rules_text(settings: TuningSettings) -> str:
    return " or ".join(repr(r) for r in settings.rules())


def _csv(rows: Sequence[TrialRow], settings: TuningSettings) -> str:
    cols = [c for c, _ in settings.reported()
            if c not in CONTEXT_KPIS or any(math.isfinite(_num(r.values.get(c))) for r in rows)]
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(["controller", "trial", "state", *cols, "feasible", "params"])
    for r in rows:
        w.writerow([r.controller, r.number, r.state, *(repr(float(r.values[c])) if c in r.values else "" for c in cols),
                    str(r.feasible).lower(), json.dumps(r.params, sort_keys=True, default=float)])
    return buf.getvalue()


def write_design(path: Path, row: TrialRow, *, study: str, selected_by: str, settings: TuningSettings,
                 command: str) -> None:
    """A tuned design file (``tuned/<controller>.toml``): the controller's specification and the
    KPIs it reached over the tuning cases, loadable as ``[[controllers]] design = "…"`` and
    ``tapm simulate --option design=…``."""
    lines = [f"# A controller design tuned by optimisation: {command}",
             f"# Trial {row.number} of the front, selected by {selected_by}; objectives "
             + ", ".join(o.label for o in settings.objectives)
             + (("; constraints " + ", ".join(c.text for c in settings.constraints)) if settings.constraints else ""),
             "", "[design]", f"format = {toml_value(DESIGN_FORMAT)}", f"name = {toml_value(row.controller)}",
             f"study = {toml_value(study)}", f"trial = {row.number}", f"selected_by = {toml_value(selected_by)}",
             "", "[design.controller]"]
    for k, v in row.spec.items():
        lines.append(f"{toml_key(k)} = {toml_value(v)}")
    lines += ["", "[design.kpis]   # aggregated over the tuning cases"]
    for k, v in row.values.items():
        lines.append(f"{toml_key(k)} = {toml_value(float(v))}")
    atomic_write_text(path, "\n".join(lines) + "\n")


# ------------------------------------------------------------------------------------------
# the whole job for a study file
# ------------------------------------------------------------------------------------------


@dataclass
class _CaseRunner:
    """Runs a controller specification on each case's inputs (the study's recipe); the KPIs per
    case, with the case's labels."""

    inputs: list
    labels: list = field(default_factory=list)

    def __call__(self, spec: dict) -> list:
        from .jobs import run_case

        out = []
        for i, inp in enumerate(self.inputs):
            _, k = run_case({**inp, "controller": spec})
            row = {n: float(v) for n, v in k.items() if isinstance(v, (int, float)) and not isinstance(v, bool)}
            if self.labels:
                row["_labels"] = self.labels[i]
            out.append(row)
        return out


def tune_study(path: str | Path, out_dir: str | Path, *, trials: int | None = None, workers: int = 1,
               scheduler: Any = None, storage: str | None = None, echo: Callable[[str], None] = print,
               poll: float = 5.0) -> dict:
    """Tune every controller of the study file ``path`` (``tapm tune``; ``docs/tuning.md``).

    Returns
    -------
    dict
        ``{"storage", "controllers": {name: {"complete", "failed", "front", "selected"}}, ...}``
        (also written as ``DIR/tuning.json``).
    """
    from .spec import study_from_dict

    path = Path(path)
    out = Path(out_dir)
    try:
        text = path.read_text(encoding="utf-8-sig")
        data = tomllib.loads(text)
    except OSError as exc:
        raise TuningError(f"{str(path)!r}: cannot read the study file: {exc.strerror or exc}") from None
    except tomllib.TOMLDecodeError as exc:
        raise TuningError(f"{str(path)!r}: not valid TOML: {exc}") from None
    study = study_from_dict(data, base_dir=path.parent, source=str(path))   # checks [tuning] and tune too
    settings = tuning_settings(data.get("tuning"))
    if trials is not None:
        settings = dataclasses.replace(settings, trials=int(trials))
    tunes = {i: e["tune"] for i, e in enumerate(data.get("controllers", [])) if "tune" in e}
    names = list(dict.fromkeys(c.labels["controller"] for c in study.cases))
    entries = data.get("controllers", [])
    out.mkdir(parents=True, exist_ok=True)
    url = storage or f"sqlite:///{(out / 'tuning.db').resolve()}"
    summary: dict[str, Any] = {"format": "tapm-tuning/1", "study": study.name, "storage": url,
                               "settings": {"objectives": [o.label for o in settings.objectives],
                                            "constraints": [c.text for c in settings.constraints],
                                            "trials": settings.trials, "sampler": settings.sampler,
                                            "seed": settings.seed, "select": settings.select,
                                            "verify_seeds": list(settings.verify_seeds),
                                            "per": list(settings.per)},
                               "limits": {k: (study.cases[0].inputs["scenario"].get("limits") or {}).get(k)
                                          for k in ("safe_radius", "alert_radius")} if study.cases else {},
                               "delta_s": DELTA_S_DEFAULT,
                               "controllers": {}}
    all_rows: list[TrialRow] = []
    fronts: dict[str, list[TrialRow]] = {}
    command = f"tapm tune {path.name} --out {out.name}" + (f" --trials {trials}" if trials is not None else "")
    (out / "tuned").mkdir(exist_ok=True)
    for ci, ctrl_name in enumerate(names):
        cases = [c for c in study.cases if c.labels["controller"] == ctrl_name]
        cname = ctrl_name
        base = dict(cases[0].inputs["controller"])
        sc_dict = cases[0].inputs["scenario"]
        safe_radius = (sc_dict.get("limits") or {}).get("safe_radius")
        idx = next((i for i, e in enumerate(entries) if _entry_name(e, path.parent) == cname), None)
        given = {k for k in (entries[idx] if idx is not None else {}) if k not in ("name", "type")}
        params, fixed = search_space(base["type"], {k: v for k, v in base.items() if k in given},
                                     tunes.get(idx), where=f"controllers[{idx if idx is not None else ci}]")
        if not params:
            raise TuningError(f"controller {cname!r}: nothing to tune (its study entry or tune table fixes every "
                              "option of its search space)")
        for gkey, gcases in _groups(cases, settings.per).items():
            cname = ctrl_name if not settings.per else f"{ctrl_name} @ {', '.join(gkey)}"
            cases = gcases
            runner = _CaseRunner([c.inputs for c in cases], [dict(c.labels) for c in cases])
            ev = TrialEvaluator(base, params, fixed, settings, runner, safe_radius)
            sname = f"{study.name}/{cname}"
            echo(f"tuning {cname} ({base['type']}): {len(params)} parameters ({', '.join(p.name for p in params)}) on "
                 f"{len(cases)} case{'s' if len(cases) != 1 else ''}, {settings.trials} trials, {settings.sampler}")
            meta = {"cases": sorted(c.id for c in cases), "params": [p.name for p in params]}
            last = [None]

            def progress(st: Any, cname: str = cname) -> None:
                rows = load_trials(st, cname, settings)
                done = sum(r.state == "COMPLETE" for r in rows)
                failed = sum(r.state == "FAIL" for r in rows)
                f = front(rows)
                msg = (f"  {cname}: {done}/{settings.trials} trials finished" + (f", {failed} failed" if failed else "")
                       + f"; front {len(f)} point{'s' if len(f) != 1 else ''}")
                if f:
                    for o in settings.objectives:
                        vals = [r.values[o.kpi] for r in f]
                        msg += f"; {o.kpi} {format_kpi(o.kpi, min(vals))}-{format_kpi(o.kpi, max(vals))}"
                if msg != last[0]:
                    echo(msg)
                    last[0] = msg

            st = optimise(url, sname, ev, trials=settings.trials, workers=workers, scheduler=scheduler, meta=meta,
                          progress=progress, poll=poll)
            rows = load_trials(st, cname, settings)
            all_rows += rows
            f = front(rows)
            fronts[cname] = f
            chosen, rule = select_with(f, settings)
            info: dict[str, Any] = {"controller": ctrl_name, "group": dict(zip(settings.per, gkey)),
                                    "broken": _broken_lines(cases[0]), "type": base["type"], "complete": sum(r.state == "COMPLETE" for r in rows),
                                    "failed": sum(r.state == "FAIL" for r in rows), "front": [r.number for r in f],
                                    "feasible": sum(r.feasible for r in rows), "selected": None}
            if not f:
                why = ("no finished trial meets the constraints " + ", ".join(c.text for c in settings.constraints)
                       if settings.constraints and info["complete"] else "no trial finished")
                echo(f"  {cname}: {why}; no design written")
                info["note"] = why
            elif chosen is None:
                echo(f"  {cname}: no front point meets the selection rule {_rules_text(settings)}; no design written")
                info["note"] = f"no front point meets {_rules_text(settings)}"
            else:
                write_design(out / "tuned" / f"{_file_name(cname)}.toml", chosen, study=study.name,
                             selected_by=rule, settings=settings, command=command)
                info["selected"] = chosen.number
                info["selected_by"] = rule
                info["design"] = str(Path("tuned") / f"{_file_name(cname)}.toml")
                info["kpis"] = chosen.values
                info["spec"] = chosen.spec
                echo(f"  {cname}: selected trial {chosen.number}: "
                     + ", ".join(f"{k} {format_kpi(k, v)}" for k, v in chosen.values.items()) + f" -> {info['design']}")
            summary["controllers"][cname] = info
    atomic_write_text(out / "trials.csv", _csv(all_rows, settings))
    atomic_write_text(out / "front.csv", _csv([r for rows in fronts.values() for r in rows], settings))
    if settings.verify_seeds:
        summary["verify"] = _verify(study, summary, settings, out, echo)
    atomic_write_text(out / "tuning.json", json.dumps(summary, indent=2, default=float))
    echo(f"wrote {out / 'trials.csv'}, {out / 'front.csv'}, {out / 'tuned'} ({url})")
    return summary


def _verify(study: Any, summary: Mapping[str, Any], settings: TuningSettings, out: Path,
            echo: Callable[[str], None]) -> dict:
    """The selected designs on the study's cases with the seeds replaced by the held-out ones:
    ``verify.csv`` with each objective's tuning and held-out values and their gap."""
    seeds = list(settings.verify_seeds)
    rows, res = [], {}
    for cname, info in summary["controllers"].items():
        if info.get("spec") is None:
            continue
        group = info.get("group") or {}
        base_cases = [c for c in study.cases if c.labels["controller"] == info.get("controller", cname)
                      and all(str(c.labels[k]) == v for k, v in group.items())]
        used = sorted({int(c.labels["seed"]) for c in base_cases})
        overlap = sorted(set(used) & set(seeds))
        if overlap:
            echo(f"  {cname}: verify_seeds {overlap} were used by the search too: not held out")
        inputs, seed_of = [], []
        for c in base_cases:
            if int(c.labels["seed"]) != used[0]:
                continue
            for s in seeds:
                inputs.append({**c.inputs, "seed": int(s)})
                seed_of.append(int(s))
        per_case = _CaseRunner(inputs)(info["spec"])
        held = reported_kpis(settings, per_case, len(base_cases))
        per_seed = {str(s): reported_kpis(settings, [k for k, si in zip(per_case, seed_of) if si == s],
                                            len(base_cases)) for s in seeds}
        res[cname] = {"seeds": seeds, "kpis": held, "per_seed": per_seed}
        for name, _ in settings.reported():
            if name not in held:
                continue
            t, h = _num(info["kpis"].get(name)), held[name]
            rows.append([cname, name, repr(t), repr(h), repr(h - t)])
        echo(f"  {cname} on held-out seeds {seeds}: " + ", ".join(
            f"{k} {format_kpi(k, v)} (tuning {format_kpi(k, _num(info['kpis'].get(k)))})" for k, v in held.items()))
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(["controller", "kpi", "tuning", "held_out", "gap"])
    w.writerows(rows)
    atomic_write_text(out / "verify.csv", buf.getvalue())
    return res


def reported_kpis(settings: TuningSettings, per_case: Sequence[Mapping[str, float]],
                  n_tuning: int | None = None) -> dict:
    """The KPIs a trial reports (``settings.reported()``) aggregated over its cases; the context
    KPIs the cases do not carry (a scenario without a riser) left out. With ``n_tuning`` (held-out
    cases) the sums are scaled to the tuning's number of cases, so that two held-out seeds of a
    one-seed study compare with the tuning's value, not twice it; worst cases stay worst over every
    case."""
    out = {}
    for name, item in settings.reported():
        v = item.value(per_case)
        if n_tuning is not None and item.aggregate == "sum" and per_case:
            v *= n_tuning / len(per_case)
        if name in CONTEXT_KPIS and not math.isfinite(v):
            continue
        out[name] = v
    return out


def gain_designs(tune_dir: str | Path) -> dict[tuple[str, str], dict]:
    """The PID designs a tuning run selected per sea state and mooring condition (``[tuning] per =
    ["sea_state", "condition"]``), as ``design.tables.gain_table``'s ``row_designs``:
    ``{(sea-state id, "intact" or the broken line): {"periods", "damping", "integral_ratio"}}``.

    Raises
    ------
    TuningError
        The folder holds no tuning run, or no PID design split by sea state (a condition that
        breaks more than one line has no gain-table row and is left out).
    """
    d = Path(tune_dir)
    try:
        info = json.loads((d / "tuning.json").read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:
        raise TuningError(f"{str(d)!r} holds no tuning run (tuning.json: {exc})") from None
    out: dict[tuple[str, str], dict] = {}
    for name, v in (info.get("controllers") or {}).items():
        spec, group = v.get("spec"), v.get("group") or {}
        if not spec or spec.get("type") != "pid" or "sea_state" not in group or len(v.get("broken", [])) > 1:
            continue
        broken = v["broken"][0] if v.get("broken") else "intact"
        key = (str(group["sea_state"]), str(broken))
        if key in out:
            raise TuningError(f"{str(d)!r}: two PID designs for sea state {key[0]!r} with mooring state {key[1]!r} "
                              f"(tune one PID per study for a gain table)")
        out[key] = {k: spec[k] for k in ("periods", "damping", "integral_ratio") if k in spec}
    if not out:
        raise TuningError(f"{str(d)!r}: no PID design per sea state: tune a PID with [tuning] per = [\"sea_state\", "
                          "\"condition\"]")
    return out


def _groups(cases: Sequence[Any], per: Sequence[str]) -> dict[tuple, list]:
    """A controller's cases grouped by the labels of ``per`` (one group of all without)."""
    out: dict[tuple, list] = {}
    for c in cases:
        out.setdefault(tuple(str(c.labels[k]) for k in per), []).append(c)
    return out


def _broken_lines(case: Any) -> list[str]:
    """The lines a case's condition breaks (its scenario's line-break faults)."""
    faults = (case.inputs.get("scenario") or {}).get("faults") or []
    return [str(f["line"]) for f in faults if f.get("kind") == "line_break" and f.get("line") is not None]


def _entry_name(e: Any, base_dir: Path) -> str | None:
    """The display name a ``[[controllers]]`` entry gets in the study (its name, else its kind's
    label, the kind read from its design file when it names one)."""
    if not isinstance(e, dict):
        return None
    if e.get("name") is not None:
        return str(e["name"])
    kind_name = e.get("type")
    if kind_name is None and isinstance(e.get("design"), str):
        from ..design.registry import load_design

        p = Path(e["design"])
        kind_name = load_design(p if p.is_absolute() else base_dir / p)["type"]
    try:
        return controller_kind(kind_name).label
    except Exception:  # noqa: BLE001 - a bad entry is the study parser's to report
        return None


def _file_name(name: str) -> str:
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", name).strip("._") or "controller"


def format_kpi(name: str, v: float) -> str:
    """A KPI value with its unit for the console and reports (energy in MWh)."""
    if not math.isfinite(v):
        return "nan"
    unit = KPIS[name].unit if name in KPIS else ""
    if unit == "J":
        return f"{v / 3.6e9:.2f} MWh"
    return f"{v:.4g}{(' ' + unit) if unit and unit != '-' else ''}"
