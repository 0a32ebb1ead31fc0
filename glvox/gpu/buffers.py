"""GPU buffers shared by the compute and raster methods.

* :func:`mesh_buffers`: a mesh is uploaded once per context (vertices as
  float32 relative to the mesh's anchor, faces as uint32) and reused by every
  method and run; the buffers are released when the mesh is garbage collected
  or the context is released.
* :class:`BufferPool`: named scratch buffers per context, grown when needed
  and reused across runs (no allocation per run once warm).
* :func:`object_cache`: other GL objects (render targets, framebuffers,
  queries) an owner keeps per context between runs.
* :func:`check_buffer_size`: refuse a buffer over GL_MAX_SHADER_STORAGE_BLOCK_SIZE
  before allocating, naming the size, the limit and what to do instead.
* :func:`read_grid_words`: a packed grid read back into numpy (in mapped memory
  the result owns, :mod:`glvox.gpu.readback`).
* :func:`clear_buffer`: fill a buffer with a 32-bit word on the GPU.
* :func:`z_slabs`: the z slabs a packed grid over the storage-block limit is
  voxelized in, by the methods that take such grids (:data:`MAX_SLAB_VOXELS`),
  and :func:`slab_reader`, which reads them into one result.

All of it lives in the context's declared ``caches`` dict
(:class:`glvox.gl.context.GLContext`) and is released with the context.
"""

from __future__ import annotations

import weakref
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..errors import CapabilityError, LimitError
from .readback import active_sink, copy_into, read_buffer


@dataclass(eq=False)
class MeshBuffers:
    """A mesh on the GPU.

    Attributes
    ----------
    vertices : moderngl.Buffer
        float32 x, y, z per vertex (tightly packed, read as ``float v[]``),
        relative to ``anchor``.
    faces : moderngl.Buffer
        uint32 vertex indices, 3 per triangle.
    anchor : (3,) float64
        World position subtracted from the vertices before the float32 cast.
    n_triangles, n_vertices : int
    bounds : (2, 3) float64
        Min and max corner of the vertices that faces reference, relative to
        ``anchor`` (before the float32 cast: within its rounding of the
        uploaded ones), so passes can be sized to the mesh without a readback.
    derived : dict of str to moderngl.Buffer
        Buffers a method derives from the mesh once (a reordered copy of the
        faces, say), kept and released with the mesh's own.
    """

    vertices: Any
    faces: Any
    anchor: np.ndarray
    n_triangles: int
    n_vertices: int
    bounds: np.ndarray
    derived: dict = field(default_factory=dict)

    def release(self) -> None:
        self.vertices.release()
        self.faces.release()
        for buf in self.derived.values():
            buf.release()
        self.derived.clear()


def _caches(ctx) -> dict:
    caches = ctx.caches.get("gpu")
    if caches is None:
        caches = ctx.caches["gpu"] = {"meshes": {}, "pools": {}, "objects": {}}
        ctx.on_release.append(lambda: _release_all(caches))
    return caches


def gpu_bytes(ctx, owners=None) -> int:
    """Bytes of the GPU buffers glvox keeps in ``ctx``: the uploaded meshes and
    the buffer pools of ``owners`` (method names; all pools when None)."""
    caches = ctx.caches.get("gpu")
    if not caches:
        return 0
    total = sum(b.vertices.size + b.faces.size + sum(d.size for d in b.derived.values())
                for b in caches["meshes"].values())
    for owner, pool in caches["pools"].items():
        if owners is None or owner in owners:
            total += pool.nbytes
    return int(total)


def _release_all(caches: dict) -> None:
    for bufs in list(caches["meshes"].values()):
        bufs.release()
    caches["meshes"].clear()
    for pool in caches["pools"].values():
        pool.release()
    caches["pools"].clear()
    for cache, release in caches["objects"].values():
        release(cache)
    caches["objects"].clear()


