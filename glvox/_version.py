"""glvox's version (one place: the package face, the CLI, batch manifests and study results read it)."""

__version__ = "0.1.0"
