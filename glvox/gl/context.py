"""Headless OpenGL 4.5 core contexts (EGL, or OSMesa as a fallback).

One context is shared per process by default (:func:`get_context`).  The
backend is chosen by argument or by the environment variable
``GLVOX_BACKEND`` (``egl``, ``osmesa`` or ``auto``; auto tries EGL first, then
OSMesa).  With EGL, a hardware device is preferred when the machine has one;
otherwise Mesa's software device (llvmpipe) is used.  ``GLVOX_EGL_DEVICE=N``
forces the N-th EGL device; ``GLVOX_OSMESA=PATH`` names the libOSMesa to load
(default: the system's).

The contexts are made through moderngl/glcontext, with the two backends of
:mod:`glvox.gl.backends`, which keep the function loader that
:class:`glvox.gl.raw.RawGL` needs for ``glLogicOp`` and stencil state.

Driver settings: before the first context, ``ZINK_INLINE_UNIFORMS`` is set to
``0`` unless the environment sets it (:data:`DRIVER_DEFAULTS`).  Mesa's zink
(GL over Vulkan) otherwise specializes programs on the uniforms their branches
read and, in Mesa 22.3, dispatched a program with another program's values
(:mod:`glvox.gpu.behaviours`, ``uniform-update``).  The variable means nothing
to any other driver.
"""

from __future__ import annotations

import os
import threading
from dataclasses import dataclass, field
from typing import Any

import moderngl

from ..errors import BackendError, GLError
from .backends import GL_VERSION_REQUIRED, egl_cuda_ordinal, last_created, register_backends
from .raw import RawGL

BACKENDS = ("egl", "osmesa")

#: Driver environment variables glvox sets before creating a context, unless the
#: environment already sets them (the user's choice wins): see the module docstring.
DRIVER_DEFAULTS = {"ZINK_INLINE_UNIFORMS": "0"}
#: Those of DRIVER_DEFAULTS this process's environment got from glvox (not the user).
_set_by_glvox: set[str] = set()


def driver_settings() -> dict[str, dict[str, str]]:
    """The :data:`DRIVER_DEFAULTS` variables as they stand: ``{name: {"value", "set_by"}}``,
    ``set_by`` 'glvox' or 'environment' (``glvox info`` prints them)."""
    return {var: {"value": os.environ.get(var, ""), "set_by": "glvox" if var in _set_by_glvox else "environment"}
            for var in DRIVER_DEFAULTS if var in os.environ}

# What to install when no backend works (Debian/Ubuntu package names).
_PACKAGE_HINT = (
    "install Mesa's EGL and OpenGL drivers, e.g. on Debian/Ubuntu "
    "`apt-get install libegl1 libegl-mesa0 libgl1-mesa-dri libgbm1` "
    "(EGL), or `apt-get install libosmesa6` (OSMesa)"
)


# ---------------------------------------------------------------------------
# the context object
# ---------------------------------------------------------------------------

#: GL limits reported by ``glvox info`` and used by the limit checks.
LIMIT_NAMES = (
    "GL_MAX_TEXTURE_SIZE",
    "GL_MAX_3D_TEXTURE_SIZE",
    "GL_MAX_ARRAY_TEXTURE_LAYERS",
    "GL_MAX_RENDERBUFFER_SIZE",
    "GL_MAX_VIEWPORT_DIMS",
    "GL_MAX_COLOR_ATTACHMENTS",
    "GL_MAX_DRAW_BUFFERS",
    "GL_MAX_COMPUTE_WORK_GROUP_COUNT",
    "GL_MAX_COMPUTE_WORK_GROUP_SIZE",
    "GL_MAX_COMPUTE_WORK_GROUP_INVOCATIONS",
    "GL_MAX_COMPUTE_SHARED_MEMORY_SIZE",
    "GL_MAX_SHADER_STORAGE_BLOCK_SIZE",
    "GL_MAX_SHADER_STORAGE_BUFFER_BINDINGS",
    "GL_MAX_COMPUTE_SHADER_STORAGE_BLOCKS",
)

