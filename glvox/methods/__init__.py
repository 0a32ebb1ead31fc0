"""The method registry and the one way to run a method.

>>> from glvox.methods import method_names, run_method
>>> "reference-solid" in method_names()
True
"""

from __future__ import annotations

import importlib
import os
import pkgutil
import warnings
from typing import Any

from ..context import get_context
from ..errors import CapabilityError, LimitError, MethodError, NotWatertightError, NotWatertightWarning
from ..grid import MAX_VOXELS, GridSpec, RunInfo
from ..mesh import Mesh
from ..timing import StageTimer
from ._base import (FAMILIES, KINDS, Method, MethodInfo, Option, Requirements, _REGISTRY,
                    register)

__all__ = ["FAMILIES", "KINDS", "Method", "MethodInfo", "Option", "Requirements", "register",
           "get_method", "method_infos", "method_names", "run_method", "validate_options"]

_discovered = False


def _discover() -> None:
    """Import every module of this package once, so their methods register."""
    global _discovered
    if _discovered:
        return
    _discovered = True
    for mod in pkgutil.iter_modules(__path__):
        if not mod.name.startswith("_"):
            importlib.import_module(f"{__name__}.{mod.name}")


def get_method(name: str) -> Method:
    """The registered method ``name``; MethodError lists the known names otherwise."""
    _discover()
    try:
        return _REGISTRY[name]
    except KeyError:
        raise MethodError(
            f"unknown method {name!r}; known methods: {', '.join(sorted(_REGISTRY))}"
        ) from None


def method_infos(kind: str | None = None, family: str | None = None) -> list[MethodInfo]:
    """Registry entries, sorted by family then name, optionally filtered."""
    _discover()
    infos = [m.info for m in _REGISTRY.values()]
    if kind is not None:
        infos = [i for i in infos if i.kind == kind]
    if family is not None:
        infos = [i for i in infos if i.family == family]
    order = {f: n for n, f in enumerate(FAMILIES)}
    return sorted(infos, key=lambda i: (order[i.family], i.name))


def method_names(kind: str | None = None, family: str | None = None) -> list[str]:
    return [i.name for i in method_infos(kind, family)]


def validate_options(info: MethodInfo, options: dict[str, Any]) -> dict[str, Any]:
    """Options with defaults filled and values coerced; MethodError on unknown names."""
    unknown = set(options) - set(info.options)
    if unknown:
        valid = ", ".join(sorted(info.options)) or "none"
        raise MethodError(
            f"method {info.name!r} has no option {', '.join(sorted(unknown))}; its options: {valid}"
        )
    out = {k: o.default for k, o in info.options.items()}
    for k, v in options.items():
        out[k] = info.options[k].coerce(k, v)
    return out


def run_method(name: str, mesh: Mesh, spec: GridSpec, *, ctx=None, backend: str | None = None,
               allow_open: bool = False, debug: bool | None = None, **options: Any):
    """Run method ``name`` on a validated mesh and grid spec.

    Parameters
    ----------
    name : str
        Registry name.
    mesh : Mesh
        From :func:`glvox.mesh.load_mesh`.
    spec : GridSpec
    ctx : GLContext, optional
        For GL methods; default the shared context (:func:`glvox.context.get_context`).
    backend : str, optional
        Backend of the shared context when ``ctx`` is not given.
    allow_open : bool
        Solid methods refuse meshes that are not watertight (parity of
        crossings is undefined for them); True runs them anyway.
    debug : bool, optional
        Check glGetError after every stage; default from ``GLVOX_DEBUG``.
    **options
        Method options (see ``glvox methods``).

    Returns
    -------
    The method's result (VoxelGrid for surface and solid methods), with
    ``result.run`` a :class:`~glvox.grid.RunInfo` holding timings and stats.
    """
    method = get_method(name)
    info = method.info
    opts = validate_options(info, options)
    if info.kind != "sparse" and spec.n_voxels > MAX_VOXELS:
        raise LimitError(
            f"method {name!r} returns a dense grid, and {spec.dims} has {spec.n_voxels} voxels, more "
            f"than the {MAX_VOXELS} glvox keeps dense; use a smaller grid or the sparse ss-octree"
        )
    if info.kind in ("solid", "sparse", "ldi") and not mesh.watertight and not allow_open:
        raise NotWatertightError(
            f"{mesh.name} is not watertight, so 'inside' is undefined for the solid method {name!r}; "
            "repair the mesh, use a surface method, or pass allow_open=True (--allow-open) to "
            "voxelize by parity of crossings anyway"
        )
    if info.kind in ("solid", "sparse", "ldi") and not mesh.watertight:
        warnings.warn(
            f"{mesh.name} is not watertight: {name!r} returns the parity of ray crossings, which "
            "is 'inside' only where the rays cross a closed part of the surface; expect streaks "
            "along the rays through holes", NotWatertightWarning, stacklevel=2)
    if debug is None:
        debug = os.environ.get("GLVOX_DEBUG", "") not in ("", "0")
    if info.uses_gl:
        ctx = ctx if ctx is not None else get_context(backend)
        ctx.make_current()
        missing = info.requires.missing(ctx)
        if missing:
            raise CapabilityError(f"method {name!r} needs {'; '.join(missing)} ({ctx.renderer})")
        if debug:
            ctx.check_error(f"method {name!r}, before the first stage")
    else:
        ctx = None
    timer = StageTimer(ctx, debug=debug, method=name)
    result = method.run(mesh, spec, ctx=ctx, timer=timer, **opts)
    timings = timer.finish()
    stats = {"triangles": mesh.n_triangles, "degenerate_dropped": mesh.n_degenerate,
             "watertight": mesh.watertight}
    stats.update(timer.stats)
    count = getattr(result, "count", None)  # once: counting a 1024^3 grid costs ~40 ms
    if count is not None:
        stats["voxels"] = count
    result.run = RunInfo(method=name, kind=info.kind, spec=spec, timings=timings,
                         stats=stats, options=opts)
    return result
