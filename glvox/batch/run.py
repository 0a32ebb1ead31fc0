"""The batch: plan, resume, run every job (in this process or on Dask), keep the manifest."""

from __future__ import annotations

import os
import sys
import time
from pathlib import Path
from typing import Any, Callable, Sequence

from ..errors import GlvoxError
from .cluster import run_dask
from .jobs import BatchSettings, Job, mesh_suffixes, plan_jobs
from .manifest import MANIFEST_COLUMNS, BatchSummary, base_row, read_manifest, write_manifest
from ..progress import Progress
from .pool import run_local
from .safety import OutputLock, remove_stale_parts, signals_held
from .worker import Task, voxelize_one

#: Seconds between rewrites of the manifest while a batch runs (at least; a
#: rewrite that takes long pushes the next one further out).
MANIFEST_INTERVAL_S = 5.0


def _plan(source: str | os.PathLike, out_dir: str | os.PathLike, settings: BatchSettings, workers: int,
          suffixes: Sequence[str] | None) -> tuple[Path, list[Job]]:
    """Check the arguments, find the meshes and make the output folder (the only thing written)."""
    # validate() imports the methods and trimesh, whose optional-import guards
    # catch BaseException: an interrupt arriving during those imports would be lost
    with signals_held():
        settings.validate()
        mesh_suffixes()
    if workers < 0:
        raise GlvoxError(f"workers must be 0 (in this process) or more, got {workers}")
    out = Path(out_dir).expanduser().absolute()
    jobs = plan_jobs(source, out, settings.fmt, suffixes=suffixes)
    out.mkdir(parents=True, exist_ok=True)
    return out, jobs


def _start(jobs: Sequence[Job], settings: BatchSettings, out: Path, manifest: Path, overwrite: bool,
           say: Callable[[str], None]) -> tuple[dict[str, dict[str, Any]], list[Job]]:
    """Clean up after an earlier run, write the starting manifest; its rows and the jobs to run."""
    old = {}
    if manifest.is_file():
        old = {r.get("input", ""): r for r in read_manifest(manifest)}
    stale = remove_stale_parts(jobs, out, manifest)
    if stale:
        say(f"removed {stale} unfinished temporary outputs of an earlier run")
    rows, todo = _resume(jobs, settings, old, overwrite, out)
    n_skip = len(jobs) - len(todo)
    if n_skip:
        say(f"{n_skip} of {len(jobs)} meshes already have their output; skipping them")
    write_manifest(manifest, rows.values())
    return rows, todo


def _resume(jobs: Sequence[Job], settings: BatchSettings, old: dict[str, dict[str, str]],
            overwrite: bool, out: Path) -> tuple[dict[str, dict[str, Any]], list[Job]]:
    """The starting rows of every job and the jobs still to run.

    A job whose output exists is ``skipped`` (unless ``overwrite``), keeping
    its finished row of the previous manifest ``old``; every other job is
    ``pending``.  GlvoxError when a kept output was made with other settings.
    """
    params = settings.params()
    rows: dict[str, dict[str, Any]] = {}
    todo: list[Job] = []
    mismatched = []
    for job in jobs:
        if not overwrite and os.path.isfile(job.output):
            prev = old.get(job.rel)
            if prev is not None and prev.get("status") in ("done", "skipped"):
                if prev.get("params") != params:
                    mismatched.append((job.rel, prev.get("params")))
                row = {c: prev.get(c, "") for c in MANIFEST_COLUMNS}
            else:
                row = base_row(job, settings)
            row["status"] = "skipped"
        else:
            row = base_row(job, settings)
            row["status"] = "pending"
            todo.append(job)
        rows[job.rel] = row
    if mismatched:
        rel, was = mismatched[0]
        raise GlvoxError(
            f"{out} holds {len(mismatched)} outputs made with other settings (e.g. {rel}: {was!r}; "
            f"this run: {params!r}); pass --overwrite to redo them or use another output folder")
    return rows, todo


class _Recorder:
    """Takes each finished row into the rows, the progress, and the manifest every few seconds."""

    def __init__(self, rows: dict[str, dict[str, Any]], manifest: Path, out: Path, overwrite: bool,
                 progress: Progress):
        self.rows = rows
        self.manifest = manifest
        self.out = out
        self.overwrite = overwrite
        self.progress = progress
        self.last_write = time.monotonic()
        self.write_s = 0.0
        self.failed = 0

    def __call__(self, row: dict[str, Any]) -> None:
        self.rows[row["input"]] = row
        if self.overwrite and row["status"] == "failed":
            # an output of earlier settings must not pass for this run's on the next one
            (self.out / row["output"]).unlink(missing_ok=True)
        if row["status"] == "failed":
            self.failed += 1
            self.progress.status(f"{self.failed} failed")
        self.progress.update()
        t = time.monotonic()
        if t - self.last_write >= max(MANIFEST_INTERVAL_S, 20 * self.write_s):
            self.write()
            self.last_write = time.monotonic()
            self.write_s = self.last_write - t

    def write(self) -> None:
        write_manifest(self.manifest, self.rows.values())


