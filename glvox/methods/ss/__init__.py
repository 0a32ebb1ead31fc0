"""Schwarz & Seidel in compute shaders: conservative and 6-separating surfaces
(``ss-conservative``, ``ss-6sep``; :mod:`.surface`) and solids (``ss-solid``, ``ss-solid-tiled``;
:mod:`.solid`); shaders in ``shaders/ss/``."""

from . import solid, solid_tuning, surface

__all__ = ["solid", "solid_tuning", "surface"]
