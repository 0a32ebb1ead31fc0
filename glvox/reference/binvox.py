"""Exact CPU binvox solid (float64, voxel space): ``reference-binvox``, the twin of
``binvox-solid`` (:mod:`glvox.methods.binvox.solid`, whose docstring states binvox's rules).

Every crossing of a column's center line with a triangle is found by
:func:`glvox.reference.solid.column_crossings` (the top-left rule, winding
ignored); ``slot = floor(q + 1/2)`` clipped to [0, n] is the first voxel whose
center lies beyond the crossing, ``floor(q)`` the voxel holding it.

* carving along an axis keeps ``max(lo - d, 0) <= k < hi + d`` with ``lo``, ``hi`` the
  slots of the nearest and farthest crossings and ``d`` 1 when dilated, 0 otherwise;
  the carve is the AND of the three axes, and a column with no crossing keeps nothing;
  with ``wire`` (binvox ``-aw``) the points of the wireframe (:func:`wire_hits`) count as
  crossings for carving (not for voting or the surface);
* voting: along each axis the parity of the crossings with ``slot <= k`` and the
  parity of the others are two votes;
* result: ``carve | (votes >= 3)`` (``'default'``), ``carve``, or ``votes >= 3``,
  OR the voxels holding a crossing when ``surface``.
"""

from __future__ import annotations

from typing import Sequence

import numpy as np

from ..tolerances import SNAP_EPS
from ._candidates import check_dims, check_tris, normals
from .solid import axis_signs, column_crossings


def fine_snap_eps(down: int) -> float:
    """The plane snap's distance on the grid binvox draws with ``down`` halvings, in
    its (finer) voxels: ``SNAP_EPS`` voxels of the grid returned, as for every other
    method.  The finer grid's own ``SNAP_EPS`` would be ``2**-down`` of that, and a
    coordinate ``SNAP_EPS / 2`` off a plane, which every method snaps for the rounding
    of a move by whole voxels, would then sit on binvox's threshold."""
    return SNAP_EPS * 2 ** int(down)

MODES = ("default", "carve", "vote")


def axis_crossings(tris: np.ndarray, dims: tuple[int, int, int], axis: int):
    """(ju, jv, q): every crossing of the column center lines along ``axis``."""
    n = normals(tris)
    keep = axis_signs(tris, n, axis) != 0
    parts = list(column_crossings(tris[keep], n[keep], dims, axis))
    if not parts:
        z = np.zeros(0, np.int64)
        return z, z, np.zeros(0)
    return (np.concatenate([p[1] for p in parts]), np.concatenate([p[2] for p in parts]),
            np.concatenate([p[3] for p in parts]))


def view_to_grid(a: np.ndarray, axis: int) -> np.ndarray:
    """(n_axis, n_u, n_v) -> (nx, ny, nz) with u = axis + 1, v = axis + 2 (mod 3)."""
    order = [0, 0, 0]
    order[axis], order[(axis + 1) % 3], order[(axis + 2) % 3] = 0, 1, 2
    return np.transpose(a, order)


