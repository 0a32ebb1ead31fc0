"""cuda_voxelizer (Jeroen Baert's command-line CUDA voxelizer) as a ``glvox bench`` peer.

The user names the binary (``glvox bench --cuda-voxelizer PATH``, or the
environment variable ``GLVOX_CUDA_VOXELIZER``); glvox runs it as a user
would: ``cuda_voxelizer -f MESH -s N -o binvox``, which writes
``<MESH without suffix>_<N>.binvox`` beside the mesh (its current source,
built for an H100 in November 2026, keeps the suffix: ``<MESH>_<N>.binvox``;
either is read), so the mesh is written to a temporary folder first, as
binary PLY.  It prints, among other lines,
``[Perf] Voxelization GPU time: <ms> ms`` (its CUDA kernel, timed with CUDA
events; absent on its CPU fallback, which it announces) and ``[Perf] Total
runtime: <ms> ms``.

Placement: cuda_voxelizer fits its own grid and takes no placement.  It pads
the mesh's bounding box to a cube about its center, then pads that cube by
1/10001 of its side on every side (float32 arithmetic), and cuts it into
N^3 voxels; its binvox header holds that cube's minimum corner and side
(binvox's own convention, ``%g`` digits).  glvox's cube (``grid_for(mesh,
N)``) has the same center and no padding, so cuda_voxelizer's voxels are
1 + 2/10001 times glvox's and voxel (i, j, k) of one is voxel (i, j, k) of
the other up to a drift of at most N / 10001 voxel at the grid's faces
(0.1 voxel at 1024^3).  :meth:`CudaVoxelizer.to_grid` puts each of its
voxel centers into the glvox voxel that holds it, so the bench's agreement
with ``reference-conservative`` on glvox's grid differs by the voxels that
drift moves; the exact check is glvox's ``ss-conservative`` run on
cuda_voxelizer's own placement (the cube recomputed from the mesh in float32
as it computes it), reported in the row's ``peer_stats`` (counts, IoU,
missing and extra voxels).  Its criterion is the Schwarz & Seidel
conservative test too, in float32.

Timing: the whole process (start, reading the PLY, CUDA initialization,
voxelization, writing the binvox) is the wall time, what a user of the tool
waits for; its own kernel time is in ``peer_stats['kernel_ms']``.
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import tempfile
import weakref
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from glvox.errors import GlvoxError
from glvox.grid import GridSpec
from glvox.io import load
from glvox.methods import run_method
from glvox.results import VoxelGrid
from .options import CUDA_VOXELIZER_ENV, check_binary
from .peer_base import Peer, PeerGrid, _from_indices

#: The environment variable naming the binary when ``--cuda-voxelizer`` is not given.
ENV = CUDA_VOXELIZER_ENV

_KERNEL = re.compile(r"\[Perf\] Voxelization GPU time:\s*([0-9.]+)\s*ms")
_TOTAL = re.compile(r"\[Perf\] Total runtime:\s*([0-9.]+)\s*ms")
_CPU = re.compile(r"CPU voxelization|Falling back to CPU", re.IGNORECASE)


def cube_placement(vertices: np.ndarray, n: int) -> GridSpec:
    """cuda_voxelizer's grid for ``vertices`` at ``n``^3, as it computes it in float32:
    the bounding box padded to a cube about its center, padded by 1/10001 of the
    side on every side; origin its minimum corner, voxel size its x side / n (the
    three sides agree to float32 rounding)."""
    v = np.asarray(vertices, dtype=np.float32)
    lo, hi = v.min(axis=0), v.max(axis=0)
    lengths = hi - lo
    longest = lengths.max()
    delta = (longest - lengths) / np.float32(2.0)
    lo = np.where(lengths != longest, lo - delta, lo).astype(np.float32)
    hi = np.where(lengths != longest, hi + delta, hi).astype(np.float32)
    eps = (hi - lo) / np.float32(10001.0)
    lo, hi = lo - eps, hi + eps
    unit = (hi[0] - lo[0]) / np.float32(n)
    return GridSpec((n, n, n), lo.astype(np.float64), float(unit))


def parse_output(text: str) -> dict[str, Any]:
    """What cuda_voxelizer printed: ``kernel_ms`` (None on its CPU path or when absent),
    ``total_ms`` (its own whole runtime, or None) and ``device`` ('gpu' or 'cpu')."""
    k, t = _KERNEL.search(text), _TOTAL.search(text)
    return {"kernel_ms": float(k.group(1)) if k else None, "total_ms": float(t.group(1)) if t else None,
            "device": "cpu" if _CPU.search(text) and not k else "gpu"}


@dataclass
class Prepared:
    """The mesh written for cuda_voxelizer, where its output goes, its own placement;
    the temporary folder goes with the object."""

    binary: str
    folder: Path
    mesh_path: Path
    n: int
    outs: tuple[Path, ...]  # the names its versions write, either one
    own: GridSpec
    mesh: Any

    def __post_init__(self):
        weakref.finalize(self, shutil.rmtree, str(self.folder), True)


class CudaVoxelizer(Peer):
    """cuda_voxelizer ``-f MESH -s N -o binvox``: conservative surface on its own cube
    (the module docstring says how it is aligned and checked)."""

    name = "cuda-voxelizer"
    kind = "surface"
    module = ""
    package = "cuda_voxelizer (https://github.com/Forceflow/cuda_voxelizer, a binary)"
    reference = "reference-conservative"
    call = "cuda_voxelizer -f MESH -s N -o binvox (whole process)"
    max_n = None

    def __init__(self):
        self.binary: str | None = None

    def configure(self, binary: str | os.PathLike | None) -> None:
        """Use ``binary`` (None: the environment variable :data:`ENV`)."""
        self.binary = None if binary is None else str(binary)

    def path(self) -> str | None:
        return self.binary or os.environ.get(ENV) or None

    def missing(self) -> str | None:
        where = self.path()
        if where is None:
            return (f"{self.name} skipped: name its binary with --cuda-voxelizer PATH or {ENV} "
                    f"(built from https://github.com/Forceflow/cuda_voxelizer)")
        try:
            check_binary(where)
        except GlvoxError as exc:
            return f"{self.name} skipped: {exc}"
        return None

    def version(self) -> str:
        return str(self.path())

    def prepare(self, mesh, spec: GridSpec) -> Prepared:
        import trimesh  # imported where used, as the other peers import their libraries

        if spec.dims[0] != spec.dims[1] or spec.dims[1] != spec.dims[2]:
            raise ValueError(f"cuda_voxelizer makes cubic grids only, got dims {spec.dims}")
        binary = str(check_binary(self.path() or ""))
        folder = Path(tempfile.mkdtemp(prefix="glvox-cuda-voxelizer-"))
        mesh_path = folder / "mesh.ply"
        trimesh.Trimesh(np.asarray(mesh.vertices, np.float64), np.asarray(mesh.faces), process=False,
                        validate=False).export(mesh_path, file_type="ply", encoding="binary")
        n = int(spec.dims[0])
        outs = (folder / f"mesh_{n}.binvox", folder / f"mesh.ply_{n}.binvox")
        return Prepared(binary, folder, mesh_path, n, outs, cube_placement(mesh.vertices, n), mesh)

    def run(self, prepared: Prepared) -> dict[str, Any]:
        for out in prepared.outs:
            out.unlink(missing_ok=True)  # never read a file an earlier run left
        p = subprocess.run([prepared.binary, "-f", str(prepared.mesh_path), "-s", str(prepared.n), "-o", "binvox"],
                           capture_output=True, text=True, cwd=prepared.folder)
        text = p.stdout + p.stderr
        out = next((o for o in prepared.outs if o.is_file()), None)
        if p.returncode != 0 or out is None:
            tail = " | ".join(text.strip().splitlines()[-3:])
            names = " or ".join(o.name for o in prepared.outs)
            raise RuntimeError(f"cuda_voxelizer exited with status {p.returncode}"
                               f"{'' if out is not None else f' without writing {names}'}: {tail}")
        return {"text": text, "binvox": out.read_bytes(), "prepared": prepared}

    def to_grid(self, native: dict[str, Any], spec: GridSpec) -> PeerGrid:
        """Its voxels into glvox's grid (each center into the glvox voxel holding it), with
        ``stats``: its printed times and :func:`own_placement_check`."""
        prepared = native["prepared"]
        path = prepared.folder / "read.binvox"
        path.write_bytes(native["binvox"])
        theirs = load(path, convention="binvox")  # its placement, from its header
        stats = parse_output(native["text"])
        stats.update(own_placement_check(theirs, prepared.own, prepared.mesh))
        stats["voxel_size_over_glvox"] = float(theirs.voxel_size / spec.voxel_size)  # 1 + 2/10001 on grid_for's cube
        ijk = np.floor((theirs.points() - np.asarray(spec.origin)) / spec.voxel_size).astype(np.int64)
        pg = _from_indices(ijk, spec)
        pg.stats = stats
        return pg


def own_placement_check(theirs, own: GridSpec, mesh) -> dict[str, Any]:
    """cuda_voxelizer's grid ``theirs`` (read from its binvox) against glvox's ``ss-conservative``
    on ``own`` (:func:`cube_placement`): the header's placement against the recomputed one, and
    the voxels of the two on the same grid."""
    header_error = float(np.max(np.abs(np.asarray(theirs.origin) - own.origin)) / own.voxel_size)
    mine = run_method("ss-conservative", mesh, own)
    c = VoxelGrid(words=theirs.words(), spec=own).compare(mine)
    return {"count": theirs.count, "glvox_count": mine.count, "iou": c.iou, "missing": c.n_missing,
            "extra": c.n_extra, "header_origin_error_voxels": header_error,
            "header_voxel_size_ratio": float(theirs.voxel_size / own.voxel_size)}
