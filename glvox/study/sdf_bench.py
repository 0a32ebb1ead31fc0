"""``glvox bench --sdf``: glvox's signed distance field against the SDF tools people use, on the
same voxel centers.

    glvox bench --sdf --meshes stanford_bunny_bun_zipper.ply -r 128

For each mesh and grid: glvox (:func:`glvox.methods.sdf.field.signed_distance_field`, band of
3 voxels, sign from the ``solid`` alias) and each installed peer run end to end (load the mesh
file with the tool's own reader, distances, sign, a numpy (nx, ny, nz) array; a generated
``gen:`` mesh is handed over as arrays).  Peers: Open3D's
``RaycastingScene.compute_signed_distance``, libigl's ``signed_distance`` (fast winding
number sign), mesh-to-sdf's ``mesh_to_sdf``; absent ones are reported as skipped with their
pip name, and mesh2sdf (which samples its own [-1, 1]^3 grid, not given centers) is listed,
not run.  Each row: seconds (median of ``--repeat`` runs, the first call in the process
included), the ratio to glvox (above 1: slower than glvox), the largest difference of the
unsigned distances from glvox's on glvox's exact voxels (its band), in voxels, and the share
of voxel centers (all of them, glvox's clamped ones carry its sign) farther than 1e-3 voxel
from the surface where the signs agree.  Signs differ by design on open meshes (the
bunny's base): winding numbers, ray parity, pseudo-normals.

libigl's ``signed_distance`` with a winding-number sign returns ``(1 - 2 w) d``, not ``+-d``
(``w`` the winding number; on an open mesh ``|1 - 2 w| < 1`` near a hole, and the fast
winding number is approximate everywhere): the distance is taken from its closest points
``C`` (``|p - C|``) and only the sign from ``S``.
"""

from __future__ import annotations

import importlib
import os
import statistics
import time
import warnings
from pathlib import Path
from typing import Any, Callable

import numpy as np

from ..datasets import resolve_mesh
from ..grid import GridSpec, grid_for
from ..mesh import load_mesh
from ..methods.sdf.field import signed_distance_field

#: Peers not run, with why: (name, pip name, reason when installed).
NOT_RUN = {"mesh2sdf": ("mesh2sdf", "samples its own [-1, 1]^3 grid, not the given voxel centers")}


def _is_file(path: str) -> bool:
    return not path.startswith("gen:") and Path(path).is_file()


def _arrays(path: str) -> tuple[np.ndarray, np.ndarray]:
    m = load_mesh(path)
    return np.asarray(m.vertices, np.float64), np.asarray(m.faces, np.int64)


def open3d_sdf(path: str, centers: np.ndarray) -> np.ndarray:
    """Open3D's RaycastingScene.compute_signed_distance at ``centers`` ((P, 3) world): (P,) float."""
    import open3d as o3d

    if _is_file(path):
        mesh = o3d.t.geometry.TriangleMesh.from_legacy(o3d.io.read_triangle_mesh(path))
    else:
        v, f = _arrays(path)
        mesh = o3d.t.geometry.TriangleMesh(o3d.core.Tensor(v.astype(np.float32)), o3d.core.Tensor(f.astype(np.int32)))
    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(mesh)
    return scene.compute_signed_distance(o3d.core.Tensor(centers.astype(np.float32))).numpy()


def igl_sdf(path: str, centers: np.ndarray) -> np.ndarray:
    """libigl's signed_distance (fast winding number sign) at ``centers``: (P,) float64.

    ``S`` is ``(1 - 2 w) d`` for winding-number signs, so the distance is ``|p - C|`` from
    the returned closest points and only the sign is ``S``'s."""
    import igl

    v, f = igl.read_triangle_mesh(path) if _is_file(path) else _arrays(path)
    p = np.ascontiguousarray(centers, np.float64)
    s, _, c = igl.signed_distance(p, np.ascontiguousarray(v, np.float64), np.ascontiguousarray(f, np.int64),
                                  sign_type=igl.SignedDistanceType.SIGNED_DISTANCE_TYPE_FAST_WINDING_NUMBER)[:3]
    return np.where(np.asarray(s) < 0, -1.0, 1.0) * np.linalg.norm(p - np.asarray(c), axis=1)


def mesh_to_sdf_sdf(path: str, centers: np.ndarray) -> np.ndarray:
    """mesh-to-sdf's mesh_to_sdf at ``centers`` (its defaults: scanned surface points, normal sign)."""
    import mesh_to_sdf
    import trimesh

    mesh = trimesh.load(path, force="mesh") if _is_file(path) else trimesh.Trimesh(*_arrays(path), process=False)
    return np.asarray(mesh_to_sdf.mesh_to_sdf(mesh, centers), np.float64)