def wire_hits(tris: np.ndarray, dims: tuple[int, int, int], axis: int):
    """(ju, jv, q): the pixels of the wireframe (every triangle edge drawn as a line) in
    the view along ``axis``, and the line's depth there, in voxel units.

    binvox ``-aw`` also renders the model in wireframe, so that parts thinner than a pixel
    (edge-on triangles, which no pixel-center ray crosses) still stop the carving.  The
    line rule, one pixel per column of the line's major axis (as GL's lines): along the
    major axis (``|du| >= |dv|``: u) the pixel centers ``c = i + 1/2`` with
    ``min <= c < max`` of the two end points, and along the minor axis the pixel holding
    the line at ``c``, ``j = floor(p_minor)``; ``p`` is interpolated from the end point
    with the smaller major coordinate (``t = (c - s) / (e - s)``, ``p = s + t (e - s)``),
    so both directions of a shared edge give the same pixels.  Edges parallel to the rays
    draw nothing.  ``shaders/binvox/wire.frag`` decides the same in double.
    """
    u, v = (axis + 1) % 3, (axis + 2) % 3
    ends = np.concatenate([tris[:, [0, 1]], tris[:, [1, 2]], tris[:, [2, 0]]])
    du, dv = ends[:, 1, u] - ends[:, 0, u], ends[:, 1, v] - ends[:, 0, v]
    out = []
    for major, minor, sel in ((u, v, np.abs(du) >= np.abs(dv)), (v, u, np.abs(du) < np.abs(dv))):
        e = ends[sel]
        first = np.where((e[:, 0, major] <= e[:, 1, major])[:, None], e[:, 0], e[:, 1])
        last = np.where((e[:, 0, major] <= e[:, 1, major])[:, None], e[:, 1], e[:, 0])
        i0 = np.ceil(first[:, major] - 0.5).astype(np.int64)
        i1 = np.ceil(last[:, major] - 0.5).astype(np.int64)  # centers c with first <= c < last
        i0 = np.maximum(i0, 0)
        i1 = np.minimum(i1, dims[major])
        cnt = np.maximum(i1 - i0, 0)
        idx = np.repeat(np.arange(len(e)), cnt)
        i = i0[idx] + np.arange(int(cnt.sum())) - np.repeat(np.cumsum(cnt) - cnt, cnt)
        s, f = first[idx], last[idx]
        t = (i + 0.5 - s[:, major]) / (f[:, major] - s[:, major])
        j = np.floor(s[:, minor] + t * (f[:, minor] - s[:, minor]))
        q = s[:, axis] + t * (f[:, axis] - s[:, axis])
        ok = (j >= 0) & (j < dims[minor])
        i, j, q = i[ok], j[ok].astype(np.int64), q[ok]
        out.append((i, j, q) if major == u else (j, i, q))
    return tuple(np.concatenate([o[k] for o in out]) for k in range(3))


def binvox_parts(tris: np.ndarray, dims: Sequence[int], dilated: bool = False, wire: bool = False,
                 cover: Sequence[np.ndarray] | None = None):
    """The parts of binvox's solid: (carve, votes, surface).

    Parameters
    ----------
    tris : (T, 3, 3) float64
        Voxel-space triangles (any mesh: open, double-sided, soup).
    dims : (3,) int
    dilated : bool
        binvox ``-dc``.
    wire : bool
        binvox ``-aw``: the wireframe (:func:`wire_hits`) also stops the carving.
    cover : three (T, 3, 3) float64, optional
        Per ray axis, the triangles whose crossings count, where they differ from
        ``tris`` (binvox-solid's, whose coverage test rounds the coordinates across
        each view's rays to its fixed point: :func:`glvox.methods.binvox.solid.gpu_cover_triangles`);
        the wireframe is drawn from ``tris``.

    Returns
    -------
    carve : (nx, ny, nz) bool
    votes : (nx, ny, nz) int8
        0 to 6.
    surface : (nx, ny, nz) bool
        The voxels holding a crossing.
    """
    tris = check_tris(tris)
    dims = check_dims(dims)
    carve = np.ones(dims, dtype=bool)
    votes = np.zeros(dims, dtype=np.int8)
    surface = np.zeros(dims, dtype=bool)
    for axis in range(3):
        keep, vote, held = axis_parts(tris, dims, axis, dilated, wire,
                                      None if cover is None else check_tris(cover[axis]))
        carve &= view_to_grid(keep, axis)
        votes += view_to_grid(vote, axis).astype(np.int8)
        surface |= view_to_grid(held, axis)
    return carve, votes, surface


