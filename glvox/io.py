"""Reading and writing results by file suffix, through the format registry.

``.npz`` (every result type), ``.binvox``, ``.nrrd``, ``.nii`` / ``.nii.gz``,
``.vti`` and ``.vdb``: one module per format in :mod:`glvox.formats`, which
lists what each holds, the library it needs and how it encodes placement (the
world center of voxel (i, j, k) is ``origin + (i, j, k) h + h/2`` in all).
:func:`check_writable` and :func:`check_readable` refuse a bad path before
any work (unknown suffix, missing library, a result the format cannot hold).
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

from .errors import FormatError
from .formats import check_dims, check_readable, check_writable, format_for
from .formats.binvox import CONVENTIONS, binvox_bytes
from .results import Result

__all__ = ["CONVENTIONS", "binvox_bytes", "check_dims", "check_readable", "check_writable", "format_for", "load", "save"]


def _options(fmt, takes: tuple[str, ...], given: dict[str, Any], path: Path) -> dict[str, Any]:
    """``given`` when ``fmt`` takes every option in it (``takes``), else a FormatError."""
    unknown = sorted(k for k in given if k not in takes)
    if unknown:
        known = f"; it takes {list(takes)}" if takes else ""
        raise FormatError(f"{fmt.name} ({path.name}) takes no option {unknown}{known}")
    return given


def save(result: Result, path: str | os.PathLike, *, convention: str = "trimesh", **options: Any) -> Path:
    """Write ``result`` (a VoxelGrid, SparseOctree or LDI) to ``path``, the format by suffix.

    Parameters
    ----------
    result : Result
    path : path-like
        ``.npz``, ``.binvox``, ``.nrrd``, ``.nii``, ``.nii.gz``, ``.vti`` or ``.vdb``.
    convention : {'trimesh', 'binvox'}
        binvox placement (ignored by the other formats).
    **options
        Format options, e.g. ``coverage=False`` for ``.vdb``.

    Returns
    -------
    Path
    """
    path = Path(path)
    fmt = format_for(path)
    if "convention" in fmt.options:
        options["convention"] = convention
    fmt.require()
    fmt.write(result, path, **_options(fmt, fmt.options, options, path))
    return path


def load(path: str | os.PathLike, *, convention: str = "trimesh", **options: Any) -> Result:
    """Read a result written by :func:`save` (or a conforming file of another tool).

    Returns a VoxelGrid, or a :class:`~glvox.results.SparseOctree` or an
    :class:`~glvox.results.LDI` for an npz holding one.  ``convention`` is
    binvox's placement (ignored by the other formats).
    """
    path = Path(path)
    fmt = check_readable(path)
    if "convention" in fmt.read_options:
        options["convention"] = convention
    return fmt.read(path, **_options(fmt, fmt.read_options, options, path))
