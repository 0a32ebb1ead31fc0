"""Write and read times and file sizes of every voxel format glvox writes.

    python compare/bench_formats.py [--mesh stanford_bunny_bun_zipper.ply] [--size 256]
                                    [--octree-size 2048] [--repeat 3] [--out DIR]

Dense rows: the mesh's conservative surface (``ss-conservative``) and its
solid (``ss-solid``, parity with allow_open for an open mesh) at SIZE^3,
written with ``glvox.save`` and read with ``glvox.load`` (the whole call a
user waits for, numpy result included), and read by the format's own
library alone (pynrrd, nibabel, VTK, OpenVDB; numpy's for npz, trimesh for
binvox).  Sparse rows: an ``ss-octree`` solid at OCTREE-SIZE^3 as npz (the
octree's arrays) and as VDB (BoolGrid, with and without the coverage
FloatGrid), never decoded to a dense grid; glvox reads .vdb only into a
dense grid, so the VDB read is OpenVDB's ``readAll`` and a deep copy of
each grid (OpenVDB loads leaf buffers lazily; the copy loads them).  Times are medians of
REPEAT runs in seconds, sizes MiB (2^20 bytes).  Prints a markdown table.
"""

from __future__ import annotations

import argparse
import contextlib
import importlib
import io as _io
import statistics
import tempfile
import time
import warnings
from pathlib import Path

import glvox
from glvox.datasets import resolve_mesh
from glvox.errors import FormatWarning, NotWatertightWarning

DENSE = [".npz", ".binvox", ".nrrd", ".nii", ".nii.gz", ".vti", ".vdb"]


def median_time(fn, repeat: int) -> float:
    times = []
    for _ in range(repeat):
        t = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t)
    return statistics.median(times)


def _vdb():
    with contextlib.redirect_stderr(_io.StringIO()):
        return importlib.import_module("pyopenvdb")


def library_reader(suffix: str):
    """The format's own library reading a file (its arrays in memory), or None."""
    if suffix == ".npz":
        import numpy as np

        def read(p):
            with np.load(p) as z:
                return {k: z[k] for k in z.files}
        return read
    if suffix == ".binvox":
        import trimesh
        return lambda p: trimesh.load(p).matrix
    if suffix == ".nrrd":
        import nrrd
        return lambda p: nrrd.read(str(p))
    if suffix in (".nii", ".nii.gz"):
        import nibabel as nib
        import numpy as np
        return lambda p: np.asanyarray(nib.load(str(p)).dataobj).copy(order="K")   # .nii is memory-mapped
    if suffix == ".vti":
        from vtkmodules.vtkIOXML import vtkXMLImageDataReader

        def read(p):
            r = vtkXMLImageDataReader()
            r.SetFileName(str(p))
            r.Update()
            return r.GetOutput()
        return read
    if suffix == ".vdb":
        vdb = _vdb()
        # deep copies: OpenVDB loads leaf buffers lazily
        return lambda p: [g.deepCopy() for g in vdb.readAll(str(p))[0]]
    return None


def row(label: str, result, suffix: str, folder: Path, repeat: int, glvox_read: bool = True, **options) -> str:
    path = folder / f"x{suffix}"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", FormatWarning)
        write = median_time(lambda: glvox.save(result, path, **options), repeat)
    size = path.stat().st_size / 2**20
    read = median_time(lambda: glvox.load(path), repeat) if glvox_read else None
    lib = library_reader(suffix)
    lib_read = median_time(lambda: lib(path), repeat) if lib is not None else None
    opt = "".join(f" ({k}={v})" for k, v in options.items())
    return f"| {label} | {suffix}{opt} | {write:.3f} | {_seconds(read)} | {_seconds(lib_read)} | {size:.2f} |"


def _seconds(t: float | None) -> str:
    return "n/a" if t is None else f"{t:.3f}"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--mesh", default="stanford_bunny_bun_zipper.ply")
    ap.add_argument("--size", type=int, default=256)
    ap.add_argument("--octree-size", type=int, default=2048)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--out", help="folder for the files (default: a temporary one)")
    args = ap.parse_args(argv)
    warnings.simplefilter("ignore", NotWatertightWarning)
    mesh = glvox.load_mesh(resolve_mesh(args.mesh))
    print(f"{mesh.name}: {mesh.n_triangles} triangles; median of {args.repeat} runs; seconds, MiB\n")
    print("| result | format | write (glvox.save) | read (glvox.load) | read (format's library) | size |")
    print("|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(args.out or tmp)
        folder.mkdir(parents=True, exist_ok=True)
        for method in ("ss-conservative", "ss-solid"):
            g = glvox.voxelize(mesh, args.size, method=method, allow_open=True)
            label = f"{method} {args.size}^3, {g.count:,} voxels"
            for suffix in DENSE:
                print(row(label, g, suffix, folder, args.repeat), flush=True)
        o = glvox.voxelize(mesh, args.octree_size, method="ss-octree", allow_open=True)
        label = f"ss-octree {args.octree_size}^3, {o.count:,} voxels"
        print(row(label, o, ".npz", folder, args.repeat), flush=True)
        for coverage in (True, False):
            print(row(label, o, ".vdb", folder, args.repeat, glvox_read=False, coverage=coverage), flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
