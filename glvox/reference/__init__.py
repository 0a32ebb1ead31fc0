"""Exact CPU references (float64, voxel space) that every GPU method is tested against.

All functions take ``tris``, a (T, 3, 3) float64 array of triangle vertices
already transformed into voxel space (voxel ``(i, j, k)`` is the closed box
``[i, i+1] x [j, j+1] x [k, k+1]``, its center ``(i+.5, j+.5, k+.5)``), and
``dims = (nx, ny, nz)``, and return a dense (nx, ny, nz) bool array indexed
``[i, j, k]``.  Geometry outside the grid is clipped, never an error.

Surfaces (:mod:`.surface`)
    :func:`conservative_surface` (Schwarz & Seidel triangle/box test),
    :func:`conservative_surface_sat` (separating axes, independent check),
    :func:`six_separating_surface` (S&S Sec. 3.4).
Solids (:mod:`.solid`)
    :func:`solid` (parity of crossings along an axis, top-left fill rule),
    :func:`solid_vote` (the majority of the three axes' parities).
Winding numbers (:mod:`.winding`)
    :func:`winding` (generalized winding number at every center, exact by a
    decomposition into signed crossings and boundary strips),
    :func:`winding_direct` (the direct sum, its independent check),
    :func:`winding_ties`.
Ties (:mod:`.ties`)
    :func:`surface_ties`, :func:`solid_ties`, :func:`binvox_ties` (:mod:`.binvox_ties`), :func:`mismatch_is_tie`,
    :func:`orientation_ambiguous`, :func:`rounding_perturbation`, :func:`snap_ambiguous`
    and the tolerance :data:`TIE_EPS`.

The triangles are snapped (:meth:`glvox.mesh.Mesh.triangles_voxel`, the plane
snap of :func:`glvox.grid.snap_to_planes` that every method applies).
"""

from .binvox_ties import binvox_ties
from .solid import solid, solid_vote
from .surface import conservative_surface, conservative_surface_sat, six_separating_surface
from .ties import (TIE_EPS, flat_axes, float32_motion, mismatch_is_tie, orientation_ambiguous,
                   point_triangle_distance, rounding_perturbation, short_edges, snap_ambiguous, solid_ties,
                   surface_ties)
from .winding import boundary_edges, winding, winding_direct, winding_ties

__all__ = [
    "TIE_EPS",
    "binvox_ties",
    "boundary_edges",
    "conservative_surface",
    "conservative_surface_sat",
    "flat_axes",
    "float32_motion",
    "mismatch_is_tie",
    "orientation_ambiguous",
    "point_triangle_distance",
    "rounding_perturbation",
    "short_edges",
    "six_separating_surface",
    "snap_ambiguous",
    "solid",
    "solid_ties",
    "solid_vote",
    "surface_ties",
    "winding",
    "winding_direct",
    "winding_ties",
]
