"""The few raw OpenGL calls moderngl does not expose.

moderngl has no ``glLogicOp`` and no stencil state; the XOR/OR solid methods
and Passalis' stencil counting need them.  They are called on the *same*
context through function pointers obtained from the loader that created it
(EGL's ``eglGetProcAddress`` or ``OSMesaGetProcAddress``), so this is the one
place where glvox touches GL below moderngl.
"""

from __future__ import annotations

import contextlib
import ctypes
from typing import Callable, Iterator

from ..errors import CapabilityError

GL_COLOR_LOGIC_OP = 0x0BF2
GL_STENCIL_TEST = 0x0B90

#: ``glLogicOp`` opcodes by name.
LOGIC_OPS = {
    "clear": 0x1500,
    "and": 0x1501,
    "copy": 0x1503,
    "noop": 0x1505,
    "xor": 0x1506,
    "or": 0x1507,
    "set": 0x150F,
}

GLenum = ctypes.c_uint
GLint = ctypes.c_int
GLuint = ctypes.c_uint
GLboolean = ctypes.c_ubyte

# name -> (restype, argtypes)
_SIGNATURES: dict[str, tuple[object, tuple[object, ...]]] = {
    "glEnable": (None, (GLenum,)),
    "glDisable": (None, (GLenum,)),
    "glIsEnabled": (GLboolean, (GLenum,)),
    "glLogicOp": (None, (GLenum,)),
    "glGetIntegerv": (None, (GLenum, ctypes.POINTER(GLint))),
    "glStencilFunc": (None, (GLenum, GLint, GLuint)),
    "glStencilOp": (None, (GLenum, GLenum, GLenum)),
    "glStencilMask": (None, (GLuint,)),
    "glClearStencil": (None, (GLint,)),
    "glGenQueries": (None, (ctypes.c_int, ctypes.POINTER(GLuint))),
    "glDeleteQueries": (None, (ctypes.c_int, ctypes.POINTER(GLuint))),
    "glQueryCounter": (None, (GLuint, GLenum)),
    "glGetQueryObjectui64v": (None, (GLuint, GLenum, ctypes.POINTER(ctypes.c_uint64))),
    "glFlush": (None, ()),
}

_SIGNATURES["glClearNamedBufferSubData"] = (
    None, (GLuint, GLenum, ctypes.c_ssize_t, ctypes.c_ssize_t, GLenum, GLenum, ctypes.c_void_p))

# persistently mapped read-back buffers (glvox.gpu.readback), GL 4.4 / 4.5
_SIGNATURES["glCreateBuffers"] = (None, (ctypes.c_int, ctypes.POINTER(GLuint)))
_SIGNATURES["glDeleteBuffers"] = (None, (ctypes.c_int, ctypes.POINTER(GLuint)))
_SIGNATURES["glNamedBufferStorage"] = (None, (GLuint, ctypes.c_ssize_t, ctypes.c_void_p, ctypes.c_uint))
_SIGNATURES["glMapNamedBufferRange"] = (ctypes.c_void_p, (GLuint, ctypes.c_ssize_t, ctypes.c_ssize_t, ctypes.c_uint))
_SIGNATURES["glUnmapNamedBuffer"] = (GLboolean, (GLuint,))
_SIGNATURES["glCopyNamedBufferSubData"] = (
    None, (GLuint, GLuint, ctypes.c_ssize_t, ctypes.c_ssize_t, ctypes.c_ssize_t))
_SIGNATURES["glFenceSync"] = (ctypes.c_void_p, (GLenum, ctypes.c_uint))
_SIGNATURES["glClientWaitSync"] = (GLenum, (ctypes.c_void_p, ctypes.c_uint, ctypes.c_uint64))
_SIGNATURES["glDeleteSync"] = (None, (ctypes.c_void_p,))
_SIGNATURES["glGetError"] = (GLenum, ())

GL_MAP_READ_BIT = 0x0001
GL_MAP_PERSISTENT_BIT = 0x0040
GL_MAP_COHERENT_BIT = 0x0080
GL_SYNC_GPU_COMMANDS_COMPLETE = 0x9117
GL_SYNC_FLUSH_COMMANDS_BIT = 0x00000001
GL_ALREADY_SIGNALED = 0x911A
GL_TIMEOUT_EXPIRED = 0x911B
GL_CONDITION_SATISFIED = 0x911C
GL_WAIT_FAILED = 0x911D

GL_R32UI = 0x8236
GL_RED_INTEGER = 0x8D94
GL_UNSIGNED_INT = 0x1405

GL_TIMESTAMP = 0x8E28
GL_QUERY_RESULT = 0x8866

GL_LOGIC_OP_MODE = 0x0BF0


