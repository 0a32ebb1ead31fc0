"""Results that stay on the GPU: packed grids handed to CUDA through DLPack.

``glvox.voxelize(..., device="cuda")`` (and ``run_method``) keeps a surface or
solid result in GPU memory for PyTorch, CuPy or JAX, for people who voxelize
straight into training batches.  The grid's GL storage buffer is registered with
CUDA (CUDA-OpenGL interop), mapped, and its packed words are copied on the GPU
into CUDA memory that the result owns; nothing passes through host memory.  The
result's :attr:`glvox.VoxelGrid.device_words` is a DLPack producer, uint32
(nz, ny, words_per_row) in the layout of :meth:`glvox.VoxelGrid.words`::

    grid = glvox.voxelize("bunny.ply", 256, device="cuda")
    words = torch.from_dlpack(grid.device_words)   # on the GL context's GPU

The grid reads the words back to the host only when host data is asked for
(``grid.words()``, ``grid.dense()``, a file).  NVIDIA's ``cuda-core`` package
does the interop and the DLPack export: ``pip install 'glvox[cuda]'``.

Requirements, each checked before any work, in one line: a GL context on an
NVIDIA GPU that CUDA sees (its EGL device's CUDA ordinal, else
``cuGLGetDevices``); a GL surface or solid method;
no per-voxel attributes; a grid within one storage block (a grid that a method
voxelizes in z slabs is refused).

The copy out of GL is one registration, one map and one device-to-device copy
per result, on a stream of the GL context's CUDA device (the map orders it after
the GL work that wrote the grid); the registration is not cached across calls,
since the methods' scratch buffers are reallocated as grids grow.
"""

from __future__ import annotations

import contextlib
from typing import Iterator

import numpy as np

from ..errors import CapabilityError, GlvoxError, LimitError
from ..results.voxels import DeviceWords
from .buffers import z_slabs

#: What to install for ``device="cuda"``.
EXTRA = "pip install 'glvox[cuda]'"

try:  # an optional extra: NVIDIA's maintained bindings do the interop and DLPack
    from cuda.bindings import driver as _driver
    from cuda.core import Buffer, Device, GraphicsResource
    from cuda.core.utils import StridedMemoryView
except ImportError as exc:  # pragma: no cover - depends on the environment
    _MISSING: ImportError | None = exc
else:
    _MISSING = None

DEVICES = ("host", "cuda")


@contextlib.contextmanager
def _cuda_errors(what: str) -> Iterator[None]:
    """A CUDA call's failure as one line (a CapabilityError naming ``what``), not a traceback."""
    try:
        yield
    except GlvoxError:
        raise
    except Exception as exc:  # cuda.core's CUDAError and whatever the driver raises
        raise CapabilityError(f"device='cuda': {what} failed ({type(exc).__name__}: {exc}); "
                              f"use device='host'") from exc


def check_device(device: str | None) -> str:
    """``device`` as run_method takes it ('host', the default, or 'cuda'), or a one-line
    error (for 'cuda' also where the cuda-core package is missing)."""
    device = "host" if device is None else device
    if device not in DEVICES:
        raise GlvoxError(f"device must be one of {', '.join(DEVICES)}, got {device!r}")
    if device == "cuda" and _MISSING is not None:
        raise CapabilityError(f"device='cuda' needs NVIDIA's cuda-core package ({_MISSING}): {EXTRA}")
    return device


class CudaWords(DeviceWords):
    """Packed words in CUDA memory (a ``cuda.core`` Buffer the object owns)."""

    def __init__(self, buffer, shape: tuple[int, int, int], stream):
        self.buffer = buffer
        self.shape = tuple(int(n) for n in shape)
        self.stream = stream
        self.view = StridedMemoryView.from_buffer(buffer, shape=self.shape, dtype=np.dtype("<u4"))

    def __dlpack__(self, **kwargs):
        return self.view.__dlpack__(**kwargs)

    def __dlpack_device__(self) -> tuple[int, int]:
        return self.view.__dlpack_device__()

    def to_host(self) -> np.ndarray:
        out = np.empty(self.shape, dtype="<u4")
        with _cuda_errors("reading the words back"):
            host = Buffer.from_handle(out.ctypes.data, out.nbytes, owner=out)
            self.buffer.copy_to(host, stream=self.stream)
            self.stream.sync()
        return out

    def __repr__(self) -> str:
        return f"CudaWords(shape={self.shape}, device={self.__dlpack_device__()})"


