"""Per-voxel attributes on the GPU (triangle, colour, normal, material) after any surface or solid
method; shaders in ``shaders/attributes/``, its float64 CPU twin in :mod:`glvox.reference.attributes`."""

from . import passes

__all__ = ["passes"]
