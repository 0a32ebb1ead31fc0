"""Exterior carving on the GPU: ``carve-solid`` (docs/design.md, "Carved solid").

binvox-style: a voxel is outside when a 6-connected path of voxels outside
the conservative surface joins it to the grid's boundary; everything else,
the surface included, is solid.  Defined for any mesh (open, multi-part,
interior faces): holes narrower than the surface's own thickness are sealed
by it, and ``close=K`` first seals gaps of up to K empty voxels between
surface voxels (a morphological closing by a box of side K + 1, the way
ShapeNet-style solids were made).  ``reference-carve`` is the same on the CPU.

Pipeline, all on the GPU until the final readback:

* ``transform``, ``voxelize``: ss-conservative's surface
  (:func:`glvox.methods.ss.surface.surface_on_gpu`, the same passes and
  buffers); the shared transform's plane snap (:func:`glvox.grid.snap_to_planes`)
  puts a face that the default fit lays on the grid's boundary exactly on it, so
  that rounding cannot drop that face and open the inside to the flood;
* ``close`` (close > 0): three dilations and three erosions along x, y and z
  (``carve/close.comp``) on a copy of the grid padded with empty voxels
  (``carve/pad.comp``), so the grid's border neither seals nor opens a gap;
* ``flood``: rounds of sweeps along x, y and z (``carve/sweep.comp``): the
  first x sweep seeds the free voxels on the grid's boundary, every sweep
  fills the free runs along its axis that hold an exterior voxel, forward and
  backward.  A flag set by the y and z sweeps is read back after each round:
  a round whose y and z sweeps add nothing leaves the exterior closed under
  all three axes (the x sweep before them already was), so the fill stops.
  ``stats['flood_rounds']`` counts the rounds;
* ``finish``: solid = not exterior, counted; ``readback`` of the z slices
  the surface can reach.
"""

from __future__ import annotations

import numpy as np

from ...gl.shaders import compute_program
from ...gpu.buffers import buffer_pool, mesh_buffers, read_grid_words
from ...gpu.dispatch import LOOP_BUDGET, barrier, bind, dispatch_1d, grid_uniforms, set_uniforms
from ...grid import GridSpec
from ...reference.carve import close_window
from ...results.voxels import VoxelGrid
from ..base import Method, MethodInfo, Requirements, register
from ..reference.registered import CLOSE_OPTION, check_close
from ..ss.surface import COMPUTE as SURFACE_COMPUTE, surface_on_gpu

_LOCAL = 64  # local_size_x of the carve shaders

#: Cells of a y or z column one sweep invocation walks, twice (forward and
#: back): far below LOOP_BUDGET.  Longer columns are split into segments that
#: meet in later rounds.
SEGMENT = 8192
assert 2 * SEGMENT < LOOP_BUDGET

#: carve-solid computes its surface with ss-conservative's ``simple`` variant on
#: grids up to this many voxels along their longest axis, ``specialized`` (the
#: default of ss-conservative, which wins at 1024^3) above: measured here on a
#: quiet machine, simple took 0.65-0.75x specialized's time on the bunny, the
#: armadillo and the dragon at 64^3-256^3, 0.6-1.0x at 512^3, 1.1-1.7x at
#: 1024^3 (``python compare/table1_ss_surface.py``).
SIMPLE_MAX_DIM = 512

#: Rounds of sweeps after which the flood fill gives up with an error instead
#: of looping on: every round but the last adds at least one voxel, and a
#: path needs a round per turn, so real meshes converge in a few (README);
#: this only guards against a broken flag.
MAX_ROUNDS = 10_000

_REQUIRES = Requirements(gl_version=430, limits={"GL_MAX_SHADER_STORAGE_BUFFER_BINDINGS": 9},
                         compute=(("carve/*.comp", {}),) + SURFACE_COMPUTE)


