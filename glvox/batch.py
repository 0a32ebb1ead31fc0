"""Dataset-scale batch voxelization: ``glvox batch``.

Every mesh of a folder (searched recursively by suffix) or of a text file
listing mesh paths is voxelized with the same method and grid options, and
written under an output folder that mirrors the input tree::

    glvox batch shapenet/ -o voxels/ -r 128 -m ss-solid --format binvox --workers 2

Each mesh goes through exactly what ``glvox voxelize MESH -r N -m METHOD -o
OUT`` does (:func:`glvox.mesh.load_mesh`, :func:`glvox.grid_for`,
:func:`glvox.methods.run_method`, :func:`glvox.io.save`), so a batch output
holds the same occupancy, origin, voxel size, method and kind as the
single-file command's (binvox files are byte-identical).

Execution
---------
Workers are processes of a Dask distributed cluster, one thread each, so each
worker has its own GL context (:func:`glvox.context.get_context` is per
process, and a GL context is never shared across processes).  Inside a worker
every GL call runs on one dedicated thread, the one that made the context
current.  Without ``scheduler`` a :class:`distributed.LocalCluster` of
``workers`` processes is started and closed; with ``scheduler`` the batch runs
on that existing cluster (its workers need glvox installed and the input and
output folders at the same paths).  ``workers=0`` runs in the calling process
without Dask: no start-up cost, but no crash isolation.

Resume and safety
-----------------
Outputs are written to a hidden temporary file in their folder
(``.NAME.part-PID-RANDOM.SUFFIX``) and renamed over the final name
(:func:`os.replace`), so a file with the final name is always complete.  A
rerun skips meshes whose output exists (unless ``overwrite``), and deletes
the temporary files a killed run left behind.  The manifest (CSV, one row per
mesh, :data:`MANIFEST_COLUMNS`) is rewritten atomically at start, every few
seconds and at the end; a rerun refuses to mix outputs of different settings
(method, grid, options) in one folder.  A lock file keeps two batches from
writing into the same output folder at once.

Failures
--------
A mesh that cannot be voxelized (unreadable, empty, NaN vertices, open for a
solid method, ...) is recorded as ``failed`` with the glvox error class as the
reason (``MeshLoadError``, ``EmptyMeshError``, ``NonFiniteVertexError``,
``FaceIndexError``, ``NotWatertightError``, ...) and the error message, and
the batch goes on.  A mesh whose worker process dies (segfault, out of
memory) is retried once on a fresh worker and then recorded with the reason
``WorkerCrashed`` (on a local cluster; an external scheduler applies its own
``distributed.scheduler.allowed-failures``).
"""

from __future__ import annotations

import contextlib
import csv
import io as _io
import os
import signal
import socket
import sys
import threading
import time
import uuid
import warnings
from collections import Counter
from dataclasses import dataclass, field
from datetime import datetime, timezone
from pathlib import Path
from typing import Any, Callable, Iterable, Sequence

from .errors import GlvoxError, GridError, MeshLoadError, MethodError

#: Columns of the manifest, in order.
MANIFEST_COLUMNS = (
    "input",               # mesh path relative to the input root (POSIX separators)
    "output",              # output path relative to the output folder
    "status",              # done | skipped | failed | pending
    "reason",              # failed: glvox error class (MeshLoadError, ...) or WorkerCrashed
    "error",               # failed: the error message
    "triangles",           # non-degenerate triangles of the mesh
    "degenerate_dropped",  # zero-area triangles dropped on load
    "watertight",          # true / false, as trimesh judges it
    "voxels",              # set voxels of the result
    "dims",                # grid dims, NXxNYxNZ
    "method",              # registry name
    "params",              # the settings as command-line arguments (resume checks them)
    "load_s",              # wall seconds: read and validate the mesh
    "voxelize_s",          # wall seconds: the method (all its stages)
    "gpu_s",               # GPU seconds from timestamp queries (GL methods)
    "save_s",              # wall seconds: write, fsync and rename the output
    "total_s",             # wall seconds for this mesh in its worker
    "cold",                # true when the run compiled shaders (first mesh of a worker)
    "worker",              # host:pid of the process that voxelized it
    "glvox_version",
    "finished",            # UTC time the row was made, ISO 8601
    "warnings",            # warnings the method raised (e.g. NotWatertightWarning), '; '-joined
)

#: Kinds of result that :func:`glvox.io.save` writes.
SAVED_KINDS = ("surface", "solid", "sparse")

#: Reasons that are not glvox error classes.
WORKER_CRASHED = "WorkerCrashed"

#: Suffixes of point clouds and other non-mesh formats trimesh reads; never batch inputs.
_NOT_MESH_FORMATS = {"xyz", "stl_ascii"}

