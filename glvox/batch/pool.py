"""Local worker processes of ``glvox batch --workers K``: a small pool on ``multiprocessing``.

Why not a local Dask cluster (still used with ``--scheduler``): measured
here (``python compare/bench_batch.py``, 200 meshes at 32^3), Dask took
1.3-1.9 s to start two workers and ~10 ms per task, so two Dask workers
voxelized 39-41 meshes/s where one process voxelized 156-160.  This pool forks its
workers from the calling process when it has no GL context and no other
thread (``glvox batch`` from the command line: ~10 ms, every import
inherited), else starts them from a ``forkserver`` that has imported glvox
once (~0.3 s); it sends each worker several small meshes per message
(:data:`CHUNK_MESHES`, up to :data:`CHUNK_BYTES` of files) and gets one row
back per mesh as it finishes.

Per worker: one process, one GL context and its compiled programs for the
whole batch (:func:`glvox.gl.context.get_context` is per process), llvmpipe's
threads divided among the workers (``LP_NUM_THREADS`` = CPUs / K unless
set), and with ``egl_devices`` one EGL device (``GLVOX_EGL_DEVICE``) per
worker, round robin: on a machine with several GPUs, K workers over D
devices put K / D contexts on each.

Crashes: a worker that dies (segfault, SIGKILL of the out-of-memory killer)
was voxelizing exactly one known mesh (rows come back one by one).  That
mesh is retried once on a fresh worker process; dying again, it is recorded
as :data:`~glvox.batch.cluster.WORKER_CRASHED`.  The rest of the dead
worker's chunk goes back to the queue.
"""

from __future__ import annotations

import multiprocessing as mp
import os
import signal
import threading
from collections import deque
from multiprocessing.connection import wait
from typing import Any, Callable, Sequence

from ..gl.context import any_context
from .cluster import crashed_row
from .jobs import BatchSettings, Job
from .manifest import base_row, now
from .worker import Task

#: Meshes per message to a worker, at most: each message costs a round trip
#: (a fraction of a millisecond), and rows stream back one by one anyway.
CHUNK_MESHES = 16

#: File bytes per message, at most (a single larger mesh goes alone), so
#: large meshes spread over the workers and the last ones finish together.
CHUNK_BYTES = 1 << 20

_forkserver: Any = None


def _mp_context():
    """How workers start: forked from this process when that is safe (one thread, no GL
    context yet), so they inherit every import (glvox, trimesh) in ~10 ms; else from a
    forkserver whose server has imported the batch worker (and so glvox) once."""
    global _forkserver
    if threading.active_count() == 1 and not any_context():
        return mp.get_context("fork")
    if _forkserver is None:
        _forkserver = mp.get_context("forkserver")
        _forkserver.set_forkserver_preload(["glvox.batch.worker"])
    return _forkserver


