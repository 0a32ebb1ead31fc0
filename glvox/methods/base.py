"""The one method interface: descriptions, requirements, the registry.

A method is a subclass of :class:`Method` with a class attribute ``info``
(:class:`MethodInfo`) and a ``run`` that takes a validated mesh and a grid
spec and returns a result of its kind.  Decorating it with :func:`register`
puts it in the registry that the CLI, the tests and the comparison iterate
over; modules in ``glvox/methods/`` are imported automatically, so adding a
method is adding one module (and its shader folder).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from functools import cached_property
from typing import Any, ClassVar, Mapping

import numpy as np

from ..errors import MethodError
from ..gl.workgroups import ComputeNeeds, needs_of
from ..gpu.behaviours import EVERY_METHOD, broken
from ..gpu.buffers import buffer_pool
from ..grid import MAX_VOXELS

KINDS = ("surface", "solid", "ldi", "sparse")
#: How a method runs: the raster pipeline, compute shaders, or numpy on the CPU.
PIPELINES = ("raster", "compute", "cpu")
#: The method families, in the order ``glvox methods`` lists them.  Each is a
#: package ``glvox/methods/<family>/`` named like its shader folder
#: ``shaders/<family>/``, its tests ``tests/test_<family>.py`` and its page
#: ``docs/methods/<family>.md`` (``tests/test_layout.py`` holds them together);
#: a method's family is the package that registers it.
FAMILIES = ("depth", "eisemann", "ldi", "ss", "ss_octree", "scanline", "carve", "gwn", "vote", "binvox", "solid",
            "reference")
#: Families of passes that run after any method and register none (``--attributes``).
PASS_FAMILIES = ("attributes", "sdf")
#: Shader folders that belong to no family: what every family includes or runs.
SHARED_SHADERS = ("common", "render", "sort", "testing")


@dataclass(frozen=True)
class Option:
    """One method option: default, help, and the values allowed (if a set)."""

    default: Any
    help: str
    choices: tuple[Any, ...] | None = None

    def coerce(self, name: str, value: Any) -> Any:
        """Convert a CLI string (or a Python value) to the default's type and check it."""
        target = type(self.default)
        if isinstance(value, str) and target is not str:
            try:
                if target is bool:
                    low = value.strip().lower()
                    if low not in ("1", "0", "true", "false", "yes", "no", "on", "off"):
                        raise ValueError(value)
                    value = low in ("1", "true", "yes", "on")
                else:
                    value = target(value)
            except ValueError:
                raise MethodError(f"option {name} must be a {target.__name__}, got {value!r}") from None
        if self.choices is not None and value not in self.choices:
            raise MethodError(f"option {name} must be one of {list(self.choices)}, got {value!r}")
        return value


#: Limits whose value is one number per component (x, y, z of compute work
#: groups; width, height of the viewport): a need for them is a tuple of as
#: many numbers, compared component by component.
ARRAY_LIMITS = {"GL_MAX_COMPUTE_WORK_GROUP_SIZE": 3, "GL_MAX_COMPUTE_WORK_GROUP_COUNT": 3,
                "GL_MAX_VIEWPORT_DIMS": 2}
_AXES = "xyz"
#: Extensions promoted to core, by the GL version (``version_code``) that made
#: them core: a core context of that version has the feature whether or not its
#: driver still lists the extension string (GL 4.6 core, Appendix F).
CORE_SINCE = {"GL_ARB_gpu_shader_fp64": 400, "GL_ARB_compute_shader": 430,
              "GL_ARB_shader_storage_buffer_object": 430, "GL_ARB_direct_state_access": 450}


