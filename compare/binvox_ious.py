"""IoU of glvox's solids with the solids binvox made (ShapeNet ``model_normalized.solid.binvox``).

For each model of a folder (a subfolder holding ``model_normalized.obj`` and
``model_normalized.solid.binvox``, or a pair ``NAME.obj`` / ``NAME.solid.binvox``)
the mesh is voxelized on binvox's placement (:func:`glvox.grid.binvox_grid` of
every ``v`` record's bounding box, the file's resolution) by ``binvox-solid``
with binvox's own defaults in each mode, with ShapeNet's recipe without the
wireframe (``-dc -down`` plus the voxels holding a crossing, the defaults before
``-aw``), with its defaults (ShapeNet's recipe, ``wire=True, dilated=True,
down=1``: binvox ``-aw -dc -down``), by the ``solid`` alias, by
``carve-solid`` and ``karabassi``, and compared with the
file's occupancy (read in binvox's convention; its header is not trusted, some
files have it rewritten).  Prints one row per model and the mean.

``--twin`` prints instead, per model, how ``binvox-solid`` (its defaults) compares
with its float64 twin ``reference-binvox``: the voxels that differ, those outside
the twin's tie set (must be 0), the tie set's share of the grid, and the voxels
that differ from binvox's rules run on the GPU's own float32 vertices (must be 0).

Usage::

    python compare/binvox_ious.py FOLDER [--markdown] [--twin]
"""

from __future__ import annotations

import argparse
import platform
import warnings
from pathlib import Path

import numpy as np

from glvox.formats.binvox import read
from glvox.gl.context import get_context
from glvox.grid import binvox_grid
from glvox.mesh import binvox_bounds, load_mesh
from glvox.methods import run_method
from glvox.methods.binvox.solid import BINVOX_DEFAULTS, OPTIONS, gpu_cover_triangles, gpu_triangles
from glvox.metrics import tie_set
from glvox.reference.binvox import binvox_solid

#: (column, method, options): binvox-solid with binvox's own defaults in each mode, then its
#: recipe without -aw (with the surface instead), its defaults (ShapeNet's recipe,
#: -aw -dc -down), the ``solid`` alias, and two other solids.
RUNS = [
    ("binvox default", "binvox-solid", BINVOX_DEFAULTS),
    ("carve (-c)", "binvox-solid", {**BINVOX_DEFAULTS, "mode": "carve"}),
    ("vote (-v)", "binvox-solid", {**BINVOX_DEFAULTS, "mode": "vote"}),
    ("-dc", "binvox-solid", {**BINVOX_DEFAULTS, "dilated": True}),
    ("no surface", "binvox-solid", {**BINVOX_DEFAULTS, "surface": False}),
    ("-dc -down + surface", "binvox-solid", {"wire": False, "surface": True}),
    ("ShapeNet (-aw -dc -down, the defaults)", "binvox-solid", {}),
    ("-m solid", "solid", {}),
    ("carve-solid", "carve-solid", {}),
    ("karabassi", "karabassi", {}),
]


def models(folder: Path):
    """(name, obj, solid.binvox) of every model under ``folder``."""
    for obj in sorted(folder.rglob("*.obj")):
        solid = obj.with_name(obj.stem + ".solid.binvox")
        if solid.exists():
            name = obj.parent.name if obj.stem == "model_normalized" else obj.stem
            yield name, obj, solid


def iou(a: np.ndarray, b: np.ndarray) -> float:
    union = int((a | b).sum())
    return int((a & b).sum()) / union if union else 1.0


def twin_rows(folder: Path):
    """(model, differing voxels, outside the ties, tie share, off the float32 twin) per model."""
    defaults = {k: o.default for k, o in OPTIONS.items()}
    for name, obj, solid in models(folder):
        mesh = load_mesh(obj)
        spec = binvox_grid(binvox_bounds(obj, mesh), read(solid, convention="binvox").spec.dims[0])
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            gpu = run_method("binvox-solid", mesh, spec).dense()
            twin = run_method("reference-binvox", mesh, spec).dense()
        ties = tie_set("reference-binvox", mesh, spec)
        mirror = binvox_solid(gpu_triangles(mesh, spec, defaults["down"]), spec.dims, **defaults,
                              cover=gpu_cover_triangles(mesh, spec, defaults["down"]))
        diff = gpu ^ twin
        yield name, int(diff.sum()), int((diff & ~ties).sum()), float(ties.mean()), int((gpu ^ mirror).sum())


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("folder", type=Path)
    ap.add_argument("--markdown", action="store_true", help="print a markdown table")
    ap.add_argument("--twin", action="store_true", help="binvox-solid against reference-binvox and its ties")
    args = ap.parse_args(argv)
    if args.twin:
        print("| model | voxels off reference-binvox | outside its ties | ties (share of the grid) | "
              "off the float32 twin |\n|---|---|---|---|---|")
        for name, diff, outside, share, mirror in twin_rows(args.folder):
            print(f"| {name} | {diff} | {outside} | {share:.3f} | {mirror} |")
        print(f"\n{get_context().renderer}; {platform.node()}")
        return 0
    rows, picked = [], {}
    for name, obj, solid in models(args.folder):
        shipped = read(solid, convention="binvox").dense()
        mesh = load_mesh(obj)
        spec = binvox_grid(binvox_bounds(obj, mesh), shipped.shape[0])
        row = [name, int(shipped.sum())]
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # open meshes: the point of the comparison
            for _, method, options in RUNS:
                result = run_method(method, mesh, spec, allow_open=True, **options)
                if method == "solid":
                    picked[name] = result.run.method
                grid = result.dense()
                row.append(iou(grid, shipped))
        rows.append(row)
    if not rows:
        raise SystemExit(f"no model with an .obj and a .solid.binvox under {args.folder}")
    head = ["model", "voxels"] + [c for c, _, _ in RUNS]
    mean = ["mean", ""] + [float(np.mean([r[i] for r in rows])) for i in range(2, len(head))]
    fmt = lambda v: f"{v:.4f}" if isinstance(v, float) else str(v)  # noqa: E731
    if args.markdown:
        print("| " + " | ".join(head) + " |")
        print("|" + "---|" * len(head))
        for r in rows + [mean]:
            print("| " + " | ".join(fmt(v) for v in r) + " |")
    else:
        print("  ".join(f"{h:>14}" for h in head))
        for r in rows + [mean]:
            print("  ".join(f"{fmt(v):>14}" for v in r))
    print(f"\n-m solid picked: {', '.join(f'{k}: {v}' for k, v in picked.items())}")
    print(f"{get_context().renderer}; {platform.node()}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
