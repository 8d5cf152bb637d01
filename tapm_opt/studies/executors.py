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

__all__ = ["run_inline", "run_local", "run_dask", "dask_client", "check_scheduler", "PARENT_POLL", "USE_PDEATHSIG",
           "SCHEDULER_TIMEOUT"]

#: Interval [s] at which a local worker checks that the process that started it is still there.
PARENT_POLL = 0.5

#: Ask the Linux kernel to kill a worker whose parent dies (else only the polling thread does it).
USE_PDEATHSIG = True

#: Time [s] a scheduler address is given to connect and answer Dask's handshake before the run
#: is refused (:func:`dask_client`).
SCHEDULER_TIMEOUT = 10.0


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
        ``scheduler`` is none of the above. An address is checked first
        (:func:`check_scheduler`, :data:`SCHEDULER_TIMEOUT` seconds at most): a service that refuses
        the connection, stays silent or answers in another protocol (an HTTP server, ...) is named
        with what it did.
    """
    try:
        from dask.distributed import Client
    except ImportError:
        raise StudyRunError("scheduler=... runs the cases on Dask, which is not installed; install the extra: "
                         "pip install 'tapm_opt[dask]'") from None
    if isinstance(scheduler, Client):
        return scheduler, False
    if isinstance(scheduler, str) or hasattr(scheduler, "scheduler_address"):
        if isinstance(scheduler, str):
            check_scheduler(scheduler)
        try:
            return Client(scheduler, timeout=max(SCHEDULER_TIMEOUT, 1.0)), True
        except Exception as exc:  # noqa: BLE001 - whatever the connection gives back, named with the address
            raise StudyRunError(f"cannot connect to the Dask scheduler {scheduler!r}: "
                                f"{type(exc).__name__}: {exc}") from None
    raise StudyRunError(f"scheduler = {scheduler!r} must be a scheduler address ('tcp://host:port'), a "
                     "dask.distributed.Client or a cluster object")


def check_scheduler(address: str, timeout: float | None = None) -> None:
    """Check that ``address`` is a Dask scheduler: connect and exchange Dask's handshake within
    ``timeout`` seconds (default :data:`SCHEDULER_TIMEOUT`), then close.

    Only ``tcp://`` addresses (and a bare ``host:port``) are checked here; other protocols (``tls://``,
    ``ws://``, ...) need their connection options and are left to ``Client``.

    Raises
    ------
    StudyRunError
        Naming the address and what happened: no connection (refused, unknown host, nothing within
        the time), a peer that accepts but says nothing within the time, or one that answers in
        another protocol (an HTTP server, ...).
    """
    import asyncio
    import concurrent.futures as cf

    from distributed.comm.addressing import parse_address

    timeout = float(SCHEDULER_TIMEOUT if timeout is None else timeout)
    try:
        scheme, loc = parse_address(address)
    except (ValueError, TypeError) as exc:
        raise StudyRunError(f"scheduler = {address!r} is not a scheduler address ('tcp://host:port'): {exc}") from None
    if scheme != "tcp":
        return
    what = f"Dask scheduler {address!r}"
    with cf.ThreadPoolExecutor(1, thread_name_prefix="tapm-scheduler-check") as ex:   # a loop of its own
        fut = ex.submit(asyncio.run, _handshake(scheme, loc, timeout))
        try:
            problem = fut.result(timeout=3 * timeout + 5)
        except cf.TimeoutError:   # pragma: no cover - each step is bounded by wait_for
            problem = f"no answer within {3 * timeout:g} s"
    if problem is not None:
        raise StudyRunError(f"{what}: {problem}")


async def _handshake(scheme: str, loc: str, timeout: float) -> str | None:
    """Connect to ``scheme://loc`` and exchange Dask's handshake, each step within ``timeout``
    seconds; None when a Dask scheduler answered, else what went wrong."""
    import asyncio

    from distributed.comm.registry import get_backend

    try:
        comm = await asyncio.wait_for(get_backend(scheme).get_connector().connect(loc, deserialize=False), timeout)
    except (TimeoutError, asyncio.TimeoutError):
        return f"no connection within {timeout:g} s (is the host up and the port open?)"
    except Exception as exc:  # noqa: BLE001 - refused, unknown host, ...
        return f"cannot connect: {_reason(exc)} (is a scheduler running there? `dask scheduler` starts one)"
    try:
        await asyncio.wait_for(comm.write(comm.handshake_info()), timeout)
        reply = await asyncio.wait_for(comm.read(), timeout)
    except (TimeoutError, asyncio.TimeoutError):
        return (f"the service there accepted the connection but sent nothing within {timeout:g} s: not a Dask "
                "scheduler, which answers at once (another service, or one that hangs?)")
    except Exception as exc:  # noqa: BLE001 - MemoryError from a nonsense length, closed stream, ...
        return (f"the service there does not speak Dask's protocol ({_reason(exc)}): an HTTP server or the "
                "dashboard's port? A scheduler listens on port 8786 unless told otherwise")
    finally:
        comm.abort()
    if not (isinstance(reply, dict) and "compression" in reply and "python" in reply):
        return f"the service there answered, but not with Dask's handshake ({reply!r:.120})"
    return None


def _reason(exc: BaseException) -> str:
    """What an exception of the check says, short: the underlying error of a closed comm, no object reprs."""
    import re

    if isinstance(exc, MemoryError):   # a length read from bytes that are not Dask's framing
        return "its reply announces a message of an impossible size"
    text = re.sub(r"^in <[^>]*>: ", "", str(exc))[:200]
    return text if text.startswith(("ConnectionRefusedError", "OSError", "TimeoutError")) else \
        (f"{type(exc).__name__}: {text}" if text else type(exc).__name__)


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
