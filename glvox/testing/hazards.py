"""Missing memory barriers, found on any driver: a trace of GL's incoherent writes.

A shader's stores to a storage buffer are *incoherent* in GL: a later command sees
them only after ``glMemoryBarrier`` with the bit for the way it reads them
(GL 4.5 core Sec. 7.12.2): ``SHADER_STORAGE_BARRIER_BIT`` for shaders that read the
buffer as a storage block, ``COMMAND_BARRIER_BIT`` for indirect dispatch or draw
arguments, ``BUFFER_UPDATE_BARRIER_BIT`` for glGetBufferSubData, glBufferSubData,
glCopyBufferSubData and glClearBufferSubData, ``VERTEX_ATTRIB_ARRAY_BARRIER_BIT`` and
``ELEMENT_ARRAY_BARRIER_BIT`` for vertex and index buffers.  Mesa's llvmpipe runs
every command to completion before the next, so a missing barrier never shows
there; a GPU overlaps commands and caches, and the same code reads stale words.

:func:`trace` records, while a block runs, every storage block a dispatch or draw
binds (read or written as its declaration says: ``readonly``, ``writeonly``, or
both; atomic where every use of it is an ``atomic*()`` call, in the ``#if``
branches the program's defines select: :attr:`glvox.gl.shaders.Source.storage_access`),
every buffer read, written, copied or cleared through moderngl or
:class:`glvox.gl.raw.RawGL`, and every barrier, and reports each command that
reads a buffer a shader wrote before it without the barrier bit that read needs
in between (atomic operations after atomic operations need none)::

    from glvox.testing.hazards import trace

    with trace() as t:
        run_method("ss-solid", mesh, spec)
    assert not t.hazards, t.describe()

A block declared without ``readonly`` is counted as written by every command that
binds it, so a shader that only reads a buffer should say so.
"""

from __future__ import annotations

import contextlib
from dataclasses import dataclass, field
from typing import Iterator

import moderngl

from ..gl import raw as rawgl
from ..gl import shaders as loader

#: The barrier bit each kind of read needs after a shader's store (GL 4.5 Sec. 7.12.2).
NEEDS = {
    "storage": moderngl.SHADER_STORAGE_BARRIER_BIT,
    "command": moderngl.COMMAND_BARRIER_BIT,
    "update": moderngl.BUFFER_UPDATE_BARRIER_BIT,
    "vertex": moderngl.VERTEX_ATTRIB_ARRAY_BARRIER_BIT,
    "index": moderngl.ELEMENT_ARRAY_BARRIER_BIT,
}


@dataclass
class Hazard:
    """A command that read a buffer a shader had written, without the barrier it needs."""

    command: str      # what read it: the program's files, or the buffer operation
    read_as: str      # a key of NEEDS
    buffer: str       # the buffer: its storage block in the reader, or its GL name
    writer: str       # the program (and block) whose store it did not wait for

    def describe(self) -> str:
        return (f"{self.command} reads {self.buffer} as {self.read_as} after {self.writer} wrote it, "
                f"with no glMemoryBarrier holding bit {NEEDS[self.read_as]:#x} in between")


@dataclass
class Trace:
    """What :func:`trace` saw: the hazards, and how many commands it checked."""

    hazards: list[Hazard] = field(default_factory=list)
    commands: int = 0
    barriers: int = 0
    # buffer name -> (writer, barrier bits still missing, written by atomics alone)
    _pending: dict[int, tuple[str, int, bool]] = field(default_factory=dict)
    _bound: dict[int, int] = field(default_factory=dict)  # storage binding -> buffer name

    def describe(self) -> str:
        seen: list[str] = []
        for h in self.hazards:
            line = h.describe()
            if line not in seen:
                seen.append(line)
        return f"{len(self.hazards)} missing barriers in {self.commands} commands:\n" + "\n".join(seen)

    # -- events ---------------------------------------------------------------
    def read(self, command: str, buffer: int, read_as: str, atomic: bool = False, block: str = "") -> None:
        """``atomic``: the command touches the buffer with atomic operations alone, which
        see every earlier atomic operation without a barrier."""
        pending = self._pending.get(buffer)
        if pending is None or not pending[1] & NEEDS[read_as] or (atomic and pending[2]):
            return
        what = f"block {block} (buffer {buffer})" if block else f"buffer {buffer}"
        self.hazards.append(Hazard(command, read_as, what, pending[0]))

    def written_by_shader(self, command: str, buffer: int, atomic: bool = False) -> None:
        old = self._pending.get(buffer)  # an earlier plain store still unseen by shaders stays one
        atomic = atomic and (old is None or old[2] or not old[1] & NEEDS["storage"])
        self._pending[buffer] = (command, sum(NEEDS.values()), atomic)

    def written(self, buffer: int) -> None:
        """A buffer update (not a shader store): it orders itself after earlier commands."""
        self._pending.pop(buffer, None)

    def barrier(self, bits: int) -> None:
        self.barriers += 1
        for buffer, (writer, missing, atomic) in list(self._pending.items()):
            missing &= ~bits
            if missing:
                self._pending[buffer] = (writer, missing, atomic)
            else:
                del self._pending[buffer]

    def shader_command(self, prog, command: str, extra_reads: tuple[tuple[int, str], ...] = ()) -> None:
        """A dispatch or draw of ``prog``: its storage blocks as bound now, then ``extra_reads``."""
        self.commands += 1
        src = loader.program_source(prog)
        access = src.storage_access if src is not None else {}
        writes = []
        for buffer, read_as in extra_reads:
            self.read(command, buffer, read_as)
        for name in prog:
            member = prog[name]
            if not isinstance(member, moderngl.StorageBlock):
                continue
            buffer = self._bound.get(member.binding)
            if buffer is None:
                continue
            read, written, atomic = access.get(name, (True, True, False))
            if read:
                self.read(command, buffer, "storage", atomic, name)
            if written:
                writes.append((buffer, atomic, name))
        for buffer, atomic, name in writes:
            self.written_by_shader(f"{command} (block {name})", buffer, atomic)

    def update(self, command: str, buffer: int, *, reads: bool, writes: bool) -> None:
        """A buffer operation (glGetBufferSubData, glBufferSubData, a copy, a clear)."""
        self.commands += 1
        if reads or writes:  # both wait for earlier shader stores (BUFFER_UPDATE_BARRIER_BIT)
            self.read(command, buffer, "update")
        if writes:
            self.written(buffer)


