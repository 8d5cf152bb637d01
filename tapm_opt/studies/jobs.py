"""One case of a study: run it from its inputs alone, and store its files.

:func:`run_case` is the whole computation of a case. Around it:

- :func:`case_payload` runs a case and returns everything its folder is made of (the ``case.json``
  content, the result, the KPIs, or the error with its traceback) without touching any file — what
  a Dask worker runs, so the workers need no file system shared with the client;
- :func:`store_case` writes such a payload into the case folder, each file atomically, ``case.json``
  last (so a case killed half-way is never taken for a finished one);
- :func:`local_case_job` does both in a local worker process, after writing a ``case.json`` that
  marks the case as started;
- :func:`record_failure` writes ``error.json`` for a case that could not run.

The layout of the files is in :mod:`tapm_opt.studies.store`.
"""

from __future__ import annotations

import os
import socket
import time
import traceback
from pathlib import Path
from typing import Any, Mapping

from ..config import scenario_from_dict
from . import store

__all__ = ["run_case", "case_payload", "store_case", "local_case_job", "record_failure",
           "error_info"]


def run_case(inputs: Mapping[str, Any]) -> tuple[Any, dict[str, float]]:
    """Run one case from its inputs alone and compute its KPIs.

    Parameters
    ----------
    inputs : mapping
        :attr:`~tapm_opt.studies.spec.Case.inputs`: ``scenario`` (scenario dict, faults included),
        ``sea_state`` (id in it), ``controller`` (``build_controller`` spec), ``seed``, ``duration``
        [s], ``segments`` (or None), ``closed_loop`` (``dt_control`` [s], ``dt_log`` [s],
        ``setpoint``, ``heading``, ``true_state``).

    Returns
    -------
    result : Result
        The closed-loop run; ``meta`` adds ``case_id``, ``controller_spec`` and ``seed``.
    kpis : dict
        :func:`tapm_opt.studies.kpis.case_kpis` of the result (the recipe, :mod:`tapm_opt.studies.recipe`).

    Notes
    -----
    Deterministic: the same inputs give identical arrays (every random process is seeded from
    ``seed``); only wall-clock figures in ``meta`` (and KPIs taken from them) differ.
    """
    from ..models.system import System
    from .closed_loop import ClosedLoopSettings
    from .recipe import run_case_on

    cid = store.case_id(inputs)
    sc = scenario_from_dict(inputs["scenario"], source=f"case {cid}")
    system = System.from_scenario(sc)  # built once; plant, controller and runner share it
    settings = ClosedLoopSettings(duration=float(inputs["duration"]), **dict(inputs.get("closed_loop") or {}))
    run = run_case_on(system, inputs["controller"], settings, sea_state=sc.sea_state(inputs["sea_state"]),
                      seed=int(inputs["seed"]), segments=inputs.get("segments"), meta={"case_id": cid})
    return run.result, run.kpis


def _head(cid: str, name: str, labels: dict, inputs: dict) -> dict:
    from .. import __version__

    return {"id": cid, "name": name, "labels": labels, "inputs": inputs, "tapm_opt_version": __version__}


def _worker() -> dict:
    """Where a case runs: ``{"host", "pid"}``."""
    return {"host": socket.gethostname(), "pid": os.getpid()}


def error_info(exc: BaseException, message: str | None = None, tb: str | None = None) -> dict:
    """The ``error.json`` content of an exception: ``{"type", "message", "traceback"}``."""
    return {"type": type(exc).__name__, "message": str(exc) if message is None else message,
            "traceback": "".join(traceback.format_exception(exc)) if tb is None else tb}


