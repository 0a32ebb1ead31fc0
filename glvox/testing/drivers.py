"""The environments that give glvox Mesa's other GL implementations, for the tests.

llvmpipe is what the suite runs on.  Three more implementations run on any
machine with Mesa (``tests/test_drivers.py``, ``tests/test_context.py``;
docs/testing.md has what each found):

* softpipe, in the same driver package: :data:`SOFTPIPE`;
* zink, Mesa's OpenGL over Vulkan, on lavapipe (Mesa's Vulkan driver on the
  CPU): :func:`zink_env`;
* the OSMesa backend (glvox's fallback where EGL fails): :func:`osmesa_library`.

The last two come from Debian packages that ``.ci/drivers`` unpacks into
``.drivers/`` without installing them; ``GLVOX_UNPACKED_DRIVERS`` names another
such folder (``compare/mutants.py``'s scratch copies do).
"""

from __future__ import annotations

import ctypes.util
import os
from pathlib import Path

from ..gl.context import DRIVER_DEFAULTS

#: Mesa's softpipe, with the version override that lifts its advertised GL 3.3.
SOFTPIPE = {"GALLIUM_DRIVER": "softpipe", "MESA_GL_VERSION_OVERRIDE": "4.5", "MESA_GLSL_VERSION_OVERRIDE": "450"}


def unpacked_dir() -> Path:
    """Where ``.ci/drivers`` unpacked lavapipe and libOSMesa: ``GLVOX_UNPACKED_DRIVERS``,
    else ``.drivers`` in the checkout glvox runs from."""
    given = os.environ.get("GLVOX_UNPACKED_DRIVERS")
    return Path(given) if given else Path(__file__).resolve().parents[2] / ".drivers"


def _lib_dir() -> Path:
    return unpacked_dir() / "root" / "usr" / "lib" / "x86_64-linux-gnu"


def zink_env() -> dict[str, str] | None:
    """This process's environment with zink on the unpacked lavapipe asked for (None
    where ``.ci/drivers`` unpacked none): the Vulkan loader pointed at the driver, and
    LIBGL_ALWAYS_SOFTWARE, without which zink (22.3) passes over a CPU device.  The
    variables of :data:`~glvox.gl.context.DRIVER_DEFAULTS` are left out, so glvox's
    own defaults apply."""
    icd = unpacked_dir() / "icd.json"
    if not icd.is_file():
        return None
    paths = [str(_lib_dir())] + [p for p in os.environ.get("LD_LIBRARY_PATH", "").split(":") if p]
    env = {k: v for k, v in os.environ.items() if k not in DRIVER_DEFAULTS}
    return {**env, "GALLIUM_DRIVER": "zink", "LIBGL_ALWAYS_SOFTWARE": "1", "VK_ICD_FILENAMES": str(icd),
            "LD_LIBRARY_PATH": ":".join(paths)}


def osmesa_library() -> str | None:
    """A libOSMesa to load (``GLVOX_OSMESA``'s value): the system's, else the unpacked
    one; None where there is neither."""
    found = ctypes.util.find_library("OSMesa")
    if found:
        return found
    unpacked = _lib_dir() / "libOSMesa.so.8"
    return str(unpacked) if unpacked.is_file() else None