@dataclass(frozen=True)
class Requirements:
    """What a GL method needs of the context.

    Attributes
    ----------
    gl_version : int
        ``major * 100 + minor * 10``, as moderngl's ``version_code``.
    extensions : tuple of str
    limits : mapping of str to int or tuple of int
        GL limit name -> the least value needed.  Array limits
        (:data:`ARRAY_LIMITS`) take a tuple compared per component: a work
        group of 256 x 1 x 1 needs ``(256, 1, 1)``, which NVIDIA's
        ``(1024, 1024, 64)`` meets.
    compute : tuple of (str, mapping)
        The compute shaders the method compiles, as ``(path, defines)`` (a path
        may be a glob, ``"ss/*.comp"``).  Their declared ``local_size`` per
        dimension, invocations per group, ``shared`` bytes and storage blocks
        and bindings (:func:`glvox.gl.workgroups.needs_of`) are checked against
        GL_MAX_COMPUTE_WORK_GROUP_SIZE, GL_MAX_COMPUTE_WORK_GROUP_INVOCATIONS,
        GL_MAX_COMPUTE_SHARED_MEMORY_SIZE, GL_MAX_COMPUTE_SHADER_STORAGE_BLOCKS
        and GL_MAX_SHADER_STORAGE_BUFFER_BINDINGS, so no number is written by hand.
    behaviours : tuple of str
        GL behaviours the method relies on that a context may advertise and
        still get wrong (:data:`glvox.gpu.behaviours.PROBES`, e.g.
        ``'integer-logic-op'``), each checked by a functional probe once per
        context.
    """

    gl_version: int = 450
    extensions: tuple[str, ...] = ()
    limits: Mapping[str, Any] = field(default_factory=dict)
    compute: tuple[tuple[str, Mapping[str, Any]], ...] = ()
    behaviours: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        for name, need in self.limits.items():
            n = ARRAY_LIMITS.get(name)
            if n is not None and not (isinstance(need, tuple) and len(need) == n):
                raise ValueError(f"{name} is a {n}-component limit: give the need per component "
                                 f"as a tuple of {n}, got {need!r}")

    @cached_property
    def compute_needs(self) -> ComputeNeeds:
        """The joined :class:`~glvox.gl.workgroups.ComputeNeeds` of :attr:`compute`."""
        return needs_of(self.compute)

    def all_limits(self) -> dict[str, Any]:
        """:attr:`limits` with the needs derived from :attr:`compute` merged in
        (the larger of both per limit and component)."""
        out = dict(self.limits)
        if self.compute:
            need = self.compute_needs
            derived = {"GL_MAX_COMPUTE_WORK_GROUP_SIZE": need.local_size,
                       "GL_MAX_COMPUTE_WORK_GROUP_INVOCATIONS": need.invocations,
                       "GL_MAX_COMPUTE_SHADER_STORAGE_BLOCKS": need.storage_blocks,
                       "GL_MAX_SHADER_STORAGE_BUFFER_BINDINGS": need.storage_bindings}
            if need.shared_bytes:
                derived["GL_MAX_COMPUTE_SHARED_MEMORY_SIZE"] = need.shared_bytes
            for name, v in derived.items():
                old = out.get(name)
                if old is None:
                    out[name] = v
                elif isinstance(v, tuple):
                    out[name] = tuple(max(a, b) for a, b in zip(old, v))
                else:
                    out[name] = max(old, v)
        return out

    def missing(self, ctx) -> list[str]:
        """Human-readable list of what ``ctx`` lacks (empty when all is there).

        ``ctx`` needs ``.mgl.version_code``, ``.mgl.extensions``, ``.limits()``
        and, for :attr:`behaviours`, ``.caches`` (tests pass published limit
        tables as fake contexts, whose caches hold the probes' answers).  The
        behaviours (:data:`~glvox.gpu.behaviours.EVERY_METHOD` and the method's
        own) are probed last, and only where nothing else is missing.
        """
        out = []
        if ctx.mgl.version_code < self.gl_version:
            out.append(f"OpenGL {self.gl_version / 100:.1f} (context has {ctx.mgl.version_code / 100:.1f})")
        exts = ctx.mgl.extensions
        out += [f"extension {e}" for e in self.extensions
                if e not in exts and ctx.mgl.version_code < CORE_SINCE.get(e, 10 ** 6)]
        lim = ctx.limits()
        for name, need in self.all_limits().items():
            have = lim.get(name)
            if isinstance(need, tuple):
                if not isinstance(have, (tuple, list)) or len(have) != len(need):
                    out.append(f"{name} >= {need} (context has {have})")
                    continue
                for axis, n, h in zip(_AXES, need, have):
                    if h < n:
                        out.append(f"{name} {axis} >= {n} (context has {tuple(have)})")
            elif isinstance(have, (tuple, list)):
                raise ValueError(f"{name} has {len(have)} components: give the need as a tuple")
            elif have is None or have < need:
                out.append(f"{name} >= {need} (context has {have})")
        if not out:
            out += [f"{b}: {why}" for b in EVERY_METHOD + tuple(b for b in self.behaviours if b not in EVERY_METHOD)
                    if (why := broken(ctx, b)) is not None]
        return out