_GL_MAX_COMPUTE_SHARED_MEMORY_SIZE = 0x8262


@dataclass
class GLContext:
    """A headless OpenGL context and what glvox keeps with it.

    Attributes
    ----------
    mgl : moderngl.Context
        The moderngl context; use it for buffers, textures, programs.
    backend : str
        ``'egl'`` or ``'osmesa'``.
    device : str
        Which EGL device (or OSMesa) was used.
    raw : RawGL
        Raw GL entry points on this context (logic op, stencil).
    programs : dict
        Program cache of :mod:`glvox.gl.shaders` (key -> moderngl program).
    caches : dict
        What higher layers keep with this context, by owner (``'gpu'``:
        :mod:`glvox.gpu.buffers`' uploaded meshes, buffer pools and GL
        objects); each owner registers its release in ``on_release``.
    """

    mgl: moderngl.Context
    backend: str
    device: str
    raw: RawGL
    programs: dict = field(default_factory=dict)
    caches: dict = field(default_factory=dict)
    compile_seconds: float = 0.0
    #: callbacks run (before the GL context goes) by :meth:`release`
    on_release: list = field(default_factory=list)
    #: callables that return True while host memory the GL context owns is still in
    #: use (results viewing mapped buffers, :mod:`glvox.gpu.readback`): :meth:`release`
    #: then keeps the GL context itself until they all return False
    keep_alive: list = field(default_factory=list)
    #: index of the EGL device (eglQueryDevicesEXT order), None for OSMesa
    egl_index: int | None = None
    _released: bool = False
    _free_pairs: list = field(default_factory=list)  # timestamp query pairs not in use
    _all_pairs: list = field(default_factory=list)
    _limits: Any = None
    _neutral_fbo: Any = None

    # -- description --------------------------------------------------------
    @property
    def vendor(self) -> str:
        return self.mgl.info["GL_VENDOR"]

    @property
    def renderer(self) -> str:
        return self.mgl.info["GL_RENDERER"]

    @property
    def version(self) -> str:
        return self.mgl.info["GL_VERSION"]

    def cuda_ordinal(self) -> int | None:
        """The CUDA device ordinal of this context's GPU as its EGL device reports it
        (:func:`egl_cuda_ordinal`), or None (OSMesa, Mesa, non-NVIDIA drivers)."""
        return None if self.egl_index is None else egl_cuda_ordinal(self.egl_index)

    @property
    def is_software(self) -> bool:
        r = self.renderer.lower()
        return any(s in r for s in ("llvmpipe", "softpipe", "swrast", "lavapipe"))

    def limits(self) -> dict[str, Any]:
        """The GL limits that matter to voxelization, by GL enum name (read once)."""
        if self._limits is not None:
            return self._limits
        info = self.mgl.info
        out: dict[str, Any] = {}
        for name in LIMIT_NAMES:
            if name == "GL_MAX_COMPUTE_SHARED_MEMORY_SIZE":
                out[name] = self.raw.get_integer(_GL_MAX_COMPUTE_SHARED_MEMORY_SIZE)
            elif name in info:
                v = info[name]
                out[name] = tuple(v) if isinstance(v, (list, tuple)) else v
        self._limits = out
        return out

    def describe(self) -> dict[str, Any]:
        """Everything ``glvox info`` prints, as a JSON-friendly dict."""
        return {
            "backend": self.backend,
            "device": self.device,
            "vendor": self.vendor,
            "renderer": self.renderer,
            "version": self.version,
            "software": self.is_software,
            "limits": {k: list(v) if isinstance(v, tuple) else v for k, v in self.limits().items()},
            "driver_settings": driver_settings(),
        }

    # -- state --------------------------------------------------------------
    def check_error(self, where: str) -> None:
        """Raise :class:`~glvox.errors.GLError` naming ``where`` if GL has an error pending."""
        err = self.mgl.error
        if err != "GL_NO_ERROR":
            raise GLError(f"OpenGL error {err} after {where}")

    def take_query_pair(self) -> tuple[int, int]:
        """Two GL_TIMESTAMP query names for one stage of a
        :class:`~glvox.gl.timing.StageTimer`, its own until :meth:`give_query_pair`
        returns them (a timer that does not wait per stage reads them at the end, and
        timers of nested runs interleave); made as needed, kept for the context's life.

        Timestamps rather than moderngl's GL_TIME_ELAPSED query: moderngl reads
        query results as 32 bits (wrapping past 4.3 s) and Mesa's llvmpipe
        reports a meaningless elapsed time for compute dispatches, while its
        64-bit timestamps are right.
        """
        if not self._free_pairs:
            pair = tuple(self.raw.gen_queries(2))
            self._all_pairs.append(pair)
            return pair
        return self._free_pairs.pop()

    def give_query_pair(self, pair: tuple[int, int]) -> None:
        self._free_pairs.append(pair)

    def release_framebuffer(self, fbo: moderngl.Framebuffer) -> None:
        """Release a transient framebuffer without leaving a deleted one bound.

        A standalone moderngl context has no default framebuffer; after
        releasing the bound FBO, moderngl rebinds the deleted name on the next
        framebuffer creation (GL_INVALID_OPERATION).  Binding a tiny
        persistent FBO first avoids it.
        """
        if self._neutral_fbo is None:
            self._neutral_fbo = self.mgl.framebuffer(color_attachments=[self.mgl.texture((1, 1), 4)])
        self._neutral_fbo.use()
        fbo.release()

    def logic_op(self, op: str):
        """Context manager enabling ``glLogicOp(op)`` ('xor', 'or', ...) around draws."""
        return self.raw.logic_op(op)

    @property
    def released(self) -> bool:
        return self._released

    def make_current(self) -> None:
        """Make this the calling thread's current GL context.

        GL calls go to whichever context is current, not to the one a
        moderngl object belongs to: with two contexts in a process (a
        private one from :func:`create_context` beside the shared one),
        running on one after creating or using the other would otherwise
        address the wrong context's objects.  :func:`glvox.methods.run_method`
        and :func:`get_context` call this; it is cheap when already current.
        """
        if self._released:
            raise BackendError("this GL context was released; create a new one")
        global _current
        if _deferred:
            _reap()
        if _current is not self:
            # unbind first: after an OSMesa context came and went (it rebinds
            # Mesa's shared dispatch), EGL takes a make-current of the context
            # it still believes current as a no-op, and nothing is bound
            self.mgl.__exit__(None, None, None)
            self.mgl.__enter__()
            _current = self

    def release(self) -> None:
        """Release every cached program and the context itself.

        Results that view this context's mapped memory (:mod:`glvox.gpu.readback`)
        stay valid: the GL context then goes when the last of them does (at the
        next make-current of any context), not now."""
        if self._released:
            return
        global _current
        previous = _current
        # deleting GL objects addresses the current context: make it this one,
        # or another context's objects of the same names would go
        self.make_current()
        for callback in self.on_release:
            callback()
        self.on_release.clear()
        if self._all_pairs:
            self.raw.delete_queries([q for pair in self._all_pairs for q in pair])
            self._all_pairs.clear()
            self._free_pairs.clear()
        for prog in self.programs.values():
            prog.release()
        self.programs.clear()
        self._released = True
        if any(busy() for busy in self.keep_alive):
            _deferred.append(self)  # released by _reap() once nothing views its memory
        else:
            self.mgl.release()
        _current = None
        # leave a live context current: the one current before, else the
        # shared one (a private context is usually current when released,
        # having been made current by its own creation)
        for ctx in (previous, _shared):
            if ctx is not None and ctx is not self and not ctx.released:
                ctx.make_current()
                break


