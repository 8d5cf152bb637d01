"""Where the cases of a study run: local worker processes, a Dask cluster, or this process.

Local processes
    :func:`run_local` runs :func:`~tapm_opt.studies.jobs.local_case_job` on a pool of ``spawn``-ed
    processes; each writes its case's files itself, atomically. A pool broken by a dying worker is
    replaced and the cases it had not started are run again. Every worker watches the process that
    started it and ends itself when that process is gone — killed with ``kill -9`` included: on
    Linux the kernel sends it ``SIGKILL`` (``prctl(PR_SET_PDEATHSIG)``), and on every platform a
    thread polls the parent pid (:data:`PARENT_POLL` seconds apart). An interrupted run
    (``Ctrl-C``, an exception) kills its workers before it returns.

Dask
    :func:`run_dask` runs :func:`~tapm_opt.studies.jobs.case_payload` on the cluster's workers:
    they compute and return the result, KPIs, ``case.json`` content or error, and write nothing;
    the client stores each case as it comes back. So the workers need no file system shared with
    the client, and a run interrupted at any point keeps every case stored so far. Killing the
    client ends its tasks through Dask itself: the scheduler forgets the tasks of a client that
    has gone.

This process
    :func:`run_inline` runs the cases one after the other here, as a local worker would (for
    debugging).
"""

from __future__ import annotations

import concurrent.futures as cf
import ctypes
import multiprocessing
import os
import signal
import sys
import threading
import time
from pathlib import Path
from typing import Any, Protocol, Sequence

from .._parallel import limit_threads, worker_threads
from . import store
from .jobs import case_payload, error_info, local_case_job, record_failure, store_case
from .spec import Case
from .store import StudyRunError

__all__ = ["run_inline", "run_local", "run_dask", "dask_client", "PARENT_POLL", "USE_PDEATHSIG"]

#: Interval [s] at which a local worker checks that the process that started it is still there.
PARENT_POLL = 0.5

#: Ask the Linux kernel to kill a worker whose parent dies (else only the polling thread does it).
USE_PDEATHSIG = True


class Progress(Protocol):
    """What the executors report to (``tapm_opt.studies.runner``'s progress bar)."""

    def set_running(self, n: int) -> None: ...

    def done(self, failed: bool, running: int) -> None: ...


def _job_args(c: Case, out: Path) -> tuple:
    return (c.id, c.name, c.labels, c.inputs, str(store.case_dir(out, c.id)))


def _lost(out: Path, cid: str, exc: BaseException, message: str) -> dict:
    """Record a case that could not run (its worker died, Dask gave up, ...)."""
    return record_failure(store.case_dir(out, cid), cid, error_info(exc, message))


# -- this process ------------------------------------------------------------------------------


def run_inline(todo: Sequence[Case], out: Path, bar: Progress, outcomes: dict) -> None:
    """Run ``todo`` one after the other in this process (for debugging); parameters as :func:`run_local`."""
    for c in todo:
        bar.set_running(1)
        outcomes[c.id] = local_case_job(*_job_args(c, out))
        bar.done(outcomes[c.id]["status"] != "finished", 0)


# -- local processes ---------------------------------------------------------------------------


def _set_pdeathsig() -> bool:
    """Linux: have the kernel send this process SIGKILL when its parent dies. True if set.

    The kernel watches the thread that started the process; :func:`run_local` starts its workers
    from the calling thread, which waits for them, so this is the parent's lifetime.
    """
    if not sys.platform.startswith("linux"):
        return False
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        return libc.prctl(1, int(signal.SIGKILL), 0, 0, 0) == 0   # 1 = PR_SET_PDEATHSIG
    except (OSError, AttributeError):   # pragma: no cover - no prctl in this libc
        return False


def _watch_parent(parent_pid: int, interval: float) -> None:
    while True:
        time.sleep(interval)
        if os.getppid() != parent_pid:   # re-parented: the parent is gone
            os._exit(1)


def _init_worker(parent_pid: int, use_pdeathsig: bool, interval: float, threads: int) -> None:
    """Initializer of every local worker: end this process when ``parent_pid`` dies; its BLAS and
    OpenMP pools get ``threads`` threads (its share of the cores, ``tapm_opt._parallel``)."""
    limit_threads(threads)
    if use_pdeathsig:
        _set_pdeathsig()
    if os.getppid() != parent_pid:   # the parent died before the watch began
        os._exit(1)
    threading.Thread(target=_watch_parent, args=(parent_pid, interval), name="tapm-parent-watch",
                     daemon=True).start()


def _kill_workers(ex: cf.ProcessPoolExecutor) -> None:
    """Kill the pool's processes now (running cases stay 'started' and are run again on resume)."""
    for p in list((getattr(ex, "_processes", None) or {}).values()):
        try:
            p.kill()
        except (OSError, AttributeError):   # pragma: no cover - already gone
            pass
    ex.shutdown(wait=False, cancel_futures=True)


def _started_mark(out: Path, cid: str) -> int | None:
    try:
        return (store.case_dir(out, cid) / store.CASE_JSON).stat().st_mtime_ns
    except OSError:
        return None


