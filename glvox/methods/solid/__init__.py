"""``solid``: the solid method chosen per mesh (:mod:`.choose`)."""

from . import choose

__all__ = ["choose"]