#: The peers run: (name, module to import, pip name, function).
PEERS: list[tuple[str, str, str, Callable[[str, np.ndarray], np.ndarray]]] = [
    ("Open3D RaycastingScene", "open3d", "open3d", open3d_sdf),
    ("libigl signed_distance", "igl", "libigl", igl_sdf),
    ("mesh-to-sdf", "mesh_to_sdf", "mesh-to-sdf", mesh_to_sdf_sdf),
]


def _installed(module: str) -> bool:
    return importlib.util.find_spec(module) is not None


def _timed(fn: Callable[[], Any], repeat: int) -> tuple[float, Any]:
    times, out = [], None
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times), out


def glvox_sdf(path: str, n: int):
    """glvox end to end: load, grid, SDF (default band and sign), numpy result."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # an open mesh's uncertain-sign warning: counted in the row
        mesh = load_mesh(path)
        return signed_distance_field(mesh, grid_for(mesh, n))


def agreement(result, values: np.ndarray) -> dict[str, float]:
    """How peer ``values`` ((nx, ny, nz) signed, world units) agree with glvox's SDFGrid ``result``:
    ``max_diff_vox`` (unsigned distances on glvox's band, voxels) and ``sign_agreement`` (share)."""
    h = result.voxel_size
    v = np.asarray(values, np.float64).reshape(result.dims)
    g = result.sdf.astype(np.float64)
    band = result.band
    diff = float(np.abs(np.abs(v[band]) - np.abs(g[band])).max() / h) if band.any() else float("nan")
    away = np.abs(g) > 1e-3 * h
    same = float(np.mean((v[away] < 0) == (g[away] < 0))) if away.any() else float("nan")
    return {"max_diff_vox": diff, "sign_agreement": same}


def run(meshes: list[str], sizes: list[int], repeat: int = 1,
        log: Callable[[str], None] = lambda s: None) -> list[dict[str, Any]]:
    """One row per (mesh, size, contender); skipped peers have ``skipped`` (why) and no time."""
    rows = []
    for m in meshes:
        path = resolve_mesh(m)
        for n in sizes:
            log(f"glvox sdf {m} {n}^3")
            t, r = _timed(lambda: glvox_sdf(path, n), repeat)
            spec: GridSpec = r.spec
            centers = spec.centers(np.indices(spec.dims).reshape(3, -1).T)
            base = {"mesh": m, "n": n, "exact_voxels": int(r.band.sum()), "uncertain": r.n_uncertain}
            rows.append({**base, "tool": "glvox sdf (band 3)", "seconds": t, "ratio": 1.0,
                         "max_diff_vox": 0.0, "sign_agreement": 1.0})
            for name, module, pip, fn in PEERS:
                if not _installed(module):
                    rows.append({**base, "tool": name, "skipped": f"not installed (pip install {pip})"})
                    continue
                log(f"{name} {m} {n}^3")
                tp, vals = _timed(lambda: fn(path, centers), repeat)
                rows.append({**base, "tool": name, "seconds": tp, "ratio": tp / t,
                             **agreement(r, np.asarray(vals).reshape(spec.dims))})
            for name, (pip, why) in NOT_RUN.items():
                rows.append({**base, "tool": name,
                             "skipped": why if _installed(name) else f"not installed (pip install {pip})"})
    return rows


def report(rows: list[dict[str, Any]], load: tuple[float, float]) -> str:
    """A markdown table of ``rows`` and the load average at the start and the end."""
    lines = ["| mesh | grid | tool | seconds | ratio to glvox | max diff (voxels, glvox's band) "
             "| sign agreement |", "|---|---|---|---|---|---|---|"]
    for r in rows:
        if "skipped" in r:
            lines.append(f"| {r['mesh']} | {r['n']}^3 | {r['tool']} | skipped: {r['skipped']} | | | |")
            continue
        lines.append(f"| {r['mesh']} | {r['n']}^3 | {r['tool']} | {r['seconds']:.2f} | {r['ratio']:.2f} "
                     f"| {r['max_diff_vox']:.2g} | {100 * r['sign_agreement']:.2f}% |")
    lines.append("")
    lines.append(f"Load average (1 min) {load[0]:.2f} at the start, {load[1]:.2f} at the end "
                 f"({os.cpu_count()} CPUs).")
    return "\n".join(lines)
