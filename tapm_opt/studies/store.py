"""On-disk layout of a study run, and reading it back.

A study run directory ``DIR`` (the shared contract of the study workbench)::

    DIR/study.toml                 copy of the study file as loaded
    DIR/study.json                 {"name", "description", "study_file", "n_cases", "scenarios": {<key>: scenario},
                                    "cases": [{"id", "name", "labels", "scenario": <key>, "inputs"}],
                                    "tapm_opt_version"}  (each distinct scenario once, under
                                    :func:`scenario_key`; a case's "inputs" without it: :func:`study_cases`
                                    gives them back whole)
    DIR/run.lock                   held (flock) by the run under way, with its pid and host: one run at a time
    DIR/cases/<id>/case.json       {"id", "name", "labels", "inputs", "tapm_opt_version", "started", "worker",
                                    "finished", "wall_time"}  ("worker": {"host", "pid"} of the process that ran
                                    it; "finished" only once the case is done)
    DIR/cases/<id>/result.npz      the closed-loop :class:`~tapm_opt.results.Result`
    DIR/cases/<id>/kpis.json       flat {kpi_name: number}
    DIR/cases/<id>/error.json      a failed case only: {"type", "message", "traceback"}
    DIR/kpis.csv, DIR/kpis.md      one row per case
    DIR/verification.csv, .json    with a [verification] table: the limit-state checks, one row per
                                   controller, condition, sea state, line and limit state
                                   (:mod:`tapm_opt.studies.verification_study`)

``<id>`` is :func:`case_id` of the case's ``inputs``: the first 12 hex digits of the SHA-256 of their
canonical JSON, so the same inputs always land in the same folder and a re-run finds them.
``case.json`` holds the case's whole ``inputs`` (its scenario in ``inputs.scenario``), so a case
folder needs nothing else; ``study.json`` lists the cases with each distinct scenario stored once
(the cases of a study share most of it: only the sea state and the faults differ), so it grows by
a few hundred bytes per case instead of a copy of the scenario.

Every file is written atomically (temporary file in the same folder, then ``os.replace``): a reader,
or a run killed at any instant, sees either the old file or the new one, never half of one. A case
is *finished* when ``case.json`` holds ``"finished"`` and ``result.npz`` and ``kpis.json`` exist;
``case.json`` is written last (by the local worker that ran the case, or by the client of a Dask
run when the case comes back), so a killed case is never taken for a finished one.

One run at a time writes into ``DIR``: :func:`study_lock` holds an exclusive ``flock`` on
``DIR/run.lock`` for the whole run. The kernel releases it when the holder's file descriptor
closes — when the run ends, however it ends (``kill -9`` included) — so a stale lock cannot stay
behind. (``flock`` on network file systems is only as good as their lock support; on a platform
without ``fcntl`` the directory is not locked.)

The report and other tools read a run through :func:`load_study_results`.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import socket
import tomllib
from dataclasses import dataclass
from datetime import datetime, timezone
from pathlib import Path
from typing import Any, Iterator, Literal, Mapping

import numpy as np

from .._io import atomic_write_text
from ..errors import IssuesError, ScenarioIssue, TapmError

__all__ = [
    "StudyError",
    "StudyIssue",
    "StudyRunError",
    "StudyBusyError",
    "study_lock",
    "read_study_file",
    "CaseRecord",
    "case_id",
    "case_id_and_size",
    "scenario_key",
    "study_json",
    "study_cases",
    "canonical_json",
    "case_dir",
    "write_json",
    "read_json",
    "is_finished",
    "case_status",
    "load_study_results",
    "now_iso",
    "CASES", "STUDY_JSON", "STUDY_TOML", "CASE_JSON", "RESULT_NPZ", "KPIS_JSON", "ERROR_JSON", "KPIS_CSV",
    "KPIS_MD", "LOCK",
]

CASES = "cases"
STUDY_JSON = "study.json"
STUDY_TOML = "study.toml"
CASE_JSON = "case.json"
RESULT_NPZ = "result.npz"
KPIS_JSON = "kpis.json"
ERROR_JSON = "error.json"
KPIS_CSV = "kpis.csv"
KPIS_MD = "kpis.md"
LOCK = "run.lock"

#: One problem of a study file: ``path`` (e.g. ``controllers[1].type``) and ``message``.
StudyIssue = ScenarioIssue


class StudyError(IssuesError):
    """A study file is invalid, or a study directory cannot be read.

    Carries *all* problems found (``issues``), each naming its field path, e.g.
    ``cases.controllers[1].type = 'lqr' is not one of pid, mpc, lmpc``.
    """

    what = "study"


class StudyRunError(StudyError):
    """A study cannot be run as asked: a bad option, an unusable output directory, Dask missing
    or its scheduler out of reach. The message says what and names the value."""

    def __init__(self, message: str):
        super().__init__(message)
        self.args = (message,)   # the message alone, without "invalid study: "


class StudyBusyError(TapmError):
    """Another run is writing into the study directory (it holds ``DIR/run.lock``).

    Attributes
    ----------
    directory : Path
        The study directory.
    pid : int or None
        Process id of the run holding it (None if it could not be read).
    host : str or None
        Host name of that run.
    """

    def __init__(self, directory: str | Path, pid: int | None, host: str | None):
        self.directory, self.pid, self.host = Path(directory), pid, host
        who = "another run" if pid is None else f"another run (pid {pid}" + (f" on {host})" if host else ")")
        super().__init__(f"study directory {self.directory} is in use by {who}: one run at a time may write into "
                         "it; wait for that run to end (or stop it), or choose another directory")


# -- ids and JSON ------------------------------------------------------------------------------


def _json_default(o: Any) -> Any:
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, (np.floating, np.integer, np.bool_)):
        return o.item()
    if isinstance(o, (tuple, set, frozenset)):
        return list(o)
    if isinstance(o, Path):
        return str(o)
    raise TypeError(f"{type(o).__name__} is not JSON serialisable")


def canonical_json(obj: Any) -> str:
    """JSON with sorted keys and no spaces (the text a case id is hashed from).

    Raises
    ------
    ValueError
        If ``obj`` holds a NaN or an infinity (not JSON, and not a reproducible input).
    """
    return json.dumps(obj, sort_keys=True, separators=(",", ":"), allow_nan=False, default=_json_default)


def case_id(inputs: Mapping[str, Any]) -> str:
    """Id of a case: the first 12 hex digits of the SHA-256 of :func:`canonical_json` of ``inputs``."""
    return case_id_and_size(inputs)[0]


def case_id_and_size(inputs: Mapping[str, Any]) -> tuple[str, int]:
    """:func:`case_id` of ``inputs`` and the size of their canonical JSON [bytes] (what
    ``case.json`` stores of them, before its indentation)."""
    raw = canonical_json(inputs).encode("utf-8")
    return hashlib.sha256(raw).hexdigest()[:12], len(raw)


def scenario_key(scenario: Mapping[str, Any]) -> str:
    """Key of a scenario dictionary in ``study.json``'s ``scenarios``: ``sha256-`` and the first 16
    hex digits of the SHA-256 of its :func:`canonical_json`."""
    return "sha256-" + hashlib.sha256(canonical_json(scenario).encode("utf-8")).hexdigest()[:16]


def study_json(name: str, description: str, study_file: str | None, cases: Any, version: str) -> dict:
    """The content of ``study.json`` for ``cases`` (each with ``id``, ``name``, ``labels``, ``inputs``):
    each distinct ``inputs["scenario"]`` once under ``scenarios``, referenced by its
    :func:`scenario_key` from the case's ``"scenario"``."""
    scenarios: dict[str, Any] = {}
    keys: dict[int, str] = {}   # by object: the cases of a study share their scenario dictionaries
    entries = []
    for c in cases:
        inputs = dict(c.inputs)
        sc = inputs.pop("scenario", None)
        entry = {"id": c.id, "name": c.name, "labels": c.labels}
        if sc is not None:
            key = keys.get(id(sc)) or scenario_key(sc)
            keys[id(sc)] = key
            scenarios.setdefault(key, sc)
            entry["scenario"] = key
        entries.append({**entry, "inputs": inputs})
    return {"name": name, "description": description, "study_file": study_file, "n_cases": len(entries),
            "scenarios": scenarios, "cases": entries, "tapm_opt_version": version}