def mesh_buffers(ctx, mesh) -> MeshBuffers:
    """The GPU copy of ``mesh`` in ``ctx``, uploaded on first use."""
    meshes = _caches(ctx)["meshes"]
    key = id(mesh)
    bufs = meshes.get(key)
    if bufs is not None:
        return bufs
    bounds = mesh.bounds  # once: the anchor and the kept bounds both come from it
    anchor = 0.5 * (bounds[0] + bounds[1])  # = mesh.anchor
    v, f = mesh.gpu_arrays(anchor)
    check_buffer_size(ctx, v.nbytes, "mesh vertices")
    check_buffer_size(ctx, f.nbytes, "mesh faces")
    bufs = MeshBuffers(ctx.mgl.buffer(v.tobytes()), ctx.mgl.buffer(f.tobytes()), anchor,
                       len(f), len(v), bounds - anchor)
    meshes[key] = bufs

    def drop(meshes=meshes, key=key):
        b = meshes.pop(key, None)
        if b is not None and not ctx.released:
            b.release()

    weakref.finalize(mesh, drop)
    return bufs


class BufferPool:
    """Named GPU buffers of one context, reused and grown on demand."""

    def __init__(self, ctx):
        self.ctx = ctx
        self._bufs: dict[str, Any] = {}

    def get(self, name: str, nbytes: int, *, what: str | None = None, clear: bool = True):
        """A buffer of at least ``nbytes`` bytes (zero-filled when ``clear``)."""
        nbytes = max(4, int(nbytes))
        check_buffer_size(self.ctx, nbytes, what or name)
        buf = self._bufs.get(name)
        if buf is None or buf.size < nbytes:
            if buf is not None:
                buf.release()
            buf = self.ctx.mgl.buffer(reserve=nbytes)
            self._bufs[name] = buf
        if clear:
            clear_buffer(self.ctx, buf, nbytes)
        return buf

    @property
    def nbytes(self) -> int:
        """Bytes of the buffers the pool holds."""
        return sum(buf.size for buf in self._bufs.values())

    def release(self) -> None:
        for b in self._bufs.values():
            b.release()
        self._bufs.clear()


def clear_buffer(ctx, buf, size: int | None = None, value: int = 0, offset: int = 0) -> None:
    """Fill ``size`` bytes of ``buf`` (default: to its end) from ``offset`` with the
    uint32 ``value``, on the GPU.

    moderngl's ``Buffer.clear`` maps the buffer for writing and fills it on the
    host: on a GPU with its own memory that waits for the GPU to finish with the
    buffer and moves the bytes over the bus (a 128 MiB grid is 16 ms at 8 GB/s).
    glClearNamedBufferSubData fills it where it lives, in command order.  Sizes
    that are not whole words (and contexts without GL 4.5) take moderngl's way.
    """
    size = buf.size - offset if size is None else int(size)
    if size <= 0:
        return
    if size % 4 or offset % 4:
        if value:
            raise ValueError(f"a word pattern needs whole words, got offset {offset} and size {size} bytes")
        buf.clear(size=size, offset=offset)
        return
    try:
        ctx.raw.clear_buffer_words(buf.glo, offset, size, value)
    except CapabilityError:
        buf.clear(size=size, offset=offset, chunk=None if value == 0 else np.uint32(value).tobytes())


def buffer_pool(ctx, owner: str) -> BufferPool:
    """The pool of ``owner`` (a method name) in ``ctx``."""
    pools = _caches(ctx)["pools"]
    pool = pools.get(owner)
    if pool is None:
        pool = pools[owner] = BufferPool(ctx)
    return pool


def release_pools(ctx) -> None:
    """Release the buffers of every owner's pool in ``ctx``: GPU memory back to the driver
    between jobs; the next run of a method allocates its buffers again."""
    for pool in _caches(ctx)["pools"].values():
        pool.release()


def object_cache(ctx, owner: str, release) -> dict:
    """A dict of GL objects (render targets, framebuffers...) that ``owner`` keeps
    in ``ctx`` between runs; ``release(cache)`` frees and empties it, and runs
    when the context is released (or by :func:`release_object_cache`)."""
    objects = _caches(ctx)["objects"]
    if owner not in objects:
        objects[owner] = ({}, release)
    return objects[owner][0]


def release_object_cache(ctx, owner: str) -> None:
    """Free what ``owner`` keeps in :func:`object_cache` (nothing if it keeps nothing)."""
    entry = _caches(ctx)["objects"].get(owner)
    if entry is not None:
        entry[1](entry[0])


def check_buffer_size(ctx, nbytes: int, what: str) -> None:
    """LimitError when one SSBO of ``nbytes`` exceeds what the context allows."""
    limit = int(ctx.limits()["GL_MAX_SHADER_STORAGE_BLOCK_SIZE"])
    if nbytes > limit:
        raise LimitError(
            f"{what} needs a {nbytes / 2**20:.1f} MiB shader storage buffer, over this context's "
            f"GL_MAX_SHADER_STORAGE_BLOCK_SIZE of {limit / 2**20:.1f} MiB ({ctx.renderer}); "
            "use a smaller grid, a sparse method (ss-octree), or tile the grid"
        )