def axis_parts(tris: np.ndarray, dims: tuple[int, int, int], axis: int, dilated: bool = False,
               wire: bool = False, cover: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """One axis of :func:`binvox_parts`, in the view's order (k along ``axis``, then the
    columns (u, v)): (keep (n, n_u, n_v) bool, votes 0-2 uint8, voxels holding a crossing);
    the crossings those of ``cover`` where given."""
    n = dims[axis]
    nu, nv = dims[(axis + 1) % 3], dims[(axis + 2) % 3]
    d = 1 if dilated else 0
    ju, jv, q = axis_crossings(tris if cover is None else cover, dims, axis)
    slot = np.clip(np.floor(q + 0.5), 0, n).astype(np.int64)
    lo = np.full((nu, nv), n + 1, dtype=np.int64)
    hi = np.full((nu, nv), -1, dtype=np.int64)
    np.minimum.at(lo, (ju, jv), slot)
    np.maximum.at(hi, (ju, jv), slot)
    if wire:
        wu, wv, wq = wire_hits(tris, dims, axis)
        wslot = np.clip(np.floor(wq + 0.5), 0, n).astype(np.int64)
        np.minimum.at(lo, (wu, wv), wslot)
        np.maximum.at(hi, (wu, wv), wslot)
    k = np.arange(n)[:, None, None]
    keep = (k >= np.maximum(lo - d, 0)[None]) & (k < (hi + d)[None]) & (hi >= 0)[None]
    flips = np.zeros((n + 1, nu, nv), dtype=np.uint8)
    np.bitwise_xor.at(flips, (slot, ju, jv), 1)
    before = np.bitwise_xor.accumulate(flips, axis=0)
    total = before[n]
    before = before[:n]
    hold = np.floor(q)
    ok = (hold >= 0) & (hold < n)
    held = np.zeros((n, nu, nv), dtype=bool)
    held[hold[ok].astype(np.int64), ju[ok], jv[ok]] = True
    return keep, before + (before ^ total[None]), held


def halve(occ: np.ndarray, dmin: int = 4) -> np.ndarray:
    """binvox ``-down``: (nx, ny, nz) bool with even dims -> (nx/2, ny/2, nz/2), a voxel set
    when at least ``dmin`` of the 8 it covers are."""
    nx, ny, nz = (d // 2 for d in occ.shape)
    return occ.reshape(nx, 2, ny, 2, nz, 2).sum(axis=(1, 3, 5)) >= dmin


def binvox_solid(tris: np.ndarray, dims: Sequence[int], mode: str = "default", dilated: bool = False,
                 surface: bool = True, down: int = 0, dmin: int = 4, wire: bool = False,
                 cover: Sequence[np.ndarray] | None = None) -> np.ndarray:
    """binvox's solid of voxel-space triangles (``reference-binvox``; see the module docstring).

    Parameters
    ----------
    tris : (T, 3, 3) float64
    dims : (3,) int
    mode : {'default', 'carve', 'vote'}
    dilated : bool
    surface : bool
    down : int
        binvox ``-down`` repeated: computed at ``2**down`` times ``dims``, then halved
        ``down`` times (:func:`halve` with ``dmin``).
    dmin : int
    wire : bool
        binvox ``-aw`` (:func:`wire_hits`).
    cover : three (T, 3, 3) float64, optional
        :func:`binvox_parts`' ``cover``, in the units of ``tris``.

    Returns
    -------
    (nx, ny, nz) bool
    """
    if mode not in MODES:
        raise ValueError(f"mode must be one of {MODES}, got {mode!r}")
    if down:
        f = 2 ** down
        out = binvox_solid(np.asarray(tris, dtype=np.float64) * f, [d * f for d in dims], mode, dilated, surface,
                          wire=wire, cover=None if cover is None else [np.asarray(c, np.float64) * f for c in cover])
        for _ in range(down):
            out = halve(out, dmin)
        return out
    carve, votes, surf = binvox_parts(tris, dims, dilated, wire, cover)
    out = np.zeros(carve.shape, dtype=bool)
    if mode in ("default", "carve"):
        out |= carve
    if mode in ("default", "vote"):
        out |= votes >= 3
    if surface:
        out |= surf
    return out


def empty_cause(method: str, mode: str, dims: Sequence[int]) -> str:
    """Why binvox's solid can be empty, as one line (the run envelope's warning): parity
    voting alone cancels on double-sided meshes, carving alone on a mesh open towards
    every view; the default combines both."""
    return (f"0 voxels (empty) from {method} (mode={mode!r}) on {tuple(int(d) for d in dims)}: parity voting "
            "alone empties double-sided meshes (every ray crosses each face twice) and carving alone "
            "empties a mesh open towards every view; use -O mode=default")
