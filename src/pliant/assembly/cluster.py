"""The Dask cluster a distributed search runs on (variation studies, sequences): a
``LocalCluster`` of single-threaded worker processes on 127.0.0.1 (no dashboard), or an
existing scheduler's."""

from __future__ import annotations

import os
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

from pliant.errors import InputError

CONNECT_TIMEOUT = 10  # s a scheduler's address may take to answer


@contextmanager
def dask_client(scheduler: str | None, workers: int | None) -> Iterator[Any]:
    """A ``distributed.Client``: to ``scheduler`` ("tcp://HOST:PORT") where given, else to
    a local cluster of ``workers`` processes (default one per core), closed on exit."""
    from distributed import Client, LocalCluster  # noqa: PLC0415 (heavy: on demand)

    if workers is not None and workers < 0:
        raise InputError("workers", f"{workers} worker processes: give 1 or more (0: judge "
                         "in this process)")
    cluster = None
    if scheduler is None:
        n = workers or os.cpu_count() or 1
        import dask  # noqa: PLC0415

        # Without Dask's MALLOC_TRIM_THRESHOLD_ for its workers: glibc would hand freed
        # memory back at once and map every large array afresh (see study._heap_kept).
        with dask.config.set({"distributed.nanny.pre-spawn-environ.MALLOC_TRIM_THRESHOLD_":
                              None}):
            cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True,
                                   host="127.0.0.1", dashboard_address=None,
                                   silence_logs=40)
        client = Client(cluster)
    else:
        try:
            client = Client(scheduler, timeout=f"{CONNECT_TIMEOUT}s")
        except (ValueError, OSError, TimeoutError) as err:
            raise InputError("scheduler", f"no Dask scheduler answers at {scheduler!r} "
                             f"within {CONNECT_TIMEOUT} s ({err}); give the tcp://HOST:PORT "
                             "of a running one, or leave --scheduler out for a local "
                             "cluster") from None
    try:
        yield client
    except KeyboardInterrupt:
        # Ctrl+C: a local cluster's workers are stopped at once. Asked to close, each
        # would first finish the sample it is solving (seconds: the whole close took
        # 4 s); what they were solving is lost either way (a store keeps what is done).
        if cluster is not None:
            _stop_workers(cluster)
        raise
    finally:
        client.close()
        if cluster is not None:
            cluster.close()


def _stop_workers(cluster: Any) -> None:
    """Kill a local cluster's worker processes (best effort: one already gone is
    left)."""
    import signal  # noqa: PLC0415

    for nanny in list(getattr(cluster, "workers", {}).values()):
        pid = getattr(getattr(nanny, "process", None), "pid", None)
        if pid:
            try:
                os.kill(pid, signal.SIGKILL)
            except OSError:
                pass


def worker_count(client: Any) -> int:
    """How many workers the client's cluster has (at least 1)."""
    return max(1, len(client.scheduler_info()["workers"]))
