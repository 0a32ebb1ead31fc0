"""The method registry and the one way to run a method.

>>> from glvox.methods import method_names, run_method
>>> "reference-solid" in method_names()
True
"""

from __future__ import annotations

import importlib
import pkgutil
from typing import Any

from ..errors import MethodError
from ..grid import GridSpec
from ..mesh import Mesh
from ..reference.attributes import reference_attributes
from .base import _REGISTRY, FAMILIES, KINDS, Method, MethodInfo, Option, Requirements, register
from .attribute_pass import check_mesh, check_request, gpu_attributes, parse_attributes
from .envelope import run_in_envelope

#: The method :func:`glvox.voxelize` and ``glvox voxelize`` use when none is named.
DEFAULT_METHOD = "ss-conservative"

__all__ = ["DEFAULT_METHOD", "FAMILIES", "KINDS", "Method", "MethodInfo", "Option", "Requirements", "register",
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
               allow_open: bool = False, debug: bool | None = None, attributes=None, normals: str = "face",
               fill_attributes: str = "none", **options: Any):
    """Run method ``name`` on a validated mesh and grid spec.

    Parameters
    ----------
    name : str
        Registry name.
    mesh : Mesh
        From :func:`glvox.mesh.load_mesh`.
    spec : GridSpec
    ctx : GLContext, optional
        For GL methods; default the shared context (:func:`glvox.gl.context.get_context`).
    backend : str, optional
        Backend of the shared context when ``ctx`` is not given.
    allow_open : bool
        Solid methods refuse meshes that are not watertight (parity of
        crossings is undefined for them); True runs them anyway.
    debug : bool, optional
        Check glGetError after every stage; default from ``GLVOX_DEBUG``.
    attributes : sequence of str or comma-separated str, optional
        Per-voxel attributes to carry (``triangle``, ``color``, ``normal``,
        ``material``; surface and solid methods): ``result.attributes``, by
        the source-triangle rule of :mod:`glvox.methods.attribute_pass`
        (computed on the GPU; CPU methods use the float64 reference).
    normals : {'face', 'vertex'}
        The ``normal`` attribute: the source triangle's, or the mesh's vertex
        normals interpolated at the closest point.
    fill_attributes : {'none', 'nearest'}
        Solids: interior voxels carry nothing (triangle -1, alpha 0), or the
        attributes of the nearest surface voxel (a GPU jump flood).
    **options
        Method options (see ``glvox methods``).

    Returns
    -------
    The method's result (VoxelGrid for surface and solid methods), with
    ``result.run`` a :class:`~glvox.results.RunInfo` holding timings and stats.
    An alias (``solid``) runs the method it picks for ``mesh``
    (:meth:`Method.resolve`): ``result.run.method`` names that one, and
    ``result.run.stats['requested']`` the alias.
    """
    requested = get_method(name)
    opts = validate_options(requested.info, options)
    method = get_method(requested.resolve(mesh))
    if method is not requested:  # the alias's options, then the defaults of the method it runs
        opts = validate_options(method.info, opts)
    names = parse_attributes(attributes)
    check_request(method.info, names, normals, fill_attributes)
    if names:
        check_mesh(mesh, names, normals)

    def work(ctx, timer):
        result = method.run(mesh, spec, ctx=ctx, timer=timer, **opts)
        if names:
            timer.stats["attributes"] = list(names)
            result.set_attributes(_attributes(ctx, mesh, result, timer, names, normals, fill_attributes))
        return result

    result = run_in_envelope(method.info, (mesh,), spec, work, options=opts, ctx=ctx, backend=backend,
                             allow_open=allow_open, debug=debug)
    if method is not requested:
        result.run.stats["requested"] = requested.info.name
    return result


def _attributes(ctx, mesh, result, timer, names, normals, fill):
    """The attributes of ``result`` on the GPU (``ctx``), or by the float64
    reference for CPU methods (no context)."""
    if ctx is not None:
        return gpu_attributes(ctx, mesh, result, timer, names, normals, fill=fill)
    with timer.stage("attributes", gpu=False):
        return reference_attributes(mesh, mesh.triangles_voxel(result.spec), result.spec.dims, result.indices(),
                                    names, normals, fill=fill)[1]