def _normalize_backend(backend: str | None) -> str:
    name = (backend or os.environ.get("GLVOX_BACKEND") or "auto").strip().lower()
    if name not in BACKENDS + ("auto",):
        raise BackendError(
            f"backend must be one of {', '.join(BACKENDS + ('auto',))}, got {name!r} "
            "(from the argument or GLVOX_BACKEND)"
        )
    return name


def create_context(backend: str | None = None, *, require: int = GL_VERSION_REQUIRED) -> GLContext:
    """Create a new headless OpenGL context.

    Parameters
    ----------
    backend : {'egl', 'osmesa', 'auto'}, optional
        Which backend; default from ``GLVOX_BACKEND``, else ``'auto'`` (EGL,
        then OSMesa).
    require : int
        Minimum GL version as moderngl writes it (450 = 4.5).

    Raises
    ------
    BackendError
        When no backend gives a context of the required version; the message
        names every backend tried, why it failed, and what to install.
    """
    name = _normalize_backend(backend)
    order = BACKENDS if name == "auto" else (name,)
    register_backends()
    for var, value in DRIVER_DEFAULTS.items():
        if var not in os.environ:  # read by the driver when its screen is created
            os.environ[var] = value
            _set_by_glvox.add(var)
    if _deferred:
        _reap()
    failures = []
    for b in order:
        last_created.clear()
        try:
            mgl = moderngl.create_context(standalone=True, backend=f"glvox-{b}", require=require)
        except Exception as exc:  # noqa: BLE001 - every failure is reported below
            failures.append(f"{b}: {str(exc).strip() or type(exc).__name__}")
            for made in last_created:
                try:
                    made.release()
                except Exception:  # noqa: BLE001
                    pass
            continue
        made = last_created[-1]
        # moderngl's info asks for every limit it knows, once, and a context that lacks
        # one leaves GL_INVALID_ENUM pending (softpipe does): read it here and take that
        # error, so that the first check after glvox's own calls sees only theirs
        _ = mgl.info
        _ = mgl.error
        ctx = GLContext(mgl=mgl, backend=b, device=made.device, raw=RawGL(made.load_opengl_function),
                        egl_index=made.egl_index)
        global _current
        _current = ctx  # a new context is current where it was made
        return ctx
    raise BackendError(
        f"no headless OpenGL {require // 100}.{(require // 10) % 10} core context could be created "
        f"({'; '.join(failures)}); {_PACKAGE_HINT}"
    )


