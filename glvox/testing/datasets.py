"""Synthetic mesh datasets for batch tests and measurements (``tests/test_batch.py``,
``compare/bench_batch.py``, and users' own tests of ``glvox batch`` pipelines)."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import numpy as np
import trimesh

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


def _shape(kind: str, rng: np.random.Generator) -> trimesh.Trimesh:
    """One mesh of ``kind``, of random size and detail, centered at the origin."""
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
    return m


def _write_broken(folder: Path) -> None:
    """The files of :data:`BROKEN`, plus a text file and a hidden mesh a folder search skips."""
    folder.mkdir(parents=True, exist_ok=True)
    stl = trimesh.creation.box().export(file_type="stl")
    (folder / "truncated.stl").write_bytes(stl[:len(stl) // 2])
    (folder / "garbage.ply").write_bytes(np.random.default_rng(1).bytes(3000))
    (folder / "garbage.obj").write_bytes(np.random.default_rng(2).bytes(3000))
    (folder / "empty.obj").write_bytes(b"")
    (folder / "nan.obj").write_text("v 0 0 0\nv nan 0 0\nv 0 1 0\nv 0 0 1\nf 1 2 3\nf 1 3 4\nf 1 4 2\nf 2 4 3\n")
    (folder / "bad_index.off").write_text("OFF\n4 2 0\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n3 0 1 2\n3 0 1 9\n")
    (folder / "degenerate.obj").write_text("v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\n")
    (folder / "README.txt").write_text("not a mesh: a folder search skips it\n")
    (folder / ".hidden.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")


def synthetic_dataset(root: str | os.PathLike, n: int = 200, *, seed: int = 0,
                      broken: bool = True) -> dict[str, dict[str, Any]]:
    """Write a dataset of small meshes for batch tests and measurements.

    ``n`` meshes (boxes, icospheres, tori, cylinders, capsules, noisy blobs;
    random sizes, rotations, offsets; a few open boxes with one face removed)
    in nested folders, with suffixes .stl .obj .ply .off in turn; plus, with
    ``broken``, the files of :data:`BROKEN`, a text file and a hidden mesh
    that a folder search must ignore.  The same ``seed`` writes the same meshes.

    Returns
    -------
    dict
        Path relative to ``root`` (POSIX) -> ``{"kind": str, "watertight": bool,
        "broken": reason or None}`` for every file a batch should pick up.
    """
    root = Path(root)
    rng = np.random.default_rng(seed)
    suffixes = (".stl", ".obj", ".ply", ".off")
    kinds = ("box", "sphere", "torus", "cylinder", "capsule", "blob", "open_box")
    files: dict[str, dict[str, Any]] = {}
    for i in range(n):
        kind = kinds[i % len(kinds)]
        m = _shape(kind, rng)
        rot = trimesh.transformations.random_rotation_matrix(rng.random(3))
        # one mesh in 50 lies 1000x farther out, where float32 on the GPU loses precision
        rot[:3, 3] = rng.uniform(-5, 5, 3) * (1000 if i % 50 == 7 else 1)
        m.apply_transform(rot)
        rel = f"group{i % 4}/sub{i % 3}/{kind}_{i:04d}{suffixes[i % len(suffixes)]}"
        (root / rel).parent.mkdir(parents=True, exist_ok=True)
        m.export(root / rel)
        files[rel] = {"kind": kind, "watertight": kind != "open_box", "broken": None}
    if broken:
        _write_broken(root / "broken")
        for rel, reason in BROKEN.items():
            files[rel] = {"kind": "broken", "watertight": False, "broken": reason}
    return files

__all__ = ["BROKEN", "synthetic_dataset"]
