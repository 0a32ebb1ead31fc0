"""The comparison harness: registered methods x meshes x grid sizes.

Each *cell* (method, mesh, resolution, options) is run cold once (shader
compilation, upload, allocation), warmed, then timed ``repeat`` times; the
row records wall and GPU medians and spreads, the per-stage GPU medians, the
voxel count, agreement with the method's exact reference (missing / extra
voxels, IoU, ties, mismatches that are not ties), separability on closed
meshes, the GPU memory the method keeps, and the method's own statistics.

Rows are appended to ``results.jsonl`` in the output folder as each cell
finishes, so an interrupted run resumes where it stopped: a cell whose key is
already there is not recomputed (``force=True`` recomputes).
"""

from __future__ import annotations

import json
import os
import platform
import statistics
import sys
import time
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Iterable, Sequence

import numpy as np

import glvox
from glvox.gpu.buffers import gpu_bytes
from glvox.errors import GlvoxError, NotWatertightWarning
from glvox.methods import get_method, method_names, run_method
from glvox.results.voxels import VoxelGrid

#: Largest grid on which results are checked against the CPU references by
#: default: the float64 references take seconds per mesh at 256^3 and minutes
#: at 1024^3 here, far longer than the methods they check.
CHECK_MAX = 256

#: The result file of a run (one JSON object per line, appended per cell).
RESULTS = "results.jsonl"


def mesh_dir() -> Path:
    """The shared meshes: ``GLVOX_MESHES``, else ``../shared/meshes`` beside the checkout."""
    env = os.environ.get("GLVOX_MESHES")
    return Path(env) if env else Path(__file__).resolve().parents[2] / "shared" / "meshes"


def resolve_mesh(name: str) -> str:
    """A generated mesh (``gen:...``), a path, or a file name in :func:`mesh_dir`."""
    if name.startswith("gen:") or os.path.exists(name):
        return name
    path = mesh_dir() / name
    if not path.is_file():
        raise GlvoxError(f"mesh {name!r} is neither a path nor a file in {mesh_dir()} (GLVOX_MESHES)")
    return str(path)


@dataclass(frozen=True)
class Cell:
    method: str
    mesh: str
    n: int
    options: tuple[tuple[str, Any], ...] = ()

    @property
    def key(self) -> str:
        opts = ",".join(f"{k}={v}" for k, v in self.options)
        return f"{self.method}[{opts}]|{Path(self.mesh).name}|{self.n}"


@dataclass
class Plan:
    """What to run: every method on every mesh at every size."""

    methods: Sequence[str]
    meshes: Sequence[str]
    sizes: Sequence[int]
    repeat: int = 5
    check_max: int = CHECK_MAX
    #: CPU methods (the references) are left out of cells above this size
    cpu_max: int | None = None
    options: dict[str, dict[str, Any]] = field(default_factory=dict)

    def cells(self) -> list[Cell]:
        cpu = {m for m in self.methods if not get_method(m).info.uses_gl}
        return [Cell(m, mesh, n, tuple(sorted(self.options.get(m, {}).items())))
                for mesh in self.meshes for n in self.sizes for m in self.methods
                if self.cpu_max is None or n <= self.cpu_max or m not in cpu]


def machine() -> dict[str, Any]:
    """The GL renderer and the versions that produced a result."""
    import moderngl
    import trimesh

    from glvox.gl.context import get_context

    ctx = get_context()
    return {"glvox": glvox.__version__, "python": platform.python_version(),
            "numpy": np.__version__, "moderngl": moderngl.__version__, "trimesh": trimesh.__version__,
            "platform": platform.platform(), "cpu_count": os.cpu_count(),
            "gl": {"vendor": ctx.vendor, "renderer": ctx.renderer, "version": ctx.version,
                   "backend": ctx.backend, "device": ctx.device}}


def _spread(values: list[float]) -> float:
    return float(max(values) - min(values)) if values else 0.0


def _grid_of(result) -> VoxelGrid | None:
    if isinstance(result, VoxelGrid):
        return result
    if hasattr(result, "to_grid"):
        return result.to_grid()
    return None