#: Seconds between rewrites of the manifest while a batch runs (at least; a
#: rewrite that takes long pushes the next one further out).
MANIFEST_INTERVAL_S = 5.0

#: Seconds between progress lines when stderr is not a terminal.
LOG_INTERVAL_S = 10.0

#: The lock file in the output folder.
LOCK_NAME = ".glvox-batch.lock"

_PART = ".part-"

# Test hooks: a Dask task whose input path contains the substring in
# _GLVOX_BATCH_TEST_CRASH kills its own worker process (SIGKILL, as the OOM
# killer would), after appending the path to the file _GLVOX_BATCH_TEST_CRASH_LOG.
_CRASH_ENV = "_GLVOX_BATCH_TEST_CRASH"
_CRASH_LOG_ENV = "_GLVOX_BATCH_TEST_CRASH_LOG"


def mesh_suffixes() -> tuple[str, ...]:
    """File suffixes (with the dot, lower case) of the mesh formats trimesh can load here."""
    from trimesh.exchange.load import mesh_formats

    return tuple(sorted(f".{f}" for f in mesh_formats() if f not in _NOT_MESH_FORMATS))


# ---------------------------------------------------------------------------
# settings and jobs
# ---------------------------------------------------------------------------


@dataclass(frozen=True)
class BatchSettings:
    """What every mesh of a batch is voxelized with (the arguments of ``glvox voxelize``).

    Attributes
    ----------
    method : str
        Registry name.
    resolution : int, optional
        N: voxels along the longest axis (cubic N^3 grid), unless ``dims`` or
        ``voxel_size`` is given.
    dims : (3,) int, optional
    voxel_size : float, optional
        World units.
    padding : int
    tight : bool
    options : tuple of (str, str)
        Method options, as ``-O KEY=VALUE`` gives them.
    allow_open : bool
        Let solid methods run on meshes that are not watertight.
    backend : str, optional
        ``'egl'``, ``'osmesa'`` or ``'auto'``.
    fmt : {'npz', 'binvox'}
        Output format.
    """

    method: str
    resolution: int | None = None
    dims: tuple[int, int, int] | None = None
    voxel_size: float | None = None
    padding: int = 0
    tight: bool = False
    options: tuple[tuple[str, str], ...] = ()
    allow_open: bool = False
    backend: str | None = None
    fmt: str = "npz"

    def validate(self) -> None:
        """Refuse unknown methods, options, formats and grid arguments before any work."""
        from .methods import get_method, validate_options

        if self.fmt not in ("npz", "binvox"):
            raise GlvoxError(f"output format must be 'npz' or 'binvox', got {self.fmt!r}")
        if self.resolution is None and self.dims is None and self.voxel_size is None:
            raise GridError("give -r/--resolution N, --dims NX NY NZ or --voxel-size H")
        info = get_method(self.method).info
        if info.kind not in SAVED_KINDS:
            raise MethodError(f"glvox batch writes voxel grids (npz, binvox), and {self.method!r} returns "
                              f"a result of kind {info.kind!r}, which glvox cannot save; use a method of "
                              f"kind {', '.join(SAVED_KINDS)}")
        validate_options(info, dict(self.options))

    def params(self) -> str:
        """The settings as ``glvox voxelize`` arguments; equal strings mean equal outputs."""
        parts = [f"-m {self.method}"]
        if self.dims is not None:
            parts.append("--dims " + " ".join(str(d) for d in self.dims))
        elif self.voxel_size is not None:
            parts.append(f"--voxel-size {self.voxel_size!r}")
        else:
            parts.append(f"-r {self.resolution}")
        if self.padding:
            parts.append(f"--padding {self.padding}")
        if self.tight:
            parts.append("--tight")
        parts += [f"-O {k}={v}" for k, v in sorted(self.options)]
        if self.allow_open:
            parts.append("--allow-open")
        parts.append(f"--format {self.fmt}")
        return " ".join(parts)


@dataclass(frozen=True)
class Job:
    """One mesh of a batch.

    Attributes
    ----------
    input : str
        Absolute path of the mesh file.
    rel : str
        Its path relative to the input root, POSIX separators (the manifest key).
    output : str
        Absolute path of the output file.
    out_rel : str
        Its path relative to the output folder.
    """

    input: str
    rel: str
    output: str
    out_rel: str


def _is_hidden(name: str) -> bool:
    # dot files include our own temporary outputs and macOS "._x.obj" resource forks
    return name.startswith(".")


