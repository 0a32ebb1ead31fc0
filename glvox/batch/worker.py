"""One mesh of a batch, as a worker runs it: load, voxelize, save, into one manifest row.

A *task* is any function ``task(job, settings) -> row`` that handles one
mesh and returns its manifest row (keys
:data:`~glvox.batch.manifest.MANIFEST_COLUMNS`); :func:`voxelize_one` is the
one glvox runs unless :func:`glvox.batch.run_batch` is given another.
"""

from __future__ import annotations

import os
import socket
import threading
import time
import warnings
from concurrent.futures import ThreadPoolExecutor
from functools import lru_cache
from typing import Any, Callable

from ..errors import GlvoxError
from ..grid import grid_for
from ..inspect import inspect_mesh, uncertain_share
from ..mesh import load_mesh
from ..methods import Request, run_method
from ..visuals import load_visual_mesh
from .atomic import atomic_save
from .jobs import BatchSettings, Job
from .manifest import INSPECT_COLUMNS, base_row, now

#: What handles one mesh: ``task(job, settings)`` returns its manifest row.
Task = Callable[[Job, BatchSettings], dict[str, Any]]

_DOING = {"load": "loading", "voxelize": "voxelizing", "save": "saving", "inspect": "inspecting"}


@lru_cache(maxsize=8)
def _request(settings: BatchSettings) -> Request:
    """The settings' method request, checked once per worker process (not once per mesh)."""
    return settings.request()


def voxelize_one(job: Job, settings: BatchSettings) -> dict[str, Any]:
    """Voxelize one mesh and write its output; never raises for a bad mesh.

    What ``glvox voxelize`` does for one file (load, fit the grid, run the
    method, save), timed, with every failure caught into the returned row.

    Returns
    -------
    dict
        A manifest row (keys :data:`~glvox.batch.manifest.MANIFEST_COLUMNS`),
        status ``done`` or ``failed``.
    """
    row = base_row(job, settings)
    row["worker"] = f"{socket.gethostname()}:{os.getpid()}"
    t0 = time.perf_counter()
    stage = "load"
    marks = {}
    try:
        mesh = load_visual_mesh(job.input) if settings.attributes else load_mesh(job.input)
        row.update(triangles=mesh.n_triangles, degenerate_dropped=mesh.n_degenerate,
                   watertight=mesh.watertight)
        marks["load"] = time.perf_counter()
        stage = "voxelize"
        r = settings.resolution if settings.dims is None and settings.voxel_size is None else None
        spec = grid_for(mesh, r, dims=settings.dims, voxel_size=settings.voxel_size,
                        padding=settings.padding, tight=settings.tight)
        row["dims"] = "x".join(str(d) for d in spec.dims)
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            result = run_method(_request(settings), mesh, spec, backend=settings.backend,
                                allow_open=settings.allow_open)
        run = result.run
        row["method"] = run.method  # an alias (-m solid) records the method it ran
        row["warnings"] = "; ".join(str(w.message) for w in caught)
        row["voxels"] = run.stats.get("voxels", "")
        gpu = run.timings.gpu_s
        row["gpu_s"] = gpu if gpu is not None else ""
        row["cold"] = run.timings.cold
        marks["voxelize"] = time.perf_counter()
        if settings.inspect:  # before the save: a mesh that fails here leaves no output
            stage = "inspect"
            row.update(inspect_row(mesh, spec, result, settings))
            marks["inspect"] = time.perf_counter()
        stage = "save"
        atomic_save(result, job.output)
        marks["save"] = time.perf_counter()
        row["status"] = "done"
    except GlvoxError as exc:
        row.update(status="failed", reason=type(exc).__name__, error=str(exc))
    except Exception as exc:  # noqa: BLE001 - one bad mesh must never stop the batch
        row.update(status="failed", reason=type(exc).__name__,
                   error=f"unexpected {type(exc).__name__} while {_DOING[stage]} {job.rel}: {exc}")
    prev = t0
    for name in ("load", "voxelize", "inspect", "save"):
        if name in marks:
            row[f"{name}_s"] = marks[name] - prev
            prev = marks[name]
    row["total_s"] = time.perf_counter() - t0
    row["finished"] = now()
    return row


def inspect_row(mesh, spec, result, settings: BatchSettings) -> dict[str, Any]:
    """The manifest's ``--inspect`` columns for ``mesh`` (voxelized into ``result`` on
    ``spec``): the report, and the uncertain share on the batch's grid, from the
    result's winding field when the method returned one, else from ``gwn-solid``'s."""
    fields = inspect_mesh(mesh).to_dict()
    row = {c: fields[c] for c in INSPECT_COLUMNS if fields.get(c) is not None}
    w = getattr(result, "fields", {}).get("winding")
    threshold = result.run.options.get("threshold", 0.5) if w is not None else 0.5
    if w is None:
        w = run_method("gwn-solid", mesh, spec, backend=settings.backend, winding=True).fields["winding"]
    row["uncertain_share"] = uncertain_share(w, threshold)[1]
    return row


_gl_lock = threading.Lock()
_gl_executor: ThreadPoolExecutor | None = None


def _gl_thread() -> ThreadPoolExecutor:
    """The one thread of this process that makes GL calls.

    A GL context is current in the thread that created it; Dask may run
    successive tasks on different threads of its pool, so every task hands its
    work to this thread instead.
    """
    global _gl_executor
    with _gl_lock:
        if _gl_executor is None:
            _gl_executor = ThreadPoolExecutor(max_workers=1, thread_name_prefix="glvox-gl")
        return _gl_executor


def dask_task(job: Job, settings: BatchSettings, task: Task = voxelize_one) -> dict[str, Any]:
    """The Dask task of one mesh: ``task(job, settings)`` on this worker's GL thread."""
    return _gl_thread().submit(task, job, settings).result()
