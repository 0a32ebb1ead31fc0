"""Agreement with the exact references, proven ties, separability.

What every method's tests and the comparison use: a result is checked
against the reference its registry entry names, and each mismatch must lie
in the tie set docs/design.md defines (surfaces: the verdict flips with box
half-size 0.5 +/- TIE_EPS; solids: the verdict can flip when the mesh moves by
at most TIE_EPS voxel).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy import ndimage

from .grid import pack_bits, popcount, unpack_bits
from .methods import get_method, method_infos, run_method
from .reference import TIE_EPS
from .results.voxels import Comparison, VoxelGrid

@dataclass
class ReferenceCheck:
    """A result against its exact reference.

    Attributes
    ----------
    comparison : Comparison
        Missing / extra voxels and IoU against the reference.
    ties : int
        Size of the tie set.
    unexplained : (M, 3) int64
        Mismatching voxels that are *not* ties (must be empty for an exact method).
    """

    reference: str
    comparison: Comparison
    ties: int
    unexplained: np.ndarray

    @property
    def ok(self) -> bool:
        return len(self.unexplained) == 0

    def describe(self) -> str:
        c = self.comparison
        return (f"against {self.reference}: {c.n_missing} missing, {c.n_extra} extra, IoU {c.iou:.6f}; "
                f"{self.ties} tie voxels; {len(self.unexplained)} mismatches are not ties"
                + (f" (first: {self.unexplained[:5].tolist()})" if len(self.unexplained) else ""))


def tie_set(reference: str, mesh, spec, eps: float = TIE_EPS, **options) -> np.ndarray:
    """Dense (nx, ny, nz) bool tie set of ``reference`` (run with ``options``) for ``mesh`` on ``spec``."""
    method = get_method(reference)
    if not method.has_ties:
        known = sorted(i.name for i in method_infos() if get_method(i.name).has_ties)
        raise ValueError(f"no tie set is defined for {reference!r}; known: {known}")
    return method.tie_set(mesh, spec, eps, **options)


def check_against_reference(result: VoxelGrid, mesh, reference: str | None = None,
                            reference_grid: VoxelGrid | None = None,
                            ties: np.ndarray | None = None) -> ReferenceCheck:
    """Compare ``result`` with the exact reference and prove mismatches are ties.

    Parameters
    ----------
    result : VoxelGrid
        A method's result (``result.run`` names the method).
    mesh : glvox.mesh.Mesh
    reference : str, optional
        Reference method name; default the one the method's registry entry names.
    reference_grid : VoxelGrid, optional
        A precomputed reference result on the same grid.
    ties : (nx, ny, nz) bool, optional
        A precomputed :func:`tie_set` of the same reference, mesh and grid.
    """
    if reference is None:
        reference = get_method(result.run.method).info.reference
    spec = result.spec
    if reference_grid is None:
        reference_grid = run_method(reference, mesh, spec, allow_open=True)
    if ties is None:
        ties = tie_set(reference, mesh, spec)
    bad = not_tie_words(result.words(), reference_grid.words(), pack_bits(ties))
    unexplained = np.argwhere(unpack_bits(bad, spec.dims)).astype(np.int64)
    return ReferenceCheck(reference, result.compare(reference_grid), int(ties.sum()), unexplained)


def not_tie_words(words: np.ndarray, ref_words: np.ndarray, tie_words: np.ndarray) -> np.ndarray:
    """Packed mismatches of a result against its reference that lie outside the tie set.

    Parameters
    ----------
    words, ref_words, tie_words : uint32 (nz, ny, words_per_row)
        A result, its exact reference and the reference's proven tie set in
        glvox's packed layout (:func:`glvox.grid.pack_bits`), on one GridSpec.

    Returns
    -------
    uint32, the same shape
        Set where ``result != reference`` and the voxel is not a tie.
    """
    w, r = np.asarray(words, np.uint32), np.asarray(ref_words, np.uint32)
    return (w ^ r) & ~np.asarray(tie_words, np.uint32)


def agreement(words: np.ndarray, ref_words: np.ndarray, tie_words: np.ndarray | None = None) -> dict[str, Any]:
    """Counts of a result against its exact reference, on packed grids.

    What ``glvox compare`` and ``glvox bench`` report per row; the same
    verdict as :func:`check_against_reference` without unpacking to dense
    grids or listing voxels.

    Parameters
    ----------
    words, ref_words : uint32 (nz, ny, words_per_row)
        A result and its reference in glvox's packed layout (same GridSpec).
    tie_words : uint32, same shape, optional
        The reference's proven tie set, packed; None to skip the tie counts.

    Returns
    -------
    dict
        ``missing`` and ``extra`` voxels, ``iou`` (1.0 when both are empty),
        ``reference_voxels``; with ``tie_words`` also ``ties`` (size of the
        tie set) and ``not_ties`` (mismatches outside it: 0 for an exact method).
    """
    w, r = np.asarray(words, np.uint32), np.asarray(ref_words, np.uint32)
    inter, union = popcount(w & r), popcount(w | r)
    out: dict[str, Any] = {"missing": popcount(r & ~w), "extra": popcount(w & ~r),
                           "iou": 1.0 if union == 0 else inter / union, "reference_voxels": popcount(r)}
    if tie_words is not None:
        out["not_ties"] = popcount(not_tie_words(w, r, tie_words))
        out["ties"] = popcount(tie_words)
    return out


_STRUCT = {6: ndimage.generate_binary_structure(3, 1), 26: ndimage.generate_binary_structure(3, 3)}


def separation_leaks(surface: np.ndarray, inside: np.ndarray, connectivity: int) -> np.ndarray:
    """Inside voxels reachable from the grid border through unset surface voxels.

    A surface voxelization of a closed mesh is N-separating when no N-path
    of voxels not in ``surface`` joins the outside to the inside: label the
    complement of ``surface`` with N-connectivity (in a grid padded by one
    empty layer, so the border is one outside component) and count the
    ``inside`` voxels (typically the reference solid) in the outside component.

    Parameters
    ----------
    surface, inside : (nx, ny, nz) bool
    connectivity : {6, 26}

    Returns
    -------
    (M, 3) int64
        Indices of the inside voxels reached from outside; empty when the
        surface separates.
    """
    if connectivity not in _STRUCT:
        raise ValueError(f"connectivity must be 6 or 26, got {connectivity!r}")
    surface = np.asarray(surface, bool)
    free = np.pad(~surface, 1, constant_values=True)
    labels, _ = ndimage.label(free, structure=_STRUCT[connectivity])
    outside = labels == labels[0, 0, 0]
    return np.argwhere(outside[1:-1, 1:-1, 1:-1] & np.asarray(inside, bool) & ~surface)
