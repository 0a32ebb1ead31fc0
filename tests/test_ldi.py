"""Layered depth images: Leung & Wang's conservative LDI, the exact depth-peeling LDI,
the CPU reference, the LDI type, and the intersecting volume (Leung & Wang 2013 Sec. III, V-A).

Every check is against exact float64 ray/mesh crossings (glvox.reference.ldi) with the
docs/design.md tie rule: a ray whose set of crossed triangles can change when the mesh moves
by TIE_EPS is a tie and left out, and a crossing may move by its
``crossing_tolerance`` (TIE_EPS times the slope of its triangle).  Nothing is tolerated
by count.

* well-formed: counts even, samples sorted, NaN exactly past the counts, in [0, n_axis];
* conservative: every exact interior segment of a non-tie ray lies in one LDI interval;
* exact where the paper says so: at a LOD-C where no two crossings of a ray share a cell
  (and none sits within its tolerance of a cell boundary), the samples are the crossings;
  peel-ldi and reference-ldi everywhere.
"""

from __future__ import annotations

import json
import math
import subprocess
import sys

import numpy as np
import pytest
import trimesh
from conftest import SLOW
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

import glvox
from glvox.errors import (FormatError, GridError, LimitError, MethodError, NotWatertightError,
                          NotWatertightWarning)
from glvox.grid import GridSpec, ldi_axes
from glvox.mesh import load_mesh
from glvox.methods import run_method
from glvox.methods.depth import raster as depth_raster
from glvox.methods.ldi.leung_wang_passes import mesh_motion
from glvox.metrics import check_against_reference, tie_set
from glvox.reference.ldi import crossing_tolerance, crossings, ray_ties
from glvox.results.ldi import LDI, close_odd
from glvox.testing import slivers
from glvox.testing.leaks import live_gl_objects
from glvox.study.selftest import TIE_HULL
from glvox.tolerances import SNAP_EPS, TIE_EPS

WATERTIGHT = ("cad_fandisk.off", "cad_featuretype.stl", "cad_rocker_arm.obj", "cad_wingnut.obj",
              "depth_reduced_diamond_lattice.stl", "stanford_armadillo_libigl_86k.obj")


def depth_rounding(n_axis: int) -> float:
    """How far a stored sample can sit from the GPU's double crossing, voxels: the normalized
    depth d (or 1 - d) in float32 (2^-24 of n_axis) and the output in float32 (2^-24 of
    the depth) -- the conservative method rounds both outwards; twice their sum is allowed."""
    return 2.0 ** -22 * n_axis


# -- helpers: exact rays ---------------------------------------------------------


class Exact:
    """Exact crossings and tie rays of a mesh on a grid along an axis."""

    def __init__(self, mesh, spec, axis):
        tris = mesh.triangles_voxel(spec)
        self.rc = crossings(tris, spec.dims, axis)
        self.ties = ray_ties(tris, spec.dims, axis)
        self.n_axis = spec.dims[axis]
        # leung-wang-ldi widens each sample outwards by what the mesh's motion on the GPU
        # (float32 upload, plane snap) can do to its crossing: m (1 + (|n_u| + |n_v|) / |n_a|)
        # <= m (1 + sqrt(2 (slope^2 - 1))) voxels (ldi/depths.frag), on top of the tie tolerance
        # (the running maximum that keeps the samples sorted can pass a neighbour's widening
        # on: the ray's largest is allowed on each of its samples)
        slope = self.rc.slopes
        w = (mesh_motion(mesh, spec) + SNAP_EPS) * (1.0 + np.sqrt(2.0 * np.maximum(slope * slope - 1.0, 0.0)))
        w = np.where(np.isnan(w), 0.0, w)
        self.widening = np.broadcast_to(w.max(axis=2, initial=0.0)[:, :, None], w.shape)
        assert np.all(self.rc.counts[~self.ties] % 2 == 0), "a closed mesh crosses a non-tie ray an odd number of times"

    def intervals(self):
        """Flat exact interior segments of the non-tie rays: ray, a, b, tol_a, tol_b."""
        return flat_intervals(self.rc.depths, self.rc.counts, crossing_tolerance(self.rc.slopes), self.ties)


def flat_intervals(depths, counts, tol, skip):
    n_rays = counts.size
    d = depths.reshape(n_rays, -1)
    t = tol.reshape(n_rays, -1)
    valid = (np.arange(d.shape[1]) < counts.reshape(-1)[:, None]) & ~skip.reshape(-1)[:, None]
    ray = np.broadcast_to(np.arange(n_rays)[:, None], d.shape)[valid]
    vals, tols = d[valid], t[valid]
    return ray[0::2], vals[0::2], vals[1::2], tols[0::2], tols[1::2]


def ldi_union(ldi: LDI):
    """The LDI's intervals, flat and sorted (ray, lo, hi), intervals that touch merged."""
    n_rays = ldi.counts.size
    d = ldi.depths.reshape(n_rays, -1).astype(np.float64)
    valid = np.arange(d.shape[1]) < ldi.counts.reshape(-1)[:, None]
    ray = np.broadcast_to(np.arange(n_rays)[:, None], d.shape)[valid][0::2]
    vals = d[valid]
    lo, hi = vals[0::2], vals[1::2]
    if len(lo) == 0:
        return ray, lo, hi
    new = np.ones(len(lo), bool)
    new[1:] = (ray[1:] != ray[:-1]) | (lo[1:] > hi[:-1])
    starts = np.flatnonzero(new)
    return ray[starts], lo[starts], np.maximum.reduceat(hi, starts)


def uncovered(ldi: LDI, ray, a, b, ta, tb) -> np.ndarray:
    """Indices of exact segments [a, b] (shrunk by their tolerances) not inside one LDI interval."""
    mray, mlo, mhi = ldi_union(ldi)
    a2, b2 = a + ta, b - tb
    check = a2 <= b2  # a segment shorter than its tolerance needs no cover
    stride = ldi.spec.dims[ldi.axis] + 16.0
    keys = mray * stride + mlo
    k = np.searchsorted(keys, ray * stride + a2, side="right") - 1
    kk = np.maximum(k, 0)
    ok = (k >= 0) & (mray[kk] == ray) & (mhi[kk] >= b2) if len(mray) else np.zeros(len(ray), bool)
    return np.flatnonzero(check & ~ok)


def assert_well_formed(ldi: LDI):
    d, c = ldi.depths, ldi.counts
    assert d.dtype == np.float32 and c.dtype == np.int32
    p, q = ldi_axes(ldi.axis)
    assert d.shape[:2] == c.shape == (ldi.spec.dims[p], ldi.spec.dims[q])
    assert np.all(c % 2 == 0), f"odd counts on {np.argwhere(c % 2)[:5].tolist()}"
    valid = np.arange(ldi.n_max) < c[:, :, None]
    assert np.array_equal(~np.isnan(d), valid), "NaN must be exactly past each ray's count"
    assert ldi.n_max == (c.max() if c.size else 0)
    v = d[valid]
    assert v.min(initial=0) >= 0 and v.max(initial=0) <= ldi.spec.dims[ldi.axis]
    both = valid[:, :, 1:]
    assert np.all(d[:, :, 1:][both] >= d[:, :, :-1][both]), "samples must be sorted"


