"""Run a compute or fragment shader on given arrays and read the results back."""

from __future__ import annotations

import inspect
import math
import os
from pathlib import Path
from typing import Any, Iterable, Mapping, Sequence

import numpy as np

from ..gl.shaders import compute_program, render_program
from ..gpu.buffers import clear_buffer
from ..gpu.dispatch import barrier, bind


def _from_caller(search: Iterable[os.PathLike | str], frame) -> list[Path]:
    """``search`` with relative folders taken from the calling file's folder, so that a test
    finds its shaders wherever pytest runs from; each relative folder is also tried from the
    working directory after that (what it meant before), and absolute folders are kept."""
    caller = frame.f_globals.get("__file__") if frame is not None else None
    base = Path(caller).resolve().parent if caller else Path.cwd()
    out: list[Path] = []
    for entry in search:
        p = Path(entry)
        out += [p] if p.is_absolute() else [base / p, Path.cwd() / p]
    return out


def set_uniforms(prog, uniforms: Mapping[str, Any]) -> None:
    """Set uniforms by name; a name the program lacks raises KeyError naming it."""
    for name, value in uniforms.items():
        member = prog.get(name, None)  # not ``in``: it walks every member
        if member is None:
            raise KeyError(f"program has no active uniform {name!r} (unused uniforms are optimized out)")
        member.value = tuple(value) if isinstance(value, (list, tuple, np.ndarray)) else value


def run_compute(ctx, shader: str, groups: int | Sequence[int], *,
                buffers: Mapping[str | int, np.ndarray | tuple[int, Any]],
                read: Iterable[str | int] = (), uniforms: Mapping[str, Any] | None = None,
                defines: Mapping[str, Any] | None = None,
                search: Iterable[os.PathLike | str] = ()) -> dict[str | int, np.ndarray]:
    """Dispatch a compute shader on SSBOs and read some back.

    Parameters
    ----------
    ctx : GLContext
    shader : str
        Path of the ``.comp`` file relative to a search folder (glvox's
        ``shaders/`` is always searched; add yours with ``search``).
    groups : int or (3,) int
        Work groups to dispatch; each runs the shader's ``local_size``
        invocations, so ``gl_GlobalInvocationID.x`` goes up to
        ``groups * local_size_x - 1``.
    buffers : {block name or binding: array or (count, dtype)}
        An array is uploaded as is; ``(count, dtype)`` makes a zero-filled
        buffer of that many elements.  A key is the storage block's name
        (``"Output"`` for ``buffer Output {...}``), bound as glvox's own
        passes bind (:func:`glvox.gpu.dispatch.bind`: a name the shader does
        not declare raises ShaderError), or its binding number.
    read : iterable of str or int
        Keys of ``buffers`` to read back after the dispatch.
    uniforms, defines : mapping, optional
        Uniforms by name (int, float, or a tuple for vectors; a uniform the
        shader does not use is optimized out and raises KeyError); defines
        inserted after ``#version``.
    search : iterable of path
        Folders to find ``shader`` and its includes in; a relative folder is
        taken from the folder of the file that calls this (your test file),
        then from the working directory.  See docs/testing.md.

    Returns
    -------
    {key: array} for each key in ``read``, with the dtype (and, for
    uploaded arrays, the shape) it was given.
    """
    search = _from_caller(search, inspect.currentframe().f_back)
    ctx.make_current()
    prog = compute_program(ctx, shader, defines, search)
    set_uniforms(prog, uniforms or {})
    made, meta = {}, {}
    try:
        _storage(ctx, prog, buffers, made, meta)
        g = (int(groups), 1, 1) if np.isscalar(groups) else tuple(int(x) for x in groups)
        prog.run(*g)
        barrier(ctx)  # the shader's stores, before glGetBufferSubData reads them (GL 4.5 Sec. 7.12.2)
        return _read_back(made, meta, read)
    finally:
        for buf in made.values():
            buf.release()


