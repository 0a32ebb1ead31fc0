"""Layered depth images: Leung & Wang conservative sampling (``leung-wang-ldi``,
``leung-wang-intersection``) and the exact depth-peeling LDI (``peel-ldi``); shaders in ``shaders/ldi/``."""

from . import common, leung_wang, leung_wang_passes, peel

__all__ = ["common", "leung_wang", "leung_wang_passes", "peel"]