def find_meshes(source: str | os.PathLike, *, suffixes: Sequence[str] | None = None,
                exclude: str | os.PathLike | None = None) -> tuple[Path, list[Path]]:
    """The mesh files of a batch input and the root their outputs mirror.

    Parameters
    ----------
    source : path
        A folder, searched recursively (hidden files and folders skipped) for
        files whose suffix is in ``suffixes``; or a text file with one mesh
        path per line (blank lines and lines starting with ``#`` ignored,
        relative paths relative to the list's folder), taken as listed.
    suffixes : sequence of str, optional
        Suffixes with or without the dot, case-insensitive; default
        :func:`mesh_suffixes`.  Ignored for a list file.
    exclude : path, optional
        A folder not to search (the output folder when it lies inside the input).

    Returns
    -------
    root : Path
        The input folder, or the deepest folder holding every listed mesh.
    meshes : list of Path
        Absolute paths, sorted (folder) or in list order, without duplicates.

    Raises
    ------
    MeshLoadError
        When ``source`` does not exist, is itself a mesh file, or holds no mesh.
    """
    src = Path(source).expanduser().absolute()
    wanted = tuple(s.lower() if s.startswith(".") else "." + s.lower()
                   for s in (suffixes or mesh_suffixes()))
    if src.is_dir():
        skip = Path(exclude).absolute() if exclude is not None else None
        found: list[Path] = []
        for dirpath, dirnames, filenames in os.walk(src):
            here = Path(dirpath)
            dirnames[:] = sorted(d for d in dirnames
                                 if not _is_hidden(d) and (skip is None or here / d != skip))
            found += [here / f for f in sorted(filenames)
                      if not _is_hidden(f) and f.lower().endswith(wanted)]
        if not found:
            raise MeshLoadError(f"no mesh files (suffixes {' '.join(wanted)}) under {src}")
        return src, found
    if not src.exists():
        raise MeshLoadError(f"batch input not found: {src} (expected a folder or a text file of mesh paths)")
    if src.name.lower().endswith(mesh_suffixes()):
        raise MeshLoadError(f"{src} is a mesh file; glvox batch takes a folder or a text file listing "
                            "mesh paths (use glvox voxelize for one mesh)")
    try:
        lines = src.read_text().splitlines()
    except (OSError, UnicodeDecodeError) as exc:
        raise MeshLoadError(f"cannot read the mesh list {src}: {exc}") from None
    meshes, seen = [], set()
    for ln in lines:
        ln = ln.strip()
        if not ln or ln.startswith("#"):
            continue
        p = Path(ln).expanduser()
        p = Path(os.path.normpath(p if p.is_absolute() else src.parent / p))
        if p not in seen:
            seen.add(p)
            meshes.append(p)
    if not meshes:
        raise MeshLoadError(f"the mesh list {src} names no file")
    root = Path(os.path.commonpath([str(p.parent) for p in meshes]))
    return root, meshes


def plan_jobs(source: str | os.PathLike, out_dir: str | os.PathLike, fmt: str = "npz", *,
              suffixes: Sequence[str] | None = None) -> list[Job]:
    """The jobs of a batch: each mesh and its output path, mirroring the input tree.

    ``chairs/a/model.obj`` under the input root goes to ``OUT/chairs/a/model.npz``.
    Meshes of one folder that differ only by suffix (``a.obj``, ``a.stl``) keep
    it: ``a.obj.npz``, ``a.stl.npz``.
    """
    out = Path(out_dir).expanduser().absolute()
    root, meshes = find_meshes(source, suffixes=suffixes, exclude=out)
    suffix = "." + fmt
    rels = [p.relative_to(root) for p in meshes]
    plain = [r.with_suffix(suffix) for r in rels]
    counts = Counter(plain)
    outs = [q if counts[q] == 1 else r.with_name(r.name + suffix) for r, q in zip(rels, plain)]
    clash = [str(o) for o, n in Counter(outs).items() if n > 1]
    if clash:
        raise GlvoxError(f"several meshes would be written to the same output: {', '.join(sorted(clash)[:5])}")
    return [Job(input=str(p), rel=r.as_posix(), output=str(out / o), out_rel=o.as_posix())
            for p, r, o in zip(meshes, rels, outs)]


# ---------------------------------------------------------------------------
# one mesh (runs in a worker)
# ---------------------------------------------------------------------------


def _now() -> str:
    return datetime.now(timezone.utc).isoformat(timespec="seconds")


def _base_row(job: Job, settings: BatchSettings) -> dict[str, Any]:
    from . import __version__

    row = {c: "" for c in MANIFEST_COLUMNS}
    row.update(input=job.rel, output=job.out_rel, method=settings.method, params=settings.params(),
               glvox_version=__version__)
    return row


