"""The voxelizers people use today, aligned to glvox's grid.

Each *peer* wraps one library call so that it produces occupancy on the very
grid glvox uses (docs/design.md): a :class:`~glvox.grid.GridSpec` with ``dims``,
world ``origin`` and voxel size ``h``, voxel (i, j, k) the closed box
``origin + [i, i+1] x [j, j+1] x [k, k+1] * h`` with its center at ``+ 0.5 h``.
How each peer is brought onto that grid is explained in its class docstring
and checked by ``tests/test_bench.py`` against glvox's exact references.

A peer runs in three steps, so the benchmark can time only the library's own
work:

1. :meth:`Peer.prepare` (not timed): the mesh in the peer's own type and the
   grid in its own terms, as a user of that library would hold them already
   (glvox's mesh is likewise uploaded once and reused across runs);
2. :meth:`Peer.run` (timed): the one call a user of the library makes;
3. :meth:`Peer.to_grid` (timed separately, reported as "convert"): the
   peer's native result as a glvox :class:`~glvox.grid.VoxelGrid`, voxels
   that fall outside glvox's grid dropped and counted.

The peers are optional (``pip install 'glvox[peers]'``), except trimesh,
which is a core dependency of glvox: its peers always run.
"""

from __future__ import annotations

from importlib import metadata
from typing import Any

import numpy as np

from glvox.errors import GlvoxError
from .peer_base import Peer, PeerGrid, _from_indices, _from_zyx
from .peer_cuda import CudaVoxelizer

#: Query points per call of libigl's fast winding number: large enough that
#: rebuilding its tree per call is a small share of the time (the V, F, Q
#: overload builds the tree on every call), small enough to keep the query
#: array (24 bytes per point) and its result well under a GiB.
IGL_CHUNK = 1 << 23


class Open3DSurface(Peer):
    """Open3D ``VoxelGrid.create_from_triangle_mesh_within_bounds``: conservative surface.

    Alignment: Open3D's voxel grid has an ``origin`` (the minimum corner of
    voxel (0, 0, 0)) and a ``voxel_size``; voxel (i, j, k) is the box
    ``origin + [i, i+1] x ... * voxel_size`` and is set when Open3D's
    triangle/box overlap test (Akenine-Moller's separating-axis test,
    ``IntersectionTest::TriangleAABB``, centered at ``origin + (idx + 0.5) *
    voxel_size`` with half-size ``voxel_size / 2``) succeeds: the conservative
    criterion of ``reference-conservative``.  We call the ``within_bounds``
    variant with ``min_bound = spec.origin``, ``max_bound = spec.origin +
    dims * h`` and ``voxel_size = h``, so Open3D's grid index is glvox's
    (i, j, k).  The plain ``create_from_triangle_mesh`` would pad the mesh's
    box by h/2 and put the origin elsewhere.  Open3D does not clip to the
    bounds: voxels just past the grid's far faces (touched by a mesh whose
    box ends on them) are dropped and counted as ``outside``.

    The result is a sparse list of Voxel objects; ``to_grid`` reads their
    ``grid_index`` (the conversion is timed separately).  Measured here
    (Open3D 0.20): equal to ``reference-conservative`` on the shared bunny.
    """

    name = "open3d"
    kind = "surface"
    module = "open3d"
    package = "open3d"
    reference = "reference-conservative"
    call = "o3d.geometry.VoxelGrid.create_from_triangle_mesh_within_bounds"
    max_n = None

    def prepare(self, mesh, spec):
        import open3d as o3d

        tm = o3d.geometry.TriangleMesh(o3d.utility.Vector3dVector(np.asarray(mesh.vertices, np.float64)),
                                       o3d.utility.Vector3iVector(np.asarray(mesh.faces, np.int32)))
        lo = np.asarray(spec.origin, np.float64)
        hi = lo + np.asarray(spec.dims, np.float64) * spec.voxel_size
        return tm, spec.voxel_size, lo.reshape(3, 1), hi.reshape(3, 1)

    def run(self, prepared):
        import open3d as o3d

        tm, h, lo, hi = prepared
        return o3d.geometry.VoxelGrid.create_from_triangle_mesh_within_bounds(tm, h, lo, hi)

    def to_grid(self, native, spec):
        voxels = native.get_voxels()
        ijk = np.array([v.grid_index for v in voxels], dtype=np.int64).reshape(-1, 3)
        return _from_indices(ijk, spec)