def run_cell(cell: Cell, plan: Plan, meshes: dict, refs: dict) -> dict[str, Any]:
    """Run one cell and return its row (see the module docstring)."""
    from glvox.gl.context import get_context
    from glvox.metrics import check_against_reference, separation_leaks, tie_set

    info = get_method(cell.method).info
    mesh = meshes[cell.mesh]
    spec = glvox.grid_for(mesh, cell.n)
    opts = dict(cell.options)
    row: dict[str, Any] = {
        "key": cell.key, "method": cell.method, "kind": info.kind, "family": info.family,
        "exact": info.exact, "options": opts, "mesh": Path(cell.mesh).name,
        "triangles": mesh.n_triangles, "watertight": mesh.watertight, "n": cell.n,
        "dims": list(spec.dims), "status": "ok", "error": None,
    }
    if info.kind in ("solid", "sparse", "ldi") and not mesh.watertight:
        row.update(status="skipped", error="mesh not watertight: inside is undefined for a solid method")
        return row
    ctx = get_context() if info.uses_gl else None
    try:
        # the first run of a cell: allocation at this size, and shader
        # compilation when the method has not run in this process before
        t0 = time.perf_counter()
        result = run_method(cell.method, mesh, spec, **opts)
        cold_wall = time.perf_counter() - t0
        cold = result.run.timings
        run_method(cell.method, mesh, spec, **opts)  # warm-up
        walls, gpus, stages = [], [], {}
        for _ in range(plan.repeat):
            t0 = time.perf_counter()
            result = run_method(cell.method, mesh, spec, **opts)
            walls.append(time.perf_counter() - t0)
            t = result.run.timings
            if t.gpu_s is not None:
                gpus.append(t.gpu_s)
            for s in t.stages:
                stages.setdefault(s.name, []).append(s.gpu_s if s.gpu_s is not None else s.wall_s)
    except GlvoxError as exc:
        row.update(status="error", error=f"{type(exc).__name__}: {exc}")
        return row
    row.update({
        "wall_ms": statistics.median(walls) * 1e3, "wall_spread_ms": _spread(walls) * 1e3,
        "gpu_ms": statistics.median(gpus) * 1e3 if gpus else None,
        "gpu_spread_ms": _spread(gpus) * 1e3 if gpus else None,
        "cold_wall_ms": cold_wall * 1e3, "compile_ms": cold.compile_s * 1e3,
        "stages_ms": {k: statistics.median(v) * 1e3 for k, v in stages.items()},
        "gpu_bytes": gpu_bytes(ctx) if ctx is not None else 0,
        "stats": {k: v for k, v in result.run.stats.items() if _jsonable(v)},
    })
    # an LDI is compared through its own checks (conservativeness), not as a grid
    grid = _grid_of(result) if info.kind in ("surface", "solid", "sparse") else None
    if grid is not None:
        row["voxels"] = grid.count
    if info.reference and grid is not None and cell.n <= plan.check_max:
        rkey = (info.reference, cell.mesh, cell.n)
        if rkey not in refs:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", NotWatertightWarning)
                ref = run_method(info.reference, mesh, spec, allow_open=True)
            refs[rkey] = (ref, tie_set(info.reference, mesh, spec))
        ref, ties = refs[rkey]
        c = check_against_reference(grid, mesh, info.reference, reference_grid=ref, ties=ties)
        row.update({"reference": info.reference, "reference_voxels": ref.count,
                    "missing": c.comparison.n_missing, "extra": c.comparison.n_extra,
                    "iou": c.comparison.iou, "ties": c.ties, "not_ties": int(len(c.unexplained))})
        if info.kind == "surface" and mesh.watertight:
            skey = ("reference-solid", cell.mesh, cell.n)
            if skey not in refs:
                refs[skey] = (run_method("reference-solid", mesh, spec), None)
            inside = refs[skey][0].dense() & ~grid.dense()
            row["leaks_26"] = int(len(separation_leaks(grid.dense(), inside, 26)))
            row["leaks_6"] = int(len(separation_leaks(grid.dense(), inside, 6)))
    return row