def _temp_path(out: Path) -> Path:
    # same folder (os.replace is atomic only within one file system), same
    # suffix (io.save picks the format by it; numpy would append .npz otherwise)
    return out.with_name(f".{out.name}{_PART}{os.getpid()}-{uuid.uuid4().hex[:8]}{out.suffix}")


def atomic_save(result, out: str | os.PathLike) -> Path:
    """Write ``result`` with :func:`glvox.io.save` to a temporary file, then rename it to ``out``.

    The file is flushed to disk before the rename, so ``out`` either does not
    exist or is complete, whatever kills the process.
    """
    from . import io

    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = _temp_path(out)
    try:
        io.save(result, tmp)
        with open(tmp, "rb+") as f:
            os.fsync(f.fileno())
        os.replace(tmp, out)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    return out


_DOING = {"load": "loading", "voxelize": "voxelizing", "save": "saving"}


def voxelize_one(job: Job, settings: BatchSettings) -> dict[str, Any]:
    """Voxelize one mesh and write its output; never raises for a bad mesh.

    What ``glvox voxelize`` does for one file (load, fit the grid, run the
    method, save), timed, with every failure caught into the returned row.

    Returns
    -------
    dict
        A manifest row (keys :data:`MANIFEST_COLUMNS`), status ``done`` or ``failed``.
    """
    from .grid import grid_for
    from .mesh import load_mesh
    from .methods import run_method

    row = _base_row(job, settings)
    row["worker"] = f"{socket.gethostname()}:{os.getpid()}"
    t0 = time.perf_counter()
    stage = "load"
    marks = {}
    try:
        mesh = load_mesh(job.input)
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
            result = run_method(settings.method, mesh, spec, backend=settings.backend,
                                allow_open=settings.allow_open, **dict(settings.options))
        run = result.run
        row["warnings"] = "; ".join(str(w.message) for w in caught)
        row["voxels"] = run.stats.get("voxels", "")
        gpu = run.timings.gpu_s
        row["gpu_s"] = gpu if gpu is not None else ""
        row["cold"] = run.timings.cold
        marks["voxelize"] = time.perf_counter()
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
    for name in ("load", "voxelize", "save"):
        if name in marks:
            row[f"{name}_s"] = marks[name] - prev
            prev = marks[name]
    row["total_s"] = time.perf_counter() - t0
    row["finished"] = _now()
    return row


_gl_lock = threading.Lock()
_gl_executor = None


def _gl_thread():
    """The one thread of this process that makes GL calls.

    A GL context is current in the thread that created it; Dask may run
    successive tasks on different threads of its pool, so every task hands its
    work to this thread instead.
    """
    global _gl_executor
    with _gl_lock:
        if _gl_executor is None:
            from concurrent.futures import ThreadPoolExecutor

            _gl_executor = ThreadPoolExecutor(max_workers=1, thread_name_prefix="glvox-gl")
        return _gl_executor


def _crash_hook(job: Job) -> None:
    token = os.environ.get(_CRASH_ENV)
    if token and token in job.input:
        log = os.environ.get(_CRASH_LOG_ENV)
        if log:
            with open(log, "a") as f:
                f.write(f"{job.rel} {os.getpid()}\n")
        os.kill(os.getpid(), signal.SIGKILL)


def dask_task(job: Job, settings: BatchSettings) -> dict[str, Any]:
    """The Dask task of one mesh: :func:`voxelize_one` on this worker's GL thread."""
    _crash_hook(job)
    return _gl_thread().submit(voxelize_one, job, settings).result()


# ---------------------------------------------------------------------------
# manifest
# ---------------------------------------------------------------------------


def _cell(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, float):
        return f"{v:.6g}"
    return str(v)


def write_manifest(path: str | os.PathLike, rows: Iterable[dict[str, Any]]) -> Path:
    """Write manifest rows as CSV (columns :data:`MANIFEST_COLUMNS`), atomically."""
    path = Path(path)
    buf = _io.StringIO()
    w = csv.DictWriter(buf, fieldnames=MANIFEST_COLUMNS, extrasaction="ignore", lineterminator="\n")
    w.writeheader()
    for r in rows:
        w.writerow({c: _cell(r.get(c, "")) for c in MANIFEST_COLUMNS})
    tmp = _temp_path(path)
    try:
        with open(tmp, "w", newline="") as f:
            f.write(buf.getvalue())
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    return path


def read_manifest(path: str | os.PathLike) -> list[dict[str, str]]:
    """Rows of a manifest written by :func:`write_manifest` (all values strings)."""
    path = Path(path)
    try:
        with open(path, newline="") as f:
            return list(csv.DictReader(f))
    except (OSError, UnicodeDecodeError, csv.Error) as exc:
        raise GlvoxError(f"cannot read the batch manifest {path}: {exc}") from None


