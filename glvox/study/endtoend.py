"""``glvox bench --end-to-end [FOLDER]``: what a user of a dataset waits for, file by file.

    glvox bench --end-to-end -r 64                      # the shared meshes, ss-conservative vs Open3D
    glvox bench --end-to-end data/ -r 128 -m ss-solid --peers open3d trimesh-subdivide

Per file and contender, one timed *job* is everything from the path to a
numpy occupancy array: read the file, fit the papers' cubic N^3 grid
(h = largest extent / N, centered on the mesh's box), voxelize, and hold a
dense bool (nx, ny, nz) array.  For glvox: ``load_mesh``, ``grid_for``,
``run_method``, ``.dense()``.  For Open3D: ``read_triangle_mesh``, the same
grid from the vertices in numpy, ``create_from_triangle_mesh_within_bounds``
and its voxels' ``grid_index`` into a dense array (``--peers open3d``; the
surface peer), and the same without the array (``open3d, no numpy``: Open3D
has no array accessor, and its list of Voxel objects costs more than the
voxelization on large surfaces).  For trimesh: ``trimesh.load``, ``voxelized(pitch)`` and its
``.matrix`` (``--peers trimesh-subdivide``; not on the same grid, and many
times slower: it is there for scale).

Protocol (as the voxelize-only bench): one untimed pass over every file and
contender first (shader compilation, Open3D's first call, page cache), then
``--repeat`` rounds in which the contenders take turns on each file, the
order rotating every round, so load from elsewhere lands on all of them.
Reported per contender: meshes per second from the sum of its per-file
best times and from the sum of its medians, and per file best and median
milliseconds; bimodal contenders are flagged as in the voxelize-only bench.
"""

from __future__ import annotations

import statistics
import time
from pathlib import Path
from typing import Any, Callable, Sequence

import numpy as np

from glvox.errors import GlvoxError
from glvox.grid import grid_for
from glvox.mesh import load_mesh
from glvox.methods import DEFAULT_METHOD, get_method, run_method

from ..batch.jobs import mesh_suffixes
from ..datasets import SHARED_MESHES, mesh_dir
from .harness import bimodal

#: The peers with an end-to-end job (read, voxelize, numpy).
E2E_PEERS = ("open3d", "trimesh-subdivide")


def _glvox_job(method: str, n: int) -> Callable[[str], np.ndarray]:
    get_method(method)  # unknown names: one error listing the known ones

    def job(path: str) -> np.ndarray:
        mesh = load_mesh(path)
        return run_method(method, mesh, grid_for(mesh, n), allow_open=True).dense()

    return job


def _open3d_job(n: int, numpy_result: bool = True) -> Callable[[str], Any]:
    import open3d as o3d  # lazy: an optional peer (glvox[peers])

    def job(path: str) -> Any:
        tm = o3d.io.read_triangle_mesh(path)
        v = np.asarray(tm.vertices)
        if len(tm.triangles) == 0:
            raise ValueError("Open3D read no triangles")  # e.g. OBJ polygons it skips
        lo, hi = v.min(axis=0), v.max(axis=0)
        h = float((hi - lo).max()) / n
        origin = 0.5 * (lo + hi) - 0.5 * n * h
        vg = o3d.geometry.VoxelGrid.create_from_triangle_mesh_within_bounds(
            tm, h, origin.reshape(3, 1), (origin + n * h).reshape(3, 1))
        if not numpy_result:
            return vg
        # Open3D has no array accessor for a VoxelGrid: a Python list of Voxel objects
        ijk = np.array([vox.grid_index for vox in vg.get_voxels()], dtype=np.int64).reshape(-1, 3)
        ijk = ijk[np.all((ijk >= 0) & (ijk < n), axis=1)]
        dense = np.zeros((n, n, n), dtype=bool)
        dense[tuple(ijk.T)] = True
        return dense

    return job


def _trimesh_job(n: int) -> Callable[[str], np.ndarray]:
    import trimesh  # lazy: ~0.5 s to import

    def job(path: str) -> np.ndarray:
        m = trimesh.load(path, force="mesh")
        return np.asarray(m.voxelized(pitch=float(m.extents.max()) / n).matrix)

    return job


