"""Published GL limits of real implementations, as fake contexts.

Each table maps the limit names of :data:`glvox.gl.context.LIMIT_NAMES` to
the values an implementation reports, with its source cited next to it, so a
test (and ``glvox selftest``) can check every registered method's
:class:`~glvox.methods.base.Requirements` against GPUs this machine does not
have.  :class:`FakeContext` gives a table the three things
``Requirements.missing`` reads: ``.limits()``, ``.mgl.version_code`` and
``.mgl.extensions``.

Where a source does not give a value, the GL 4.5 core minimum stands in
(marked "spec floor"): the least any conforming implementation reports, so a
method that passes with it passes on the real one.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from types import SimpleNamespace
from typing import Any, Mapping

from ..gpu.behaviours import PROBES

# GL 4.5 core profile (June 29, 2017), chapter 23 tables; GL 4.6 core (May 5,
# 2022) gives the same values.  KhronosGroup/OpenGL-Registry specs/gl/glspec45.core.pdf.
SPEC_MINIMUM: dict[str, Any] = {
    "GL_MAX_TEXTURE_SIZE": 16384,                                # Table 23.53
    "GL_MAX_3D_TEXTURE_SIZE": 2048,                              # Table 23.53
    "GL_MAX_ARRAY_TEXTURE_LAYERS": 2048,                         # Table 23.53
    "GL_MAX_RENDERBUFFER_SIZE": 16384,                           # Table 23.53
    # Table 23.54 gives no number: "see sec. 13.8.1", at least the largest
    # renderbuffer that can be attached, hence MAX_RENDERBUFFER_SIZE.
    "GL_MAX_VIEWPORT_DIMS": (16384, 16384),
    "GL_MAX_COLOR_ATTACHMENTS": 8,                               # Table 23.70
    "GL_MAX_DRAW_BUFFERS": 8,                                    # Table 23.70
    "GL_MAX_COMPUTE_WORK_GROUP_COUNT": (65535, 65535, 65535),    # Table 23.62
    "GL_MAX_COMPUTE_WORK_GROUP_SIZE": (1024, 1024, 64),          # Table 23.62: "1024 (x, y), 64 (z)"
    "GL_MAX_COMPUTE_WORK_GROUP_INVOCATIONS": 1024,               # Table 23.62
    "GL_MAX_COMPUTE_SHARED_MEMORY_SIZE": 32768,                  # Table 23.62
    "GL_MAX_SHADER_STORAGE_BLOCK_SIZE": 2 ** 27,                 # Table 23.64 (GetInteger64v)
    "GL_MAX_SHADER_STORAGE_BUFFER_BINDINGS": 8,                  # Table 23.64
    "GL_MAX_COMPUTE_SHADER_STORAGE_BLOCKS": 8,                   # Table 23.62
}

# NVIDIA GeForce RTX 3070 Ti, Linux proprietary driver "4.6.0 NVIDIA 580.65.06":
# voldien/glinfo EXAMPLES.md (commit 93f4e980), section "NVIDIA GeForce RTX 3070".
# An H100 on driver 580 (EGL) reported the same work group size, (1024, 1024, 64).
NVIDIA: dict[str, Any] = {
    **SPEC_MINIMUM,  # spec floor: MAX_TEXTURE_SIZE and MAX_VIEWPORT_DIMS are not in the dump
    "GL_MAX_3D_TEXTURE_SIZE": 16384,
    "GL_MAX_ARRAY_TEXTURE_LAYERS": 2048,
    "GL_MAX_RENDERBUFFER_SIZE": 32768,
    "GL_MAX_COLOR_ATTACHMENTS": 8,
    "GL_MAX_DRAW_BUFFERS": 8,
    "GL_MAX_COMPUTE_WORK_GROUP_COUNT": (2147483647, 65535, 65535),
    "GL_MAX_COMPUTE_WORK_GROUP_SIZE": (1024, 1024, 64),
    "GL_MAX_COMPUTE_WORK_GROUP_INVOCATIONS": 1024,
    "GL_MAX_COMPUTE_SHARED_MEMORY_SIZE": 49152,
    "GL_MAX_SHADER_STORAGE_BLOCK_SIZE": 2147483647,
    "GL_MAX_SHADER_STORAGE_BUFFER_BINDINGS": 96,
    "GL_MAX_COMPUTE_SHADER_STORAGE_BLOCKS": 16,
}

# AMD, Mesa radeonsi: derived from Mesa's source, not from a live report:
# src/gallium/drivers/radeonsi/si_get.c (bminor/mesa-mesa commit 0565b834) and
# src/mesa/state_tracker/st_extensions.c.
RADEONSI: dict[str, Any] = {
    **SPEC_MINIMUM,
    "GL_MAX_TEXTURE_SIZE": 16384,                                # PIPE_CAP_MAX_TEXTURE_2D_SIZE
    "GL_MAX_3D_TEXTURE_SIZE": 2048,                              # before GFX10 (8192 on GFX10+)
    "GL_MAX_ARRAY_TEXTURE_LAYERS": 2048,                         # before GFX10 (8192 on GFX10+)
    # get_max_threads_per_block: "LLVM only supports 1024 threads per block"
    "GL_MAX_COMPUTE_WORK_GROUP_SIZE": (1024, 1024, 1024),
    "GL_MAX_COMPUTE_WORK_GROUP_INVOCATIONS": 1024,
    # st clamps the grid (UINT32_MAX) to INT_MAX - 1
    "GL_MAX_COMPUTE_WORK_GROUP_COUNT": (2147483646, 2147483646, 2147483646),
    # 65536, "Value reported by the closed source driver"; GFX6 reports 32768 (the lower here)
    "GL_MAX_COMPUTE_SHARED_MEMORY_SIZE": 32768,
    # min(heap / 4, UINT32_MAX): heap-dependent, so the spec floor
    "GL_MAX_SHADER_STORAGE_BLOCK_SIZE": 2 ** 27,
    # SI_NUM_SHADER_BUFFERS: 32 in newer si_pipe.h, 16 in older; the per-stage
    # count times Mesa's 5 graphics stages gives the bindings (as llvmpipe's 16 -> 80)
    "GL_MAX_COMPUTE_SHADER_STORAGE_BLOCKS": 16,
    "GL_MAX_SHADER_STORAGE_BUFFER_BINDINGS": 80,
}

# Intel, Mesa iris on an Arc A750 (DG2), "4.6 (Core Profile) Mesa 25.0.7":
# voldien/glinfo EXAMPLES.md (commit 93f4e980), section "Intel A750".
IRIS: dict[str, Any] = {
    **SPEC_MINIMUM,  # spec floor: MAX_TEXTURE_SIZE and MAX_VIEWPORT_DIMS are not in the dump
    "GL_MAX_3D_TEXTURE_SIZE": 2048,
    "GL_MAX_ARRAY_TEXTURE_LAYERS": 2048,
    "GL_MAX_RENDERBUFFER_SIZE": 16384,
    "GL_MAX_COMPUTE_WORK_GROUP_COUNT": (2147483646, 2147483646, 2147483646),
    "GL_MAX_COMPUTE_WORK_GROUP_SIZE": (1024, 1024, 1024),
    "GL_MAX_COMPUTE_WORK_GROUP_INVOCATIONS": 1024,
    "GL_MAX_COMPUTE_SHARED_MEMORY_SIZE": 65536,
    "GL_MAX_SHADER_STORAGE_BLOCK_SIZE": 134217728,
    "GL_MAX_SHADER_STORAGE_BUFFER_BINDINGS": 80,
    "GL_MAX_COMPUTE_SHADER_STORAGE_BLOCKS": 16,
}

# Hypothetical: Intel's Windows driver is said to report z = 64 like NVIDIA; no
# source was found, so this is iris with the spec's conservative compute shape
# (z = 64, 32 KiB shared memory) -- a context a real driver may well present.
INTEL_CONSERVATIVE: dict[str, Any] = {
    **IRIS,
    "GL_MAX_COMPUTE_WORK_GROUP_SIZE": (1024, 1024, 64),
    "GL_MAX_COMPUTE_SHARED_MEMORY_SIZE": 32768,
}

# Mesa llvmpipe (LLVM 15.0.6, 256 bits), "4.5 (Core Profile) Mesa 22.3.6", EGL:
# read with glvox.gl.context.GLContext.limits() on the development machine.
LLVMPIPE: dict[str, Any] = {
    "GL_MAX_TEXTURE_SIZE": 16384,
    "GL_MAX_3D_TEXTURE_SIZE": 2048,
    "GL_MAX_ARRAY_TEXTURE_LAYERS": 2048,
    "GL_MAX_RENDERBUFFER_SIZE": 16384,
    "GL_MAX_VIEWPORT_DIMS": (16384, 16384),
    "GL_MAX_COLOR_ATTACHMENTS": 8,
    "GL_MAX_DRAW_BUFFERS": 8,
    "GL_MAX_COMPUTE_WORK_GROUP_COUNT": (65535, 65535, 65535),
    "GL_MAX_COMPUTE_WORK_GROUP_SIZE": (1024, 1024, 1024),
    "GL_MAX_COMPUTE_WORK_GROUP_INVOCATIONS": 1024,
    "GL_MAX_COMPUTE_SHARED_MEMORY_SIZE": 32768,
    "GL_MAX_SHADER_STORAGE_BLOCK_SIZE": 134217728,
    "GL_MAX_SHADER_STORAGE_BUFFER_BINDINGS": 80,
    "GL_MAX_COMPUTE_SHADER_STORAGE_BLOCKS": 16,
}

#: Extensions every listed real driver advertises that glvox methods name
#: (the sources above list GL_ARB_gpu_shader_fp64 for all of them).
_REAL_EXTENSIONS = frozenset({"GL_ARB_gpu_shader_fp64"})


@dataclass(frozen=True)
class Published:
    """One implementation's limits: ``name``, GL ``version_code``, the limit
    table, the extensions it lists and whether it is a real report (False: the
    spec floor or a hypothetical context)."""

    name: str
    version_code: int
    limits: Mapping[str, Any]
    extensions: frozenset = field(default_factory=frozenset)
    real: bool = True


#: The implementations checked by tests and ``glvox selftest --published``.
PUBLISHED = (
    Published("nvidia-580", 460, NVIDIA, _REAL_EXTENSIONS),
    Published("amd-radeonsi", 460, RADEONSI, _REAL_EXTENSIONS),
    Published("intel-iris", 460, IRIS, _REAL_EXTENSIONS),
    Published("llvmpipe", 450, LLVMPIPE, _REAL_EXTENSIONS),
    Published("intel-windows-z64", 460, INTEL_CONSERVATIVE, _REAL_EXTENSIONS, real=False),
    # a core 4.5 context listing no extension at all: what is core is there anyway
    Published("gl45-minimum", 450, SPEC_MINIMUM, frozenset(), real=False),
)


class FakeContext:
    """What ``Requirements.missing`` reads of a context, from a published table."""

    def __init__(self, published: Published):
        self.published = published
        self.renderer = f"published limits of {published.name}"
        self.mgl = SimpleNamespace(version_code=published.version_code, extensions=set(published.extensions))
        # the behaviour probes' answers: a published driver is taken to do them right
        self.caches = {"behaviours": dict.fromkeys(PROBES)}

    def limits(self) -> dict[str, Any]:
        return dict(self.published.limits)


def published(name: str) -> Published:
    """The :data:`PUBLISHED` entry called ``name``."""
    for p in PUBLISHED:
        if p.name == name:
            return p
    raise KeyError(f"no published limits named {name!r}: {[p.name for p in PUBLISHED]}")