def _jsonable(v) -> bool:
    try:
        json.dumps(v)
        return True
    except TypeError:
        return False


def load_rows(out: Path) -> list[dict[str, Any]]:
    path = Path(out) / RESULTS
    if not path.is_file():
        return []
    rows = []
    for line in path.read_text().splitlines():
        if line.strip():
            try:
                rows.append(json.loads(line))
            except json.JSONDecodeError:
                continue  # a line cut by an interruption: that cell runs again
    return rows


class Progress:
    """One line on stderr: cells done, rate, ETA, the cell being run."""

    def __init__(self, total: int, quiet: bool = False):
        self.total, self.done, self.t0 = total, 0, time.perf_counter()
        self.quiet = quiet or not sys.stderr.isatty()

    def show(self, what: str) -> None:
        if self.quiet:
            return
        el = time.perf_counter() - self.t0
        eta = el / self.done * (self.total - self.done) if self.done else float("nan")
        bar = "#" * int(20 * self.done / max(1, self.total))
        sys.stderr.write(f"\r[{bar:<20}] {self.done}/{self.total}  {el:6.0f} s  ETA {eta:6.0f} s  "
                         f"{what[:60]:<60}")
        sys.stderr.flush()

    def step(self) -> None:
        self.done += 1

    def close(self) -> None:
        if not self.quiet:
            sys.stderr.write("\n")


def run_plan(plan: Plan, out: str | os.PathLike, *, force: bool = False, quiet: bool = False,
             log: Callable[[str], None] | None = None) -> list[dict[str, Any]]:
    """Run every cell of ``plan`` missing from ``out`` and return all rows.

    Writes ``out/machine.json`` and appends each row to ``out/results.jsonl``
    as soon as its cell finishes.
    """
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "machine.json").write_text(json.dumps(machine(), indent=2))
    rows = {} if force else {r["key"]: r for r in load_rows(out)}
    if force and (out / RESULTS).exists():
        (out / RESULTS).unlink()
    known = set(method_names())
    unknown = [m for m in plan.methods if m not in known]
    if unknown:
        raise GlvoxError(f"unknown methods {unknown}; known: {sorted(known)}")
    cells = [c for c in plan.cells() if c.key not in rows]
    meshes: dict[str, Any] = {}
    refs: dict = {}
    progress = Progress(len(cells), quiet)
    if log and len(cells) < len(plan.cells()):
        log(f"resuming: {len(plan.cells()) - len(cells)} of {len(plan.cells())} cells already in {out}")
    path = out / RESULTS
    if path.is_file() and path.stat().st_size:
        with open(path, "rb") as f:
            f.seek(-1, os.SEEK_END)
            cut = f.read(1) != b"\n"
        if cut:  # an interrupted write: end that line so new rows start cleanly
            with open(path, "a") as f:
                f.write("\n")
    with open(path, "a") as f:
        for cell in cells:
            progress.show(cell.key)
            if cell.mesh not in meshes:
                refs.clear()  # references of the previous mesh are not needed again
                meshes = {cell.mesh: glvox.load_mesh(resolve_mesh(cell.mesh))}
            row = run_cell(cell, plan, meshes, refs)
            rows[cell.key] = row
            f.write(json.dumps(row) + "\n")
            f.flush()
            progress.step()
    progress.close()
    order = {c.key: i for i, c in enumerate(plan.cells())}
    return sorted((r for r in rows.values() if r["key"] in order), key=lambda r: order[r["key"]])


def write_csv(rows: Iterable[dict[str, Any]], path: Path) -> None:
    """A tidy CSV: one row per cell, nested fields as JSON strings."""
    import csv

    rows = list(rows)
    cols: list[str] = []
    for r in rows:
        cols += [k for k in r if k not in cols]
    with open(path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=cols)
        w.writeheader()
        for r in rows:
            w.writerow({k: json.dumps(v) if isinstance(v, (dict, list)) else v for k, v in r.items()})