def assert_conservative(ldi: LDI, ex: Exact):
    ray, a, b, ta, tb = ex.intervals()
    bad = uncovered(ldi, ray, a, b, ta, tb)
    if len(bad):
        i = bad[0]
        pix = np.unravel_index(ray[i], ldi.counts.shape)
        raise AssertionError(
            f"{len(bad)} exact segments not enclosed, first ray {tuple(int(x) for x in pix)}: exact "
            f"[{a[i]:.6f}, {b[i]:.6f}], LDI {ldi.ray(*pix).tolist()}")


def eligible_for_equality(ex: Exact, lod_c: int) -> np.ndarray:
    """Non-tie rays whose crossings lie in distinct LOD-C cells, each farther than its
    tolerance from an inner cell boundary (the far and near faces are not ambiguous)."""
    q = ex.rc.depths
    valid = ~np.isnan(q)
    tol = crossing_tolerance(ex.rc.slopes) + depth_rounding(ex.n_axis)  # the cell is the unwidened crossing's
    c = np.where(valid, q, 0.0) * lod_c / ex.n_axis
    cell = np.clip(np.floor(c), 0, lod_c - 1)
    b = np.round(c)
    inner = (b >= 1) & (b <= lod_c - 1)
    margin = np.where(inner, np.abs(c - b) * ex.n_axis / lod_c, np.inf)
    ok = np.all((margin > tol) | ~valid, axis=2)
    both = valid[:, :, 1:]
    ok &= np.all((cell[:, :, 1:] != cell[:, :, :-1]) | ~both, axis=2)
    return ok & ~ex.ties


def assert_equal_on(ldi: LDI, ex: Exact, rays: np.ndarray):
    c = ex.rc.counts
    assert np.array_equal(ldi.counts[rays], c[rays]), \
        f"counts differ on {np.argwhere(rays & (ldi.counts != c))[:5].tolist()}"
    n = ex.rc.depths.shape[2]
    valid = (np.arange(n) < c[:, :, None]) & rays[:, :, None]
    tol = crossing_tolerance(ex.rc.slopes) + depth_rounding(ex.n_axis) + ex.widening
    got = np.full(ex.rc.depths.shape, np.nan)
    k = min(n, ldi.n_max)  # rays with fewer samples than the exact ones are not in ``rays``
    got[:, :, :k] = ldi.depths[:, :, :k]
    err = np.abs(got - ex.rc.depths)
    bad = valid & ~(err <= tol)
    assert not bad.any(), (f"{bad.sum()} samples differ from the exact crossings beyond tolerance, "
                           f"first {np.argwhere(bad)[:3].tolist()}")


def check_conservative_run(mesh, spec, axis=2, **opts) -> tuple[LDI, Exact]:
    ldi = run_method("leung-wang-ldi", mesh, spec, axis=axis, **opts)
    assert_well_formed(ldi)
    ex = Exact(mesh, spec, axis)
    assert_conservative(ldi, ex)
    return ldi, ex


# -- meshes ----------------------------------------------------------------------


def box_mesh(lo, hi, name="box"):
    b = trimesh.creation.box(bounds=[lo, hi])
    return b.vertices, b.faces


def join(parts, name):
    vs, fs, off = [], [], 0
    for v, f in parts:
        vs.append(np.asarray(v, float))
        fs.append(np.asarray(f) + off)
        off += len(v)
    return load_mesh((np.concatenate(vs), np.concatenate(fs)), name=name)


def nest_of_shells(shells: int, gap: float = 0.05, subdivisions: int = 3, center=(0.0, 0.0, 0.0)):
    """``shells`` concentric spherical shells (each a solid between two spheres), radii
    1, 1 - gap, 1 - 2 gap, ...: 4 shells x 2 spheres = 8 crossings on the central ray per shell pair."""
    parts = []
    base = trimesh.creation.icosphere(subdivisions, radius=1.0)
    for k in range(2 * shells):
        r = 1.0 - k * gap
        faces = base.faces if k % 2 == 0 else base.faces[:, ::-1]
        parts.append((base.vertices * r + np.asarray(center), faces))
    return join(parts, f"nest{shells}")


def sphere(radius=1.0, center=(0.0, 0.0, 0.0), subdivisions=4):
    s = trimesh.creation.icosphere(subdivisions, radius=radius)
    return load_mesh((s.vertices + np.asarray(center), s.faces), name="sphere")


UNIT = GridSpec((8, 8, 8), (0.0, 0.0, 0.0), 1.0)


def close_to(actual, expected, n_axis):
    """Samples (..., k) equal to ``expected`` (k,) up to float32 storage."""
    actual = np.asarray(actual, np.float64)
    np.testing.assert_allclose(actual, np.broadcast_to(expected, actual.shape), rtol=0,
                               atol=depth_rounding(n_axis))


# -- hand-worked -----------------------------------------------------------------


def test_encloses_the_true_mesh_where_the_snap_moves_steep_faces(gl_context):
    """Leung & Wang's claim is per ray: the sampled intervals contain the exact ones, of the
    mesh as given, not only of the snapped mesh every method sees.  A tall thin tetrahedron
    (side faces about 20 times steeper than flat) with every coordinate 3e-4 voxel off a
    voxel or center plane: the snap (SNAP_EPS = 2^-11) moves them all, and on the side faces
    a move of 3e-4 across the ray moves the crossing by about 6e-3 along it.  Checked with
    no tolerance on every ray that the motion cannot uncover or cover (ray_ties with the
    motion as eps), at a LOD-C where the samples are the crossings themselves."""
    d = 3e-4
    v = np.array([[1.5 + d, 1.5 - d, 1.0 + d], [6.5 - d, 2.0 + d, 1.5 - d], [3.0 + d, 6.5 - d, 1.0 - d],
                  [3.5 - d, 3.5 + d, 60.5 - d]])
    f = np.array([[0, 2, 1], [0, 1, 3], [1, 2, 3], [2, 0, 3]])
    mesh = load_mesh((v, f), name="steep")
    spec = GridSpec((8, 8, 64), (0.0, 0.0, 0.0), 1.0)
    tris = v[f]  # the true mesh in voxel space (unit voxels at the origin), unsnapped
    assert np.abs(tris - mesh.triangles_voxel(spec)).max() == pytest.approx(d)  # the snap moved them
    exact = crossings(tris, spec.dims, 2)
    ties = ray_ties(tris, spec.dims, 2, eps=2 * SNAP_EPS)
    ldi = run_method("leung-wang-ldi", mesh, spec, lod_c=8192)
    assert_well_formed(ldi)
    checked = 0
    for p, q in zip(*np.nonzero((exact.counts > 0) & ~ties)):
        e = exact.depths[p, q, :exact.counts[p, q]]
        s = ldi.ray(p, q).astype(np.float64)
        assert len(s) == len(e) and np.all(s[0::2] <= e[0::2]) and np.all(s[1::2] >= e[1::2]), \
            f"ray {(int(p), int(q))}: exact {e.tolist()}, LDI {s.tolist()}"
        checked += 1
    assert checked >= 8


