"""Depth-buffer solids: Karabassi et al. and Passalis et al. (``karabassi``, ``passalis-stencil``,
``passalis-peel``); shaders in ``shaders/depth/``, the raster machinery (:mod:`.raster`) shared
with ``peel-ldi``."""

from . import layers, raster

__all__ = ["layers", "raster"]
