"""binvox's solid (``binvox-solid``): z-buffer carving from the six axis directions and
z-buffer parity voting along the three axes, on glvox's depth-buffer raster passes
(:mod:`glvox.methods.depth.raster`); shaders in ``shaders/binvox/``, its exact CPU twin
in :mod:`glvox.reference.binvox`."""

from . import solid

__all__ = ["solid"]
