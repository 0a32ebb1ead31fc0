"""The two headless backends glvox registers with glcontext: EGL and OSMesa.

glcontext has no OSMesa backend and does not hand its function loader to
moderngl's users, so glvox registers its own two backend names
(:func:`register_backends`): ``glvox-egl`` wraps glcontext's EGL backend on the
device :func:`glvox.gl.context.create_context` should use (a hardware one where
the machine has one, else Mesa's software device; ``GLVOX_EGL_DEVICE=N`` forces
the N-th), ``glvox-osmesa`` drives libOSMesa through ctypes (``GLVOX_OSMESA=PATH``
names the library).  Both keep the loader (:class:`glvox.gl.raw.RawGL` needs it)
and record what they made in :data:`last_created`, for the factory to release
a context that moderngl then refused.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import os
from typing import Any

import glcontext

from ..errors import BackendError

GL_VERSION_REQUIRED = 450

#: The GALLIUM_DRIVER values libOSMesa can run (any other crashes it).
OSMESA_DRIVERS = ("llvmpipe", "softpipe", "swrast")


class _LoaderContext:
    """The object moderngl gets from a glcontext backend, keeping the loader."""

    def __init__(self, inner: Any, backend: str, device: str, egl_index: int | None = None):
        self._inner = inner
        self.backend = backend
        self.device = device
        self.egl_index = egl_index

    def load_opengl_function(self, name: str) -> int:
        return self._inner.load_opengl_function(name)

    def release(self) -> None:
        self._inner.release()

    def __enter__(self):
        return self._inner.__enter__()

    def __exit__(self, *args):
        return self._inner.__exit__(*args)


_EGL_EXTENSIONS = 0x3055
last_created: list[_LoaderContext] = []


#: eglQueryDeviceAttribEXT's attribute for the CUDA ordinal of an NVIDIA EGL device
#: (EGL_NV_device_cuda): its place among the devices CUDA_VISIBLE_DEVICES lets CUDA see.
_EGL_CUDA_DEVICE_NV = 0x323A


def _egl_query() -> tuple[Any, list[int]]:
    """The EGL library (or None) and its devices' handles, in eglQueryDevicesEXT order."""
    name = ctypes.util.find_library("EGL")
    if not name:
        return None, []
    egl = ctypes.CDLL(name)
    egl.eglGetProcAddress.restype = ctypes.c_void_p
    egl.eglGetProcAddress.argtypes = [ctypes.c_char_p]
    addr = egl.eglGetProcAddress(b"eglQueryDevicesEXT")
    if not addr:
        return egl, []
    query = ctypes.CFUNCTYPE(ctypes.c_uint, ctypes.c_int, ctypes.POINTER(ctypes.c_void_p),
                             ctypes.POINTER(ctypes.c_int))(addr)
    devs = (ctypes.c_void_p * 16)()
    n = ctypes.c_int(0)
    if not query(16, devs, ctypes.byref(n)):
        return egl, []
    return egl, [devs[i] for i in range(n.value)]


def egl_devices() -> list[str]:
    """Extension strings of the EGL devices, in eglQueryDevicesEXT order."""
    egl, devs = _egl_query()
    saddr = egl.eglGetProcAddress(b"eglQueryDeviceStringEXT") if devs else None
    if not saddr:
        return []
    qstr = ctypes.CFUNCTYPE(ctypes.c_char_p, ctypes.c_void_p, ctypes.c_int)(saddr)
    return [(qstr(d, _EGL_EXTENSIONS) or b"").decode() for d in devs]


def egl_cuda_ordinal(index: int) -> int | None:
    """The CUDA device ordinal of EGL device ``index`` (EGL_NV_device_cuda), or None
    where the device has none (Mesa's, any non-NVIDIA driver) or EGL cannot say."""
    try:
        egl, devs = _egl_query()
    except OSError:
        return None
    addr = egl.eglGetProcAddress(b"eglQueryDeviceAttribEXT") if 0 <= index < len(devs) else None
    if not addr:
        return None
    attrib = ctypes.CFUNCTYPE(ctypes.c_uint, ctypes.c_void_p, ctypes.c_int, ctypes.POINTER(ctypes.c_ssize_t))(addr)
    value = ctypes.c_ssize_t(-1)
    if not attrib(devs[index], _EGL_CUDA_DEVICE_NV, ctypes.byref(value)) or value.value < 0:
        return None
    return int(value.value)


def _egl_device_index() -> int:
    """Index of the first hardware EGL device, else of the software one."""
    forced = os.environ.get("GLVOX_EGL_DEVICE")
    if forced:
        return int(forced)
    try:
        exts = egl_devices()
    except OSError:
        return 0
    for i, e in enumerate(exts):
        if "EGL_MESA_device_software" not in e:
            return i
    return 0