def run_local(todo: Sequence[Case], out: Path, workers: int, bar: Progress, outcomes: dict) -> None:
    """Run ``todo`` on ``workers`` spawned processes; put each outcome in ``outcomes[id]``.

    Parameters
    ----------
    todo : sequence of Case
        The cases to run.
    out : Path
        The study run directory.
    workers : int
        Processes, >= 1 (at most one per case is started).
    bar : Progress
        Told when a case is done and how many are running.
    outcomes : dict
        Filled with ``{id: outcome}`` (:func:`~tapm_opt.studies.jobs.store_case`) as cases end.
    """
    ctx = multiprocessing.get_context("spawn")   # no fork of a parent holding threads or solver state
    pending = list(todo)
    while pending:
        n = min(workers, len(pending))
        init = (os.getpid(), USE_PDEATHSIG, PARENT_POLL, worker_threads(n))   # the pool's share of the cores
        marks = {c.id: _started_mark(out, c.id) for c in pending}
        retry: list[Case] = []
        ex = cf.ProcessPoolExecutor(max_workers=n, mp_context=ctx, initializer=_init_worker, initargs=init)
        try:
            futs = {ex.submit(local_case_job, *_job_args(c, out)): c for c in pending}
            left = len(futs)
            bar.set_running(min(n, left))
            for fut in cf.as_completed(futs):
                c = futs[fut]
                try:
                    outcomes[c.id] = fut.result()
                except cf.process.BrokenProcessPool as exc:
                    if _started_mark(out, c.id) == marks[c.id]:
                        retry.append(c)     # never started: run it in the next pool
                        continue
                    outcomes[c.id] = _lost(out, c.id, exc, "the worker process running it died "
                                           "(killed, out of memory or crashed)")
                except Exception as exc:  # noqa: BLE001 - e.g. inputs that cannot be pickled
                    outcomes[c.id] = _lost(out, c.id, exc, str(exc))
                left -= 1
                bar.done(outcomes[c.id]["status"] != "finished", min(n, left - len(retry)))
        except BaseException:
            _kill_workers(ex)
            raise
        ex.shutdown(wait=True)
        if len(retry) == len(pending):   # pragma: no cover - a pool that dies before running anything
            for c in retry:
                outcomes[c.id] = _lost(out, c.id, RuntimeError("worker pool died"),
                                       "the worker pool died before the case started")
                bar.done(True, 0)
            return
        pending = retry


# -- Dask --------------------------------------------------------------------------------------


def dask_client(scheduler: Any) -> tuple[Any, bool]:
    """A Dask client for ``scheduler``, and whether the caller owns it (and must close it).

    Parameters
    ----------
    scheduler : str or dask.distributed.Client or cluster
        A scheduler address (``"tcp://host:8786"``), a ``Client`` (used as is) or a cluster object
        (anything with ``scheduler_address``, e.g. ``LocalCluster``).

    Raises
    ------
    StudyRunError
        Dask is not installed (the message names the extra), the scheduler cannot be reached, or
        ``scheduler`` is none of the above.
    """
    try:
        from dask.distributed import Client
    except ImportError:
        raise StudyRunError("scheduler=... runs the cases on Dask, which is not installed; install the extra: "
                         "pip install 'tapm_opt[dask]'") from None
    if isinstance(scheduler, Client):
        return scheduler, False
    if isinstance(scheduler, str) or hasattr(scheduler, "scheduler_address"):
        try:
            return Client(scheduler), True
        except (OSError, TimeoutError, ValueError) as exc:
            raise StudyRunError(f"cannot connect to the Dask scheduler {scheduler!r}: {exc}") from None
    raise StudyRunError(f"scheduler = {scheduler!r} must be a scheduler address ('tcp://host:port'), a "
                     "dask.distributed.Client or a cluster object")


def run_dask(todo: Sequence[Case], out: Path, client: Any, bar: Progress, outcomes: dict) -> None:
    """Run ``todo`` on the Dask cluster of ``client``; store each case here as it comes back.

    Parameters are those of :func:`run_local`, with ``client`` a ``dask.distributed.Client``
    instead of a number of workers. The tasks are named ``tapm-case-<id>-<random>``.
    """
    from dask.distributed import as_completed

    futs = {}
    for c in todo:
        f = client.submit(case_payload, c.id, c.name, c.labels, c.inputs,
                          key=f"tapm-case-{c.id}-{os.urandom(4).hex()}", pure=False)
        futs[f] = c
    left = len(futs)
    bar.set_running(left)
    try:
        for fut in as_completed(list(futs)):
            c = futs.pop(fut)
            try:
                payload = fut.result()
            except Exception as exc:  # noqa: BLE001 - e.g. KilledWorker
                outcomes[c.id] = _lost(out, c.id, exc, f"Dask could not run the case: {exc}")
            else:
                outcomes[c.id] = store_case(store.case_dir(out, c.id), payload)
            fut.release()   # the result is stored: the cluster can forget it
            left -= 1
            bar.done(outcomes[c.id]["status"] != "finished", left)
    except BaseException:
        client.cancel(list(futs))
        raise