# ---------------------------------------------------------------------------
# progress and summary
# ---------------------------------------------------------------------------


def _hms(seconds: float) -> str:
    s = int(round(seconds))
    return f"{s // 3600}:{s % 3600 // 60:02d}:{s % 60:02d}"


class Progress:
    """Progress of a batch on a text stream: a bar with rate and ETA on a
    terminal (redrawn at most 10 times a second), a plain line every
    ``log_interval`` seconds otherwise, nothing when disabled."""

    def __init__(self, total: int, *, stream=None, enabled: bool = True, tty: bool | None = None,
                 log_interval: float = LOG_INTERVAL_S, clock: Callable[[], float] = time.monotonic):
        self.total = total
        self.stream = stream if stream is not None else sys.stderr
        self.enabled = enabled and total > 0
        self.tty = bool(tty if tty is not None else getattr(self.stream, "isatty", lambda: False)())
        self.log_interval = log_interval
        self.clock = clock
        self.t0 = clock()
        self.done = 0
        self.failed = 0
        self._last = self.t0

    def line(self) -> str:
        """``57/200  28% |#####       |  9.8 mesh/s  ETA 0:00:15  2 failed``."""
        elapsed = self.clock() - self.t0
        rate = self.done / elapsed if elapsed > 0 else 0.0
        frac = self.done / self.total if self.total else 1.0
        eta = _hms((self.total - self.done) / rate) if rate > 0 else "?"
        width = 24
        bar = "#" * int(frac * width)
        return (f"{self.done}/{self.total} {frac:4.0%} |{bar:<{width}}| {rate:5.1f} mesh/s  "
                f"ETA {eta}  {self.failed} failed")

    def update(self, row: dict[str, Any]) -> None:
        self.done += 1
        self.failed += row.get("status") == "failed"
        if not self.enabled:
            return
        now = self.clock()
        final = self.done == self.total
        if self.tty and (now - self._last >= 0.1 or final):
            self.stream.write("\r\x1b[2K" + self.line())
            self.stream.flush()
            self._last = now
        elif not self.tty and (now - self._last >= self.log_interval or final):
            self.stream.write(f"[{now - self.t0:8.1f} s] {self.line()}\n")
            self.stream.flush()
            self._last = now

    def close(self) -> None:
        if self.enabled and self.tty:
            self.stream.write("\n")
            self.stream.flush()


@dataclass
class BatchSummary:
    """The outcome of a batch.

    Attributes
    ----------
    total : int
        Meshes in the batch.
    done, skipped, failed, pending : int
        Rows of each status (``pending``: not finished, after an interruption).
    failed_by_reason : dict of str to int
    elapsed_s : float
        Wall seconds of the whole run, start-up included.
    processed_per_s : float
        Meshes voxelized or failed (not skipped) per second of ``elapsed_s``.
    manifest : str
    mode : str
        ``'in-process'``, ``'local cluster (K workers)'`` or ``'scheduler ADDRESS'``.
    startup_s : float
        Seconds to get the workers (cluster start or connection).
    """

    total: int
    done: int
    skipped: int
    failed: int
    pending: int
    failed_by_reason: dict[str, int]
    elapsed_s: float
    processed_per_s: float
    manifest: str
    mode: str
    startup_s: float = 0.0
    rows: list[dict[str, Any]] = field(default_factory=list, repr=False)

    def to_dict(self) -> dict[str, Any]:
        return {k: getattr(self, k) for k in ("total", "done", "skipped", "failed", "pending",
                                              "failed_by_reason", "elapsed_s", "processed_per_s",
                                              "manifest", "mode", "startup_s")}

    def format(self) -> str:
        lines = [f"{self.total} meshes in {self.elapsed_s:.1f} s ({self.mode}, start-up "
                 f"{self.startup_s:.1f} s): {self.processed_per_s:.2f} meshes/s",
                 f"  done {self.done}, skipped {self.skipped}, failed {self.failed}"
                 + (f", not finished {self.pending}" if self.pending else "")]
        if self.failed_by_reason:
            lines.append("  failed by reason: " + ", ".join(
                f"{k} {v}" for k, v in sorted(self.failed_by_reason.items(), key=lambda kv: (-kv[1], kv[0]))))
        lines.append(f"  manifest: {self.manifest}")
        return "\n".join(lines)


# ---------------------------------------------------------------------------
# the batch
# ---------------------------------------------------------------------------


