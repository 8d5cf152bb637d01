"""Worker processes share the cores: their BLAS/OpenMP pools are sized to their share
(``tapm_opt._parallel``), so several workers do not oversubscribe the machine."""

from __future__ import annotations

import concurrent.futures as cf
import multiprocessing as mp
import os

from tapm_opt._parallel import limit_threads, worker_threads


def _blas_threads() -> list[int]:
    import numpy  # noqa: F401  (loads OpenBLAS)
    from threadpoolctl import threadpool_info

    return [int(i["num_threads"]) for i in threadpool_info()]


def test_threads_per_worker_are_the_cores_shared_out():
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    assert worker_threads(1) == cores
    assert worker_threads(2) == max(1, cores // 2)
    assert worker_threads(cores + 5) == 1
    assert worker_threads(0) == cores            # "no workers" is read as one


def test_spawned_and_forked_workers_get_their_share():
    """The initializer limits the pools of a spawned worker (which loads numpy afresh) and of a
    forked one (which inherits the parent's loaded libraries)."""
    methods = [m for m in ("spawn", "fork") if m in mp.get_all_start_methods()]
    for method in methods:
        with cf.ProcessPoolExecutor(max_workers=1, mp_context=mp.get_context(method), initializer=limit_threads,
                                    initargs=(1,)) as ex:
            counts = ex.submit(_blas_threads).result(timeout=120)
        assert counts and all(n == 1 for n in counts), (method, counts)