def taking_grid(kind: str, n_voxels: int, any_mesh: bool = False) -> list[str]:
    """The registered methods of ``kind`` that take a grid of ``n_voxels`` voxels
    (with ``any_mesh``, only those that define an inside for an open mesh too)."""
    return sorted(m.info.name for m in _REGISTRY.values() if m.info.kind == kind and m.info.max_voxels >= n_voxels
                  and (m.info.any_mesh or not any_mesh))


def alternative(info: "MethodInfo", ctx) -> str | None:
    """What runs on ``ctx`` instead of ``info``: a registered GL method of the
    same kind checked against the same reference whose requirements ``ctx``
    meets (exact before approximate), else the CPU reference ``info.reference``
    (the same definition, on the CPU); None when there is neither."""
    cands = [m.info for m in _REGISTRY.values()
             if m.info.kind == info.kind and m.info.reference == info.reference and m.info.name != info.name
             and m.info.uses_gl and m.info.family != "solid"]
    cands.sort(key=lambda i: (not i.exact, i.name))
    for cand in cands:
        if not cand.requires.missing(ctx):
            return cand.name
    return info.reference if info.reference in _REGISTRY and info.reference != info.name else None


@dataclass(frozen=True)
class MethodInfo:
    """Registry entry of a method.

    Attributes
    ----------
    name : str
        Registry key, e.g. ``'reference-solid'``.
    kind : {'surface', 'solid', 'ldi', 'sparse'}
    pipeline : {'raster', 'compute', 'cpu'}
        How it runs (:data:`PIPELINES`).
    paper : str
        Paper and section implemented.
    summary : str
        One line for ``glvox methods``.
    reference : str or None
        Name of the exact reference this method is compared with.
    exact : bool
        True when the method claims exactness against ``reference`` (up to
        ties); False for approximate-by-design methods.
    requires : Requirements
    options : mapping of str to Option
    any_mesh : bool
        True for a solid method whose inside is defined for any mesh (open,
        non-manifold, self-intersecting; e.g. generalized winding numbers):
        the run envelope does not refuse open meshes for it.
    family : str
        The package that registers it (:data:`FAMILIES`); set by :func:`register`.
    max_voxels : int
        Largest grid (voxels) it takes; :data:`glvox.grid.MAX_VOXELS` (what glvox
        keeps dense with int32 flat indices) unless its shaders index only packed
        words and it streams grids over the storage-block limit.
    """

    name: str
    kind: str
    pipeline: str
    paper: str
    summary: str
    reference: str | None = None
    exact: bool = True
    requires: Requirements = field(default_factory=Requirements)
    options: Mapping[str, Option] = field(default_factory=dict)
    any_mesh: bool = False
    family: str = ""
    max_voxels: int = MAX_VOXELS

    def __post_init__(self) -> None:
        if self.kind not in KINDS:
            raise ValueError(f"kind must be one of {KINDS}, got {self.kind!r}")
        if self.pipeline not in PIPELINES:
            raise ValueError(f"pipeline must be one of {PIPELINES}, got {self.pipeline!r}")
        if self.family and self.family not in FAMILIES:
            raise ValueError(f"family must be one of {FAMILIES}, got {self.family!r}")

    @property
    def uses_gl(self) -> bool:
        return self.pipeline != "cpu"

    def to_dict(self) -> dict[str, Any]:
        return {
            "name": self.name, "kind": self.kind, "family": self.family, "pipeline": self.pipeline, "paper": self.paper,
            "summary": self.summary, "reference": self.reference, "exact": self.exact,
            "any_mesh": self.any_mesh, "max_voxels": self.max_voxels,
            "requires": {"gl_version": self.requires.gl_version,
                         "extensions": list(self.requires.extensions),
                         "limits": {k: list(v) if isinstance(v, tuple) else v
                                    for k, v in self.requires.all_limits().items()}},
            "options": {k: {"default": o.default, "help": o.help,
                            "choices": list(o.choices) if o.choices else None}
                        for k, o in self.options.items()},
        }