class _TrimeshBase(Peer):
    module = "trimesh"
    package = "trimesh"

    def prepare(self, mesh, spec):
        import trimesh

        # trimesh puts voxel centers at integer multiples of the pitch (its
        # voxelize_subdivide rounds vertex / pitch); moving the mesh by
        # -(origin + h/2) puts glvox's center of voxel (i, j, k) at (i, j, k) * h
        shift = np.asarray(spec.origin, np.float64) + 0.5 * spec.voxel_size
        tm = trimesh.Trimesh(np.asarray(mesh.vertices, np.float64) - shift, np.asarray(mesh.faces),
                             process=False, validate=False)
        return tm, spec.voxel_size

    def to_grid(self, native, spec):
        h = spec.voxel_size
        t = np.asarray(native.transform, np.float64)
        if not np.allclose(t[:3, :3], np.eye(3) * h, rtol=1e-9, atol=0):
            raise ValueError(f"expected a trimesh voxel transform of scale {h}, got\n{t}")
        # the transform maps the encoding's indices to centers in the moved frame, where
        # center (i, j, k) * h is glvox's voxel (i, j, k); its translation is a whole
        # number of pitches (trimesh: the smallest occupied index times the pitch)
        offset = np.round(t[:3, 3] / h).astype(np.int64)
        return _from_indices(np.asarray(native.sparse_indices, np.int64) + offset, spec)


class TrimeshSubdivide(_TrimeshBase):
    """trimesh ``Trimesh.voxelized(pitch)`` (method ``'subdivide'``): sampled surface.

    Alignment: trimesh subdivides the mesh until every edge is shorter than
    ``pitch / 2`` and sets the voxel whose center is nearest to each vertex
    (``round(vertex / pitch)``), so its voxel (i, j, k) is the box centered at
    ``(i, j, k) * pitch`` of the mesh's frame.  ``prepare`` moves the mesh by
    ``-(origin + h/2)`` with ``pitch = h``: trimesh's centers then fall on
    glvox's centers, and the result's transform (scale h, translation =
    smallest occupied index * h) gives the glvox index of every voxel.

    What it computes: the voxels that contain a vertex of the subdivided
    mesh, a subset of the conservative surface (it misses voxels a triangle
    only clips; a vertex exactly on a voxel face picks one side by rounding).
    It is not clipped to the grid (vertices on the grid's faces may round one
    voxel past it: counted as ``outside``).  Its subdivided mesh grows 4x per
    doubling of N: measured here on the bunny, 4 s at 128^3, 27 s at 256^3
    and 155 s with 6.4 GB of memory at 512^3, so the default ``max_n`` is 256.
    """

    name = "trimesh-subdivide"
    kind = "surface"
    reference = "reference-conservative"
    call = "trimesh.Trimesh.voxelized(pitch)"
    max_n = 256

    def run(self, prepared):
        tm, h = prepared
        return tm.voxelized(pitch=h)


class TrimeshFill(_TrimeshBase):
    """trimesh ``Trimesh.voxelized(pitch).fill()``: solid by filling the sampled surface.

    Alignment as :class:`TrimeshSubdivide` (the same call first), then
    ``fill()`` (method ``'holes'``: ``scipy.ndimage.binary_fill_holes`` on the
    dense box of occupied voxels) keeps the transform.

    What it computes: the sampled surface plus every voxel enclosed by it.
    Against ``reference-solid`` (voxel centers inside) it has the surface
    shell as extra voxels, by design, and where the sampled surface has a
    gap the interior leaks out and stays empty.  Same ``max_n`` as the
    subdivide peer.
    """

    name = "trimesh-fill"
    kind = "solid"
    reference = "reference-solid"
    call = "trimesh.Trimesh.voxelized(pitch).fill()"
    max_n = 256

    def run(self, prepared):
        tm, h = prepared
        return tm.voxelized(pitch=h).fill()