def case_payload(cid: str, name: str, labels: dict, inputs: dict, started: str | None = None) -> dict:
    """Run one case and return what its folder holds, writing no file.

    Parameters
    ----------
    cid, name, labels, inputs
        The case (:class:`~tapm_opt.studies.spec.Case` fields).
    started : str, optional
        ISO time the case started (default: now).

    Returns
    -------
    dict
        ``{"id", "case": case.json content, "result": Result or None, "kpis": dict or None,
        "error": error.json content or None}``. ``case`` has ``started``, ``worker``
        (``{"host", "pid"}``) and, for a finished run, ``finished`` and ``wall_time`` [s]. A case
        that raises gives its ``error`` (type, message, traceback); nothing is raised.
    """
    case = {**_head(cid, name, labels, inputs), "started": started or store.now_iso(), "worker": _worker()}
    w0 = time.perf_counter()
    try:
        result, kpis = run_case(inputs)
    except Exception as exc:  # noqa: BLE001 - a failed case is recorded, the study goes on
        return {"id": cid, "case": {**case, "wall_time": time.perf_counter() - w0}, "result": None, "kpis": None,
                "error": error_info(exc)}
    case.update(finished=store.now_iso(), wall_time=time.perf_counter() - w0)
    return {"id": cid, "case": case, "result": result, "kpis": kpis, "error": None}


def store_case(cdir: str | Path, payload: Mapping[str, Any]) -> dict:
    """Write a :func:`case_payload` into the case folder ``cdir``.

    A finished case: ``result.npz``, ``kpis.json``, then ``case.json`` (with ``finished``), each
    atomically, and any old ``error.json`` removed first. A failed case: ``case.json`` (without
    ``finished``) and :func:`record_failure`. A file that cannot be written makes the case failed
    (its error recorded), as if it had raised.

    Returns
    -------
    dict
        ``{"id", "status": "finished" | "failed", "wall_time" [s], "error": "Type: message" or None}``.
    """
    d = Path(cdir)
    cid = payload["id"]
    wall = float(payload["case"].get("wall_time", 0.0))
    d.mkdir(parents=True, exist_ok=True)
    if payload["error"] is not None:
        store.write_json(d / store.CASE_JSON, payload["case"])   # without "finished": never taken for done
        return record_failure(d, cid, payload["error"], wall)
    try:
        (d / store.ERROR_JSON).unlink(missing_ok=True)
        payload["result"].save(d / store.RESULT_NPZ)
        store.write_json(d / store.KPIS_JSON, payload["kpis"])
        store.write_json(d / store.CASE_JSON, payload["case"])
    except Exception as exc:  # noqa: BLE001 - e.g. a full disk: the case failed, the study goes on
        return record_failure(d, cid, error_info(exc), wall)
    return {"id": cid, "status": "finished", "wall_time": wall, "error": None}


def local_case_job(cid: str, name: str, labels: dict, inputs: dict, cdir: str) -> dict:
    """Run one case in a local worker process and write its folder there.

    Writes ``case.json`` (started, with this worker's host and pid), runs :func:`case_payload` and
    :func:`store_case`. Returns the outcome of :func:`store_case`.
    """
    d = Path(cdir)
    d.mkdir(parents=True, exist_ok=True)
    (d / store.ERROR_JSON).unlink(missing_ok=True)
    started = store.now_iso()
    store.write_json(d / store.CASE_JSON, {**_head(cid, name, labels, inputs), "started": started,
                                           "worker": _worker()})
    return store_case(d, case_payload(cid, name, labels, inputs, started=started))


def record_failure(cdir: str | Path, cid: str, error: Mapping[str, str], wall: float = 0.0) -> dict:
    """Write ``error.json`` (``error``: type, message, traceback) and remove any result or KPIs of
    the case, so that it cannot look finished.

    Returns
    -------
    dict
        The outcome ``{"id", "status": "failed", "wall_time" [s], "error": "Type: message"}``.
    """
    d = Path(cdir)
    d.mkdir(parents=True, exist_ok=True)
    for f in (store.RESULT_NPZ, store.KPIS_JSON):
        if (d / f).is_file():
            (d / f).unlink()
    store.write_json(d / store.ERROR_JSON, dict(error))
    return {"id": cid, "status": "failed", "wall_time": wall, "error": f"{error['type']}: {error['message']}"}