class Method:
    """Base class of every method.

    Subclasses set ``info`` and implement :meth:`run`.  A method object lives
    as long as the process and may keep GPU resources keyed by context (see
    :meth:`release`).
    """

    info: ClassVar[MethodInfo]

    def run(self, mesh, spec, *, ctx, timer, **options):
        """Voxelize ``mesh`` on ``spec``.

        Parameters
        ----------
        mesh : glvox.mesh.Mesh
        spec : glvox.grid.GridSpec
        ctx : glvox.gl.context.GLContext or None
            The context for GL methods; None for CPU methods.
        timer : glvox.gl.timing.StageTimer
            Wrap each stage in ``with timer.stage(name):``.
        **options
            The method's options, already validated and with defaults filled.

        Returns
        -------
        A result of the method's kind (VoxelGrid for surface and solid).
        """
        raise NotImplementedError

    def resolve(self, mesh) -> str:
        """The registry name of the method that runs on ``mesh``: this one's, except
        for aliases that pick a method by the mesh (``solid``); :func:`run_method`
        runs that one and records it in the run info."""
        return self.info.name

    def why(self, mesh) -> str | None:
        """For an alias, why :meth:`resolve` picks its method for ``mesh`` (recorded as
        ``result.run.stats['picked_because']``); None for other methods."""
        return None

    #: True for references that define :meth:`tie_set`.
    has_ties: ClassVar[bool] = False

    def tie_set(self, mesh, spec, eps: float, **options) -> np.ndarray:
        """Dense (nx, ny, nz) bool: the voxels whose verdict under this method's
        definition is a proven tie (docs/design.md, "Ties") for ``mesh`` on ``spec``,
        with tolerance ``eps`` voxel; ``options``: the reference's options that
        move the definition (reference-gwn's threshold, reference-carve's close).
        Defined by the exact references (:attr:`has_ties`), which results are
        checked against."""
        raise ValueError(f"no tie set is defined for {self.info.name!r}")

    def release(self, ctx) -> None:
        """Free GPU resources held for ``ctx``: by default the method's buffer pool
        (``buffer_pool(ctx, info.name)``); methods keeping more override this."""
        if self.info.uses_gl:
            buffer_pool(ctx, self.info.name).release()


_REGISTRY: dict[str, Method] = {}


def family_of(module: str) -> str:
    """The family of a method defined in ``module``: ``'glvox.methods.ss.surface'`` -> ``'ss'``."""
    parts = module.split(".")
    if len(parts) < 4 or parts[:2] != ["glvox", "methods"] or parts[2] not in FAMILIES:
        raise ValueError(f"methods are registered from a family package glvox.methods.<family> "
                         f"({', '.join(FAMILIES)}), not from {module}")
    return parts[2]


def register(cls: type[Method]) -> type[Method]:
    """Class decorator: add a method to the registry (name must be new); its
    family is the package it is defined in (:func:`family_of`)."""
    name = cls.info.name
    if name in _REGISTRY and type(_REGISTRY[name]) is not cls:
        raise ValueError(f"method name {name!r} is registered twice")
    cls.info = replace(cls.info, family=family_of(cls.__module__))
    _REGISTRY[name] = cls()
    return cls
