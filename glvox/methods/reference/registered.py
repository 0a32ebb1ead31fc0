"""The exact CPU references (float64 numpy), registered as methods.

They are what every GPU method is checked against (docs/design.md, "Kinds of
result"); the geometry lives in :mod:`glvox.reference`.  ``reference-ldi``
gives the exact crossings of every pixel ray; its rays are checked with
:func:`glvox.reference.ldi.ray_ties` rather than a voxel tie set (an LDI is
compared ray by ray).
"""

from __future__ import annotations

import weakref
from typing import Any

import numpy as np

from ...errors import MethodError
from ...gpu.transform import gpu_triangles_voxel
from ...grid import snap_to_planes
from ...reference import (conservative_surface, six_separating_surface, solid, solid_ties, solid_vote, surface_ties,
                         winding, winding_ties)
from ...reference.binvox import binvox_solid, empty_cause, fine_snap_eps
from ...reference.carve import MAX_CLOSE, carve_ties, carved_solid
from ...reference.ldi import crossings
from ...reference.binvox_ties import binvox_ties
from ...results.ldi import LDI, close_odd
from ...results.voxels import VoxelGrid
from ..base import Method, MethodInfo, Option, register
from ..binvox.solid import OPTIONS as BINVOX_OPTIONS, fine_spec
from ..ldi.common import AXIS_OPTION, warn_open

_SS = "Schwarz & Seidel 2010"


class _CpuReference(Method):
    """Voxel-space triangles in float64 (snapped, as every method sees them), then
    one reference function; ``ties(tris, dims, eps)`` gives the tie set of that
    function's definition, and with ``ties_see_unsnapped`` it also gets the
    triangles before the snap (``unsnapped=``, for the coordinates the GPU may
    snap otherwise: :func:`glvox.reference.ties.snap_ambiguous`)."""

    has_ties = True
    ties_see_unsnapped = False
    #: the tie function also gets the GPU's float32 triangles (``gpu=``)
    ties_see_gpu = False

    @staticmethod
    def ties(tris, dims, eps, **unsnapped):
        raise NotImplementedError

    def tie_set(self, mesh, spec, eps, **options):
        # the references' options (reference-solid's axis) do not move their ties
        raw = spec.world_to_voxel(mesh.triangles())
        extra = {"unsnapped": raw} if self.ties_see_unsnapped else {}
        if self.ties_see_gpu:
            extra["gpu"] = gpu_triangles_voxel(mesh, spec)
        return self.ties(snap_to_planes(raw), spec.dims, eps, **extra)

    @staticmethod
    def compute(tris, dims, **options):
        raise NotImplementedError

    def run(self, mesh, spec, *, ctx, timer, **options):
        with timer.stage("setup", gpu=False):
            tris = mesh.triangles_voxel(spec)
        with timer.stage("voxelize", gpu=False):
            occ = self.compute(tris, spec.dims, **options)
        return VoxelGrid(occ, spec)


@register
class ReferenceConservative(_CpuReference):
    info = MethodInfo(
        name="reference-conservative", kind="surface", pipeline="cpu",
        paper=f"{_SS}, Sec. 3.1-3.2 (triangle/box overlap, touched voxels included)",
        summary="exact conservative (26-separating) surface: every voxel a triangle overlaps or touches",
        reference="reference-conservative",
    )
    compute = staticmethod(conservative_surface)
    ties = staticmethod(lambda tris, dims, eps, unsnapped=None, gpu=None: surface_ties(
        tris, dims, "conservative", eps, unsnapped, gpu))
    ties_see_unsnapped = True
    ties_see_gpu = True


@register
class Reference6Sep(_CpuReference):
    info = MethodInfo(
        name="reference-6sep", kind="surface", pipeline="cpu",
        paper=f"{_SS}, Sec. 3.4 (6-separating criterion after Huang et al. 1998)",
        summary="exact 6-separating (thin) surface",
        reference="reference-6sep",
    )
    compute = staticmethod(six_separating_surface)
    ties = staticmethod(lambda tris, dims, eps, unsnapped=None, gpu=None: surface_ties(
        tris, dims, "6sep", eps, unsnapped, gpu))
    ties_see_unsnapped = True
    ties_see_gpu = True


