"""Schwarz & Seidel sparse solid voxelization into an octree (``ss-octree``); shaders in
``shaders/ss_octree/``."""

from . import octree

__all__ = ["octree"]