def test_a_face_along_the_rays_adds_nothing_beyond_a_cell(gl_context):
    """The hull whose face [1, 3, 2] is parallel to z and whose projection runs through
    column centers (tests/test_eisemann.py): the float32 upload makes that face a steep
    sliver, whose widened samples spanned its whole height (9 voxels) where its section
    through the ray is a point of the face.  Bounded by the section as well, the LDI stays
    conservative and adds no voxel center farther than a LOD-C cell outside."""
    mesh = load_mesh(TIE_HULL, name="edge-on hull")
    spec = glvox.grid_for(mesh, dims=(35, 59, 22))
    ldi, _ = check_conservative_run(mesh, spec)
    got = ldi.to_grid().dense()
    ref = run_method("reference-solid", mesh, spec).dense()
    near = tie_set("reference-solid", mesh, spec, eps=max(22 / 1024, TIE_EPS) + TIE_EPS)
    assert not (ref & ~got).any()
    assert not (got & ~ref & ~near).any(), np.argwhere(got & ~ref & ~near)[:5].tolist()


def test_a_box_is_sampled_at_its_faces(gl_context):
    """One crossing per cell (an EV and an LV): the samples are the faces' depths."""
    mesh = join([box_mesh((1.2, 0.3, 2.6), (5.7, 4.4, 6.1))], "box")
    for lod_c in (8, 80, 1024):
        ldi = run_method("leung-wang-ldi", mesh, UNIT, lod_c=lod_c)
        assert_well_formed(ldi)
        inside = np.zeros((8, 8), bool)
        inside[1:6, 0:4] = True  # pixel centers i + 1/2 in (1.2, 5.7) x (0.3, 4.4)
        assert np.array_equal(ldi.counts, np.where(inside, 2, 0))
        close_to(ldi.depths[inside], [2.6, 6.1], 8)
        # rounded outwards: the entering sample never after the face, the leaving never before
        assert np.all(ldi.depths[inside][:, 0] <= np.float32(2.6)) and np.all(ldi.depths[inside][:, 1] >= 6.1)
        assert ldi.run.stats["draws"] == 3  # 2 + ceil(n_max / 32) rendering passes (Sec. I)


def test_parts_sharing_a_cell_are_merged_conservatively(gl_context):
    """Leung & Wang's Fig. 2: two thin plates inside one cell (an ELV) give one interval from
    the first entering to the last leaving crossing; a gap inside a cell (an LEV) is filled;
    with cells finer than the parts, each is sampled on its own."""
    mesh = join([box_mesh((0.0, 0.0, 2.1), (8.0, 8.0, 2.3)), box_mesh((0.0, 0.0, 2.6), (8.0, 8.0, 2.8)),
                 box_mesh((0.0, 0.0, 4.5), (8.0, 8.0, 5.4)), box_mesh((0.0, 0.0, 5.6), (8.0, 8.0, 6.5))],
                 "plates")
    coarse = run_method("leung-wang-ldi", mesh, UNIT, lod_c=8)
    assert_well_formed(coarse)
    assert np.all(coarse.counts == 4)
    close_to(coarse.depths[3, 3], [2.1, 2.8, 4.5, 6.5], 8)
    fine = run_method("leung-wang-ldi", mesh, UNIT, lod_c=80)
    assert np.all(fine.counts == 8)
    close_to(fine.depths[5, 2], [2.1, 2.3, 2.6, 2.8, 4.5, 5.4, 5.6, 6.5], 8)
    ex = Exact(mesh, UNIT, 2)
    for ldi in (coarse, fine):
        assert_conservative(ldi, ex)


def test_faces_on_the_grid_boundary_are_sampled(gl_context):
    """The default fit puts the mesh's extreme faces on the grid's faces: a crossing at the far
    face belongs to the last cell, and the solid between the faces is all there."""
    mesh = join([box_mesh((0.0, 0.0, 0.0), (8.0, 8.0, 8.0))], "cube")
    spec = glvox.grid_for(mesh, 8)
    for lod_c in (8, 1000):
        ldi = run_method("leung-wang-ldi", mesh, spec, lod_c=lod_c)
        assert np.all(ldi.counts == 2)
        assert np.all(ldi.depths[..., 0] == 0.0) and np.all(ldi.depths[..., 1] == 8.0)
        assert ldi.volume == pytest.approx(512.0 * spec.voxel_size ** 3, rel=1e-6)


def test_geometry_beyond_the_grid_is_clipped(gl_context):
    """Along the rays the solid is clipped to the grid's range, like every glvox result."""
    mesh = join([box_mesh((0.3, 0.3, -3.0), (7.7, 7.7, 3.25))], "tall")
    for name, opts in (("leung-wang-ldi", {"lod_c": 64}), ("peel-ldi", {}), ("reference-ldi", {})):
        ldi = run_method(name, mesh, UNIT, **opts)
        assert np.all(ldi.counts == 2), name
        assert np.all(ldi.depths[..., 0] == 0.0), name
        close_to(ldi.depths[..., 1:2], [3.25], 8)
    # nothing on the grid's rays: an empty LDI
    away = GridSpec((8, 8, 8), (20.0, 0.0, 0.0), 1.0)
    for name in ("leung-wang-ldi", "peel-ldi", "reference-ldi"):
        ldi = run_method(name, mesh, away)
        assert ldi.depths.shape == (8, 8, 0) and ldi.samples == 0 and ldi.volume == 0.0


def test_axes_and_pixel_order(gl_context):
    """Pixels are the other two axes in increasing order; rays along x, y and z of a box agree
    with the box's extent along each."""
    lo, hi = np.array([1.2, 0.3, 2.6]), np.array([5.7, 4.4, 6.1])
    mesh = join([box_mesh(lo, hi)], "box")
    spec = GridSpec((8, 10, 12), (0.0, 0.0, 0.0), 1.0)
    for axis in range(3):
        p, q = ldi_axes(axis)
        for name in ("leung-wang-ldi", "peel-ldi", "reference-ldi"):
            ldi = run_method(name, mesh, spec, axis=axis)
            assert ldi.counts.shape == (spec.dims[p], spec.dims[q])
            cp = np.arange(spec.dims[p]) + 0.5
            cq = np.arange(spec.dims[q]) + 0.5
            inside = ((cp > lo[p]) & (cp < hi[p]))[:, None] & ((cq > lo[q]) & (cq < hi[q]))[None, :]
            assert np.array_equal(ldi.counts, np.where(inside, 2, 0)), (name, axis)
            close_to(ldi.depths[inside], [lo[axis], hi[axis]], 12)


# -- the LDI type ----------------------------------------------------------------


def test_ldi_to_grid_matches_the_reference_solid(gl_context, shared_mesh):
    mesh = load_mesh(shared_mesh("cad_rocker_arm.obj"))
    spec = glvox.grid_for(mesh, 48)
    ref = run_method("reference-solid", mesh, spec)
    ties = tie_set("reference-solid", mesh, spec)
    for axis in range(3):
        for name in ("reference-ldi", "peel-ldi"):
            g = run_method(name, mesh, spec, axis=axis).to_grid()
            g.run = ref.run
            c = check_against_reference(g, mesh, reference_grid=ref, ties=ties)
            assert c.ok, f"{name} axis {axis}: {c.describe()}"
        # the conservative solid encloses the exact one (up to ties)
        lw = run_method("leung-wang-ldi", mesh, spec, axis=axis, lod_c=32).to_grid().dense()
        missing = ref.dense() & ~lw & ~ties
        assert not missing.any(), f"axis {axis}: {missing.sum()} inside voxels lost"


