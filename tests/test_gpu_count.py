"""Every dense GPU method counts its voxels on the GPU, and the count is its grid's.

Issue 23: ``VoxelGrid.count`` of a GPU method's result must come from the
GPU, fused into a pass that writes the final words anyway (no CPU popcount
after the readback).  The methods are taken from the registry (every
surface or solid method not of the ``cpu`` pipeline), so a new dense method is
covered as soon as it registers; :data:`NOT_COUNTED` lists the exceptions,
which must then count on the CPU (a stale exception fails too).  Each is run on a generated torus, a shared mesh, an odd-sized
non-cubic grid that clips the mesh (partial last words and bits past nx),
nested shells (several crossings per column), a tiled run where the method
has a ``tile`` option, and every non-default choice of its options; the
count it returned must equal ``np.bitwise_count`` of its words, for the
result and for every extra mask.
"""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

import glvox
from glvox.grid import GridSpec
from glvox.mesh import load_mesh
from glvox.methods import method_infos, run_method
from glvox.methods.ss import solid as ss_solid
from glvox.results import VoxelGrid

#: Dense GPU methods that count on the CPU (lazily: only when ``count`` is read), with the reason.
_SCANLINE = ("its marks are one atomicOr per voxel; counting the bits each sets first made scanline-rlv "
             "13-17% slower at 64^3-128^3 (glvox bench --preset quick --against 8304ca8), for a count "
             "numpy gives in under 0.1 ms at 128^3 when asked")
NOT_COUNTED: dict[str, str] = {f"scanline-{mode}": _SCANLINE for mode in ("ilv", "rlv", "slv")}

DENSE_GPU = [i for kind in ("surface", "solid") for i in method_infos(kind) if i.pipeline != "cpu"]


def popcount(words) -> int:
    return int(np.bitwise_count(np.asarray(words)).sum())


def check_counted(g: VoxelGrid, what: str) -> None:
    """The grid and its extras were counted on the GPU (on the CPU for :data:`NOT_COUNTED`),
    and the counts are their bits'."""
    where = "cpu" if g.run.method in NOT_COUNTED else "gpu"
    for name, grid in {"result": g, **g.extras}.items():
        assert grid.counted_on == where, f"{what}: {name} was counted on the {grid.counted_on}, not the {where}"
        assert grid.count == popcount(grid.words()), f"{what}: {name}'s count is not its bits'"


def torus():
    return load_mesh("gen:torus")


def nested_cubes(n: int):
    """``n`` nested box surfaces, all of them around the center: 2 n crossings per central column."""
    sizes = np.linspace(2.0, 15.0, n)
    m = trimesh.util.concatenate([trimesh.creation.box(extents=(s, s * 0.9, s * 0.8)) for s in sizes])
    return load_mesh((m.vertices, m.faces), name=f"nested-cubes-{n}")


def clipping_spec(mesh):
    """(37, 50, 29) voxels, a bit larger than the cubic fit's: rows of 37 voxels end in a word with
    5 valid bits, and the grid cuts the mesh along x and z."""
    fit = glvox.grid_for(mesh, 50)
    return GridSpec((37, 50, 29), fit.origin, fit.voxel_size * 1.1)


def variants(info):
    """Every non-default choice of the method's options (bools flipped), one at a time."""
    out = []
    for name, opt in info.options.items():
        if isinstance(opt.default, bool):
            out.append({name: not opt.default})
        elif opt.choices:
            out += [{name: c} for c in opt.choices if c != opt.default]
    return out


def tiles(stat) -> int:
    """The tiles a run drew: stats 'tiles' as [along u, along v] or as {axis: tiles}."""
    return int(np.prod(stat)) if isinstance(stat, list) else max(stat.values())


def run(name, mesh, spec, **options) -> VoxelGrid:
    return run_method(name, mesh, spec, allow_open=True, **options)


