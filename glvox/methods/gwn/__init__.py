"""Generalized winding numbers in compute shaders (``gwn-solid``): the field (:mod:`.field`) over a
cluster tree (:mod:`.tree`), its work divided by :mod:`.plan`; shaders in ``shaders/gwn/``, its exact
CPU twin in :mod:`glvox.reference.winding`."""

from . import field, plan, tree

__all__ = ["field", "plan", "tree"]