def test_ldi_conversions_save_and_load(gl_context, tmp_path):
    mesh = nest_of_shells(2, gap=0.2)
    spec = glvox.grid_for(mesh, 24)
    ldi = run_method("leung-wang-ldi", mesh, spec, lod_c=96, axis=1)
    g = ldi.to_grid()
    assert g.spec == spec
    # nz: the same voxel size, a longer grid along the axis (empty beyond), or a resampling
    longer = ldi.to_grid(nz=30).dense()
    assert longer.shape == (24, 30, 24)
    assert np.array_equal(longer[:, :24], g.dense()) and not longer[:, 24:].any()
    assert np.array_equal(ldi.occupancy(), g.dense())
    fine = ldi.occupancy(96)
    assert fine.shape == (24, 96, 24)
    # a slice center (k + 1/2) / 4 is inside iff an interval holds it
    k = np.arange(96)
    centers = (k + 0.5) / 4.0
    for (i, j) in ((12, 12), (3, 12), (12, 5)):
        iv = ldi.intervals(i, j).astype(np.float64)
        expect = np.zeros(96, bool)
        for a, b in iv:
            expect |= (centers > a) & (centers <= b)
        assert np.array_equal(fine[i, :, j], expect)
    with pytest.raises(GridError, match="pixel plane"):
        ldi.to_grid(glvox.grid_for(mesh, 25))
    path = ldi.save(tmp_path / "nest.npz")
    with np.load(path) as z:
        assert {"depths", "counts", "origin", "voxel_size", "axis"} <= set(z.files)
        assert z["depths"].dtype == np.float32 and z["depths"].shape == (24, 24, ldi.n_max)
        assert int(z["axis"]) == 1 and int(z["lod_c"]) == 96
    back = LDI.load(path)
    assert np.array_equal(back.depths, ldi.depths, equal_nan=True) and np.array_equal(back.counts, ldi.counts)
    assert back.spec == spec and back.axis == 1 and back.lod_c == 96
    assert back.volume == ldi.volume
    np.testing.assert_allclose(back.depths_world[12, 12, :2],
                               spec.origin[1] + ldi.depths[12, 12, :2].astype(float) * spec.voxel_size)
    with pytest.raises(FormatError, match=r"an LDI is saved as \.npz"):
        ldi.save(tmp_path / "x.binvox")
    np.savez(tmp_path / "bad.npz", depths=np.zeros((2, 2, 0)))
    with pytest.raises(FormatError, match=r"lacks the LDI npz keys \['axis', 'counts', 'dims', 'origin', 'voxel_size'\]"):
        LDI.load(tmp_path / "bad.npz")
    with pytest.raises(GridError, match=r"depths must have shape \(24, 24, 'n_max'\)"):
        LDI(np.zeros((3, 3, 2), np.float32), np.zeros((24, 24)), spec, 1)
    with pytest.raises(GridError, match=r"counts must lie in \[0, 2\]"):
        LDI(np.zeros((24, 24, 2), np.float32), np.full((24, 24), 4), spec, 1)


def test_close_odd_appends_the_far_face():
    d = np.array([[[1.0, 2.0, 3.0], [4.0, np.nan, np.nan]]])
    c = np.array([[3, 1]])
    d2, c2 = close_odd(d, c, 9)
    assert c2.tolist() == [[4, 2]]
    assert d2.shape == (1, 2, 4)
    assert d2[0, 0].tolist() == [1.0, 2.0, 3.0, 9.0] and d2[0, 1, :2].tolist() == [4.0, 9.0]


# -- every watertight shared mesh ---------------------------------------------------


@pytest.mark.parametrize("mesh_name", WATERTIGHT)
def test_conservative_on_shared_meshes(gl_context, shared_mesh, mesh_name):
    mesh = load_mesh(shared_mesh(mesh_name))
    spec = glvox.grid_for(mesh, 64)
    axis = WATERTIGHT.index(mesh_name) % 3
    for lod_c in (16, 1024):
        ldi, ex = check_conservative_run(mesh, spec, axis=axis, lod_c=lod_c)
        assert ldi.n_max <= ex.rc.counts.max()
        # the exact volume sampled on the rays is a lower bound
        ray, a, b, _, _ = ex.intervals()
        non_tie = ~ex.ties
        assert ldi.lengths()[non_tie].sum() >= (b - a).sum() - 1e-3 * len(a)


@pytest.mark.slow
@pytest.mark.parametrize("mesh_name", WATERTIGHT)
@pytest.mark.parametrize("axis", [0, 1, 2])
def test_conservative_on_shared_meshes_at_128_every_axis(gl_context, shared_mesh, mesh_name, axis):
    mesh = load_mesh(shared_mesh(mesh_name))
    spec = glvox.grid_for(mesh, 128)
    for lod_c in (8, 100, 1024, 2048):
        check_conservative_run(mesh, spec, axis=axis, lod_c=lod_c)


@pytest.mark.parametrize("mesh_name, lod_c, covered", [
    ("depth_reduced_diamond_lattice.stl", 2048, 0.5),
    ("cad_featuretype.stl", 4096, 0.4),  # faces on cell boundaries and edges on pixel centers: ties
    ("stanford_armadillo_libigl_86k.obj", 4096, 0.5),
])
def test_high_lod_c_equals_the_exact_crossings(gl_context, shared_mesh, mesh_name, lod_c, covered):
    """At a LOD-C of 2048 or 4096 cells on 48^3 (2 or 4 Phase-1 passes of 1024 cells) the
    samples are the exact crossings on every ray whose crossings sit in distinct cells, each
    farther from a cell boundary than the float32 mesh can move it (the rays checked: at
    least ``covered`` of those that hit the mesh)."""
    mesh = load_mesh(shared_mesh(mesh_name))
    spec = glvox.grid_for(mesh, 48)
    ldi, ex = check_conservative_run(mesh, spec, axis=2, lod_c=lod_c)
    assert ldi.run.stats["phase1_passes"] == lod_c // 1024
    rays = eligible_for_equality(ex, lod_c)
    hit = ex.rc.counts > 0
    assert rays[hit].mean() > covered, "the equality check must cover many rays"
    assert_equal_on(ldi, ex, rays)


@pytest.mark.slow
@pytest.mark.parametrize("mesh_name", WATERTIGHT)
def test_high_lod_c_equals_the_exact_crossings_every_mesh(gl_context, shared_mesh, mesh_name):
    mesh = load_mesh(shared_mesh(mesh_name))
    spec = glvox.grid_for(mesh, 96)
    for axis in range(3):
        ldi, ex = check_conservative_run(mesh, spec, axis=axis, lod_c=8192)
        assert_equal_on(ldi, ex, eligible_for_equality(ex, 8192))