def study_cases(study: Mapping[str, Any], *, where: str | Path = STUDY_JSON) -> list[dict]:
    """The case entries of a ``study.json`` content with their whole ``inputs``: the scenario
    a case references (``"scenario": <key>``) put back as ``inputs["scenario"]``. An entry of an
    older ``study.json`` (its scenario inside its inputs) is returned as it is.

    Raises
    ------
    StudyError
        ``cases`` is not a list, or a case references a scenario ``scenarios`` does not hold
        (the message names ``where``, the case and the key).
    """
    cases = study.get("cases")
    if not isinstance(cases, list):
        raise StudyError(f"{where}: 'cases' is not a list")
    scenarios = study.get("scenarios")
    scenarios = scenarios if isinstance(scenarios, Mapping) else {}
    out = []
    for i, e in enumerate(cases):
        if isinstance(e, Mapping) and isinstance(e.get("scenario"), str):
            key = e["scenario"]
            if key not in scenarios:
                raise StudyError(f"{where}: cases[{i}] (id {e.get('id')!r}) references scenario {key!r}, which "
                                 f"its 'scenarios' does not hold ({len(scenarios)} scenarios)")
            inputs = e.get("inputs") if isinstance(e.get("inputs"), Mapping) else {}
            e = {k: v for k, v in e.items() if k != "scenario"}
            e["inputs"] = {**inputs, "scenario": scenarios[key]}
        out.append(e)
    return out


