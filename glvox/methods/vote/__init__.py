"""Three-axis parity vote on the GPU (``vote-solid``); shaders in ``shaders/vote/``."""

from . import vote

__all__ = ["vote"]