@register
class ReferenceSolid(_CpuReference):
    info = MethodInfo(
        name="reference-solid", kind="solid", pipeline="cpu",
        paper=f"{_SS}, Sec. 4.1 (parity of crossings at voxel centers, top-left fill rule)",
        summary="exact solid: voxel set iff its center is inside (parity along a ray)",
        reference="reference-solid",
        options={"axis": Option(0, "ray direction of the parity count (0=x, 1=y, 2=z)", (0, 1, 2))},
    )
    compute = staticmethod(solid)
    ties = staticmethod(solid_ties)
    ties_see_unsnapped = True


@register
class ReferenceVote(_CpuReference):
    info = MethodInfo(
        name="reference-vote", kind="solid", pipeline="cpu",
        paper=f"majority of reference-solid along x, y and z ({_SS}, Sec. 4.1 parity; VoxSurf, Open3D)",
        summary="exact three-axis vote: a voxel is set when two of its three parities of crossings say inside",
        reference="reference-vote", any_mesh=True,
    )
    compute = staticmethod(solid_vote)
    # a parity's verdict, hence the vote's, can flip only where the center is within eps of the surface
    ties = staticmethod(solid_ties)


#: carve-solid's and reference-carve's ``close`` option (one definition: the two
#: are compared with the same value).
CLOSE_OPTION = Option(0, "first seal gaps of up to this many empty voxels between surface voxels (a "
                         f"morphological closing by a box of side close + 1; 0 to {MAX_CLOSE})")


def check_close(close: int) -> int:
    """``close`` when it is a gap width carving supports, else a one-line MethodError."""
    if not 0 <= close <= MAX_CLOSE:
        raise MethodError(f"option close must be a gap width from 0 to {MAX_CLOSE} voxels, got {close}")
    return close


@register
class ReferenceCarve(_CpuReference):
    info = MethodInfo(
        name="reference-carve", kind="solid", pipeline="cpu",
        paper="exterior carving (docs/design.md, 'Carved solid'; binvox-style): a 6-connected flood fill "
              f"(scipy.ndimage.label) around the exact conservative surface of {_SS}, Sec. 3.1",
        summary="exact carved solid: every voxel not 6-connected to the grid boundary outside the "
                "conservative surface (closed first with close=K), surface included",
        reference="reference-carve", any_mesh=True,
        options={"close": CLOSE_OPTION},
    )
    @staticmethod
    def compute(tris, dims, close):
        return carved_solid(tris, dims, check_close(close))

    def tie_set(self, mesh, spec, eps, close=0):
        return carve_ties(mesh.triangles_voxel(spec), spec.dims, close, eps)


@register
class ReferenceBinvox(Method):
    """binvox's solid in float64 (:mod:`glvox.reference.binvox`); its tie set
    (:mod:`glvox.reference.binvox_ties`) holds the voxels whose verdict a motion of ``eps``
    can change: whole columns where a crossing is tied, the carving's ends where a
    wireframe pixel is."""

    has_ties = True

    info = MethodInfo(
        name="reference-binvox", kind="solid", pipeline="cpu",
        paper="binvox (P. Min): z-buffer carving (Karabassi et al. 1999) and parity voting "
              "(Nooruddin & Turk 2003) at the pixel-center rays, in float64",
        summary="exact binvox solid: carving | parity votes >= 3 of 6, surface included (mode, dilated)",
        # its tie set is whole columns (a tie in one crossing moves a column's interval or
        # parity), 6 % of the bunny's voxels at 64^3; it does not claim exactness to the
        # checks that excuse mismatches at ties (binvox-solid is checked against it and
        # against its float32 twin: tests/test_binvox.py)
        reference="reference-binvox", exact=False, any_mesh=True,
        options=BINVOX_OPTIONS,
    )

    def run(self, mesh, spec, *, ctx, timer, mode, dilated, surface, down, dmin, wire):
        with timer.stage("setup", gpu=False):
            tris = _drawn_triangles(mesh, spec, down)
        with timer.stage("voxelize", gpu=False):
            occ = binvox_solid(tris, spec.dims, mode, dilated, surface, down, dmin, wire)
        grid = VoxelGrid(occ, spec)
        if grid.count == 0:  # the run envelope warns with this cause
            timer.stats["suspicious"] = empty_cause("reference-binvox", mode, grid.spec.dims)
        return grid

    def tie_set(self, mesh, spec, eps, **options):
        o = {k: opt.default for k, opt in BINVOX_OPTIONS.items()} | options
        raw = spec.world_to_voxel(mesh.triangles())
        return binvox_ties(_drawn_triangles(mesh, spec, o["down"]), spec.dims, wire=o["wire"],
                           surface=o["surface"], down=o["down"], dilated=o["dilated"], eps=eps, unsnapped=raw)