class PyVistaStencil(Peer):
    """PyVista ``PolyData.voxelize_binary_mask`` (VTK ``vtkPolyDataToImageStencil``): solid.

    PyVista's ``voxelize_volume`` that the issue names was deprecated in
    0.46 and raises ``DeprecationError`` since 0.49; its documented
    replacement ``voxelize_rectilinear`` wraps ``voxelize_binary_mask``,
    called here directly so the grid can be given exactly.

    Alignment: the mask is point data of an ``ImageData`` (one sample per
    grid point).  We pass ``reference_volume = ImageData(dimensions=dims,
    spacing=h, origin=origin + h/2)``, so grid point (i, j, k) is glvox's
    center of voxel (i, j, k); the mask, x fastest, is reshaped to (nz, ny,
    nx) and transposed to glvox's [i, j, k].

    What it computes: VTK cuts the surface with the plane of each z row of
    samples, closes the cut polylines where it can, and fills the samples
    inside them by scanlines in x and y: inside-at-centers, the solid
    criterion of ``reference-solid``, with VTK's own tie rules for samples on
    the surface.  Open meshes: VTK tries to close open polylines per slice.
    """

    name = "pyvista"
    kind = "solid"
    module = "pyvista"
    package = "pyvista"
    reference = "reference-solid"
    call = "pv.PolyData.voxelize_binary_mask(reference_volume=...)"
    max_n = None

    def prepare(self, mesh, spec):
        import pyvista as pv

        poly = pv.PolyData.from_regular_faces(np.asarray(mesh.vertices, np.float64),
                                              np.asarray(mesh.faces, np.int64))
        h = spec.voxel_size
        ref = pv.ImageData(dimensions=spec.dims, spacing=(h, h, h),
                           origin=tuple(np.asarray(spec.origin, np.float64) + 0.5 * h))
        return poly, ref

    def run(self, prepared):
        poly, ref = prepared
        return poly.voxelize_binary_mask(reference_volume=ref)

    def to_grid(self, native, spec):
        if tuple(native.dimensions) != spec.dims:
            raise ValueError(f"expected a PyVista mask of dimensions {spec.dims}, got {native.dimensions}")
        return _from_zyx(np.asarray(native.point_data["mask"]) != 0, spec)


