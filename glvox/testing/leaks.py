"""Counting what a process holds: live GL objects and resident memory.

Used by the reliability tests (a method run a thousand times must not grow
either) and handy when hunting a leak by hand::

    >>> from glvox.testing.leaks import live_gl_objects, rss_bytes
    >>> before = live_gl_objects(ctx)
"""

from __future__ import annotations

import ctypes
import os

from ..gl.raw import _SIGNATURES, GLuint
from ..gl.shaders import preprocess

GLboolean = ctypes.c_ubyte

#: GL object kinds and the ``glIs*`` query that tells a live name of each.
#: Programs and shaders share one namespace; so do none of the others.
KINDS = {
    "buffers": "glIsBuffer",
    "textures": "glIsTexture",
    "framebuffers": "glIsFramebuffer",
    "renderbuffers": "glIsRenderbuffer",
    "programs": "glIsProgram",
    "shaders": "glIsShader",
    "vertex_arrays": "glIsVertexArray",
    "queries": "glIsQuery",
    "samplers": "glIsSampler",
}

for _fn in KINDS.values():
    _SIGNATURES.setdefault(_fn, (GLboolean, (GLuint,)))
del _fn

#: Names scanned beyond the largest name a fresh object gets (GL hands out
#: names from a counter that may reuse freed ones; a live object always has a
#: name at most the counter's current value).
SCAN_MARGIN = 64


def _newest_name(ctx) -> int:
    """The largest name a new buffer, texture or framebuffer gets now (an upper
    bound of every live name, since the names come from increasing counters
    that only reuse freed ones)."""
    mgl = ctx.mgl
    buf = mgl.buffer(reserve=4)
    tex = mgl.texture((1, 1), 1)
    fbo = mgl.framebuffer(color_attachments=[tex])
    # a fresh, uncached program: the shader cache would hand back an old name
    prog = mgl.program(vertex_shader=preprocess("testing/fullscreen.vert").text)
    top = max(buf.glo, tex.glo, fbo.glo, prog.glo)
    ctx.release_framebuffer(fbo)
    for obj in (prog, tex, buf):
        obj.release()
    return int(top)


def live_gl_objects(ctx) -> dict[str, int]:
    """Live GL objects of each kind in ``ctx``, by asking ``glIs*`` of every name
    up to the newest name plus :data:`SCAN_MARGIN`.

    Returns
    -------
    dict of str to int
        One count per key of :data:`KINDS`, plus ``'total'``.
    """
    top = _newest_name(ctx) + SCAN_MARGIN
    out = {}
    for kind, fn in KINDS.items():
        f = ctx.raw.fn(fn)
        out[kind] = sum(1 for name in range(1, top + 1) if f(name))
    out["total"] = sum(out.values())
    return out


def rss_bytes() -> int:
    """Resident set size of this process in bytes (Linux ``/proc/self/statm``)."""
    with open("/proc/self/statm") as f:
        pages = int(f.read().split()[1])
    return pages * os.sysconf("SC_PAGE_SIZE")


__all__ = ["KINDS", "live_gl_objects", "rss_bytes"]