#: Largest grid of the methods that voxelize in z slabs (ss-conservative, ss-6sep,
#: ss-solid): their shaders index packed words (uint32: fewer than 2^32 words, i.e.
#: 2^37 voxels) and a grid over the storage-block limit is voxelized in z slabs
#: (:func:`z_slabs`), so glvox's dense limit (glvox.grid.MAX_VOXELS, int32 flat
#: indices) does not bind them; 2^36 voxels (4096^3, 8 GiB of bits on the host)
#: leaves the word index room.
MAX_SLAB_VOXELS = 2**36


def z_slabs(ctx, spec) -> list[tuple[int, int]] | None:
    """The z slabs ``(k0, nk)`` a packed grid over GL_MAX_SHADER_STORAGE_BLOCK_SIZE is
    voxelized in (as many whole z slices as the limit holds), or None when it fits.
    A single z slice over the limit is refused in one line."""
    limit = int(ctx.limits()["GL_MAX_SHADER_STORAGE_BLOCK_SIZE"])
    if spec.n_words * 4 <= limit:
        return None
    per_slice = spec.dims[1] * spec.words_per_row * 4
    nk = limit // per_slice
    if nk == 0:
        raise LimitError(f"one z slice of the {spec.dims} bit grid needs {per_slice} bytes, over "
                         f"GL_MAX_SHADER_STORAGE_BLOCK_SIZE {limit} of this context; use a smaller grid in x "
                         f"and y or the sparse ss-octree")
    return [(k0, min(nk, spec.dims[2] - k0)) for k0 in range(0, spec.dims[2], nk)]


def slab_reader(ctx, spec, timer):
    """For a grid voxelized in z slabs (:func:`z_slabs`): its packed words, uint32
    (nz, ny, words_per_row), and ``read_slab(k0, nk, grid)``, which reads a slab's
    buffer into its slices of them, timed as stage ``readback``.  The words are a
    mapped read-back buffer where the context lends one (:mod:`glvox.gpu.readback`),
    each slab copied into its part on the GPU."""
    if active_sink() is not None:  # refused before any work (glvox.gpu.cuda.CudaSink.begin)
        raise LimitError("a grid voxelized in z slabs cannot stay on the GPU")
    flat = read_buffer(ctx, None, 0, total=spec.n_words * 4, fill=False).view("<u4")
    per_slice = spec.dims[1] * spec.words_per_row

    def read_slab(k0: int, nk: int, grid) -> None:
        with timer.stage("readback", gpu=False):
            copy_into(ctx, grid, flat, k0 * per_slice * 4, nk * per_slice * 4)

    return flat.reshape(spec.dims[2], spec.dims[1], spec.words_per_row), read_slab


def read_grid_words(ctx, buf, spec, slices: tuple[int, int] | None = None) -> np.ndarray:
    """The packed grid words of ``spec`` from ``buf`` (uint32, (nz, ny, words_per_row)).

    ``slices=(k0, nk)``: only z slices k0 .. k0 + nk - 1 can hold a set voxel;
    only they are read, the rest of the array is zero.  Large grids arrive in a
    mapped read-back buffer that the array owns (:mod:`glvox.gpu.readback`).
    Inside a :func:`~glvox.gpu.readback.device_sink` block the words stay on the
    GPU: :class:`glvox.results.DeviceWords` instead of an array.
    """
    per_slice = spec.dims[1] * spec.words_per_row * 4
    k0, nk = (0, spec.dims[2]) if slices is None else slices
    shape = (spec.dims[2], spec.dims[1], spec.words_per_row)
    sink = active_sink()
    if sink is not None:  # a device result: copied on the GPU, never through host memory
        return sink.grid_words(ctx, buf, k0 * per_slice, max(nk, 0) * per_slice, k0 * per_slice, shape)
    words = read_buffer(ctx, buf, max(nk, 0) * per_slice, k0 * per_slice, total=spec.n_words * 4,
                        at=k0 * per_slice).view("<u4")
    return words.reshape(spec.dims[2], spec.dims[1], spec.words_per_row)