@pytest.mark.parametrize("mesh_name", WATERTIGHT)
def test_peel_and_reference_ldi_are_exact(gl_context, shared_mesh, mesh_name):
    mesh = load_mesh(shared_mesh(mesh_name))
    spec = glvox.grid_for(mesh, 48)
    axis = (WATERTIGHT.index(mesh_name) + 1) % 3
    ex = Exact(mesh, spec, axis)
    rays = ~ex.ties
    for name in ("peel-ldi", "reference-ldi"):
        ldi = run_method(name, mesh, spec, axis=axis)
        assert_well_formed(ldi)
        assert_equal_on(ldi, ex, rays)
        assert ldi.n_max == ex.rc.counts.max()


@pytest.mark.parametrize("mesh_name, axis", [("cad_rocker_arm.obj", 2), ("cad_wingnut.obj", 0)])
def test_reference_ldi_against_trimesh_rays(shared_mesh, mesh_name, axis):
    """reference-ldi is built from glvox.reference.ldi.crossings, which the tests above also use
    as the truth; here an independent oracle: trimesh's ray/triangle intersector (its own
    barycentric test, all hits) along every pixel ray, away from the tie rays (rays through an
    edge or vertex, where a hit may count twice or not at all).  Counts equal; depths within
    1e-5 voxel (trimesh's intersection is accurate to ~1e-6 here)."""
    mesh = load_mesh(shared_mesh(mesh_name))
    spec = glvox.grid_for(mesh, 32)
    tris = mesh.triangles_voxel(spec)
    ldi = run_method("reference-ldi", mesh, spec, axis=axis)
    u, v = (axis + 1) % 3, (axis + 2) % 3
    lo_uv, hi_uv = (u, v) if u < v else (v, u)  # pixels are the other two axes in increasing order
    cu, cv = np.meshgrid(np.arange(spec.dims[lo_uv]) + 0.5, np.arange(spec.dims[hi_uv]) + 0.5, indexing="ij")
    origins = np.zeros((cu.size, 3))
    origins[:, lo_uv], origins[:, hi_uv], origins[:, axis] = cu.ravel(), cv.ravel(), -1.0
    directions = np.zeros((cu.size, 3))
    directions[:, axis] = 1.0
    tm = trimesh.Trimesh(tris.reshape(-1, 3), np.arange(3 * len(tris)).reshape(-1, 3), process=False)
    loc, ray, _ = trimesh.ray.ray_triangle.RayMeshIntersector(tm).intersects_location(
        origins, directions, multiple_hits=True)
    ok = ~ray_ties(tris, spec.dims, axis).ravel()
    counts = np.bincount(ray, minlength=cu.size)
    np.testing.assert_array_equal(counts[ok], ldi.counts.ravel()[ok])
    order = np.lexsort((loc[:, axis], ray))
    depths = ldi.depths.reshape(cu.size, -1)
    start = np.concatenate([[0], np.cumsum(counts)])
    checked = 0
    for r in np.flatnonzero(ok & (counts > 0)):
        want = loc[order][start[r]:start[r + 1], axis]
        np.testing.assert_allclose(depths[r, :counts[r]], want, rtol=0, atol=1e-5)
        checked += 1
    assert checked > 50 and ldi.counts.max() >= 4


# -- generated nests of shells: many layers, several passes ----------------------------


def test_nest_of_shells_many_layers_and_passes(gl_context):
    """10 shells: 40 crossings on the central rays, so Phase 2 needs two passes of 32 layers;
    with 2 targets, 4 Phase-1 passes of 256 cells and 5 Phase-2 passes of 8 layers."""
    mesh = nest_of_shells(10)
    spec = glvox.grid_for(mesh, 48)
    ex = Exact(mesh, spec, 2)
    assert ex.rc.counts.max() == 40
    peel = run_method("peel-ldi", mesh, spec)
    assert_equal_on(peel, ex, ~ex.ties)
    for opts, passes in (({"lod_c": 1024}, (1, 2)), ({"lod_c": 1000, "targets": 2}, (4, 5))):
        ldi, _ = check_conservative_run(mesh, spec, **opts)
        assert ldi.n_max == 40
        assert (ldi.run.stats["phase1_passes"], ldi.run.stats["phase2_passes"]) == passes
        assert_equal_on(ldi, ex, eligible_for_equality(ex, opts["lod_c"]))
    # coarse cells merge neighbouring shells (gaps of 1.2 voxels < 1.5-voxel cells): fewer
    # layers, still enclosing every shell
    coarse, _ = check_conservative_run(mesh, spec, lod_c=32)
    assert coarse.n_max < 40


@pytest.mark.slow
@pytest.mark.parametrize("shells", [3, 17, 40])
def test_nests_of_shells_at_every_lod_c(gl_context, shells):
    mesh = nest_of_shells(shells, gap=0.8 / (2 * shells), subdivisions=4)
    spec = glvox.grid_for(mesh, 128)
    ex = Exact(mesh, spec, 0)
    for lod_c in (16, 128, 1024, 3000):
        ldi = run_method("leung-wang-ldi", mesh, spec, axis=0, lod_c=lod_c)
        assert_well_formed(ldi)
        assert_conservative(ldi, ex)
        assert_equal_on(ldi, ex, eligible_for_equality(ex, lod_c))


coords = st.floats(-1.0, 1.0, allow_nan=False, width=32)


@st.composite
def closed_hulls(draw):
    """Convex hulls of random points (closed), possibly snapped to a lattice (faces and
    vertices on voxel and cell planes, edges through pixel centers) and far from the origin."""
    n = draw(st.integers(4, 14))
    pts = np.array([[draw(coords) for _ in range(3)] for _ in range(n)])
    if draw(st.booleans()):
        pts = np.round(pts * 4.0) / 4.0
    try:
        hull = trimesh.convex.convex_hull(pts)
    except Exception:  # noqa: BLE001 - qhull refuses flat or repeated point sets
        assume(False)
    assume(hull.is_watertight and hull.volume > 1e-3)
    return hull.vertices + draw(st.sampled_from([0.0, 1e6])), hull.faces


@settings(max_examples=150 if SLOW else 12, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much])
@given(solid=closed_hulls(), n=st.integers(2, 40), lod_c=st.sampled_from([1, 3, 32, 100, 1024, 1500]),
       axis=st.integers(0, 2))
def test_fuzzed_hulls(gl_context, solid, n, lod_c, axis):
    """Conservative (leung-wang-ldi) and exact (peel-ldi) on random closed hulls."""
    mesh = load_mesh(solid, name="hull")
    spec = glvox.grid_for(mesh, n)
    _, ex = check_conservative_run(mesh, spec, axis=axis, lod_c=lod_c)
    peel = run_method("peel-ldi", mesh, spec, axis=axis)
    assert_well_formed(peel)
    assert_equal_on(peel, ex, ~ex.ties)


def test_tiles_give_the_same_ldi(gl_context):
    mesh = nest_of_shells(3, gap=0.1)
    spec = glvox.grid_for(mesh, dims=(40, 36, 30))
    whole = {a: run_method("leung-wang-ldi", mesh, spec, axis=a, lod_c=300) for a in range(3)}
    peel = {a: run_method("peel-ldi", mesh, spec, axis=a) for a in range(3)}
    for a in range(3):
        tiled = run_method("leung-wang-ldi", mesh, spec, axis=a, lod_c=300, tile=16)
        assert tiled.run.stats["tiles"][0] * tiled.run.stats["tiles"][1] > 1
        assert np.array_equal(tiled.depths, whole[a].depths, equal_nan=True)
        p = run_method("peel-ldi", mesh, spec, axis=a, tile=16)
        assert p.run.stats["tiles"] > 1
        assert np.array_equal(p.depths, peel[a].depths, equal_nan=True)


