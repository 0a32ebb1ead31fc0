"""Exception types of glvox.

Every error glvox raises on purpose derives from :class:`GlvoxError`, so a
caller (or the CLI, which turns them into one line and a non-zero exit) can
tell a refused input from a bug.  Messages say what was expected and what was
got.
"""

from __future__ import annotations


class GlvoxError(Exception):
    """Base class of every error glvox raises deliberately."""


class BackendError(GlvoxError, RuntimeError):
    """No headless OpenGL backend could give the required context."""


class ShaderError(GlvoxError, RuntimeError):
    """A shader could not be loaded, preprocessed, compiled or linked."""


class GLError(GlvoxError, RuntimeError):
    """An OpenGL error was raised by a stage (checked in debug mode)."""


class MeshError(GlvoxError, ValueError):
    """The input mesh cannot be voxelized as given."""


class MeshLoadError(MeshError):
    """The mesh file is missing, unreadable or not a triangle mesh."""


class EmptyMeshError(MeshError):
    """The mesh has no (non-degenerate) triangles."""


class NonFiniteVertexError(MeshError):
    """Some vertex coordinates are NaN or infinite."""


class FaceIndexError(MeshError):
    """Face indices are out of range or of the wrong shape."""


class NotWatertightError(MeshError):
    """A solid method was asked for a mesh that is not closed."""


class NotWatertightWarning(UserWarning):
    """A solid method ran on a mesh that is not closed (``allow_open=True``):
    the result is the parity of crossings along the method's rays."""


class SuspiciousResultWarning(UserWarning):
    """A solid method's result is empty, or its mesh's traits (doubled faces,
    orientation, holes: :mod:`glvox.traits`) say the method gets it wrong: the
    one-line message names the cause and the method to use instead."""


class GridError(GlvoxError, ValueError):
    """The grid specification is invalid (resolution, bounds, dims)."""


class LimitError(GlvoxError, MemoryError):
    """A request exceeds a GL limit or the memory available."""


class MethodError(GlvoxError, KeyError):
    """Unknown method name, or a method used with the wrong arguments."""

    def __str__(self) -> str:  # KeyError quotes its message; we don't want that
        return str(self.args[0]) if self.args else ""


class CapabilityError(GlvoxError, RuntimeError):
    """The GL context lacks something a method requires."""


class FormatError(GlvoxError, ValueError):
    """A result file is malformed, of an unknown format, or its format's library is missing."""


class CalibrationWarning(UserWarning):
    """A stored calibration (``glvox calibrate``'s variant choices) could not be read
    and is ignored: the built-in rule decides."""


class FormatWarning(UserWarning):
    """A format keeps less than the result holds (e.g. NIfTI has no room for
    extra masks): what is dropped is named."""


class DatasetError(GlvoxError, LookupError):
    """A mesh asked for by name is unknown, or not on this machine and cannot be downloaded."""


class MeshNotFoundError(MeshLoadError, DatasetError):
    """A mesh argument is neither a file, a generated mesh (``gen:NAME``) nor a mesh name
    glvox knows (``glvox data list``): a :class:`MeshLoadError` to those who load files, a
    :class:`DatasetError` to those who ask for names."""
