"""A batch on a Dask distributed cluster: a local one started here, or an existing scheduler.

Workers are processes, one thread each, so each has its own GL context;
inside a worker the GL calls run on one dedicated thread
(:func:`glvox.batch.worker.dask_task`).  A task whose worker process dies is
retried once on another worker and then recorded as :data:`WORKER_CRASHED`
(on a local cluster; an external scheduler applies its own
``distributed.scheduler.allowed-failures``).
"""

from __future__ import annotations

import logging
import time
import uuid
from typing import Any, Callable, Sequence

from ..errors import GlvoxError
from .jobs import BatchSettings, Job
from .manifest import base_row, now
from .safety import signals_held
from .worker import Task, dask_task, voxelize_one

#: The reason of a mesh whose worker died on the first try and on the retry.
WORKER_CRASHED = "WorkerCrashed"

#: Dask settings of a batch.  allowed-failures 1: a task whose worker dies is
#: retried once, then KilledWorker.  worker-saturation 1.0: a worker holds only
#: the task it runs, so a crash does not count against a task merely queued behind it.
DASK_CONFIG = {"distributed.scheduler.allowed-failures": 1,
               "distributed.scheduler.worker-saturation": 1.0}


def _require_dask():
    """The dask module, after importing dask and distributed; GlvoxError says how to install them."""
    # dask and distributed are imported lazily in this module (here and below):
    # they are slow to import, and only a batch on a cluster needs them.
    # An interrupt during these imports can be swallowed by an import guard in
    # a dependency, hence the held signals.
    with signals_held():
        try:
            import dask
            import distributed  # noqa: F401
        except ImportError:
            raise GlvoxError("glvox batch runs its workers with Dask distributed, which is not installed: "
                             "pip install 'glvox[batch]' (or run in this process with --workers 0)") from None
    return dask


def _connect(workers: int, scheduler: str | None, say: Callable[[str], None]):
    """A client of the scheduler at ``scheduler``, or of a new local cluster of ``workers`` processes.

    Returns
    -------
    client : distributed.Client
    cluster : distributed.LocalCluster or None
        The cluster started here (to close), None with ``scheduler``.
    mode : str
        ``'scheduler ADDRESS'`` or ``'local cluster (K workers)'``.
    """
    from distributed import Client, LocalCluster

    if scheduler:
        try:
            return Client(scheduler, timeout="30s"), None, f"scheduler {scheduler}"
        except (OSError, TimeoutError) as exc:
            raise GlvoxError(f"cannot connect to the Dask scheduler at {scheduler}: {exc}") from None
    say(f"starting a local Dask cluster of {workers} worker processes")
    cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                           dashboard_address=None, silence_logs=logging.CRITICAL)
    try:
        client = Client(cluster)
    except BaseException:
        cluster.close()
        raise
    return client, cluster, f"local cluster ({workers} worker{'s' * (workers != 1)})"


def crashed_row(job: Job, settings: BatchSettings, detail: str = "") -> dict[str, Any]:
    """The row of a mesh whose worker died on the first try and on the retry (``detail``: what
    is known of the last death, appended after a semicolon)."""
    row = base_row(job, settings)
    row.update(status="failed", reason=WORKER_CRASHED, finished=now(),
               error=f"worker crashed: the worker process died while voxelizing {job.rel}, and again on "
                     f"the retry (a crash in a library, or out of memory){'; ' + detail if detail else ''}")
    return row


def _crashed_row(job: Job, settings: BatchSettings, exc: BaseException) -> dict[str, Any]:
    last = getattr(exc, "last_worker", None)
    return crashed_row(job, settings, f"the last worker was {last.address}" if getattr(last, "address", None) else "")


def _collect(client, jobs: Sequence[Job], settings: BatchSettings, task: Task,
             on_result: Callable[[dict], None]) -> None:
    """Submit one Dask task per job and hand each row to ``on_result`` as it finishes."""
    from distributed import as_completed
    from distributed.scheduler import KilledWorker

    token = uuid.uuid4().hex[:8]
    keys = [f"glvox-batch-{token}-{i}" for i in range(len(jobs))]
    by_key = dict(zip(keys, jobs))
    futures = client.map(dask_task, list(jobs), settings=settings, task=task, key=keys, pure=False)
    for fut in as_completed(futures):
        job = by_key[fut.key]
        try:
            row = fut.result()
        except KilledWorker as exc:
            row = _crashed_row(job, settings, exc)
        except Exception as exc:  # noqa: BLE001 - a lost task is one failed mesh
            row = base_row(job, settings)
            row.update(status="failed", reason=type(exc).__name__, finished=now(),
                       error=f"the Dask task failed: {exc}")
        fut.release()
        on_result(row)


def _close(client, cluster) -> None:
    """Close the client and the cluster started here, quietly."""
    # the scheduler logs every cancelled task when a run is cut short
    log = logging.getLogger("distributed")
    level = log.level
    log.setLevel(logging.CRITICAL)
    try:
        if client is not None:
            client.close()
        if cluster is not None:
            cluster.close()
    finally:
        log.setLevel(level)


def run_dask(jobs: Sequence[Job], settings: BatchSettings, *, workers: int, scheduler: str | None,
             on_result: Callable[[dict], None], say: Callable[[str], None],
             task: Task = voxelize_one) -> tuple[str, float]:
    """Run ``task`` on every job on a Dask cluster, handing each manifest row to ``on_result``.

    Parameters
    ----------
    jobs : sequence of Job
    settings : BatchSettings
    workers : int
        Processes of the local cluster started when ``scheduler`` is None.
    scheduler : str, optional
        Address of an existing scheduler; its workers run the batch.
    on_result : callable
        Called in this process with each row, in order of completion.
    say : callable
        Takes one-line messages for the user.
    task : callable
        ``task(job, settings) -> row``, run on each worker's GL thread; the
        workers unpickle it by module path, so it must be importable there.

    Returns
    -------
    mode : str
        ``'local cluster (K workers)'`` or ``'scheduler ADDRESS'``.
    startup_s : float
        Seconds to start the cluster or connect to the scheduler.
    """
    dask = _require_dask()
    t0 = time.perf_counter()
    client = cluster = None
    try:
        # a local cluster's scheduler reads DASK_CONFIG when it starts (an external one keeps its own)
        with dask.config.set(DASK_CONFIG), signals_held():
            client, cluster, mode = _connect(workers, scheduler, say)
        startup = time.perf_counter() - t0
        _collect(client, jobs, settings, task, on_result)
        return mode, startup
    finally:
        _close(client, cluster)