class RawGL:
    """Lazily bound raw GL entry points of one context.

    Parameters
    ----------
    loader : callable
        ``loader(name: str) -> int`` returning the address of a GL function
        in the current context (0 when missing).
    """

    def __init__(self, loader: Callable[[str], int]):
        self._loader = loader
        self._fns: dict[str, Callable] = {}

    def fn(self, name: str) -> Callable:
        """The ctypes function ``name``; raises CapabilityError when absent."""
        f = self._fns.get(name)
        if f is None:
            if name not in _SIGNATURES:
                raise KeyError(f"no signature known for GL function {name!r}")
            addr = self._loader(name)
            if not addr:
                raise CapabilityError(f"the GL context does not provide {name}")
            restype, argtypes = _SIGNATURES[name]
            f = ctypes.CFUNCTYPE(restype, *argtypes)(addr)
            self._fns[name] = f
        return f

    def get_integer(self, pname: int) -> int:
        out = GLint(0)
        self.fn("glGetIntegerv")(pname, ctypes.byref(out))
        return int(out.value)

    # -- buffers ------------------------------------------------------------
    def clear_buffer_words(self, buffer: int, offset: int, size: int, value: int) -> None:
        """Fill bytes ``offset .. offset + size`` of buffer object ``buffer`` with the
        uint32 ``value`` on the GPU (glClearNamedBufferSubData, GL 4.5): no mapping,
        no host memory, no wait for earlier commands.  ``offset`` and ``size`` are
        multiples of 4."""
        word = GLuint(value & 0xFFFFFFFF)
        self.fn("glClearNamedBufferSubData")(buffer, GL_R32UI, offset, size, GL_RED_INTEGER, GL_UNSIGNED_INT,
                                             ctypes.byref(word))

    def create_mapped_buffer(self, size: int) -> tuple[int, int]:
        """A buffer of ``size`` bytes with immutable storage, mapped for reading,
        persistently and coherently: ``(name, address of the mapping)``.  The mapping
        stays valid while the buffer lives, whatever is bound or current.  Read only:
        a driver may then keep it in cached host memory (the flags the H100 probe
        measured at 53 GB/s for a GPU copy into it)."""
        name = GLuint(0)
        self.fn("glCreateBuffers")(1, ctypes.byref(name))
        access = GL_MAP_READ_BIT | GL_MAP_PERSISTENT_BIT | GL_MAP_COHERENT_BIT
        self.fn("glNamedBufferStorage")(name.value, size, None, access)
        address = self.fn("glMapNamedBufferRange")(name.value, 0, size, access)
        if not address:
            self.delete_buffer(name.value)
            errors = self.take_errors()  # GL_OUT_OF_MEMORY, say: not left for a later check
            raise CapabilityError(f"the GL context could not map a {size}-byte buffer persistently "
                                  f"(GL errors {[hex(e) for e in errors]})")
        return int(name.value), int(address)

    def take_errors(self) -> list[int]:
        """The GL errors pending (glGetError until GL_NO_ERROR), cleared."""
        out = []
        while len(out) < 16:
            err = int(self.fn("glGetError")())
            if not err:
                break
            out.append(err)
        return out

    def delete_buffer(self, buffer: int) -> None:
        """Unmap (if mapped) and delete buffer object ``buffer``."""
        self.fn("glUnmapNamedBuffer")(buffer)
        name = GLuint(buffer)
        self.fn("glDeleteBuffers")(1, ctypes.byref(name))

    def copy_buffer(self, src: int, dst: int, src_offset: int, dst_offset: int, size: int) -> None:
        """Copy ``size`` bytes between buffer objects on the GPU (glCopyNamedBufferSubData)."""
        self.fn("glCopyNamedBufferSubData")(src, dst, src_offset, dst_offset, size)

    def wait_for_gpu(self) -> None:
        """Block until every command issued so far has completed (a fence and
        glClientWaitSync: after it, the GPU's writes to coherently mapped buffers
        are visible to the host)."""
        fence = self.fn("glFenceSync")(GL_SYNC_GPU_COMMANDS_COMPLETE, 0)
        try:
            flags = GL_SYNC_FLUSH_COMMANDS_BIT
            while True:
                status = self.fn("glClientWaitSync")(fence, flags, 1_000_000_000)
                if status in (GL_ALREADY_SIGNALED, GL_CONDITION_SATISFIED):
                    return
                if status != GL_TIMEOUT_EXPIRED:
                    raise CapabilityError(f"glClientWaitSync failed (status {status:#x})")
                flags = 0
        finally:
            self.fn("glDeleteSync")(fence)

    # -- timestamps ---------------------------------------------------------
    def gen_queries(self, n: int) -> list[int]:
        ids = (GLuint * n)()
        self.fn("glGenQueries")(n, ids)
        return list(ids)

    def delete_queries(self, ids: list[int]) -> None:
        arr = (GLuint * len(ids))(*ids)
        self.fn("glDeleteQueries")(len(ids), arr)

    def timestamp(self, query: int) -> None:
        """Record the GPU time when the commands before it complete (glQueryCounter)."""
        self.fn("glQueryCounter")(query, GL_TIMESTAMP)

    def flush(self) -> None:
        """Submit the commands so far without waiting for them (glFlush)."""
        self.fn("glFlush")()

    def query_result_ns(self, query: int) -> int:
        """The 64-bit result of a query, waiting for it (nanoseconds for timestamps)."""
        out = ctypes.c_uint64(0)
        self.fn("glGetQueryObjectui64v")(query, GL_QUERY_RESULT, ctypes.byref(out))
        return int(out.value)

    # -- logic op -----------------------------------------------------------
    def set_logic_op(self, op: str | None) -> None:
        """Enable COLOR_LOGIC_OP with ``op`` ('xor', 'or', ...), or disable it with None."""
        if op is None:
            self.fn("glDisable")(GL_COLOR_LOGIC_OP)
            return
        try:
            code = LOGIC_OPS[op]
        except KeyError:
            raise ValueError(f"logic op must be one of {sorted(LOGIC_OPS)}, got {op!r}") from None
        self.fn("glEnable")(GL_COLOR_LOGIC_OP)
        self.fn("glLogicOp")(code)

    def logic_op_state(self) -> tuple[bool, str | None]:
        """(enabled, op name) as GL reports them."""
        enabled = bool(self.fn("glIsEnabled")(GL_COLOR_LOGIC_OP))
        code = self.get_integer(GL_LOGIC_OP_MODE)
        name = next((k for k, v in LOGIC_OPS.items() if v == code), hex(code))
        return enabled, name

    @contextlib.contextmanager
    def logic_op(self, op: str) -> Iterator[None]:
        """Context manager: draws inside combine with the framebuffer by ``op``."""
        self.set_logic_op(op)
        try:
            yield
        finally:
            self.set_logic_op(None)