def case_dir(out_dir: str | Path, cid: str) -> Path:
    """``out_dir/cases/<cid>``."""
    return Path(out_dir) / CASES / cid


def now_iso() -> str:
    """The current UTC time, ISO 8601 with microseconds."""
    return datetime.now(timezone.utc).isoformat(timespec="microseconds")


def write_json(path: str | Path, obj: Any) -> Path:
    """Write ``obj`` as indented JSON, atomically (numpy scalars and arrays become plain JSON)."""
    return atomic_write_text(path, json.dumps(obj, indent=2, default=_json_default, allow_nan=False) + "\n")


def read_json(path: str | Path) -> Any:
    """Read a JSON file.

    Raises
    ------
    StudyError
        If the file is missing or is not valid JSON (the message names the file).
    """
    path = Path(path)
    try:
        return json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise StudyError(f"{path} does not exist") from None
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise StudyError(f"cannot read {path}: {exc}") from None


def _read_json_or_none(path: Path) -> Any:
    try:
        return json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError):
        return None


# -- state of a case ---------------------------------------------------------------------------


def is_finished(cdir: str | Path, *, version: str | None = None) -> bool:
    """True when the case in ``cdir`` is finished: ``case.json`` holds ``"finished"`` and
    ``result.npz`` and ``kpis.json`` are files; with ``version``, also that the case was run by
    that ``tapm_opt`` version (a result of another version is not reused)."""
    cdir = Path(cdir)
    if not ((cdir / RESULT_NPZ).is_file() and (cdir / KPIS_JSON).is_file()):
        return False
    meta = _read_json_or_none(cdir / CASE_JSON)
    if not (isinstance(meta, dict) and bool(meta.get("finished"))):
        return False
    return version is None or meta.get("tapm_opt_version") == version


CaseStatus = Literal["finished", "failed", "started", "missing"]


def case_status(cdir: str | Path) -> CaseStatus:
    """``"finished"`` (:func:`is_finished`), ``"failed"`` (``error.json``), ``"started"`` (a
    ``case.json`` without ``"finished"``: running, or killed while running) or ``"missing"``."""
    cdir = Path(cdir)
    if is_finished(cdir):
        return "finished"
    if (cdir / ERROR_JSON).is_file():
        return "failed"
    if (cdir / CASE_JSON).is_file():
        return "started"
    return "missing"


# -- one run at a time ------------------------------------------------------------------------


def _holder(fd: int) -> tuple[int | None, str | None]:
    try:
        words = os.pread(fd, 512, 0).decode("utf-8", "replace").split()
    except OSError:   # pragma: no cover
        return None, None
    pid = int(words[0]) if words and words[0].isdigit() else None
    return pid, (words[1] if len(words) > 1 else None)


@contextlib.contextmanager
def study_lock(out_dir: str | Path) -> Iterator[Path]:
    """Hold the study directory ``out_dir`` for one run: an exclusive ``flock`` on ``out_dir/run.lock``.

    The file gets the holder's pid and host name. The lock is released when the block ends, or
    when the holding process dies in any way (the kernel closes its file descriptor).

    Parameters
    ----------
    out_dir : path
        An existing study run directory.

    Yields
    ------
    Path
        The lock file.

    Raises
    ------
    StudyBusyError
        Another process (or another block in this one) holds it; the message names the
        directory and the holder's pid.
    StudyRunError
        The lock file cannot be opened or locked.
    """
    path = Path(out_dir) / LOCK
    try:
        import fcntl
    except ImportError:   # pragma: no cover - not POSIX: no lock
        yield path
        return
    try:
        fd = os.open(path, os.O_RDWR | os.O_CREAT | getattr(os, "O_CLOEXEC", 0), 0o666)
    except OSError as exc:
        raise StudyRunError(f"cannot open the lock file {path}: {exc.strerror or exc}") from None
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:   # held by another open file description
            raise StudyBusyError(out_dir, *_holder(fd)) from None
        except OSError as exc:    # e.g. a file system without locks
            raise StudyRunError(f"cannot lock {path}: {exc.strerror or exc}") from None
        os.ftruncate(fd, 0)
        os.pwrite(fd, f"{os.getpid()} {socket.gethostname()}\n".encode(), 0)
        yield path
    finally:
        os.close(fd)   # releases the lock (the file stays: removing it would race with a new run)


# -- reading a run back ------------------------------------------------------------------------