def test_depth_buffers_split_at_the_storage_limit(gl_context, monkeypatch):
    """Depths larger than one storage block go into several buffers (for leung-wang-ldi a
    whole number of Phase-2 passes each), with the same result."""
    mesh = nest_of_shells(10, subdivisions=2)  # 6400 triangles, 40 layers: 2 Phase-2 passes of 32
    spec = glvox.grid_for(mesh, dims=(40, 40, 40))  # 1600 rays
    whole = run_method("leung-wang-ldi", mesh, spec, lod_c=256)
    peel = run_method("peel-ldi", mesh, spec)
    assert whole.n_max == peel.n_max == 40
    real = gl_context.limits()

    def limit(nbytes):
        monkeypatch.setattr(gl_context, "limits", lambda: {**real, "GL_MAX_SHADER_STORAGE_BLOCK_SIZE": nbytes})

    limit(320 << 10)  # one pass of 32 layers fits (200 KiB), two do not; the mesh's setup (300 KiB) fits
    assert np.array_equal(run_method("leung-wang-ldi", mesh, spec, lod_c=256).depths, whole.depths, equal_nan=True)
    limit(160 << 10)  # 25 layers per buffer
    assert np.array_equal(run_method("peel-ldi", mesh, spec).depths, peel.depths, equal_nan=True)


def test_peeling_past_a_saturated_stencil(gl_context, monkeypatch):
    """When the 8-bit stencil count saturates, peel-ldi peels until a pass draws nothing."""
    mesh = nest_of_shells(4, gap=0.1)
    spec = glvox.grid_for(mesh, 24)
    normal = run_method("peel-ldi", mesh, spec)
    monkeypatch.setattr(depth_raster, "STENCIL_MAX", 5)
    saturated = run_method("peel-ldi", mesh, spec)
    assert np.array_equal(saturated.depths, normal.depths, equal_nan=True)
    assert saturated.run.stats["passes"] > normal.run.stats["passes"]


def test_open_meshes_are_closed_at_the_far_face(gl_context):
    """An open cup: rays crossing it once see the parity solid run to the grid's end, closed there."""
    s = trimesh.creation.icosphere(3)
    keep = s.triangles_center[:, 2] < 0.3
    mesh = load_mesh((s.vertices, s.faces[keep]), name="cup")
    assert not mesh.watertight
    spec = glvox.grid_for(mesh, 32, bounds=[[-1, -1, -1], [1, 1, 1]])
    ties = ray_ties(mesh.triangles_voxel(spec), spec.dims, 2)
    for name in ("reference-ldi", "leung-wang-ldi", "peel-ldi"):  # refused unless allowed, as solids are
        with pytest.raises(NotWatertightError, match="not watertight.*allow_open"):
            run_method(name, mesh, spec)
    with pytest.warns(NotWatertightWarning, match="closed at the grid's far face"):
        ref = run_method("reference-ldi", mesh, spec, allow_open=True)
    once = (ref.counts == 2) & (ref.depths[..., 1] == 32.0) & ~ties
    assert once.sum() > 100
    for name in ("leung-wang-ldi", "peel-ldi"):
        with pytest.warns(NotWatertightWarning, match="not watertight"):
            ldi = run_method(name, mesh, spec, allow_open=True)
        assert_well_formed(ldi)
        assert np.all(ldi.depths[once][:, 1] == 32.0)
        assert np.array_equal(ldi.counts[~ties], ref.counts[~ties])


# -- intersecting volume (Sec. V-A) -----------------------------------------------------


def exact_overlap(ex_a: Exact, ex_b: Exact):
    """Flat exact segments of A and B's overlap on the rays that are ties of neither:
    ray, a, b, tol_a, tol_b, and the crossings of A and B per ray."""
    skip = ex_a.ties | ex_b.ties
    parts = []
    for label, ex in enumerate((ex_a, ex_b)):
        n_rays = ex.rc.counts.size
        d = ex.rc.depths.reshape(n_rays, -1)
        t = crossing_tolerance(ex.rc.slopes).reshape(n_rays, -1)
        valid = (np.arange(d.shape[1]) < ex.rc.counts.reshape(-1)[:, None]) & ~skip.reshape(-1)[:, None]
        ray = np.broadcast_to(np.arange(n_rays)[:, None], d.shape)[valid]
        parts.append((ray, d[valid], t[valid], np.full(len(ray), label)))
    ray, x, tol, lab = (np.concatenate(p) for p in zip(*parts))
    order = np.lexsort((x, ray))
    ray, x, tol, lab = ray[order], x[order], tol[order], lab[order]
    # each ray of a closed mesh has an even count of each, so running parities reset per ray
    in_a = np.cumsum(lab == 0) % 2 == 1
    in_b = np.cumsum(lab == 1) % 2 == 1
    both = in_a & in_b
    before = np.concatenate([[False], both[:-1]])
    before[1:] &= ray[1:] == ray[:-1]
    starts = np.flatnonzero(both & ~before)
    ends = np.flatnonzero(~both & before)
    assert len(starts) == len(ends)
    per_ray = (ex_a.rc.counts + ex_b.rc.counts).reshape(-1)
    return ray[starts], x[starts], x[ends], tol[starts], tol[ends], per_ray, skip


def lens_volume(r: float, d: float) -> float:
    """Volume of the intersection of two balls of radius r whose centers are d apart."""
    return math.pi * (4 * r + d) * (2 * r - d) ** 2 / 12.0 if d < 2 * r else 0.0


def lens_length(r: float, d: float, rho: np.ndarray) -> np.ndarray:
    """Chord of that lens at distance rho from the line of centers (along it)."""
    return np.maximum(0.0, 2.0 * np.sqrt(np.maximum(r * r - rho * rho, 0.0)) - d)


def pixel_sum_error(r: float, d: float, x: np.ndarray, y: np.ndarray, h: float) -> tuple[float, float]:
    """Bounds (lo, hi) on S - V, where S = h^2 sum L(pixel center) over the pixels of side h
    centered at (x, y) (a grid covering the lens's disk) and V the lens volume = integral of L.

    L (the chord at distance rho from the axis) is 2 sqrt(r^2 - rho^2) - d on the disk
    rho <= rho_max = sqrt(r^2 - d^2 / 4), concave there, and 0 outside.
    * A pixel inside the disk: by concavity L lies above its bilinear interpolation from the
      four corners and below its tangent plane at the center, so
      h^2 mean(L(corners)) <= integral over the pixel <= h^2 L(center).
    * A pixel across the rim: 0 <= integral <= h^2 max L <= h^2 L(rho_c - h / sqrt(2)), L
      decreasing in rho and every point within h / sqrt(2) of the center.
    Summing: S - V >= -sum_rim h^2 L(rho_c - h / sqrt(2)) and
    S - V <= sum_inside h^2 (L(center) - mean L(corners)) + sum_rim h^2 L(center).
    """
    X, Y = np.meshgrid(x, y, indexing="ij")
    rho = np.hypot(X, Y)
    delta = h / math.sqrt(2.0)
    rho_max = math.sqrt(r * r - d * d / 4.0)
    inside = rho + delta <= rho_max
    rim = ~inside & (rho - delta < rho_max)
    center = lens_length(r, d, rho)
    corners = np.mean([lens_length(r, d, np.hypot(X + sx * h / 2, Y + sy * h / 2))
                       for sx in (-1, 1) for sy in (-1, 1)], axis=0)
    hi = h * h * (np.sum((center - corners)[inside]) + np.sum(center[rim]))
    lo = -h * h * np.sum(lens_length(r, d, np.maximum(rho - delta, 0.0))[rim])
    return float(lo), float(hi)