def _drawn_triangles(mesh, spec, down: int) -> np.ndarray:
    """The triangles in the voxel units of ``spec``, snapped on the grid binvox draws:
    with ``down``, the finer one (as binvox-solid snaps them, within
    :func:`~glvox.reference.binvox.fine_snap_eps`), divided by ``2**down`` (exact)."""
    return mesh.triangles_voxel(fine_spec(spec, down), fine_snap_eps(down)) / 2 ** down


class _WindingCache:
    """The last few exact winding fields, so that a reference run and its tie set
    (or a test's several thresholds) share one evaluation: it is the costly part.
    Entries hold a weak reference to their mesh: a new mesh at a recycled id
    never matches.  A run served from here says so (``run.stats['cached']``),
    so that timings of it are not taken for the evaluation's (``glvox compare``
    marks those rows and leaves them out of its timing plots)."""

    def __init__(self, size: int = 2):
        self.size = size
        self._items: list[tuple[Any, tuple, np.ndarray]] = []

    def lookup(self, mesh, spec) -> tuple[np.ndarray, bool]:
        """The winding field of ``mesh`` on ``spec``, float64 (nx, ny, nz), and whether it was cached."""
        key = (spec.dims, tuple(spec.origin), spec.voxel_size)
        for ref, k, w in self._items:
            if ref() is mesh and k == key:
                return w, True
        w = winding(mesh.triangles_voxel(spec), spec.dims)
        self._items = [(weakref.ref(mesh), key, w)] + self._items[: self.size - 1]
        return w, False

    def get(self, mesh, spec) -> np.ndarray:
        return self.lookup(mesh, spec)[0]


@register
class ReferenceGwn(Method):
    info = MethodInfo(
        name="reference-gwn", kind="solid", pipeline="cpu",
        paper="Jacobson et al. 2013 (generalized winding number >= 1/2 at voxel centers; float64, exact "
              "decomposition into signed crossings and boundary strips, glvox.reference.winding)",
        summary="exact robust solid for any mesh: w >= threshold at centers; w in fields['winding']",
        reference="reference-gwn", any_mesh=True,
        options={"threshold": Option(0.5, "inside when w >= threshold"),
                 "shell": Option(False, "also set every voxel of the conservative surface")},
    )
    has_ties = True
    cache = _WindingCache()

    def run(self, mesh, spec, *, ctx, timer, threshold, shell):
        with timer.stage("winding", gpu=False):
            w, timer.stats["cached"] = self.cache.lookup(mesh, spec)
            occ = w >= threshold
        if shell:
            with timer.stage("shell", gpu=False):
                occ = occ | conservative_surface(mesh.triangles_voxel(spec), spec.dims)
        return VoxelGrid(occ, spec, fields={"winding": w.astype(np.float32)})

    def tie_set(self, mesh, spec, eps, threshold=0.5, shell=False):
        tris = mesh.triangles_voxel(spec)
        ties = winding_ties(tris, spec.dims, self.cache.get(mesh, spec), threshold, eps)
        if shell:
            ties |= surface_ties(tris, spec.dims, "conservative", eps)
        return ties


@register
class ReferenceLDI(Method):
    info = MethodInfo(
        name="reference-ldi", kind="ldi", pipeline="cpu",
        paper="exact ray/mesh crossings (float64) with the fill rule of reference-solid "
              "(Schwarz & Seidel 2010, Sec. 4.1)",
        summary="exact LDI on the CPU: every crossing of every pixel ray, sorted, rounded to float32",
        reference="reference-solid", exact=True,
        options={"axis": AXIS_OPTION},
    )

    def run(self, mesh, spec, *, ctx, timer, axis):
        warn_open(mesh, self.info.name)
        with timer.stage("setup", gpu=False):
            tris = mesh.triangles_voxel(spec)
        with timer.stage("crossings", gpu=False):
            rc = crossings(tris, spec.dims, axis)
            depths, counts = close_odd(rc.depths, rc.counts, spec.dims[axis])
        timer.stats.update({"axis": axis, "n_max": int(depths.shape[2]), "samples": int(counts.sum())})
        return LDI(depths.astype(np.float32), counts, spec, axis)