class _OutputLock:
    """An exclusive lock on the output folder, released when the process ends however it ends."""

    def __init__(self, out: Path):
        self.path = out / LOCK_NAME
        self.f = None

    def __enter__(self):
        try:
            import fcntl
        except ImportError:  # not POSIX: no lock
            return self
        self.f = open(self.path, "a+")
        try:
            fcntl.flock(self.f.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            self.f.close()
            self.f = None
            raise GlvoxError(f"another glvox batch is writing into {self.path.parent} "
                             f"(it holds {self.path}); wait for it or use another output folder") from None
        return self

    def __exit__(self, *exc):
        if self.f is not None:
            self.f.close()
            self.f = None


def _remove_stale_parts(jobs: Sequence[Job], out: Path, manifest: Path) -> int:
    """Delete the temporary files a killed run left: outputs in the output
    folders, and the manifest's own in its folder."""
    n = 0
    folders = {Path(j.output).parent for j in jobs} | {out}
    for folder in sorted(folders | {manifest.parent}):
        if not folder.is_dir():
            continue
        ours = folder in folders
        for entry in os.scandir(folder):
            name = entry.name
            if (name.startswith(f".{manifest.name}{_PART}") if not ours
                    else name.startswith(".") and _PART in name) and entry.is_file():
                os.unlink(entry.path)
                n += 1
    return n


def _crashed_row(job: Job, settings: BatchSettings, exc: BaseException) -> dict[str, Any]:
    row = _base_row(job, settings)
    last = getattr(exc, "last_worker", None)
    where = f"; the last worker was {last.address}" if getattr(last, "address", None) else ""
    row.update(status="failed", reason=WORKER_CRASHED, finished=_now(),
               error=f"worker crashed: the worker process died while voxelizing {job.rel}, and again on "
                     f"the retry (a crash in a library, or out of memory){where}")
    return row


@contextlib.contextmanager
def _signals_held():
    """Hold SIGINT and SIGTERM while a Dask cluster starts, and act on them right after.

    Used around whatever an interrupt must not cut in two: a LocalCluster
    interrupted half-way through its start cannot be closed (distributed
    prints a traceback at exit); imports and mesh loaders that catch
    BaseException would swallow the interrupt or record it as a bad mesh.  A
    second signal interrupts at once.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    got: list[int] = []

    def hold(signum, frame):
        if got:
            raise KeyboardInterrupt
        got.append(signum)

    previous = {s: signal.signal(s, hold) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield
    finally:
        for s, h in previous.items():
            signal.signal(s, h)
    if got:
        raise KeyboardInterrupt


def _run_dask(jobs: Sequence[Job], settings: BatchSettings, workers: int, scheduler: str | None,
              on_result: Callable[[dict], None], say: Callable[[str], None]) -> tuple[str, float]:
    import logging

    # an interrupt during these imports can be swallowed by an import guard in a dependency
    with _signals_held():
        try:
            import dask
            from distributed import Client, LocalCluster, as_completed
            from distributed.scheduler import KilledWorker
        except ImportError:
            raise GlvoxError("glvox batch runs its workers with Dask distributed, which is not installed: "
                             "pip install 'glvox[batch]' (or run in this process with --workers 0)") from None

    t0 = time.perf_counter()
    cluster = client = None
    # allowed-failures 1: a task whose worker dies is retried once, then
    # KilledWorker.  worker-saturation 1.0: a worker holds only the task it
    # runs, so a crash does not count against a task merely queued behind it.
    config = {"distributed.scheduler.allowed-failures": 1,
              "distributed.scheduler.worker-saturation": 1.0}
    try:
        with dask.config.set(config), _signals_held():
            if scheduler:
                mode = f"scheduler {scheduler}"
                try:
                    client = Client(scheduler, timeout="30s")
                except (OSError, TimeoutError) as exc:
                    raise GlvoxError(f"cannot connect to the Dask scheduler at {scheduler}: {exc}") from None
            else:
                mode = f"local cluster ({workers} worker{'s' * (workers != 1)})"
                say(f"starting a local Dask cluster of {workers} worker processes")
                cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                                       dashboard_address=None, silence_logs=logging.CRITICAL)
                client = Client(cluster)
        startup = time.perf_counter() - t0
        token = uuid.uuid4().hex[:8]
        keys = [f"glvox-batch-{token}-{i}" for i in range(len(jobs))]
        by_key = dict(zip(keys, jobs))
        futures = client.map(dask_task, list(jobs), settings=settings, key=keys, pure=False)
        for fut in as_completed(futures):
            job = by_key[fut.key]
            try:
                row = fut.result()
            except KilledWorker as exc:
                row = _crashed_row(job, settings, exc)
            except Exception as exc:  # noqa: BLE001 - a lost task is one failed mesh
                row = _base_row(job, settings)
                row.update(status="failed", reason=type(exc).__name__, finished=_now(),
                           error=f"the Dask task failed: {exc}")
            fut.release()
            on_result(row)
        return mode, startup
    finally:
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


def run_batch(source: str | os.PathLike, out_dir: str | os.PathLike, settings: BatchSettings, *,
              workers: int = 1, scheduler: str | None = None, overwrite: bool = False,
              manifest: str | os.PathLike | None = None, suffixes: Sequence[str] | None = None,
              quiet: bool = False, stream=None) -> BatchSummary:
    """Voxelize every mesh of ``source`` into ``out_dir`` (see the module docstring).

    Parameters
    ----------
    source : path
        Folder (recursive, by suffix) or text file listing mesh paths.
    out_dir : path
        Output folder; outputs mirror the input tree.
    settings : BatchSettings
    workers : int
        Worker processes of the local Dask cluster; 0 runs in this process
        without Dask.  Ignored with ``scheduler``.
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

    # validate() imports the methods and trimesh, whose optional-import guards
    # catch BaseException: an interrupt arriving during those imports would be lost
    with _signals_held():
        settings.validate()
        mesh_suffixes()
    if workers < 0:
        raise GlvoxError(f"workers must be 0 (in this process) or more, got {workers}")
    out = Path(out_dir).expanduser().absolute()
    jobs = plan_jobs(source, out, settings.fmt, suffixes=suffixes)
    out.mkdir(parents=True, exist_ok=True)
    manifest_path = Path(manifest).expanduser().absolute() if manifest else out / "manifest.csv"
    with _OutputLock(out):
        old = {}
        if manifest_path.is_file():
            old = {r.get("input", ""): r for r in read_manifest(manifest_path)}
        stale = _remove_stale_parts(jobs, out, manifest_path)
        if stale:
            say(f"removed {stale} unfinished temporary outputs of an earlier run")
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
                    row = _base_row(job, settings)
                row["status"] = "skipped"
                rows[job.rel] = row
            else:
                row = _base_row(job, settings)
                row["status"] = "pending"
                rows[job.rel] = row
                todo.append(job)
        if mismatched:
            rel, was = mismatched[0]
            raise GlvoxError(
                f"{out} holds {len(mismatched)} outputs made with other settings (e.g. {rel}: {was!r}; "
                f"this run: {params!r}); pass --overwrite to redo them or use another output folder")
        n_skip = len(jobs) - len(todo)
        if n_skip:
            say(f"{n_skip} of {len(jobs)} meshes already have their output; skipping them")
        write_manifest(manifest_path, rows.values())

        progress = Progress(len(todo), stream=stream, enabled=not quiet)
        last_write = [time.monotonic(), 0.0]

        def on_result(row: dict[str, Any]) -> None:
            rows[row["input"]] = row
            if overwrite and row["status"] == "failed":
                # an output of earlier settings must not pass for this run's on the next one
                (out / row["output"]).unlink(missing_ok=True)
            progress.update(row)
            now = time.monotonic()
            if now - last_write[0] >= max(MANIFEST_INTERVAL_S, 20 * last_write[1]):
                write_manifest(manifest_path, rows.values())
                last_write[:] = [time.monotonic(), time.monotonic() - now]

        mode, startup = "in-process", 0.0
        try:
            if todo and scheduler is None and workers == 0:
                for job in todo:
                    with _signals_held():      # Ctrl+C stops after the mesh at hand
                        on_result(voxelize_one(job, settings))
            elif todo:
                mode, startup = _run_dask(todo, settings, workers, scheduler, on_result, say)
        finally:
            progress.close()
            write_manifest(manifest_path, rows.values())
    status = Counter(r["status"] for r in rows.values())
    elapsed = time.perf_counter() - t_start
    processed = status["done"] + status["failed"]
    return BatchSummary(
        total=len(jobs), done=status["done"], skipped=status["skipped"], failed=status["failed"],
        pending=status["pending"],
        failed_by_reason=dict(Counter(r["reason"] for r in rows.values() if r["status"] == "failed")),
        elapsed_s=elapsed, processed_per_s=processed / elapsed if elapsed > 0 else 0.0,
        manifest=str(manifest_path), mode=mode, startup_s=startup, rows=list(rows.values()))


# ---------------------------------------------------------------------------
# a synthetic dataset (tests and compare/bench_batch.py)
# ---------------------------------------------------------------------------

#: Broken files of :func:`synthetic_dataset` and the reason glvox gives for each.
BROKEN = {
    "broken/truncated.stl": "MeshLoadError",       # binary STL cut in half (glvox checks the size)
    "broken/garbage.ply": "MeshLoadError",         # random bytes
    "broken/garbage.obj": "EmptyMeshError",        # random bytes: no 'v' / 'f' lines
    "broken/empty.obj": "EmptyMeshError",          # 0 bytes
    "broken/nan.obj": "NonFiniteVertexError",      # a NaN coordinate
    "broken/bad_index.off": "MeshLoadError",       # a face index past the vertices
    "broken/degenerate.obj": "EmptyMeshError",     # one zero-area triangle
}


def synthetic_dataset(root: str | os.PathLike, n: int = 200, *, seed: int = 0,
                      broken: bool = True) -> dict[str, dict[str, Any]]:
    """Write a dataset of small meshes for batch tests and measurements.

    ``n`` meshes (boxes, icospheres, tori, cylinders, capsules, noisy blobs;
    random sizes, rotations, offsets; a few open boxes with one face removed)
    in nested folders, with suffixes .stl .obj .ply .off in turn; plus, with
    ``broken``, the files of :data:`BROKEN`, a text file and a hidden mesh
    that a folder search must ignore.

    Returns
    -------
    dict
        Path relative to ``root`` (POSIX) -> ``{"kind": str, "watertight": bool,
        "broken": reason or None}`` for every file a batch should pick up.
    """
    import numpy as np
    import trimesh

    root = Path(root)
    rng = np.random.default_rng(seed)
    suffixes = (".stl", ".obj", ".ply", ".off")
    kinds = ("box", "sphere", "torus", "cylinder", "capsule", "blob", "open_box")
    files: dict[str, dict[str, Any]] = {}
    for i in range(n):
        kind = kinds[i % len(kinds)]
        if kind in ("box", "open_box"):
            m = trimesh.creation.box(extents=rng.uniform(0.2, 2.0, 3))
        elif kind == "sphere":
            m = trimesh.creation.icosphere(subdivisions=int(rng.integers(1, 4)), radius=rng.uniform(0.3, 2))
        elif kind == "torus":
            m = trimesh.creation.torus(major_radius=1.0, minor_radius=rng.uniform(0.1, 0.5),
                                       major_sections=int(rng.integers(12, 40)), minor_sections=12)
        elif kind == "cylinder":
            m = trimesh.creation.cylinder(radius=rng.uniform(0.1, 1), height=rng.uniform(0.5, 3),
                                          sections=int(rng.integers(8, 40)))
        elif kind == "capsule":
            m = trimesh.creation.capsule(radius=rng.uniform(0.1, 0.8), height=rng.uniform(0.2, 2),
                                         count=[12, 12])
        else:
            m = trimesh.creation.icosphere(subdivisions=3)
            m.vertices *= (1 + 0.25 * rng.standard_normal(len(m.vertices)))[:, None].clip(0.5, 1.6)
        if kind == "open_box":
            m = trimesh.Trimesh(m.vertices, m.faces[2:], process=False)
        rot = trimesh.transformations.random_rotation_matrix(rng.random(3))
        rot[:3, 3] = rng.uniform(-5, 5, 3) * (1000 if i % 50 == 7 else 1)
        m.apply_transform(rot)
        rel = f"group{i % 4}/sub{i % 3}/{kind}_{i:04d}{suffixes[i % len(suffixes)]}"
        (root / rel).parent.mkdir(parents=True, exist_ok=True)
        m.export(root / rel)
        files[rel] = {"kind": kind, "watertight": kind != "open_box", "broken": None}
    if broken:
        b = root / "broken"
        b.mkdir(parents=True, exist_ok=True)
        stl = trimesh.creation.box().export(file_type="stl")
        (b / "truncated.stl").write_bytes(stl[:len(stl) // 2])
        (b / "garbage.ply").write_bytes(np.random.default_rng(1).bytes(3000))
        (b / "garbage.obj").write_bytes(np.random.default_rng(2).bytes(3000))
        (b / "empty.obj").write_bytes(b"")
        (b / "nan.obj").write_text("v 0 0 0\nv nan 0 0\nv 0 1 0\nv 0 0 1\nf 1 2 3\nf 1 3 4\nf 1 4 2\nf 2 4 3\n")
        (b / "bad_index.off").write_text("OFF\n4 2 0\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n3 0 1 2\n3 0 1 9\n")
        (b / "degenerate.obj").write_text("v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\n")
        (b / "README.txt").write_text("not a mesh: a folder search skips it\n")
        (b / ".hidden.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
        for rel, reason in BROKEN.items():
            files[rel] = {"kind": "broken", "watertight": False, "broken": reason}
    return files


__all__ = ["BatchSettings", "BatchSummary", "Job", "MANIFEST_COLUMNS", "Progress", "atomic_save",
           "dask_task", "find_meshes", "mesh_suffixes", "plan_jobs", "read_manifest", "run_batch",
           "synthetic_dataset", "voxelize_one", "write_manifest"]
