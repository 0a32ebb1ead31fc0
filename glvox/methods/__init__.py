"""The method registry and the one way to run a method.

>>> from glvox.methods import method_names, run_method
>>> "reference-solid" in method_names()
True
"""

from __future__ import annotations

from typing import Any

from ..errors import LimitError, MethodError

from ..gpu.cuda import CudaSink, check_device
from ..gpu.readback import device_sink, readback_mode
from ..grid import MAX_VOXELS, GridSpec
from ..mesh import Mesh
from ..reference.attributes import reference_attributes
from ..results.voxels import VoxelGrid
from .base import _REGISTRY, FAMILIES, KINDS, PIPELINES, Method, MethodInfo, Option, Requirements, register
from .attributes.passes import check_mesh, gpu_attributes
from .envelope import run_in_envelope
from .request import Request, discover, get_method, validate_options

#: The method :func:`glvox.voxelize` and ``glvox voxelize`` use when none is named.
DEFAULT_METHOD = "ss-conservative"

__all__ = ["DEFAULT_METHOD", "FAMILIES", "KINDS", "PIPELINES", "Method", "MethodInfo", "Option", "Requirements",
           "register", "Request", "get_method", "method_infos", "method_names", "run_method", "validate_options"]

def method_infos(kind: str | None = None, family: str | None = None,
                 pipeline: str | None = None) -> list[MethodInfo]:
    """Registry entries, sorted by family (:data:`FAMILIES` order) then name, optionally filtered.

    A filter value that names nothing (a kind, family or pipeline glvox does not have) is a
    MethodError, not an empty list: ``family='compute'`` is a pipeline, and would select nothing.
    """
    for what, value, known in (("kind", kind, KINDS), ("family", family, FAMILIES), ("pipeline", pipeline, PIPELINES)):
        if value is not None and value not in known:
            raise MethodError(f"unknown {what} {value!r}; known: {', '.join(known)}")
    discover()
    infos = [m.info for m in _REGISTRY.values()]
    if kind is not None:
        infos = [i for i in infos if i.kind == kind]
    if family is not None:
        infos = [i for i in infos if i.family == family]
    if pipeline is not None:
        infos = [i for i in infos if i.pipeline == pipeline]
    order = {f: n for n, f in enumerate(FAMILIES)}
    return sorted(infos, key=lambda i: (order[i.family], i.name))


def method_names(kind: str | None = None, family: str | None = None, pipeline: str | None = None) -> list[str]:
    return [i.name for i in method_infos(kind, family, pipeline)]


def run_method(name: str | Request, mesh: Mesh, spec: GridSpec, *, ctx=None, backend: str | None = None,
               allow_open: bool = False, debug: bool | None = None, attributes=None, normals: str = "face",
               fill_attributes: str = "none", progress=None, device: str | None = None, **options: Any):
    """Run method ``name`` on a validated mesh and grid spec.

    Parameters
    ----------
    name : str or Request
        Registry name, or a :class:`~glvox.methods.request.Request` checked
        before (then ``attributes``, ``normals``, ``fill_attributes`` and
        ``options`` are the request's and must not be given again).
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
        the source-triangle rule of :mod:`glvox.methods.attributes.passes`
        (computed on the GPU; CPU methods use the float64 reference).
    normals : {'face', 'vertex'}
        The ``normal`` attribute: the source triangle's, or the mesh's vertex
        normals interpolated at the closest point.
    fill_attributes : {'none', 'nearest'}
        Solids: interior voxels carry nothing (triangle -1, alpha 0), or the
        attributes of the nearest surface voxel (a GPU jump flood).
    progress : callable, optional
        ``progress(done, total)`` after each z slab, where the method works the
        grid in slabs (grids over the storage-block limit; gwn-solid's passes).
    device : {'host', 'cuda'}, optional
        Where the result's packed words go: host memory (default), or CUDA memory
        on the GL context's GPU, without passing through the host
        (``result.device_words``, a DLPack producer; :mod:`glvox.gpu.cuda`).
        'cuda' takes GL surface and solid methods without attributes, and needs
        ``pip install 'glvox[cuda]'``.
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
    if isinstance(name, Request):
        if options or attributes is not None or normals != "face" or fill_attributes != "none":
            raise TypeError("run_method: a Request carries its options and attributes; give them to Request.make")
        asked = name
    else:
        asked = Request.make(name, options, attributes, normals, fill_attributes)
    picked = asked.method.resolve(mesh)
    request = asked if picked == asked.name else asked.for_method(get_method(picked))
    method, opts, names = request.method, dict(request.options), request.attributes
    readback_mode()  # a bad GLVOX_READBACK is refused before any work
    sink = _device_sink(check_device(device), method.info, names)
    if names:
        check_mesh(mesh, names, request.normals)
        if spec.n_voxels > MAX_VOXELS:  # the attribute passes keep int32 voxel counts and ranks
            raise LimitError(f"per-voxel attributes are computed on grids of up to {MAX_VOXELS} voxels, and "
                             f"{spec.dims} has {spec.n_voxels}: use a smaller grid")

    def work(ctx, timer):
        if sink is None:
            return _work(ctx, timer)
        sink.begin(ctx, spec)
        with device_sink(sink):
            result = _work(ctx, timer)
        timer.stats["device"] = "cuda"
        timer.stats["device_path"] = "gpu" if result.device_words is not None else "host"
        if result.device_words is None:  # a method whose grid did not reach the sink
            result = VoxelGrid(words=sink.upload(result.words()), spec=result.spec, extras=result.extras,
                               fields=result.fields, attributes=result.attributes,
                               count=result.count if result.counted_on == "gpu" else None)
        return result

    def _work(ctx, timer):
        result = method.run(mesh, spec, ctx=ctx, timer=timer, **opts)
        if names:
            timer.stats["attributes"] = list(names)
            result.set_attributes(_attributes(ctx, mesh, result, timer, names, request.normals,
                                              request.fill_attributes))
        return result

    result = run_in_envelope(method.info, (mesh,), spec, work, options=opts, ctx=ctx, backend=backend,
                             allow_open=allow_open, debug=debug, progress=progress)
    if request is not asked:
        result.run.stats["requested"] = asked.name
        result.run.stats["picked_because"] = asked.method.why(mesh)
    return result


def _device_sink(device: str, info: MethodInfo, attributes) -> CudaSink | None:
    """The sink of a ``device='cuda'`` run (None for the host), after the checks that
    need no GL context."""
    if device == "host":
        return None
    if info.kind not in ("surface", "solid") or not info.uses_gl:
        what = "a CPU method" if not info.uses_gl else f"its result is {info.kind!r}"
        raise MethodError(f"device={device!r} keeps a packed grid on the GPU, and {info.name!r} makes none "
                          f"({what}); use a GPU surface or solid method")
    if attributes:
        raise MethodError(f"device={device!r} results carry no per-voxel attributes; ask for them with "
                          f"device='host'")
    return CudaSink()


def _attributes(ctx, mesh, result, timer, names, normals, fill):
    """The attributes of ``result`` on the GPU (``ctx``), or by the float64
    reference for CPU methods (no context)."""
    if ctx is not None:
        return gpu_attributes(ctx, mesh, result, timer, names, normals, fill=fill)
    with timer.stage("attributes", gpu=False):
        return reference_attributes(mesh, mesh.triangles_voxel(result.spec), result.spec.dims, result.indices(),
                                    names, normals, fill=fill)[1]