def _storage(ctx, prog, buffers, made: dict, meta: dict) -> None:
    """Make and bind the storage buffers of ``buffers`` (see :func:`run_compute`) into ``made``,
    with each one's dtype and shape in ``meta``."""
    for binding, spec in buffers.items():
        if isinstance(spec, tuple):
            count, dtype = spec
            dtype = np.dtype(dtype)
            buf = ctx.mgl.buffer(reserve=max(4, int(count) * dtype.itemsize))
            clear_buffer(ctx, buf)
            meta[binding] = (dtype, (int(count),))
        else:
            arr = np.ascontiguousarray(spec)
            buf = ctx.mgl.buffer(arr.tobytes() if arr.nbytes else b"\0" * 4)
            meta[binding] = (arr.dtype, arr.shape)
        made[binding] = buf
        if isinstance(binding, str):
            bind(prog, **{binding: buf})
        else:
            buf.bind_to_storage_buffer(binding)


def _read_back(made: dict, meta: dict, read) -> dict:
    out = {}
    for binding in read:
        dtype, shape = meta[binding]
        n = math.prod(shape) * dtype.itemsize
        out[binding] = np.frombuffer(made[binding].read(size=n), dtype=dtype).reshape(shape).copy()
    return out


def run_fragment(ctx, fragment: str, size: tuple[int, int], *, outputs: int = 1,
                 dtype: str = "u4", components: int = 4, vertex: str = "testing/fullscreen.vert",
                 vertices: int = 3, draws: int = 1, logic_op: str | None = None,
                 uniforms: Mapping[str, Any] | None = None, defines: Mapping[str, Any] | None = None,
                 textures: Mapping[int, Any] | None = None,
                 buffers: Mapping[str | int, np.ndarray | tuple[int, Any]] | None = None,
                 read: Iterable[str | int] = (),
                 search: Iterable[os.PathLike | str] = ()):
    """Draw ``vertices`` vertices (default a full-screen triangle) into color targets.

    Parameters
    ----------
    fragment : str
        ``.frag`` path; writes to ``outputs`` color attachments.
    size : (width, height)
    outputs : int
        Number of color attachments (up to GL_MAX_DRAW_BUFFERS).
    dtype : {'u4', 'i4', 'f4', 'f1'}
        Texture format of every attachment, with ``components`` channels.
    draws : int
        Repeat the draw (e.g. to test blending or a logic op).
    logic_op : str, optional
        ``'xor'``, ``'or'``... enabled around the draws (see :mod:`glvox.gl`).
    textures : {unit: moderngl texture}, optional
        Bound before drawing.
    buffers, read : optional
        Storage buffers the shaders read or write, as for :func:`run_compute`
        (a fragment shader may write one: GL 4.3 and later).
    search : iterable of path
        As for :func:`run_compute` (relative to the calling file's folder).

    Returns
    -------
    list of arrays, one per attachment, shape (height, width, components)
        and ``dtype`` (``'f1'``: uint8); ``out[y, x]`` is the pixel whose
        ``gl_FragCoord.xy`` is ``(x + 0.5, y + 0.5)`` (row 0 at the bottom).
        With ``read``: that list and {key: array} of the buffers read back,
        as a pair.
    """
    search = _from_caller(search, inspect.currentframe().f_back)
    ctx.make_current()
    prog = render_program(ctx, vertex, fragment, defines=defines, search=search)
    set_uniforms(prog, uniforms or {})
    mgl = ctx.mgl
    targets = [mgl.texture(size, components, dtype=dtype) for _ in range(outputs)]
    fbo = mgl.framebuffer(color_attachments=targets)
    vao = mgl.vertex_array(prog, [])
    made, meta = {}, {}
    try:
        _storage(ctx, prog, buffers or {}, made, meta)
        fbo.use()
        for t in targets:
            t.write(np.zeros((size[1], size[0], components), dtype=np.dtype(dtype)).tobytes())
        for unit, tex in (textures or {}).items():
            tex.use(unit)
        if logic_op is not None:
            with ctx.logic_op(logic_op):
                for _ in range(draws):
                    vao.render(mode=mgl.TRIANGLES, vertices=vertices)
        else:
            for _ in range(draws):
                vao.render(mode=mgl.TRIANGLES, vertices=vertices)
        out = []
        np_dtype = np.dtype("u1" if dtype == "f1" else dtype)
        for t in targets:
            data = t.read()
            out.append(np.frombuffer(data, dtype=np_dtype).reshape(size[1], size[0], components).copy())
        if read:
            mgl.memory_barrier()  # the fragment shader's stores, before the buffers are read
            return out, _read_back(made, meta, read)
        return out
    finally:
        for buf in made.values():
            buf.release()
        vao.release()
        ctx.release_framebuffer(fbo)
        for t in targets:
            t.release()