def _run_in_process(jobs: Sequence[Job], settings: BatchSettings, task: Task,
                    on_result: Callable[[dict], None]) -> None:
    for job in jobs:
        with signals_held():      # Ctrl+C stops after the mesh at hand
            on_result(task(job, settings))


def run_batch(source: str | os.PathLike, out_dir: str | os.PathLike, settings: BatchSettings, *,
              workers: int = 1, scheduler: str | None = None, overwrite: bool = False,
              manifest: str | os.PathLike | None = None, suffixes: Sequence[str] | None = None,
              quiet: bool = False, stream=None, task: Task = voxelize_one,
              egl_devices: Sequence[int] | None = None) -> BatchSummary:
    """Voxelize every mesh of ``source`` into ``out_dir`` (see :mod:`glvox.batch`).

    Parameters
    ----------
    source : path
        Folder (recursive, by suffix) or text file listing mesh paths.
    out_dir : path
        Output folder; outputs mirror the input tree.
    settings : BatchSettings
    workers : int
        Local worker processes (:mod:`glvox.batch.pool`); 0 runs in this
        process.  Ignored with ``scheduler``.
    scheduler : str, optional
        Address of an existing Dask scheduler (``tcp://host:8786``).
    overwrite : bool
        Redo meshes whose output exists.
    manifest : path, optional
        CSV manifest; default ``out_dir/manifest.csv``.
    suffixes : sequence of str, optional
        Mesh suffixes to search a folder for; default :func:`mesh_suffixes`.
    quiet : bool
        No progress and no messages.
    stream : text stream, optional
        Where progress goes; default stderr.
    task : callable, optional
        What handles each mesh: ``task(job, settings)`` returns its manifest
        row (:class:`Job`, :class:`BatchSettings`; a dict with the keys of
        :data:`MANIFEST_COLUMNS`, status ``done`` or ``failed``) and should
        never raise for a bad mesh.  Default :func:`voxelize_one`, what
        ``glvox voxelize`` does.  On a Dask cluster the workers unpickle it
        by module path, so it must be importable there (a module-level
        function, or an instance of a module-level class); it runs on each
        worker's GL thread.  :class:`glvox.testing.crash.CrashingTask` is one.
    egl_devices : sequence of int, optional
        With local workers: EGL device indices handed out round robin, one
        per worker process (``GLVOX_EGL_DEVICE``), for machines with several GPUs.

    Returns
    -------
    BatchSummary
        With ``rows``, the manifest rows.  The manifest is written even when
        the run is interrupted (KeyboardInterrupt propagates after it).
    """
    t_start = time.perf_counter()
    stream = stream if stream is not None else sys.stderr

    def say(msg: str) -> None:
        if not quiet:
            stream.write(f"glvox batch: {msg}\n")
            stream.flush()

    out, jobs = _plan(source, out_dir, settings, workers, suffixes)
    manifest_path = Path(manifest).expanduser().absolute() if manifest else out / "manifest.csv"
    with OutputLock(out):
        rows, todo = _start(jobs, settings, out, manifest_path, overwrite, say)
        progress = Progress(len(todo), unit="mesh", stream=stream, enabled=not quiet)
        record = _Recorder(rows, manifest_path, out, overwrite, progress)
        mode, startup = "in-process", 0.0
        try:
            if todo and scheduler is None and workers == 0:
                _run_in_process(todo, settings, task, record)
            elif todo and scheduler is None:
                mode = f"local cluster ({workers} worker{'s' * (workers != 1)})"
                run_local(todo, settings, workers=workers, task=task, on_result=record, egl_devices=egl_devices)
            elif todo:
                mode, startup = run_dask(todo, settings, workers=workers, scheduler=scheduler,
                                         on_result=record, say=say, task=task)
        finally:
            progress.close()
            record.write()
    return BatchSummary.from_rows(list(rows.values()), elapsed_s=time.perf_counter() - t_start,
                                  manifest=str(manifest_path), mode=mode, startup_s=startup)