class IglWinding(Peer):
    """libigl ``fast_winding_number`` at every voxel center: robust but slow solid.

    Alignment: the queries are glvox's centers ``origin + (i + 0.5, j + 0.5,
    k + 0.5) * h`` themselves (built in slabs of k, x fastest within a slab,
    and part of the timed work); a voxel is set when the generalized winding
    number is at least 1/2.

    What it computes: the generalized winding number (Jacobson et al. 2013,
    Barill et al. 2018's fast hierarchical evaluation, accuracy beta = 2) is
    the parity-free inside test that degrades gracefully on open and
    self-intersecting meshes: the criterion of ``reference-gwn`` (on a closed
    mesh, of ``reference-solid``), up to its expansion's error where w is
    near 1/2.  2-6 s for the 2.1M centers of 128^3 here (2 cores, quiet to
    busy), 17-44 s for the 16.8M of 256^3, so the default ``max_n`` is 256.
    """

    name = "igl-winding"
    kind = "solid"
    module = "igl"
    package = "libigl"
    reference = "reference-gwn"
    call = "igl.fast_winding_number(V, F, centers) >= 0.5"
    max_n = 256

    def version(self) -> str:
        try:
            return metadata.version("libigl")
        except Exception:
            return "?"

    def prepare(self, mesh, spec):
        return (np.ascontiguousarray(mesh.vertices, np.float64), np.ascontiguousarray(mesh.faces, np.int64),
                spec)

    def run(self, prepared):
        import igl

        V, F, spec = prepared
        nx, ny, nz = spec.dims
        h = spec.voxel_size
        o = np.asarray(spec.origin, np.float64)
        xs = o[0] + (np.arange(nx) + 0.5) * h
        ys = o[1] + (np.arange(ny) + 0.5) * h
        out = np.empty((nz, ny, nx), dtype=bool)
        slab = max(1, IGL_CHUNK // (nx * ny))
        yy, xx = np.meshgrid(ys, xs, indexing="ij")
        for k0 in range(0, nz, slab):
            k1 = min(nz, k0 + slab)
            zs = o[2] + (np.arange(k0, k1) + 0.5) * h
            q = np.empty((k1 - k0, ny, nx, 3), dtype=np.float64)
            q[..., 0] = xx
            q[..., 1] = yy
            q[..., 2] = zs[:, None, None]
            w = igl.fast_winding_number(V, F, q.reshape(-1, 3))
            out[k0:k1] = (w >= 0.5).reshape(k1 - k0, ny, nx)
        return out

    def to_grid(self, native, spec):
        return _from_zyx(native, spec)


_WARP: dict[str, Any] = {}


def _warp_kernel():
    """Warp (initialized quietly) and its kernel: voxel tid of a grid, x fastest,
    inside by the winding number's sign at the center (compiled once per process,
    cached on disk by Warp)."""
    if not _WARP:
        import warp as wp  # lazy: an optional peer

        wp.config.log_level = wp.LOG_ERROR  # no greeting or module-load lines on stdout
        wp.init()

        @wp.kernel
        def inside(mesh: wp.uint64, nx: int, ny: int, max_dist: float, out: wp.array(dtype=wp.int8)):
            tid = wp.tid()
            i = tid % nx
            j = (tid // nx) % ny
            k = tid // (nx * ny)
            p = wp.vec3(float(i) + 0.5, float(j) + 0.5, float(k) + 0.5)
            q = wp.mesh_query_point_sign_winding_number(mesh, p, max_dist, 2.0, 0.5)
            if q.result and q.sign < 0.0:
                out[tid] = wp.int8(1)

        _WARP.update(wp=wp, kernel=inside)
    return _WARP["wp"], _WARP["kernel"]


class WarpWinding(Peer):
    """NVIDIA Warp ``mesh_query_point_sign_winding_number`` on the CPU device: robust solid.

    Alignment: the mesh is handed to Warp in glvox's voxel space (float32,
    ``(v - origin) / h``), so voxel (i, j, k)'s center is the query point
    ``(i + 0.5, j + 0.5, k + 0.5)``, computed in the kernel from the thread
    index (x fastest); the int8 result is (nz, ny, nx).

    What it computes: the query finds the closest point within ``max_dist``
    (the grid's diagonal, so every center gets one) and classifies the point
    by the fast winding number (Barill et al. 2018, second-order dipoles,
    accuracy 2.0, threshold 0.5): inside when ``w >= 1/2``, the criterion of
    ``reference-gwn`` up to the expansion's error near 1/2.  Building the
    ``wp.Mesh`` (BVH and winding-number data) is ``prepare``, as a Warp user
    keeps the mesh object; the kernel's first compilation is a cold start.
    Warp runs CPU kernels on one thread: ~17 s for the 2.1M centers of 128^3
    on the bunny here (8x that at 256^3), so the default ``max_n`` is 64 and
    ``--peer-max warp-winding=256`` asks for more.
    """

    name = "warp-winding"
    kind = "solid"
    module = "warp"
    package = "warp-lang"
    reference = "reference-gwn"
    call = "wp.mesh_query_point_sign_winding_number(mesh, center, max_dist) (device 'cpu')"
    max_n = 64

    def prepare(self, mesh, spec):
        wp, _ = _warp_kernel()
        vox = np.ascontiguousarray(spec.world_to_voxel(mesh.vertices), dtype=np.float32)
        m = wp.Mesh(points=wp.array(vox, dtype=wp.vec3, device="cpu"),
                    indices=wp.array(np.ascontiguousarray(mesh.faces, np.int32).ravel(), dtype=wp.int32,
                                     device="cpu"),
                    support_winding_number=True)
        return m, spec.dims

    def run(self, prepared):
        wp, kernel = _warp_kernel()
        m, (nx, ny, nz) = prepared
        out = wp.zeros(nx * ny * nz, dtype=wp.int8, device="cpu")
        wp.launch(kernel, dim=nx * ny * nz, inputs=[m.id, nx, ny, float(np.sqrt(nx * nx + ny * ny + nz * nz))],
                  outputs=[out], device="cpu")
        wp.synchronize_device("cpu")
        return out.numpy().reshape(nz, ny, nx)

    def to_grid(self, native, spec):
        return _from_zyx(native != 0, spec)


#: Every peer, in table order.
PEERS: dict[str, Peer] = {p.name: p for p in (Open3DSurface(), TrimeshSubdivide(), TrimeshFill(),
                                              PyVistaStencil(), IglWinding(), WarpWinding(), CudaVoxelizer())}


def get_peer(name: str) -> Peer:
    """The peer ``name``; GlvoxError names the known peers otherwise."""
    try:
        return PEERS[name]
    except KeyError:
        raise GlvoxError(f"unknown peer {name!r}; known peers: {', '.join(PEERS)}") from None


__all__ = ["PEERS", "Peer", "PeerGrid", "get_peer", "_from_indices", "_from_zyx"]