def surface_slices(spec, bufs) -> tuple[int, int]:
    """``(k0, nk)``: the z slices of ``spec`` that can hold a voxel of the conservative
    surface of the mesh of ``bufs``, hence of its closing (a closing by a box stays in
    the set's bounding box) and of its carved solid.

    A triangle touches voxel k only if its z range meets [k, k + 1]; one more
    slice each way covers the GPU's float32 rounding of the vertices.
    """
    z0 = (bufs.bounds[0, 2] - (spec.origin[2] - bufs.anchor[2])) / spec.voxel_size
    z1 = (bufs.bounds[1, 2] - (spec.origin[2] - bufs.anchor[2])) / spec.voxel_size
    nz = spec.dims[2]
    if not (np.isfinite(z0) and np.isfinite(z1)):
        return 0, nz
    k0 = int(max(np.floor(z0) - 2, 0))
    k1 = int(min(np.floor(z1) + 1, nz - 1))
    return (k0, k1 - k0 + 1) if k1 >= k0 else (0, 0)


def padded_spec(spec, k: int) -> GridSpec:
    """The grid the closing runs on: one word more on each side along x, ``hi`` voxels
    along y and z (:func:`close_window`; the dilation reaches ``lo <= hi`` voxels past
    the border, where the erosion reads it): ``carve/pad.comp``'s layout."""
    m = close_window(k)[1]
    _, ny, nz = spec.dims
    return GridSpec((32 * (spec.words_per_row + 2), ny + 2 * m, nz + 2 * m), (0, 0, 0), 1.0)


def close_on_gpu(ctx, spec, timer, pool, surface, k: int) -> None:
    """Stage ``close``: ``surface`` := its closing by a box of side ``k + 1``
    (:func:`glvox.reference.carve.close`), computed on a padded grid (pool buffers
    ``padded`` and ``padded_tmp``) so that the grid's border plays no part."""
    lo, hi = close_window(k)
    pspec = padded_spec(spec, k)
    a = pool.get("padded", pspec.n_words * 4, what=f"the {pspec.dims} padded grid of the closing", clear=False)
    b = pool.get("padded_tmp", pspec.n_words * 4, what=f"the {pspec.dims} padded grid of the closing",
                 clear=False)
    pad = [compute_program(ctx, "carve/pad.comp", {"UNPAD": u}) for u in (0, 1)]
    for p in pad:
        set_uniforms(p, {**grid_uniforms(spec, np.zeros(3)), "u_margin": hi})
    uniforms = {**grid_uniforms(pspec, np.zeros(3)), "u_lo": lo, "u_hi": hi}
    with timer.stage("close"):
        bind(pad[0], Grid=surface, Padded=a)
        dispatch_1d(ctx, pad[0], pspec.n_words, _LOCAL)
        barrier(ctx)
        src, dst = a, b
        for erode in (0, 1):
            for axis in range(3):
                prog = compute_program(ctx, "carve/close.comp", {"AXIS": axis, "ERODE": erode})
                set_uniforms(prog, uniforms)
                bind(prog, Src=src, Dst=dst)
                dispatch_1d(ctx, prog, pspec.n_words, _LOCAL)
                barrier(ctx)
                src, dst = dst, src
        bind(pad[1], Grid=surface, Padded=src)
        dispatch_1d(ctx, pad[1], spec.n_words, _LOCAL)
        barrier(ctx)