def _name(prog) -> str:
    src = loader.program_source(prog)
    return src.name if src is not None else type(prog).__name__


@contextlib.contextmanager
def trace() -> Iterator[Trace]:
    """Record GL's incoherent writes and barriers in the block (every context, this
    process); the yielded :class:`Trace` holds the hazards found."""
    t = Trace()
    saved: list[tuple[object, str, object]] = []

    def patch(owner, attr, make):
        original = getattr(owner, attr)
        saved.append((owner, attr, original))
        setattr(owner, attr, make(original))

    def bind(original):
        def wrapped(self, binding=0, *args, **kwargs):
            t._bound[int(binding)] = self.glo
            return original(self, binding, *args, **kwargs)
        return wrapped

    def run(original):
        def wrapped(self, *args, **kwargs):
            t.shader_command(self, _name(self))
            return original(self, *args, **kwargs)
        return wrapped

    def run_indirect(original):
        def wrapped(self, buffer, *args, **kwargs):
            t.shader_command(self, _name(self), ((buffer.glo, "command"),))
            return original(self, buffer, *args, **kwargs)
        return wrapped

    def vao_reads(vao, indirect=None):
        reads = [(b.glo, "vertex") for b, *_ in (vao._content or ()) if isinstance(b, moderngl.Buffer)]
        if vao._index_buffer is not None:
            reads.append((vao._index_buffer.glo, "index"))
        if indirect is not None:
            reads.append((indirect.glo, "command"))
        return tuple(reads)

    def render(original):
        def wrapped(self, *args, **kwargs):
            t.shader_command(self._program, _name(self._program), vao_reads(self))
            return original(self, *args, **kwargs)
        return wrapped

    def render_indirect(original):
        def wrapped(self, buffer, *args, **kwargs):
            t.shader_command(self._program, _name(self._program), vao_reads(self, buffer))
            return original(self, buffer, *args, **kwargs)
        return wrapped

    def buffer_op(what, reads, writes):
        def make(original):
            def wrapped(self, *args, **kwargs):
                t.update(f"Buffer.{what}", self.glo, reads=reads, writes=writes)
                return original(self, *args, **kwargs)
            return wrapped
        return make

    def release(original):
        def wrapped(self, *args, **kwargs):
            t._pending.pop(getattr(self, "glo", None), None)
            return original(self, *args, **kwargs)
        return wrapped

    def memory_barrier(original):
        def wrapped(self, barriers=moderngl.ALL_BARRIER_BITS, *args, **kwargs):
            t.barrier(int(barriers))
            return original(self, barriers, *args, **kwargs)
        return wrapped

    def raw_copy(original):
        def wrapped(self, src, dst, *args, **kwargs):
            t.update("glCopyNamedBufferSubData (source)", int(src), reads=True, writes=False)
            t.update("glCopyNamedBufferSubData (destination)", int(dst), reads=False, writes=True)
            return original(self, src, dst, *args, **kwargs)
        return wrapped

    def raw_clear(original):
        def wrapped(self, buffer, *args, **kwargs):
            t.update("glClearNamedBufferSubData", int(buffer), reads=False, writes=True)
            return original(self, buffer, *args, **kwargs)
        return wrapped

    try:
        patch(moderngl.Buffer, "bind_to_storage_buffer", bind)
        patch(moderngl.ComputeShader, "run", run)
        patch(moderngl.ComputeShader, "run_indirect", run_indirect)
        patch(moderngl.VertexArray, "render", render)
        patch(moderngl.VertexArray, "render_indirect", render_indirect)
        for what, reads, writes in (("read", True, False), ("read_into", True, False),
                                    ("write", False, True), ("clear", False, True)):
            patch(moderngl.Buffer, what, buffer_op(what, reads, writes))
        patch(moderngl.Buffer, "release", release)
        patch(moderngl.Context, "memory_barrier", memory_barrier)
        patch(rawgl.RawGL, "copy_buffer", raw_copy)
        patch(rawgl.RawGL, "clear_buffer_words", raw_clear)
        yield t
    finally:
        for owner, attr, original in reversed(saved):
            setattr(owner, attr, original)
