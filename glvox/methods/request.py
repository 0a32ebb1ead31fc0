"""A method request, validated once: the method, its options, the attributes asked of it.

Every way into a method (``glvox voxelize``, ``glvox batch``,
:func:`glvox.voxelize`, :func:`~glvox.methods.run_method`) builds one
:class:`Request` before any mesh is loaded; what it checks is then not checked
again.  What depends on the mesh (the method an alias such as ``solid`` picks,
whether the mesh carries the colours asked for) is checked when it runs.

>>> from glvox.methods.request import Request
>>> r = Request.make("ss-conservative", {"variant": "simple"})
>>> (r.name, r.options["variant"], r.attributes)
('ss-conservative', 'simple', ())
"""

from __future__ import annotations

import importlib
import pkgutil
from dataclasses import dataclass
from pathlib import Path
from types import MappingProxyType
from typing import Any, Mapping, Sequence

from ..errors import MethodError
from .attributes.passes import check_request, parse_attributes
from .base import _REGISTRY, Method, MethodInfo


_discovered = False


def discover() -> None:
    """Import every family package of ``glvox.methods`` once, so their methods register
    (a family is a package: adding one is adding its folder)."""
    global _discovered
    if _discovered:
        return
    _discovered = True
    package = __name__.rsplit(".", 1)[0]
    for mod in pkgutil.iter_modules([str(Path(__file__).parent)]):
        if mod.ispkg:
            importlib.import_module(f"{package}.{mod.name}")


@dataclass(frozen=True)
class Request:
    """A registered method with its options coerced (defaults filled) and the
    attributes asked of it checked against its kind.

    Attributes
    ----------
    method : Method
        The registered method asked for (an alias stays an alias until it runs).
    options : mapping of str to value
        Read-only; every option of the method, coerced to its type.
    attributes : tuple of str
        ``triangle``, ``color``, ``normal``, ``material`` (or none).
    normals : {'face', 'vertex'}
    fill_attributes : {'none', 'nearest'}
    """

    method: Method
    options: Mapping[str, Any]
    attributes: tuple[str, ...] = ()
    normals: str = "face"
    fill_attributes: str = "none"

    @property
    def info(self) -> MethodInfo:
        return self.method.info

    @property
    def name(self) -> str:
        return self.method.info.name

    @classmethod
    def make(cls, method: str, options: Mapping[str, Any] | None = None,
             attributes: str | Sequence[str] | None = None, normals: str = "face",
             fill_attributes: str = "none", kinds: Sequence[str] | None = None,
             command: str = "glvox voxelize") -> "Request":
        """Check a method request before any work; MethodError names what is wrong.

        Parameters
        ----------
        method : str
            Registry name (``glvox methods``).
        options : mapping, optional
            Method options, as Python values or command-line strings.
        attributes : str or sequence of str, optional
            Per-voxel attributes (comma-separated or a sequence).
        normals, fill_attributes : str
            As :func:`glvox.methods.run_method` takes them.
        kinds : sequence of str, optional
            The kinds of method the caller accepts (``('ldi',)`` for ``glvox ldi``).
        command : str
            The caller's name in the message of a wrong kind.
        """
        found = get_method(method)
        info = found.info
        if kinds is not None and info.kind not in kinds:
            raise MethodError(f"{command} needs a method of kind {' or '.join(repr(k) for k in kinds)}, got "
                              f"{method!r} (kind {info.kind!r})")
        opts = validate_options(info, dict(options or {}))
        names = parse_attributes(attributes)
        check_request(info, names, normals, fill_attributes)
        return cls(found, MappingProxyType(opts), names, normals, fill_attributes)

    def for_method(self, method: Method) -> "Request":
        """This request for the method an alias picked: its options taken by that method
        (the alias's defaults filled in, then the picked method's)."""
        if method is self.method:
            return self
        opts = validate_options(method.info, dict(self.options))
        check_request(method.info, self.attributes, self.normals, self.fill_attributes)
        return Request(method, MappingProxyType(opts), self.attributes, self.normals, self.fill_attributes)


def get_method(name: str) -> Method:
    """The registered method ``name``; MethodError lists the known names otherwise."""
    discover()
    try:
        return _REGISTRY[name]
    except KeyError:
        raise MethodError(
            f"unknown method {name!r}; known methods: {', '.join(sorted(_REGISTRY))}"
        ) from None


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