_shared: GLContext | None = None
_lock = threading.Lock()
#: Contexts released while results still viewed their mapped memory (GLContext.keep_alive).
_deferred: list[GLContext] = []


def _reap() -> None:
    """Release the GL contexts of :data:`_deferred` that nothing views any more (from
    the thread that uses GL, never from a finalizer: it makes each current)."""
    global _current
    for ctx in list(_deferred):
        if not any(busy() for busy in ctx.keep_alive):
            _deferred.remove(ctx)
            ctx.mgl.__exit__(None, None, None)
            ctx.mgl.__enter__()
            ctx.mgl.release()
            _current = None


def deferred_contexts() -> int:
    """How many released contexts still wait for their results to go (see GLContext.release)."""
    return len(_deferred)


#: The GLContext glvox last made current (see GLContext.make_current).
_current: GLContext | None = None


def get_context(backend: str | None = None) -> GLContext:
    """The process-wide shared context, created on first use.

    A ``backend`` different from the shared context's raises BackendError
    rather than silently returning the other one; use :func:`create_context`
    for a second, private context.
    """
    global _shared
    with _lock:
        if _shared is not None and not _shared.released:
            if backend is not None and _normalize_backend(backend) not in ("auto", _shared.backend):
                raise BackendError(
                    f"the shared context uses backend {_shared.backend!r}, asked for {backend!r}; "
                    "call glvox.gl.context.close_context() first or use create_context()"
                )
            _shared.make_current()
            return _shared
        _shared = create_context(backend)
        return _shared


def any_context() -> bool:
    """Whether this process has made a GL context (one a forked child must not inherit)."""
    return _current is not None or _shared is not None


def close_context() -> None:
    """Release the shared context (a later :func:`get_context` makes a new one)."""
    global _shared
    with _lock:
        if _shared is not None:
            _shared.release()
            _shared = None