@dataclass(frozen=True)
class CaseRecord:
    """One case of a study run as found on disk.

    Attributes
    ----------
    id, name : str
        Case id (folder name) and display name.
    labels : dict
        ``{"scenario", "sea_state", "controller", "condition", "seed"}``.
    inputs : dict
        Everything the case was run from (see :func:`tapm_opt.studies.study.run_case`).
    result_path : Path or None
        ``result.npz`` of a finished case, else None.
    kpis : dict or None
        ``kpis.json`` of a finished case, else None.
    error : dict or None
        ``error.json`` (``type``, ``message``, ``traceback``) of a failed case, else None.
    meta : dict
        ``case.json`` (``started``, ``finished``, ``wall_time``, ``tapm_opt_version``), or {} if absent.
    """

    id: str
    name: str
    labels: dict
    inputs: dict
    result_path: Path | None
    kpis: dict | None
    error: dict | None
    meta: dict

    @property
    def status(self) -> CaseStatus:
        """``"finished"``, ``"failed"``, ``"started"`` or ``"missing"`` (not run yet)."""
        if self.result_path is not None and self.kpis is not None:
            return "finished"
        if self.error is not None:
            return "failed"
        return "started" if self.meta else "missing"

    def load_result(self) -> Any:
        """The case's :class:`~tapm_opt.results.Result`.

        Raises
        ------
        StudyError
            If the case is not finished.
        """
        from ..results import Result

        if self.result_path is None:
            raise StudyError(f"case {self.id} ({self.name}) has no result: it is {self.status}")
        return Result.load(self.result_path)

    def scenario(self) -> Any:
        """The scenario the case ran with (its faults included)."""
        from ..config import scenario_from_dict

        return scenario_from_dict(self.inputs["scenario"], source=f"case {self.id}")


def load_study_results(out_dir: str | Path) -> list[CaseRecord]:
    """Every case of the study run in ``out_dir``, in study order.

    The cases are those listed in ``study.json``; without it (a run killed before writing it), those
    found under ``cases/`` (in the order of their folder names). Cases not run yet have
    ``status == "missing"``.

    Raises
    ------
    StudyError
        If ``out_dir`` is not a study run directory.
    """
    out = Path(out_dir)
    if not out.is_dir():
        raise StudyError(f"{out} is not a directory")
    study = _read_json_or_none(out / STUDY_JSON)
    if (out / STUDY_JSON).exists() and not isinstance(study, dict):
        raise StudyError(f"cannot read {out / STUDY_JSON}: not a JSON object")
    if study is not None:
        entries = study_cases(study, where=out / STUDY_JSON) if study.get("cases") is not None else []
    else:
        cases_dir = out / CASES
        if not cases_dir.is_dir():
            raise StudyError(f"{out} is not a study run directory (no {STUDY_JSON} and no {CASES}/)")
        entries = []
        for d in sorted(p for p in cases_dir.iterdir() if p.is_dir()):
            meta = _read_json_or_none(d / CASE_JSON)
            if isinstance(meta, dict) and meta.get("id") == d.name:
                entries.append(meta)
    records = []
    for e in entries:
        cid = str(e["id"])
        d = case_dir(out, cid)
        meta = _read_json_or_none(d / CASE_JSON)
        meta = meta if isinstance(meta, dict) else {}
        finished = is_finished(d)
        kpis = _read_json_or_none(d / KPIS_JSON) if finished else None
        if finished and not isinstance(kpis, dict):
            finished, kpis = False, None
        error = None if finished else _read_json_or_none(d / ERROR_JSON)
        records.append(CaseRecord(
            id=cid, name=str(meta.get("name", e.get("name", cid))), labels=dict(meta.get("labels", e.get("labels", {}))),
            inputs=dict(meta.get("inputs", e.get("inputs", {}))), result_path=(d / RESULT_NPZ) if finished else None,
            kpis=kpis, error=error if isinstance(error, dict) else None,
            meta={k: v for k, v in meta.items() if k not in ("id", "name", "labels", "inputs")}))
    return records


def read_study_file(path: str | Path) -> tuple[dict, str]:
    """The parsed TOML of a study file and its text, not yet validated.

    Raises
    ------
    StudyError
        If the file is missing, unreadable or not valid TOML.
    """
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8-sig")   # a byte-order mark, as the scenario loader
    except FileNotFoundError:
        raise StudyError(f"no study file {path}") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise StudyError(f"cannot read {path}: {exc}") from None
    try:
        return tomllib.loads(text), text
    except tomllib.TOMLDecodeError as exc:
        raise StudyError(f"{path.name} is not valid TOML: {exc}", source=str(path)) from None
    except RecursionError:
        raise StudyError(f"{path.name} nests arrays or tables too deeply to be read as TOML",
                         source=str(path)) from None
