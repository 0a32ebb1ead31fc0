"""Results read back into persistently mapped memory, handed to the caller without a second copy.

A packed grid leaves the GPU one of two ways:

* ``glGetBufferSubData`` (moderngl's ``read_into``) into a fresh numpy array.  The
  driver copies through its own staging memory, and the array's pages are
  touched for the first time by that copy: on the H100 this ran at 6.5-7.5 GB/s
  for 128 MiB, on this project's 2-core llvmpipe machine the first touch alone
  costs 100-250 ms per 128 MiB;
* ``glCopyNamedBufferSubData`` into a buffer whose storage is mapped
  persistently and coherently in host memory, then a fence.  The GPU's copy
  engine moves the bits over the bus (53 GB/s on the H100), and the mapping is
  the result: numpy views it directly.

:func:`read_buffer` takes the second way for results of :data:`MIN_MAPPED_BYTES`
and more.  The mapped buffers come from a pool per context (:class:`ReadbackPool`):
the array handed out *owns* its buffer (a lease), and when the array and every
view of it are gone the buffer goes back to the pool, already mapped and with
its pages faulted in, for the next result of that size.  Nothing GL happens in
that hand-back (it may run in any thread, from the garbage collector): the pool
takes returned buffers back on its next use.

``GLVOX_READBACK=copy`` reads every result the first way (``mapped``, the
default, the second): the switch for comparing the two on a GPU, or for a
driver where mapped memory misbehaves.

Limits.  At most :func:`lent_limit` bytes (a quarter of the machine's memory) are
lent at once; a result past that is read the first way, as is every result where
the context cannot map persistently (GL < 4.4).  A context released while some of
its results still view its memory keeps its GL context until they are gone
(:meth:`glvox.gl.context.GLContext.release`); the arrays stay valid.  They are
read-only, as the mapping is (a driver keeps such memory cached for reading); a
caller that wants to write copies first, as with any :class:`glvox.VoxelGrid`'s words.
"""

from __future__ import annotations

import contextlib
import contextvars
import os
import threading
import weakref
from dataclasses import dataclass
from typing import Iterator

import numpy as np

from ..errors import CapabilityError, GlvoxError

#: Results smaller than this are read with glGetBufferSubData: a mapping per
#: result costs more than it saves there.
MIN_MAPPED_BYTES = 1 << 20

#: Mapped buffers are allocated in multiples of this (so similar sizes share them).
_GRANULE = 1 << 20


READBACK_MODES = ("mapped", "copy")

_forced: list[str] = []


@contextlib.contextmanager
def forced_mode(mode: str) -> Iterator[None]:
    """Read results the ``mode`` way ('mapped' or 'copy') inside the block, whatever
    ``GLVOX_READBACK`` says (``glvox selftest`` compares the two ways)."""
    if mode not in READBACK_MODES:
        raise ValueError(f"mode must be one of {', '.join(READBACK_MODES)}, got {mode!r}")
    _forced.append(mode)
    try:
        yield
    finally:
        _forced.pop()


def readback_mode() -> str:
    """'mapped' or 'copy' (see the module): :func:`forced_mode`'s, else ``GLVOX_READBACK``'s
    (default 'mapped')."""
    if _forced:
        return _forced[-1]
    mode = os.environ.get("GLVOX_READBACK", "mapped").strip().lower() or "mapped"
    if mode not in READBACK_MODES:
        raise GlvoxError(f"GLVOX_READBACK must be one of {', '.join(READBACK_MODES)}, got {mode!r}")
    return mode


#: The device sinks of the enclosing :func:`device_sink` blocks (per thread and task:
#: a GL context is current in one thread).
_sinks: contextvars.ContextVar[tuple] = contextvars.ContextVar("glvox_device_sinks", default=())