def test_every_dense_gpu_method_is_covered():
    names = {i.name for i in DENSE_GPU}
    # the methods issue 23 named, and those that counted on the GPU before it
    assert {"eisemann-solid", "eisemann-surface", "karabassi", "passalis-peel", "passalis-stencil",
            "scanline-ilv", "scanline-rlv", "scanline-slv", "ss-solid-tiled", "gwn-solid", "solid",
            "ss-conservative", "ss-6sep", "ss-solid", "carve-solid", "vote-solid"} <= names
    assert not any(n.startswith("reference-") for n in names)
    assert set(NOT_COUNTED) <= names


@pytest.mark.parametrize("info", DENSE_GPU, ids=lambda i: i.name)
def test_gpu_count_equals_the_bits(gl_context, info):
    mesh = torus()
    check_counted(run(info.name, mesh, glvox.grid_for(mesh, 40)), "torus 40^3")
    check_counted(run(info.name, mesh, clipping_spec(mesh)), "torus on (37, 50, 29), clipped")
    shells = nested_cubes(4)
    check_counted(run(info.name, shells, glvox.grid_for(shells, 33)), "4 nested cubes 33^3")
    for opts in variants(info):
        check_counted(run(info.name, mesh, clipping_spec(mesh), **opts), f"torus, clipped, {opts}")
    if "tile" in info.options:
        spec = GridSpec((70, 45, 66), glvox.grid_for(mesh, 70).origin, glvox.grid_for(mesh, 70).voxel_size)
        g = run(info.name, mesh, spec, tile=32)
        assert tiles(g.run.stats["tiles"]) > 1
        check_counted(g, "torus (70, 45, 66) in tiles of 32")


@pytest.mark.filterwarnings("ignore::glvox.errors.NotWatertightWarning")  # parity solids: streaks expected
@pytest.mark.parametrize("info", DENSE_GPU, ids=lambda i: i.name)
def test_gpu_count_on_a_shared_mesh(gl_context, glvox_mesh, info):
    mesh = load_mesh(glvox_mesh("stanford_bunny_bun_zipper.ply"))  # open: holes in its base
    check_counted(run(info.name, mesh, glvox.grid_for(mesh, 48)), "bunny 48^3")


def test_passalis_stencil_counts_a_nonempty_unclassifiable_mask(gl_context):
    """Columns through 4 nested cubes cross 8 faces in every direction: unclassifiable voxels,
    counted on the GPU beside the result."""
    mesh = nested_cubes(4)
    g = run("passalis-stencil", mesh, glvox.grid_for(mesh, 33))
    assert g.extras["unclassifiable"].count > 0
    check_counted(g, "passalis-stencil, 4 nested cubes")


def test_ss_solid_tiled_counts_over_several_tile_passes(gl_context):
    """1100 nested cubes on 16^3: more triangles per tile than one pass of ss/tile_process.comp takes,
    so words are flipped by several passes and the count follows every flip."""
    mesh = nested_cubes(1100)
    g = run("ss-solid-tiled", mesh, GridSpec((16, 16, 16), (-8.0, -8.0, -8.0), 1.0))
    assert g.run.stats["max_triangles_per_tile"] > ss_solid.TILE_TRIANGLES
    assert g.run.stats["tile_passes"] >= 2
    check_counted(g, "ss-solid-tiled, several passes")


def test_counted_on_says_cpu_without_a_gpu_count():
    spec = GridSpec((5, 3, 2), (0.0, 0.0, 0.0), 1.0)
    dense = np.zeros(spec.dims, dtype=bool)
    dense[1:4, 1, :] = True
    g = VoxelGrid(dense, spec)
    assert g.counted_on == "cpu" and g.count == 6
    w = VoxelGrid(words=g.words(), spec=spec)
    assert w.counted_on == "cpu" and w.count == 6
    assert VoxelGrid(words=g.words(), spec=spec, count=6).counted_on == "gpu"