def test_lens_volume_of_two_spheres(gl_context):
    """Two spheres of radius 1, centers 1 apart along z: the overlap's LDI volume lies between
    the lenses of the spheres inscribed in and circumscribing the mesh spheres, widened by the
    discretization error derived here.

    * Sampling: the LDI's rays are the pixel centers, so it measures S = h^2 sum L(center)
      of the chord L; :func:`pixel_sum_error` bounds S - V for the analytic lenses.
    * Meshes: an icosphere lies between its inscribed sphere (radius r_in, the smallest
      distance from the center to a face plane) and its circumscribed one (the vertices), so
      the chord of the mesh lens lies between those of the two analytic lenses, ray by ray.
    * Conservative sampling: on each ray the LDI holds the mesh lens's chord; for two convex
      solids the overlap on a ray is one interval, and each of its two samples lies at most
      one cell beyond it (the nearest or farthest crossing in its cell; an overlap inside a
      single cell is an ELV bounded by that cell's crossings).
    * float32: every crossing may move by its tolerance (``slack``).
    """
    d, r_out = 1.0, 1.0
    a = sphere(r_out, (0.0, 0.0, -d / 2))
    b = sphere(r_out, (0.0, 0.0, d / 2))
    base = trimesh.creation.icosphere(4, radius=r_out)
    r_in = float(np.min(np.abs(np.einsum("ij,ij->i", base.face_normals, base.triangles[:, 0]))))
    n, lod_c = 64, 1024
    ldi = glvox.intersect_ldi(a, b, n, lod_c=lod_c)
    spec = ldi.spec
    h = spec.voxel_size
    assert spec.dims == (n, n, n) and ldi.run.method == "leung-wang-intersection"
    assert_well_formed(ldi)
    x = spec.origin[0] + (np.arange(n) + 0.5) * h
    y = spec.origin[1] + (np.arange(n) + 0.5) * h
    ex_a, ex_b = Exact(a, spec, 2), Exact(b, spec, 2)
    both = (ex_a.rc.counts > 0) & (ex_b.rc.counts > 0)
    cell = spec.dims[2] * h / lod_c
    overshoot = h * h * both.sum() * 2 * cell
    slack = h ** 3 * (np.nansum(crossing_tolerance(ex_a.rc.slopes)) + np.nansum(crossing_tolerance(ex_b.rc.slopes)))
    lower = lens_volume(r_in, d) + pixel_sum_error(r_in, d, x, y, h)[0] - slack
    upper = lens_volume(r_out, d) + pixel_sum_error(r_out, d, x, y, h)[1] + overshoot + slack
    assert lower <= ldi.volume <= upper, (lower, ldi.volume, upper)
    assert (upper - lower) / lens_volume(r_out, d) < 0.05  # the bound is tight enough to mean something
    # and against the exact overlap on the rays: conservative, within a cell per crossing
    ray, x0, x1, t0, t1, per_ray, skip = exact_overlap(ex_a, ex_b)
    assert len(uncovered(ldi, ray, x0, x1, t0, t1)) == 0
    exact_len = np.bincount(ray, weights=x1 - x0, minlength=per_ray.size)
    got = ldi.lengths().reshape(-1)
    tol = 4 * crossing_tolerance(np.ones(1))[0]
    keep = ~skip.reshape(-1)
    assert np.all(got[keep] >= exact_len[keep] - tol * per_ray[keep])
    assert np.all(got[keep] <= exact_len[keep] + per_ray[keep] * (spec.dims[2] / lod_c + tol))
    assert glvox.intersecting_volume(a, b, n, lod_c=lod_c) == ldi.volume


def test_intersecting_volume_of_two_meshes_against_dense_voxels(gl_context, shared_mesh):
    """The rocker arm and a shifted copy.  Dense estimate: h^3 times the voxels whose centers
    are inside both (reference-solid on the LDI's grid, whose columns are the LDI's rays).  An
    interval [a, b] of a ray holds between b - a - 1 and b - a + 1 voxel centers, so a column's
    count differs from the exact overlap length on its ray by less than the number k of
    overlap intervals; the LDI's length exceeds the exact one by at most one cell per cell
    holding a crossing, at most X cells (X: the crossings of A and B on the ray).  Hence
    |V_ldi - V_dense| <= h^3 sum (k + cell X), on the rays that are ties of neither mesh."""
    path = shared_mesh("cad_rocker_arm.obj")
    a = load_mesh(path)
    ext = a.bounds[1] - a.bounds[0]
    b = load_mesh((a.vertices + 0.05 * ext, a.faces), name="shifted")
    n, lod_c = 64, 1024
    ldi = glvox.intersect_ldi(a, b, n, lod_c=lod_c, axis=1)
    spec = ldi.spec
    assert_well_formed(ldi)
    ex_a, ex_b = Exact(a, spec, 1), Exact(b, spec, 1)
    ray, x0, x1, t0, t1, per_ray, skip = exact_overlap(ex_a, ex_b)
    assert len(x0) > 100
    assert len(uncovered(ldi, ray, x0, x1, t0, t1)) == 0
    keep = ~skip  # (n_x, n_z)
    dense = (run_method("reference-solid", a, spec).dense() & run_method("reference-solid", b, spec).dense())
    dense_cols = dense.sum(axis=1)  # along y: (n_x, n_z), the LDI's pixel order
    h3 = spec.voxel_size ** 3
    v_dense = h3 * dense_cols[keep].sum()
    v_ldi = h3 * ldi.lengths()[keep].sum()
    k = np.bincount(ray, minlength=per_ray.size).reshape(keep.shape)[keep]
    x = per_ray.reshape(keep.shape)[keep]
    cell = spec.dims[1] / lod_c
    bound = h3 * np.sum(k + cell * x)
    assert abs(v_ldi - v_dense) <= bound, (v_ldi, v_dense, bound)
    # a worst case of one voxel per interval on a thin-walled part at 64^3: about a fifth of the
    # volume (measured differences are ~0.4%); the tight check is the one against the rays below
    assert bound < 0.25 * v_dense
    # the exact overlap sampled on the rays: a lower bound, exceeded by at most a cell per crossing
    v_rays = h3 * np.sum(x1 - x0)
    assert v_rays - h3 * np.sum(t0 + t1) <= v_ldi <= v_rays + h3 * np.sum(cell * x)


