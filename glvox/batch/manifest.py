"""The batch manifest (CSV, one row per mesh) and the summary of a batch drawn from its rows."""

from __future__ import annotations

import csv
import io as _io
import os
from collections import Counter
from dataclasses import dataclass, field
from datetime import datetime, timezone
from pathlib import Path
from typing import Any, Iterable

from .._version import __version__
from ..errors import GlvoxError
from .atomic import atomic_write_text
from .jobs import BatchSettings, Job

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
    # --inspect: glvox.inspect.MeshReport's fields (empty without it)
    "components",          # parts connected through manifold edges
    "boundary_edges",      # edges of one triangle (holes)
    "nonmanifold_edges",   # edges of three or more triangles
    "duplicate_faces",     # triangles on the same three positions as an earlier one
    "inconsistent_edges",  # edges of two triangles that run them the same way
    "winding_consistent",  # true / false
    "signed_volume",       # world units cubed; > 0 when the faces point outward
    "orientation",         # outward | inward | flat
    "self_intersections",  # edges crossing a triangle (an estimate on large meshes)
    "uncertain_share",     # share of the solid whose winding number is within 0.1 of the threshold
    "inspect_s",           # wall seconds of the inspection
)

#: The manifest columns that ``--inspect`` fills from :class:`glvox.inspect.MeshReport`.
INSPECT_COLUMNS = MANIFEST_COLUMNS[MANIFEST_COLUMNS.index("components"):MANIFEST_COLUMNS.index("inspect_s")]


def now() -> str:
    """The UTC time, ISO 8601 to the second (the ``finished`` column)."""
    return datetime.now(timezone.utc).isoformat(timespec="seconds")


def base_row(job: Job, settings: BatchSettings) -> dict[str, Any]:
    """A manifest row of ``job`` with what is known before it runs; every other column empty."""
    row = {c: "" for c in MANIFEST_COLUMNS}
    row.update(input=job.rel, output=job.out_rel, method=settings.method, params=settings.params(),
               glvox_version=__version__)
    return row


def _cell(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, float):
        return f"{v:.6g}"
    return str(v)


def write_manifest(path: str | os.PathLike, rows: Iterable[dict[str, Any]]) -> Path:
    """Write manifest rows as CSV (columns :data:`MANIFEST_COLUMNS`), atomically."""
    buf = _io.StringIO()
    w = csv.DictWriter(buf, fieldnames=MANIFEST_COLUMNS, extrasaction="ignore", lineterminator="\n")
    w.writeheader()
    for r in rows:
        w.writerow({c: _cell(r.get(c, "")) for c in MANIFEST_COLUMNS})
    return atomic_write_text(path, buf.getvalue())


def read_manifest(path: str | os.PathLike) -> list[dict[str, str]]:
    """Rows of a manifest written by :func:`write_manifest` (all values strings)."""
    path = Path(path)
    try:
        with open(path, newline="") as f:
            return list(csv.DictReader(f))
    except (OSError, UnicodeDecodeError, csv.Error) as exc:
        raise GlvoxError(f"cannot read the batch manifest {path}: {exc}") from None


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
    warned : int
        Meshes done with warnings (the manifest's ``warnings`` column: an
        open mesh let through, a suspicious solid...).
    empty : int
        Meshes done with 0 voxels.
    rows : list of dict
        The manifest rows.
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
    warned: int = 0
    empty: int = 0
    rows: list[dict[str, Any]] = field(default_factory=list, repr=False)

    @classmethod
    def from_rows(cls, rows: list[dict[str, Any]], *, elapsed_s: float, manifest: str, mode: str,
                  startup_s: float) -> BatchSummary:
        """Count the rows of a finished (or interrupted) batch by status and failure reason."""
        status = Counter(r["status"] for r in rows)
        processed = status["done"] + status["failed"]
        return cls(
            total=len(rows), done=status["done"], skipped=status["skipped"], failed=status["failed"],
            pending=status["pending"],
            failed_by_reason=dict(Counter(r["reason"] for r in rows if r["status"] == "failed")),
            elapsed_s=elapsed_s, processed_per_s=processed / elapsed_s if elapsed_s > 0 else 0.0,
            manifest=manifest, mode=mode, startup_s=startup_s,
            warned=sum(1 for r in rows if r["status"] == "done" and r.get("warnings")),
            empty=sum(1 for r in rows if r["status"] == "done" and str(r.get("voxels", "")) == "0"),
            rows=rows)

    def to_dict(self) -> dict[str, Any]:
        """Every attribute but ``rows`` (what ``glvox batch --json`` prints)."""
        return {k: getattr(self, k) for k in ("total", "done", "skipped", "failed", "pending",
                                              "failed_by_reason", "elapsed_s", "processed_per_s",
                                              "manifest", "mode", "startup_s", "warned", "empty")}

    def format(self) -> str:
        """The summary lines ``glvox batch`` prints at the end."""
        if self.done + self.failed:
            rate = f"{self.processed_per_s:.2f} meshes/s"
        else:  # a rate of 0 would read as a stall: say why nothing ran
            rate = ("none processed: every output exists (--overwrite redoes them)" if self.skipped == self.total
                    else "none processed")
        lines = [f"{self.total} meshes in {self.elapsed_s:.1f} s ({self.mode}, start-up "
                 f"{self.startup_s:.1f} s): {rate}",
                 f"  done {self.done}, skipped {self.skipped}, failed {self.failed}"
                 + (f", not finished {self.pending}" if self.pending else "")]
        if self.failed_by_reason:
            lines.append("  failed by reason: " + ", ".join(
                f"{k} {v}" for k, v in sorted(self.failed_by_reason.items(), key=lambda kv: (-kv[1], kv[0]))))
        if self.warned or self.empty:
            lines.append(f"  with warnings {self.warned}, empty results {self.empty}: see the manifest's "
                         f"warnings column")
        lines.append(f"  manifest: {self.manifest}")
        return "\n".join(lines)