def lp_threads(workers: int) -> str:
    """llvmpipe threads per worker: the CPUs divided among ``workers`` (at least 1)."""
    return str(max(1, (os.cpu_count() or 1) // max(1, workers)))


def worker_envs(workers: int, egl_devices: Sequence[int] | None = None) -> list[dict[str, str]]:
    """The environment defaults of each worker: llvmpipe's threads and glvox's host threads
    (``GLVOX_THREADS``: :func:`glvox.grid.host_threads`), both :func:`lp_threads`, and an
    EGL device per worker, round robin over ``egl_devices``.  Variables already set win."""
    envs = []
    for i in range(workers):
        env = {"LP_NUM_THREADS": lp_threads(workers), "GLVOX_THREADS": lp_threads(workers)}
        if egl_devices:
            env["GLVOX_EGL_DEVICE"] = str(egl_devices[i % len(egl_devices)])
        envs.append(env)
    return envs


def _serve(conn, task: Task, settings: BatchSettings, env: dict[str, str]) -> None:
    """A worker process: run ``task`` on each job of each message, one row back per job."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl+C is the parent's to handle
    for key, value in env.items():
        os.environ.setdefault(key, value)  # before the first GL call makes the context
    while True:
        try:
            jobs = conn.recv()
        except EOFError:
            return
        if jobs is None:
            return
        for job in jobs:
            try:
                row = task(job, settings)
            except Exception as exc:  # noqa: BLE001 - a task that raises is one failed mesh
                row = base_row(job, settings)
                row.update(status="failed", reason=type(exc).__name__, finished=now(),
                           error=f"the task failed: {exc}")
            conn.send(row)


class _Worker:
    def __init__(self, ctx, task: Task, settings: BatchSettings, env: dict[str, str]):
        self.conn, child = ctx.Pipe()
        self.proc = ctx.Process(target=_serve, args=(child, task, settings, env), daemon=True)
        self.proc.start()
        child.close()
        self.inflight: deque[Job] = deque()

    def send(self, jobs: list[Job]) -> None:
        self.inflight.extend(jobs)
        self.conn.send(jobs)

    def stop(self, timeout: float = 5.0) -> None:
        try:
            self.conn.send(None)
        except OSError:
            pass
        self.proc.join(timeout)
        if self.proc.is_alive():
            self.proc.kill()
            self.proc.join()
        self.conn.close()


def _size(job: Job) -> int:
    try:
        return os.path.getsize(job.input)
    except OSError:
        return 0


def chunks(jobs: Sequence[Job], *, largest_first: bool = False) -> deque[list[Job]]:
    """Jobs in messages of up to :data:`CHUNK_MESHES` meshes and :data:`CHUNK_BYTES` of files
    (``largest_first``: the largest files first, so the workers finish together)."""
    out: deque[list[Job]] = deque()
    cur: list[Job] = []
    size = 0
    sized = [(job, _size(job)) for job in jobs]
    if largest_first:
        sized.sort(key=lambda js: -js[1])
    for job, n in sized:
        if cur and (len(cur) >= CHUNK_MESHES or size + n > CHUNK_BYTES):
            out.append(cur)
            cur, size = [], 0
        cur.append(job)
        size += n
    if cur:
        out.append(cur)
    return out


def run_local(jobs: Sequence[Job], settings: BatchSettings, *, workers: int, task: Task,
              on_result: Callable[[dict], None], egl_devices: Sequence[int] | None = None) -> None:
    """Run ``task`` on every job in ``workers`` local processes, each row to ``on_result``.

    Parameters
    ----------
    jobs, settings, task, on_result
        As :func:`glvox.batch.cluster.run_dask`.
    workers : int
        Worker processes (at least 1).
    egl_devices : sequence of int, optional
        EGL device indices; worker i gets ``GLVOX_EGL_DEVICE = egl_devices[i % len]``.
    """
    ctx = _mp_context()
    queue = chunks(jobs, largest_first=True)
    retries: deque[Job] = deque()
    crashes: dict[str, int] = {}
    envs = worker_envs(workers, egl_devices)
    pool = [_Worker(ctx, task, settings, envs[i]) for i in range(min(workers, len(queue)))]
    try:
        for w in pool:
            w.send(queue.popleft())
        while any(w.inflight for w in pool):
            busy = [w for w in pool if w.inflight]
            ready = set(wait([w.conn for w in busy] + [w.proc.sentinel for w in busy]))
            for i, w in enumerate(pool):
                if w.inflight and (w.conn in ready or w.proc.sentinel in ready) and not _drain(w, on_result):
                    pool[i] = _replace(w, ctx, task, settings, envs[i], crashes, retries, queue, on_result)
            for w in pool:
                if not w.inflight and (retries or queue):
                    # a mesh that killed a worker runs alone, so a second death is its own
                    w.send([retries.popleft()] if retries else queue.popleft())
    finally:
        for w in pool:
            w.stop(timeout=0.0 if w.inflight else 5.0)


def _drain(w: _Worker, on_result) -> bool:
    """Hand on every row ``w`` has sent; False when its process is gone."""
    try:
        while w.inflight and w.conn.poll():
            row = w.conn.recv()
            w.inflight.popleft()
            on_result(row)
    except (EOFError, OSError):
        return False
    return w.proc.is_alive() or not w.inflight


def _replace(dead: _Worker, ctx, task, settings, env, crashes: dict[str, int], retries: deque,
             queue: deque, on_result) -> _Worker:
    """A fresh worker for ``dead``: its current mesh retried or recorded, the rest requeued."""
    dead.proc.join()
    dead.conn.close()
    job = dead.inflight.popleft()
    crashes[job.rel] = crashes.get(job.rel, 0) + 1
    if crashes[job.rel] >= 2:
        on_result(crashed_row(job, settings, f"the worker process exited with code {dead.proc.exitcode}"))
    else:
        retries.append(job)
    if dead.inflight:
        queue.appendleft(list(dead.inflight))
    return _Worker(ctx, task, settings, env)