def _create_egl(**kwargs) -> _LoaderContext:
    index = _egl_device_index()
    kwargs["device_index"] = index
    inner = glcontext.get_backend_by_name("egl")(**kwargs)
    ctx = _LoaderContext(inner, "egl", f"EGL device {index}", index)
    last_created.append(ctx)
    return ctx


class _OSMesa:
    """A tiny ctypes driver of libOSMesa: a core-profile context on a 1x1 buffer."""

    _FORMAT, _DEPTH_BITS, _STENCIL_BITS, _PROFILE = 0x22, 0x30, 0x31, 0x33
    _CORE_PROFILE, _MAJOR, _MINOR = 0x34, 0x36, 0x37
    _RGBA, _UNSIGNED_BYTE = 0x1908, 0x1401

    def __init__(self, glversion: int = GL_VERSION_REQUIRED, **_: Any):
        driver = os.environ.get("GALLIUM_DRIVER", "").strip()
        if driver and driver not in OSMESA_DRIVERS:
            # libOSMesa (Mesa 22.3) dies in OSMesaCreateContextAttribs with any other
            # driver named there (zink, d3d12, a typo): a segfault, not an error
            raise BackendError(f"OSMesa runs only Mesa's software rasterizers ({', '.join(OSMESA_DRIVERS)}); "
                               f"GALLIUM_DRIVER={driver} is set, and would crash it")
        name = os.environ.get("GLVOX_OSMESA") or ctypes.util.find_library("OSMesa") or "libOSMesa.so.8"
        try:
            lib = ctypes.CDLL(name)
        except OSError as exc:
            raise BackendError(f"libOSMesa not found ({exc})") from None
        lib.OSMesaCreateContextAttribs.restype = ctypes.c_void_p
        lib.OSMesaCreateContextAttribs.argtypes = [ctypes.POINTER(ctypes.c_int), ctypes.c_void_p]
        lib.OSMesaMakeCurrent.restype = ctypes.c_ubyte
        lib.OSMesaMakeCurrent.argtypes = [ctypes.c_void_p, ctypes.c_void_p, ctypes.c_uint,
                                          ctypes.c_int, ctypes.c_int]
        lib.OSMesaGetProcAddress.restype = ctypes.c_void_p
        lib.OSMesaGetProcAddress.argtypes = [ctypes.c_char_p]
        lib.OSMesaDestroyContext.argtypes = [ctypes.c_void_p]
        attribs = [self._FORMAT, self._RGBA, self._DEPTH_BITS, 24, self._STENCIL_BITS, 8,
                   self._PROFILE, self._CORE_PROFILE,
                   self._MAJOR, glversion // 100, self._MINOR, (glversion // 10) % 10, 0]
        arr = (ctypes.c_int * len(attribs))(*attribs)
        self._lib = lib
        self._ctx = lib.OSMesaCreateContextAttribs(arr, None)
        if not self._ctx:
            raise BackendError(f"OSMesa could not create an OpenGL {glversion / 100:.1f} core context")
        self._buf = ctypes.create_string_buffer(4)
        self.make_current()

    def make_current(self) -> None:
        if not self._lib.OSMesaMakeCurrent(self._ctx, self._buf, self._UNSIGNED_BYTE, 1, 1):
            raise BackendError("OSMesaMakeCurrent failed")

    def load_opengl_function(self, name: str) -> int:
        return self._lib.OSMesaGetProcAddress(name.encode()) or 0

    def release(self) -> None:
        if self._ctx:
            self._lib.OSMesaDestroyContext(self._ctx)
            self._ctx = None

    def __enter__(self):
        self.make_current()

    def __exit__(self, *args):
        return None


def _create_osmesa(**kwargs) -> _LoaderContext:
    ctx = _LoaderContext(_OSMesa(**kwargs), "osmesa", "OSMesa")
    last_created.append(ctx)
    return ctx


_REGISTERED = False


def register_backends() -> None:
    """Teach glcontext the names 'glvox-egl' and 'glvox-osmesa' (once)."""
    global _REGISTERED
    if _REGISTERED:
        return
    original = glcontext.get_backend_by_name
    ours = {"glvox-egl": _create_egl, "glvox-osmesa": _create_osmesa}

    def get_backend_by_name(name: str):
        factory = ours.get(name)
        if factory is None:
            return original(name)

        def create(*args, **kwargs):
            kwargs.pop("backend", None)
            kwargs.pop("mode", None)
            return factory(**kwargs)

        return create

    glcontext.get_backend_by_name = get_backend_by_name
    _REGISTERED = True