def flood_on_gpu(ctx, spec, timer, pool, blocker, ext) -> int:
    """Stage ``flood``: ``ext`` (cleared) := the voxels joined to the grid's boundary
    by 6-connected paths outside ``blocker``; ``pool`` holds the round's flag and each
    line's clean flag.  Returns the rounds of sweeps run."""
    uniforms = grid_uniforms(spec, np.zeros(3))
    nx, ny, nz = spec.dims
    wpr = spec.words_per_row
    vec = 4 if wpr % 4 == 0 else 2 if wpr % 2 == 0 else 1
    # every line starts dirty (0): carve/sweep.comp's clean flags
    clean = [pool.get(f"clean_{a}", n * 4) for a, n in (("x", ny * nz), ("y", wpr // vec * nz), ("z", wpr // vec * ny))]
    progs = [compute_program(ctx, "carve/sweep.comp", {"AXIS": a, "SEGMENT": SEGMENT, "VEC": vec}) for a in range(3)]
    for p in progs:
        set_uniforms(p, uniforms)
    work = [ny * nz, wpr // vec * nz * -(-ny // SEGMENT), wpr // vec * ny * -(-nz // SEGMENT)]
    zero = np.zeros(1, dtype="<u4").tobytes()
    flags = pool.get("flags", 4)
    rounds = 0
    with timer.stage("flood"):
        blocks = {"BlockerV": blocker, "ExteriorV": ext, "Flags": flags,
                  "CleanX": clean[0], "CleanY": clean[1], "CleanZ": clean[2]}
        while True:
            rounds += 1
            if rounds > MAX_ROUNDS:
                raise RuntimeError(f"carve-solid's flood fill did not converge in {MAX_ROUNDS} rounds")
            flags.write(zero)
            set_uniforms(progs[0], {"u_seed": rounds == 1})
            for axis in range(3):
                bind(progs[axis], **blocks)
                dispatch_1d(ctx, progs[axis], work[axis], _LOCAL)
                barrier(ctx)
            # y and z added nothing: the exterior is closed under every axis
            if np.frombuffer(flags.read(size=4), dtype="<u4")[0] == 0:
                return rounds


@register
class CarveSolid(Method):
    info = MethodInfo(
        name="carve-solid", kind="solid", pipeline="compute",
        paper="exterior carving (docs/design.md, 'Carved solid'; binvox-style) around the conservative surface of "
              "Schwarz & Seidel 2010, Sec. 3.1-3.2: a flood fill by sweeps along x, y and z on the GPU",
        summary="robust solid for any mesh: everything not 6-connected to the grid boundary outside the "
                "conservative surface (optionally closed first: close=K), surface included",
        reference="reference-carve", any_mesh=True,
        requires=_REQUIRES,
        options={"close": CLOSE_OPTION},
    )

    def run(self, mesh, spec, *, ctx, timer, close):
        check_close(close)
        pool = buffer_pool(ctx, self.info.name)
        variant = "simple" if max(spec.dims) <= SIMPLE_MAX_DIM else "specialized"
        surface, _ = surface_on_gpu(ctx, mesh, spec, timer, pool, variant=variant)
        ext = pool.get("exterior", spec.n_words * 4, what=f"the {spec.dims} exterior grid")
        if close:
            close_on_gpu(ctx, spec, timer, pool, surface, close)
        rounds = flood_on_gpu(ctx, spec, timer, pool, surface, ext)
        k0, nk = surface_slices(spec, mesh_buffers(ctx, mesh))
        per_slice = spec.dims[1] * spec.words_per_row
        count = pool.get("count", 4)
        finish = compute_program(ctx, "carve/finish.comp")
        set_uniforms(finish, {**grid_uniforms(spec, np.zeros(3)), "u_first_word": k0 * per_slice,
                              "u_words": nk * per_slice})
        with timer.stage("finish"):
            bind(finish, Exterior=ext, Count=count)
            dispatch_1d(ctx, finish, nk * per_slice, _LOCAL)
            barrier(ctx)
        with timer.stage("readback", gpu=False):
            # the solid lies in the surface's slices (the exterior holds the others)
            words = read_grid_words(ctx, ext, spec, (k0, nk))
            voxels = int(np.frombuffer(count.read(size=4), dtype="<u4")[0])
        timer.stats.update({"flood_rounds": rounds, "close": close, "solid_slices": nk, "surface_variant": variant})
        return VoxelGrid(words=words, spec=spec, count=voxels)
