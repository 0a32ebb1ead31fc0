"""The exact CPU references of :mod:`glvox.reference`, registered as methods (``reference-*``)."""

from . import registered

__all__ = ["registered"]
