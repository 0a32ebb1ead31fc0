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
from typing import Any, ClassVar, Mapping

import numpy as np

from ..errors import MethodError
from ..gpu.buffers import buffer_pool

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
PASS_FAMILIES = ("attributes",)
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


@dataclass(frozen=True)
class Requirements:
    """What a GL method needs of the context.

    ``limits`` maps GL limit names to the minimum value needed (for array
    limits such as work group counts, the minimum of every component).
    """

    gl_version: int = 450
    extensions: tuple[str, ...] = ()
    limits: Mapping[str, int] = field(default_factory=dict)

    def missing(self, ctx) -> list[str]:
        """Human-readable list of what ``ctx`` lacks (empty when all is there)."""
        out = []
        if ctx.mgl.version_code < self.gl_version:
            out.append(f"OpenGL {self.gl_version / 100:.1f} (context has {ctx.mgl.version_code / 100:.1f})")
        exts = ctx.mgl.extensions
        out += [f"extension {e}" for e in self.extensions if e not in exts]
        lim = ctx.limits()
        for name, need in self.limits.items():
            have = lim.get(name)
            have_min = min(have) if isinstance(have, (tuple, list)) else have
            if have_min is None or have_min < need:
                out.append(f"{name} >= {need} (context has {have})")
        return out


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
            "any_mesh": self.any_mesh,
            "requires": {"gl_version": self.requires.gl_version,
                         "extensions": list(self.requires.extensions),
                         "limits": dict(self.requires.limits)},
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