# -- for the depth-buffer methods (glvox/methods/depth/) -------------
# Framebuffers with a depth-stencil *texture* (moderngl makes depth attachments
# without stencil), reading its stencil in shaders, integer colour clears and
# stencil state.  Only the entry points and enums; the helpers that use them
# live with the methods.

GL_FRAMEBUFFER = 0x8D40
GL_DRAW_FRAMEBUFFER_BINDING = 0x8CA6
GL_FRAMEBUFFER_COMPLETE = 0x8CD5
GL_COLOR_ATTACHMENT0 = 0x8CE0
GL_DEPTH_STENCIL_ATTACHMENT = 0x821A
GL_TEXTURE_2D = 0x0DE1
GL_TEXTURE0 = 0x84C0
GL_TEXTURE_BINDING_2D = 0x8069
GL_ACTIVE_TEXTURE = 0x84E0
GL_DEPTH32F_STENCIL8 = 0x8CAD
GL_DEPTH24_STENCIL8 = 0x88F0
GL_TEXTURE_MIN_FILTER = 0x2801
GL_TEXTURE_MAG_FILTER = 0x2800
GL_NEAREST = 0x2600
GL_DEPTH_STENCIL_TEXTURE_MODE = 0x90EA
GL_STENCIL_INDEX = 0x1901
GL_COLOR = 0x1800
GL_DEPTH = 0x1801
GL_DEPTH_STENCIL = 0x84F9
GL_ALWAYS = 0x0207
GL_KEEP = 0x1E00
GL_INCR = 0x1E02

_SIGNATURES.update({
    "glGenFramebuffers": (None, (ctypes.c_int, ctypes.POINTER(GLuint))),
    "glDeleteFramebuffers": (None, (ctypes.c_int, ctypes.POINTER(GLuint))),
    "glBindFramebuffer": (None, (GLenum, GLuint)),
    "glFramebufferTexture2D": (None, (GLenum, GLenum, GLenum, GLuint, GLint)),
    "glCheckFramebufferStatus": (GLenum, (GLenum,)),
    "glGenTextures": (None, (ctypes.c_int, ctypes.POINTER(GLuint))),
    "glDeleteTextures": (None, (ctypes.c_int, ctypes.POINTER(GLuint))),
    "glBindTexture": (None, (GLenum, GLuint)),
    "glActiveTexture": (None, (GLenum,)),
    "glTexStorage2D": (None, (GLenum, ctypes.c_int, GLenum, ctypes.c_int, ctypes.c_int)),
    "glTexParameteri": (None, (GLenum, GLenum, GLint)),
    "glClearBufferuiv": (None, (GLenum, GLint, ctypes.POINTER(GLuint))),
    "glClearBufferfv": (None, (GLenum, GLint, ctypes.POINTER(ctypes.c_float))),
    "glClearBufferfi": (None, (GLenum, GLint, ctypes.c_float, GLint)),
})