@contextlib.contextmanager
def device_sink(sink) -> Iterator[None]:
    """Inside the block, packed grids read with :func:`glvox.gpu.buffers.read_grid_words`
    go to ``sink`` (a GPU-to-GPU copy, :class:`glvox.gpu.cuda.CudaSink`) instead of host
    memory: ``sink.grid_words(ctx, buf, offset, nbytes, at, shape)`` returns
    :class:`glvox.results.DeviceWords` holding ``nbytes`` of ``buf`` from ``offset`` at
    byte ``at`` of a zeroed grid of ``shape`` words.  Other reads are unchanged."""
    token = _sinks.set(_sinks.get() + (sink,))
    try:
        yield
    finally:
        _sinks.reset(token)


def active_sink():
    """The sink of the innermost :func:`device_sink` block, or None."""
    sinks = _sinks.get()
    return sinks[-1] if sinks else None


def lent_limit() -> int:
    """Most bytes of mapped memory lent to results at once: a quarter of physical memory."""
    try:
        total = os.sysconf("SC_PHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (AttributeError, ValueError, OSError):  # not Linux: assume 16 GiB
        total = 16 << 30
    return int(total) // 4


@dataclass(eq=False)
class MappedBuffer:
    """A GL buffer mapped persistently: its name, the mapping's address, its size in bytes."""

    name: int
    address: int
    size: int


class _MappedView:
    """The object numpy arrays of a lease view; its life is the lease's."""

    def __init__(self, buf: MappedBuffer, nbytes: int):
        self.buf = buf
        self.__array_interface__ = {"data": (buf.address, True), "shape": (nbytes,),
                                    "typestr": "|u1", "version": 3}


class ReadbackPool:
    """The mapped read-back buffers of one context: free ones, and those lent to results."""

    def __init__(self, ctx):
        self.ctx = ctx
        self._free: list[MappedBuffer] = []
        self._lent: dict[int, MappedBuffer] = {}
        self._returned: list[int] = []  # appended by finalizers, in any thread
        self._lock = threading.Lock()
        self.closing = False
        #: how results were read: "mapped" (a new buffer), "reused" (a pooled one), "copied"
        self.counts = {"mapped": 0, "reused": 0, "copied": 0}
        self.unmappable = False

    # -- leases ---------------------------------------------------------------
    def _give_back(self, name: int) -> None:
        with self._lock:
            self._returned.append(name)

    def _collect(self) -> None:
        with self._lock:
            returned, self._returned = self._returned, []
        for name in returned:
            buf = self._lent.pop(name)
            if not self.closing:
                self._free.append(buf)
            # closing: the buffer goes with the GL context, released when nothing is lent

    def busy(self) -> bool:
        """True while a result still views one of this pool's buffers."""
        self._collect()
        return bool(self._lent)

    @property
    def lent_bytes(self) -> int:
        self._collect()
        return sum(b.size for b in self._lent.values())

    @property
    def free_bytes(self) -> int:
        return sum(b.size for b in self._free)

    def lease(self, nbytes: int) -> tuple[MappedBuffer, np.ndarray] | None:
        """A mapped buffer of at least ``nbytes`` and a uint8 array of its first
        ``nbytes`` that owns it, or None where this context lends no more (the
        limit, or no persistent mapping).  The buffer's content is undefined."""
        if self.closing or self.unmappable:
            return None
        self._collect()
        size = -(-nbytes // _GRANULE) * _GRANULE
        fits = [b for b in self._free if size <= b.size <= 2 * size]
        limit = lent_limit()
        if self.lent_bytes + (min(b.size for b in fits) if fits else size) > limit:
            return None
        if fits:  # the smallest that fits, the last returned of those (its pages are the warmest)
            buf = min(reversed(fits), key=lambda b: b.size)
            self._free.remove(buf)
            self.counts["reused"] += 1
        else:
            while self._free and self.lent_bytes + self.free_bytes + size > limit:
                self._delete(self._free.pop(0))
            try:
                name, address = self.ctx.raw.create_mapped_buffer(size)
            except CapabilityError:
                # a small buffer refused: this context maps nothing; a large one: this result
                self.unmappable = size <= MIN_MAPPED_BYTES * 64
                return None
            buf = MappedBuffer(name, address, size)
            self.counts["mapped"] += 1
        self._lent[buf.name] = buf
        owner = _MappedView(buf, nbytes)
        weakref.finalize(owner, self._give_back, buf.name)
        return buf, np.asarray(owner)

    def _delete(self, buf: MappedBuffer) -> None:
        self.ctx.raw.delete_buffer(buf.name)

    def release(self) -> None:
        """Delete the free buffers (the context is current); lent ones stay mapped
        until their results are gone and the GL context itself is released."""
        self._collect()
        for buf in self._free:
            self._delete(buf)
        self._free.clear()
        self.closing = True


def readback_pool(ctx) -> ReadbackPool:
    """The read-back pool of ``ctx`` (created on first use; the context keeps its GL
    context alive while the pool lends memory)."""
    pool = ctx.caches.get("readback")
    if pool is None:
        pool = ctx.caches["readback"] = ReadbackPool(ctx)
        ctx.on_release.append(pool.release)
        ctx.keep_alive.append(pool.busy)
    return pool


def read_buffer(ctx, buf, nbytes: int, offset: int = 0, *, total: int | None = None,
                at: int = 0, fill: bool = True) -> np.ndarray:
    """``nbytes`` bytes of the moderngl buffer ``buf`` from ``offset``, as a new uint8
    array of ``total`` bytes (default ``nbytes``) holding them at ``at``; the rest is 0
    (undefined without ``fill``, for a caller that writes it all with :func:`copy_into`).

    Mapped and lent (see the module) from :data:`MIN_MAPPED_BYTES`, else read into
    a numpy array.  Waits for the GPU.
    """
    total = nbytes if total is None else int(total)
    pool = readback_pool(ctx)
    whole_words = total % 4 == 0 and at % 4 == 0 and nbytes % 4 == 0  # GPU clears fill words
    wanted = total >= MIN_MAPPED_BYTES and whole_words and readback_mode() == "mapped"
    lease = pool.lease(total) if wanted else None
    if lease is None:
        pool.counts["copied"] += 1
        out = np.zeros(total, dtype=np.uint8) if fill and nbytes < total else np.empty(total, dtype=np.uint8)
        if nbytes:
            buf.read_into(out[at:at + nbytes], size=nbytes, offset=offset)
        return out
    mapped, out = lease
    if nbytes:
        ctx.raw.copy_buffer(buf.glo, mapped.name, offset, at, nbytes)
    if fill:  # the rest zeroed by the GPU too: the mapping is read-only
        for start, end in ((0, at), (at + nbytes, total)):
            if end > start:
                ctx.raw.clear_buffer_words(mapped.name, start, end - start, 0)
    if nbytes or fill:
        ctx.raw.wait_for_gpu()
    return out


def copy_into(ctx, buf, out: np.ndarray, at: int, nbytes: int, offset: int = 0) -> None:
    """Copy ``nbytes`` of ``buf`` from ``offset`` into bytes ``at ..`` of ``out``, an array
    from :func:`read_buffer` (of any dtype): on the GPU where ``out`` views a lent
    buffer, else with glGetBufferSubData.  Waits for the GPU."""
    mapped = _lease_of(out)
    if mapped is None or out.__array_interface__["data"][0] != mapped.address:  # not from the buffer's start
        buf.read_into(out.reshape(-1).view(np.uint8)[at:at + nbytes], size=nbytes, offset=offset)
        return
    ctx.raw.copy_buffer(buf.glo, mapped.name, offset, at, nbytes)
    ctx.raw.wait_for_gpu()


def _lease_of(arr: np.ndarray) -> MappedBuffer | None:
    """The lent buffer ``arr`` views (through its bases), or None."""
    base = arr
    while base is not None:
        if isinstance(base, _MappedView):
            return base.buf
        base = getattr(base, "base", None)
    return None


def is_mapped(arr: np.ndarray) -> bool:
    """True when ``arr`` (or what it views) is a lent mapped buffer of some context."""
    return _lease_of(arr) is not None