class CudaSink:
    """Where packed grids go in a ``device="cuda"`` run (:func:`glvox.gpu.readback.device_sink`)."""

    def __init__(self):
        check_device("cuda")
        self.device = None
        self.stream = None

    def begin(self, ctx, spec) -> None:
        """Before any work (the GL context current): a grid the methods keep in one
        buffer, and the CUDA device of the context."""
        if z_slabs(ctx, spec) is not None:
            raise LimitError(f"device='cuda': {spec.dims} is over GL_MAX_SHADER_STORAGE_BLOCK_SIZE of this "
                             f"context, so it is voxelized in z slabs, which stay on the host; use a smaller grid")
        self.open_device(ctx)

    def open_device(self, ctx) -> None:
        """The CUDA device the current GL context runs on, made current, and a stream on it,
        found once per context (kept in ``ctx.caches['cuda']``): the ordinal its EGL device
        reports (EGL_NV_device_cuda, as EGL renderers that share with CUDA find it), else
        CUDA's answer for the current GL context (cuGLGetDevices)."""
        opened = ctx.caches.get("cuda")
        if opened is None:
            self._open(ctx)
            ctx.caches["cuda"] = (self.device, self.stream)
            return
        self.device, self.stream = opened
        with _cuda_errors(f"making CUDA device {self.device.device_id} current"):
            self.device.set_current()

    def _open(self, ctx) -> None:
        ordinal = ctx.cuda_ordinal()
        try:
            Device().set_current()  # initializes CUDA; cuGLGetDevices may want a current context
            if ordinal is None:
                err, n, devices = _driver.cuGLGetDevices(1, _driver.CUGLDeviceList.CU_GL_DEVICE_LIST_ALL)
                if err == _driver.CUresult.CUDA_SUCCESS and n >= 1:
                    ordinal = int(devices[0])
                else:
                    why = f"cuGLGetDevices: {getattr(err, 'name', err)}"
        except Exception as exc:  # no driver library, no device
            raise CapabilityError(f"device='cuda': CUDA is not available here ({exc}); use device='host'") from None
        if ordinal is None:
            raise CapabilityError(f"device='cuda': the GL context ({ctx.renderer}, {ctx.device}) is on no CUDA "
                                  f"device ({why}); use device='host'")
        with _cuda_errors(f"opening CUDA device {ordinal}"):
            self.device = Device(ordinal)
            self.device.set_current()
            self.stream = self.device.create_stream()

    def grid_words(self, ctx, buf, offset: int, nbytes: int, at: int, shape) -> CudaWords:
        """``nbytes`` of GL buffer ``buf`` from ``offset``, at byte ``at`` of a zeroed
        grid of ``shape`` words in new CUDA memory."""
        with _cuda_errors("the copy from the GL buffer (CUDA-OpenGL interop)"):
            return self._grid_words(buf, offset, nbytes, at, shape)

    def _grid_words(self, buf, offset: int, nbytes: int, at: int, shape) -> CudaWords:
        s = self.stream
        total = int(np.prod(shape)) * 4
        out = self.device.allocate(total, stream=s)
        if nbytes < total:
            out.fill(0, stream=s)
        if nbytes:
            resource = GraphicsResource.from_gl_buffer(buf.glo, flags="read_only")
            try:
                with resource.map(stream=s) as mapped:  # ordered after the GL work that wrote it
                    src = Buffer.from_handle(int(mapped.handle) + offset, nbytes, owner=mapped)
                    dst = Buffer.from_handle(int(out.handle) + at, nbytes, owner=out)
                    dst.copy_from(src, stream=s)
                s.sync()  # copied and unmapped before the registration goes
            finally:
                resource.close()
        s.sync()
        return CudaWords(out, shape, s)

    def upload(self, words: np.ndarray) -> CudaWords:
        """Host words copied to CUDA memory: the fallback for a method whose grid did
        not reach :meth:`grid_words` (the run's ``stats['device_path']`` says 'host')."""
        host = np.ascontiguousarray(words, dtype="<u4")
        with _cuda_errors("the upload of the host words"):
            out = self.device.allocate(host.nbytes, stream=self.stream)
            out.copy_from(Buffer.from_handle(host.ctypes.data, host.nbytes, owner=host), stream=self.stream)
            self.stream.sync()
            return CudaWords(out, host.shape, self.stream)
