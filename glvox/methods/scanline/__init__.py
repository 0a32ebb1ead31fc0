"""Zhang et al. projected optimal scanline (``scanline-*``); shaders in ``shaders/scanline/``,
its float64 CPU twin in :mod:`glvox.reference.scanline`."""

from . import voxelize

__all__ = ["voxelize"]
