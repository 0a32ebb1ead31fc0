"""Signed distance fields on the grid and near-surface samples (``glvox sdf``): a pass family
that registers no method; shaders in ``shaders/sdf/``, its float64 reference in
:mod:`glvox.reference.sdf`."""

from . import band, field

__all__ = ["band", "field"]
