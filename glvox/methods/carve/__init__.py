"""Exterior carving on the GPU (``carve-solid``); shaders in ``shaders/carve/``, its exact
CPU twin in :mod:`glvox.reference.carve`."""

from . import sweep

__all__ = ["sweep"]
