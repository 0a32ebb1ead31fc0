"""Headless OpenGL: contexts (:mod:`.context`), the raw GL calls moderngl lacks
(:mod:`.raw`), GLSL loading (:mod:`.shaders`) and stage timing (:mod:`.timing`)."""

from .context import GLContext, close_context, create_context, get_context

__all__ = ["GLContext", "close_context", "create_context", "get_context"]
