"""Counting what a process holds: live GL objects and resident memory.

Used by the reliability tests (a method run a thousand times must not grow
either) and handy when hunting a leak by hand::

    >>> from glvox.testing.leaks import live_gl_objects, rss_bytes
    >>> before = live_gl_objects(ctx)

:func:`measure_growth` tells glvox's growth from a driver's: glvox's own
objects are the GL objects it creates and the Python heap (numpy arrays
included), counted exactly; the driver's memory shows only in the resident
size, where a one-time pool (NVIDIA's driver grew 10 MiB over the first
thousand runs of a method) stops growing while a leak grows by the same
amount every run, so only the second half of the runs is held to a bound.
"""

from __future__ import annotations

import ctypes
import gc
import os
import tracemalloc
from dataclasses import dataclass
from typing import Callable

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


@dataclass(frozen=True)
class Growth:
    """What ``runs`` calls grew (:func:`measure_growth`).

    Attributes
    ----------
    runs : int
    gl_objects : dict of str to int
        Live GL objects gained (or lost) per kind, only the kinds that changed.
    python_bytes : int
        Python heap (tracemalloc: objects and numpy arrays) after minus before.
    rss_first, rss_second : int
        Resident-size growth over the first and the second half of the runs,
        in bytes: a one-time driver pool shows in the first, a leak in both.
    """

    runs: int
    gl_objects: dict
    python_bytes: int
    rss_first: int
    rss_second: int

    def problems(self, python_allowance: int, steady_allowance: int) -> list[str]:
        """What reads as a leak: any GL object gained, the Python heap grown by
        ``python_allowance`` bytes or more, or the second half's resident size
        grown by ``steady_allowance`` bytes or more."""
        half = self.runs - self.runs // 2
        out = []
        if self.gl_objects:
            out.append(f"live GL objects changed over {self.runs} runs: {self.gl_objects}")
        if self.python_bytes >= python_allowance:
            out.append(f"the Python heap grew by {self.python_bytes >> 10} KiB over {self.runs} runs")
        if self.rss_second >= steady_allowance:
            out.append(f"resident memory grew by {self.rss_second >> 10} KiB over the last {half} runs "
                       f"({self.rss_first >> 10} KiB over the first {self.runs // 2}): a steady growth")
        return out


def measure_growth(ctx, run: Callable[[], object], runs: int) -> Growth:
    """Call ``run`` ``runs`` times (after the caller's warm-up) and measure what
    grew: GL objects of ``ctx`` and the Python heap over all runs, the resident
    size over each half."""
    objects = live_gl_objects(ctx)
    tracing = tracemalloc.is_tracing()
    if not tracing:
        tracemalloc.start()
    try:
        py0 = tracemalloc.get_traced_memory()[0]
        rss0 = rss_bytes()
        for _ in range(runs // 2):
            run()
        rss1 = rss_bytes()
        for _ in range(runs - runs // 2):
            run()
        gc.collect()
        rss2 = rss_bytes()
        py2 = tracemalloc.get_traced_memory()[0]
    finally:
        if not tracing:
            tracemalloc.stop()
    after = live_gl_objects(ctx)
    grown = {k: after[k] - objects[k] for k in after if after[k] != objects[k]}
    return Growth(runs, grown, py2 - py0, rss1 - rss0, rss2 - rss1)


__all__ = ["KINDS", "Growth", "live_gl_objects", "measure_growth", "rss_bytes"]
