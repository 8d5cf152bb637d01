"""Worker processes that share the machine's cores: one BLAS/OpenMP thread pool size for all.

numpy's OpenBLAS starts a thread per core in every process. With several worker processes on the
same cores (a study's cases, a capability envelope's cases, an anchor network's runs) those pools
oversubscribe the cores and their spinning threads slow every BLAS call many times over: two
one-hour storm cases of the nonlinear MPC run side by side on 2 cores took 19.8 s each with
OpenBLAS's default of 2 threads per process against 6.8 s with 1 (the condensed QP's dense
products; ``docs/performance.md``). :func:`limit_threads` sizes the pools of a worker to its share
of the cores (threadpoolctl, which acts on the libraries already loaded, so it works in forked
and spawned workers alike).
"""

from __future__ import annotations

import os

__all__ = ["worker_threads", "limit_threads"]


def worker_threads(workers: int) -> int:
    """Threads per worker for ``workers`` processes sharing this machine's cores (at least 1)."""
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)
    return max(1, cores // max(1, int(workers)))


def limit_threads(threads: int) -> None:
    """Limit the BLAS and OpenMP thread pools of this process to ``threads`` (in a worker's
    initializer). Kept for the life of the process."""
    from threadpoolctl import threadpool_limits

    global _LIMITS
    _LIMITS = threadpool_limits(limits=int(threads))


_LIMITS = None