def contenders(methods: Sequence[str] | None, peers: Sequence[str] | None, n: int,
               log: Callable[[str], None]) -> dict[str, Callable[[str], np.ndarray]]:
    """Label -> job: each glvox method (default ``ss-conservative``), then the peers asked for
    (default: Open3D when installed)."""
    jobs = {f"glvox {m}": _glvox_job(m, n) for m in (methods or [DEFAULT_METHOD])}
    for name in (["open3d"] if peers is None else peers):
        if name not in E2E_PEERS:
            log(f"{name} has no end-to-end job (only {', '.join(E2E_PEERS)}); skipped")
            continue
        try:
            if name == "open3d":
                jobs[name] = _open3d_job(n)
                jobs["open3d, no numpy"] = _open3d_job(n, numpy_result=False)
            else:
                jobs[name] = _trimesh_job(n)
        except ImportError:
            log(f"{name} is not installed (pip install 'glvox[peers]'); skipped")
    return jobs


def files_of(folder: str | None) -> list[str]:
    """The mesh files under ``folder`` (recursively, by suffix), or the shared meshes."""
    if folder is None:
        paths = [mesh_dir() / name for name in SHARED_MESHES]
        paths = [p for p in paths if p.is_file()]
    else:
        root = Path(folder)
        if not root.is_dir():
            raise GlvoxError(f"--end-to-end takes a folder of meshes, got {folder}")
        suffixes = set(mesh_suffixes())
        paths = sorted(p for p in root.rglob("*") if p.is_file() and p.suffix.lower() in suffixes)
    if not paths:
        raise GlvoxError(f"no mesh files in {folder or mesh_dir()}")
    return [str(p) for p in paths]


def run(files: Sequence[str], jobs: dict[str, Callable[[str], np.ndarray]], repeat: int,
        progress: Callable[[str], None] = lambda s: None) -> dict[str, dict[str, list[float]]]:
    """Seconds per contender and file, ``repeat`` interleaved rounds after one untimed pass.

    A job that raises on a file is recorded as the error text instead of times."""
    labels = list(jobs)
    times: dict[str, dict[str, Any]] = {k: {f: [] for f in files} for k in labels}
    for rnd in range(repeat + 1):
        progress(f"end-to-end round {rnd}/{repeat}" + (" (untimed warm-up)" if rnd == 0 else ""))
        for i, f in enumerate(files):
            k = (rnd + i) % len(labels)
            for label in labels[k:] + labels[:k]:
                if isinstance(times[label][f], str):
                    continue
                t0 = time.perf_counter()
                try:
                    jobs[label](f)
                except Exception as exc:  # noqa: BLE001 - a file a library cannot read is one row
                    times[label][f] = f"{type(exc).__name__}: {str(exc).splitlines()[0] if str(exc) else ''}"
                    continue
                if rnd:
                    times[label][f].append(time.perf_counter() - t0)
    return times


def report(times: dict[str, dict[str, Any]], n: int, repeat: int) -> str:
    """Markdown: meshes/s per contender (files every contender read), then per file best / median ms."""
    labels = list(times)
    files = list(next(iter(times.values())))
    common = [f for f in files if all(not isinstance(times[k][f], str) for k in labels)]
    out = [f"End to end at {n}^3 (read the file, fit the grid, voxelize, dense numpy occupancy), "
           f"{len(common)} of {len(files)} files that every contender read, best / median of {repeat} "
           "interleaved rounds:", "",
           "| contender | meshes/s (best) | meshes/s (median) | total s (median) | bimodal files |",
           "|---|---|---|---|---|"]
    for k in labels:
        best = sum(min(times[k][f]) for f in common)
        med = sum(statistics.median(times[k][f]) for f in common)
        flagged = sum(bimodal(times[k][f]) for f in common)
        out.append(f"| {k} | {len(common) / best:.1f} | {len(common) / med:.1f} | {med:.3f} | {flagged} |")
    out += ["", "| file | " + " | ".join(f"{k} best / median ms" for k in labels) + " |",
            "|---|" + "---|" * len(labels)]
    for f in files:
        cells = []
        for k in labels:
            t = times[k][f]
            if isinstance(t, str):
                cells.append(t)
                continue
            flag = " (bimodal)" if bimodal(t) else ""
            cells.append(f"{min(t) * 1e3:.1f} / {statistics.median(t) * 1e3:.1f}{flag}")
        out.append(f"| {Path(f).name} | " + " | ".join(cells) + " |")
    return "\n".join(out)
