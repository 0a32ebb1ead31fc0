"""The one run envelope: what happens around every method's work.

:func:`run_in_envelope` checks the grid size, the mesh (watertight where a
solid is asked for, unless the method's ``any_mesh`` defines inside for any
mesh), the GL context and its capabilities, runs the work with a
:class:`~glvox.gl.timing.StageTimer`, and attaches a
:class:`~glvox.results.RunInfo`.  :func:`glvox.methods.run_method` runs every
registered method through it, and the Leung & Wang intersection application
(two meshes, so not a registry entry) does too.
"""

from __future__ import annotations

import os
import warnings
from typing import Any, Callable, Sequence

import numpy as np

from ..errors import CapabilityError, LimitError, NotWatertightError, NotWatertightWarning, SuspiciousResultWarning
from ..gl.context import get_context
from ..gl.timing import StageTimer
from ..grid import GridSpec
from ..results.base import Result, RunInfo
from ..traits import ALL_SHARE, ROBUST, SOLID_MECHANISMS, mesh_traits, solid_warning
from .base import MethodInfo, alternative, taking_grid

#: Kinds whose result depends on an inside: undefined for an open mesh.
INSIDE_KINDS = ("solid", "sparse", "ldi")


def _what(info: MethodInfo) -> str:
    return {"ldi": "LDI method", "sparse": "sparse solid method"}.get(info.kind, "solid method")


def check_inputs(info: MethodInfo, meshes: Sequence[Any], spec: GridSpec, allow_open: bool) -> None:
    """The checks done before any work: dense size, closed meshes for inside kinds
    (a warning when ``allow_open`` lets an open one through; none for a
    method with ``any_mesh``)."""
    if info.kind != "sparse" and spec.n_voxels > info.max_voxels:
        # for an open mesh, only the methods that define an inside for it
        open_mesh = info.kind in INSIDE_KINDS and not all(m.watertight for m in meshes)
        larger = taking_grid(info.kind, spec.n_voxels, any_mesh=open_mesh)
        instead = f"use a smaller grid, {' or '.join(larger)}, or" if larger else "use a smaller grid or"
        raise LimitError(
            f"method {info.name!r} returns a dense grid, and {spec.dims} has {spec.n_voxels} voxels, more "
            f"than the {info.max_voxels} it keeps dense; {instead} the sparse ss-octree"
        )
    if info.kind not in INSIDE_KINDS or info.any_mesh:
        return
    for mesh in meshes:
        if mesh.watertight:
            continue
        if not allow_open:
            traits = mesh_traits(mesh)  # on the way to an error only: name the likely cause
            if traits.opposite_share + traits.duplicate_share >= ALL_SHARE:
                raise NotWatertightError(
                    f"{mesh.name} is double-sided (every face twice, coincident), so the {_what(info)} "
                    f"{info.name!r} would find it empty (the crossings cancel); use {ROBUST}"
                )
            raise NotWatertightError(
                f"{mesh.name} is not watertight, so 'inside' is undefined for the {_what(info)} "
                f"{info.name!r}; repair the mesh, use a surface method, or pass allow_open=True "
                "(--allow-open) to voxelize by parity of crossings anyway"
            )
        warnings.warn(
            f"{mesh.name} is not watertight: {info.name!r} returns the parity of ray crossings, which "
            "is 'inside' only where the rays cross a closed part of the surface; expect streaks "
            "along the rays through holes", NotWatertightWarning, stacklevel=4)


def run_in_envelope(info: MethodInfo, meshes: Sequence[Any], spec: GridSpec,
                    work: Callable[[Any, StageTimer], Result], *, options: dict[str, Any],
                    ctx=None, backend: str | None = None, allow_open: bool = False,
                    debug: bool | None = None, progress=None) -> Result:
    """Run ``work(ctx, timer)`` for ``info`` on ``meshes`` and ``spec``.

    Parameters
    ----------
    info : MethodInfo
        Kind (for the checks), family (GL or not), requirements, name.
    meshes : sequence of Mesh
        The validated meshes the work reads (one for a method).
    spec : GridSpec
    work : callable ``(ctx, timer) -> Result``
        ``ctx`` is the made-current GLContext for GL work, None for CPU work.
    options : dict
        Validated options, recorded in the run info.
    ctx, backend, allow_open, debug, progress
        As :func:`glvox.methods.run_method`.

    Returns
    -------
    The work's result with ``result.run`` set.
    """
    check_inputs(info, meshes, spec, allow_open)
    if debug is None:
        debug = os.environ.get("GLVOX_DEBUG", "") not in ("", "0")
    if info.uses_gl:
        ctx = ctx if ctx is not None else get_context(backend)
        ctx.make_current()
        missing = info.requires.missing(ctx)
        if missing:
            other = alternative(info, ctx)
            instead = f"; {other!r} runs on this context instead" if other else ""
            raise CapabilityError(f"method {info.name!r} needs {'; '.join(missing)} ({ctx.renderer}){instead}")
        if debug:
            ctx.check_error(f"method {info.name!r}, before the first stage")
    else:
        ctx = None
    timer = StageTimer(ctx, debug=debug, method=info.name, progress=progress)
    result = work(ctx, timer)
    timings = timer.finish()
    stats: dict[str, Any] = {"triangles": sum(m.n_triangles for m in meshes),
                             "degenerate_dropped": sum(m.n_degenerate for m in meshes),
                             "watertight": all(m.watertight for m in meshes)}
    stats.update(timer.stats)
    # once: counting walks every word of the grid (and would read a device result back)
    on_device = getattr(result, "device_words", None) is not None and result.counted_on != "gpu"
    count = None if on_device else getattr(result, "count", None)
    if count is not None:
        stats["voxels"] = count
    result.run = RunInfo(method=info.name, kind=info.kind, spec=spec, timings=timings,
                         stats=stats, options=options)
    if info.kind == "solid" and count is not None and len(meshes) == 1:
        # a method that knows why its own result is suspect says so in its stats (one line,
        # its cause); else the mesh's traits judge the count
        line = stats.get("suspicious") or suspicious_solid(info.name, meshes[0], spec, count)
        if line:
            stats["suspicious"] = line
            warnings.warn(f"{meshes[0].name}: {line}", SuspiciousResultWarning, stacklevel=3)
    return result


def suspicious_solid(method: str, mesh, spec: GridSpec, count: int) -> str | None:
    """The warning line a solid result of ``count`` voxels deserves (:func:`glvox.traits.solid_warning`), or None.

    Cheap on the common path: a watertight mesh (no doubled faces, no hole)
    run by a parity method with a non-empty result needs no traits; else
    the traits (cached per mesh, ~0.1 s per 100k triangles) and a count
    compared with the grid voxels in the mesh's bounding box.
    """
    if count > 0 and mesh.watertight and SOLID_MECHANISMS.get(method) not in ("winding", None):
        return None
    lo, hi = spec.world_to_voxel(mesh.bounds)
    dims = np.asarray(spec.dims)
    span = np.clip(np.ceil(hi), 0, dims) - np.clip(np.floor(lo), 0, dims)
    return solid_warning(mesh_traits(mesh), method, count, int(np.prod(np.maximum(span, 0))))