def test_thin_overlaps_are_kept(gl_context):
    """Two slabs overlapping by 0.2 voxel, inside one cell: the paper's AND of the solids alone
    loses the overlap; the T2 of the overlap keeps it (an ELV), conservatively."""
    a = join([box_mesh((0.5, 0.5, 1.0), (7.5, 7.5, 3.5))], "a")
    b = join([box_mesh((0.5, 0.5, 3.3), (7.5, 7.5, 6.0))], "b")
    ldi = glvox.intersect_ldi(a, b, grid=UNIT, lod_c=8)
    assert np.all(ldi.counts[1:7, 1:7] == 2)
    close_to(ldi.depths[3, 3, :2], [3.3, 3.5], 8)
    assert glvox.intersecting_volume(a, join([box_mesh((0, 0, 7.0), (8, 8, 8))], "c"), 8) == 0.0


def test_intersection_cli_and_api(gl_context, tmp_path):
    a = "gen:sphere"
    out = subprocess.run([sys.executable, "-m", "glvox", "volume", a, a, "-r", "24", "--lod-c", "128", "-q"],
                         capture_output=True, text=True, check=True)
    v = float(out.stdout.strip())
    assert v == pytest.approx(glvox.intersecting_volume(a, a, 24, lod_c=128), rel=1e-9)
    assert v >= 4.0 / 3.0 * math.pi * 0.98  # the whole (tessellated) unit ball, conservatively
    out = subprocess.run([sys.executable, "-m", "glvox", "volume", a, a, "-r", "24", "--json", "--axis", "x",
                          "-o", str(tmp_path / "o.npz")], capture_output=True, text=True, check=True)
    d = json.loads(out.stdout)
    assert d["volume"] == pytest.approx(LDI.load(tmp_path / "o.npz").volume)
    assert d["options"]["axis"] == 0


# -- CLI, options and limits --------------------------------------------------------


def test_cli_ldi_writes_the_issue_npz(tmp_path):
    out = tmp_path / "t.npz"
    r = subprocess.run([sys.executable, "-m", "glvox", "ldi", "gen:torus", "-r", "20", "--lod-c", "64",
                        "--axis", "z", "-o", str(out), "-q"], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    with np.load(out) as z:
        depths, counts = z["depths"], z["counts"]
        assert depths.dtype == np.float32 and depths.shape[:2] == (20, 20) == counts.shape
        assert np.array_equal(~np.isnan(depths), np.arange(depths.shape[2]) < counts[:, :, None])
        assert z["origin"].shape == (3,) and float(z["voxel_size"]) > 0 and int(z["axis"]) == 2
    r = subprocess.run([sys.executable, "-m", "glvox", "ldi", "gen:torus", "-r", "8", "-m", "ss-solid"],
                       capture_output=True, text=True)
    assert r.returncode == 1 and "glvox ldi needs a method of kind 'ldi'" in r.stderr
    r = subprocess.run([sys.executable, "-m", "glvox", "ldi", "gen:torus", "-r", "8", "-m", "peel-ldi",
                        "--lod-c", "4"], capture_output=True, text=True)
    assert r.returncode == 1 and "--lod-c is an option of leung-wang-ldi" in r.stderr
    r = subprocess.run([sys.executable, "-m", "glvox", "ldi", "gen:torus", "-r", "8", "--axis", "w"],
                       capture_output=True, text=True)
    assert r.returncode == 2 and "axis must be x, y, z" in r.stderr


def test_options_are_checked(gl_context):
    mesh = load_mesh("gen:box")
    spec = glvox.grid_for(mesh, 8)
    with pytest.raises(MethodError, match=r"option lod_c \(cells along the rays\) must be in 1\.\.65536, got 0"):
        run_method("leung-wang-ldi", mesh, spec, lod_c=0)
    with pytest.raises(MethodError, match=r"option targets must be one of"):
        run_method("leung-wang-ldi", mesh, spec, targets=9)
    with pytest.raises(MethodError, match=r"option tile must be 0 \(the context's limit\) or a positive number "
                                          r"of pixels, got -1"):
        run_method("leung-wang-ldi", mesh, spec, tile=-1)
    with pytest.raises(MethodError, match="needs a method of kind 'ldi'"):
        glvox.ldi(mesh, 8, method="ss-solid")
    # a single cell: every ray through the box is an ELV, bounded by its two crossings
    one, ref = glvox.ldi(mesh, 8, lod_c=1), glvox.ldi(mesh, 8, method="reference-ldi")
    assert np.array_equal(one.counts, ref.counts) and one.samples > 0
    close_to(one.depths[one.counts > 0] - ref.depths[one.counts > 0], [0.0, 0.0], 8)


def test_masks_over_the_storage_limit_are_refused_before_any_work(gl_context, monkeypatch):
    mesh = load_mesh("gen:sphere")
    spec = glvox.grid_for(mesh, 64)
    run_method("leung-wang-ldi", mesh, spec, lod_c=1024)
    real = gl_context.limits()
    need = 64 * 64 * 32 * 4
    monkeypatch.setattr(gl_context, "limits", lambda: {**real, "GL_MAX_SHADER_STORAGE_BLOCK_SIZE": need - 4})
    before = live_gl_objects(gl_context)
    with pytest.raises(LimitError, match=r"a bit mask of 4096 rays x 1024 cells needs a 0\.5 MiB shader storage "
                                         r"buffer, over .*GL_MAX_SHADER_STORAGE_BLOCK_SIZE"):
        run_method("leung-wang-ldi", mesh, spec, lod_c=1024)
    assert live_gl_objects(gl_context) == before


def test_stages_and_stats(gl_context):
    mesh = nest_of_shells(2, gap=0.2)
    spec = glvox.grid_for(mesh, 16)
    ldi = run_method("leung-wang-ldi", mesh, spec, lod_c=2048)
    names = [s.name for s in ldi.run.timings.stages]
    assert names[:2] == ["transform", "setup"] and names.count("t1") == 2 and names.count("t2") == 2
    assert {"count", "depths", "store", "readback"} <= set(names)
    st = ldi.run.stats
    assert st["n_max"] == ldi.n_max == 8 and st["samples"] == ldi.samples
    assert st["draws"] == 2 * 2 + 1 and st["lod_c"] == 2048
    assert all(s.gpu_s is not None for s in ldi.run.timings.stages if s.name != "readback")


def test_peel_ldi_crossing_of_a_float32_sliver(gl_context):
    """peel-ldi's sample where a column meets glvox.testing.slivers' float32 sliver: the
    exact crossing, 33.5 voxels along the rays (1033.5 on this grid), in every vertex
    order.  depth/raster.frag decides the coverage and peel_record.comp the depth, both on
    the fixed point's exact edge functions; the plane's formula in double (the code
    before) recorded 1033.5375 in two of the four orders."""
    tri = slivers.float32_sliver()
    spec = GridSpec((2048, 1, 1), (-1000.0, 0.0, 0.0), 1.0)
    for order in slivers.ORDERS:
        mesh = load_mesh((tri, np.array([order])), name="sliver")
        with pytest.warns(NotWatertightWarning):
            ldi = run_method("peel-ldi", mesh, spec, axis=0, allow_open=True)
        assert ldi.counts.ravel()[0] >= 1 and ldi.depths.ravel()[0] == 1000.0 + slivers.CROSSING, \
            (order, ldi.depths.ravel()[:2])
