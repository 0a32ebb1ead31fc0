"""Eisemann & Decoret slicing with XOR / OR logic ops (``eisemann-solid``, ``eisemann-surface``);
shaders in ``shaders/eisemann/``; the slice-mask render (:mod:`.passes`) is shared with the LDI family."""

from . import passes, slicing

__all__ = ["passes", "slicing"]
