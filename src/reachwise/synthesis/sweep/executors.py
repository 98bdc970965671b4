"""Where the runs go: a local process pool or a Dask cluster (``concurrent.futures``).

By default a local ``ProcessPoolExecutor`` on all cores (spawned workers that ignore
Ctrl-C and exit when the sweep's process dies), or a Dask cluster through
``dask_executor`` (``client.get_executor()``; the ``cluster`` extra).
"""

from __future__ import annotations

import os
import time
from collections.abc import Iterator
from concurrent.futures import Executor
from contextlib import contextmanager

from reachwise.errors import MissingDependency


def _watch_parent(parent: int) -> None:  # pragma: no cover - runs in worker processes
    while True:
        time.sleep(1.0)
        if os.getppid() != parent:
            os._exit(1)


def _worker_init(parent: int) -> None:  # pragma: no cover - runs in worker processes
    """Process-pool worker: leave Ctrl-C to the sweep (it stops submitting and waits for
    the running items); exit when the sweep's process is gone (killed)."""
    import signal
    import threading

    signal.signal(signal.SIGINT, signal.SIG_IGN)
    threading.Thread(target=_watch_parent, args=(parent,), daemon=True).start()


def process_pool(workers: int | None = None) -> Executor:
    """A local process pool (spawned workers, ``workers`` defaults to all cores)."""
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor

    n = workers or os.cpu_count() or 1
    return ProcessPoolExecutor(
        max_workers=n,
        mp_context=multiprocessing.get_context("spawn"),
        initializer=_worker_init,
        initargs=(os.getpid(),),
    )


@contextmanager
def dask_executor(address: str, workers: int | None = None) -> Iterator[Executor]:
    """A ``concurrent.futures`` executor on a Dask cluster (``client.get_executor()``).

    ``address`` ``tcp://HOST:8786`` connects to a running scheduler; ``local`` starts a
    ``LocalCluster`` of ``workers`` single-threaded worker processes bound to 127.0.0.1
    with the dashboard off, and closes it afterwards. Needs the ``cluster`` extra
    (``pip install "reachwise[cluster]"``, i.e. ``dask[distributed]``).
    """
    try:
        from distributed import Client, LocalCluster
    except ImportError as exc:  # pragma: no cover - depends on the environment
        raise MissingDependency("distributed", "cluster", "a sweep on a Dask cluster") from exc
    if address == "local":
        n = workers or os.cpu_count() or 1
        cluster = LocalCluster(
            n_workers=n,
            threads_per_worker=1,
            processes=True,
            host="127.0.0.1",
            dashboard_address=None,
        )
        client = Client(cluster)
        try:
            yield client.get_executor(pure=False)
        finally:
            client.close()
            cluster.close()
    else:
        client = Client(address)
        try:
            yield client.get_executor(pure=False)
        finally:
            client.close()
