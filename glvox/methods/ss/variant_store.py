"""``ss-conservative``'s variant choices measured on a GPU, stored per renderer.

``glvox calibrate`` times the variants on this GL device and stores the
fastest one per *density band* (triangles per voxel of a grid face,
F / N^2 with N^2 the geometric mean of the grid's face areas: the quantity
the llvmpipe rule of :func:`glvox.methods.ss.surface.default_variant`
reads) under the renderer string (``GL_RENDERER``), in a small JSON file in
the user's cache folder (:func:`store_path`; ``GLVOX_CALIBRATION`` names another file).  ``variant='auto'`` takes the
stored entry of the current renderer with the nearest density (in ratio)
when there is one, else the llvmpipe rule.  Another renderer's entries are
never used; a file that cannot be read or does not hold the expected
layout is ignored with a :class:`~glvox.errors.CalibrationWarning`.

File layout (``version`` 1)::

    {"version": 1,
     "renderers": {"<GL_RENDERER>": [
         {"n": 256, "triangles": 69451, "density": 1.06, "variant": "simple",
          "best_ms": {"simple": 9.1, "specialized": 11.0, "sorted": 14.2},
          "mesh": "stanford_bunny_bun_zipper.ply"}, ...]}}
"""

from __future__ import annotations

import json
import math
import os
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ...errors import CalibrationWarning

VERSION = 1
VARIANT_NAMES = ("simple", "specialized", "sorted")


def store_path() -> Path:
    """``$GLVOX_CALIBRATION`` (a file) when set, else ``$XDG_CACHE_HOME/glvox/ss_variants.json``
    (``~/.cache`` when ``XDG_CACHE_HOME`` is unset)."""
    if os.environ.get("GLVOX_CALIBRATION"):
        return Path(os.environ["GLVOX_CALIBRATION"])
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "glvox" / "ss_variants.json"


def density(n_triangles: int, dims) -> float:
    """F / N^2: triangles per voxel of a grid face, N^2 = (nx ny nz)^(2/3)."""
    volume = float(dims[0]) * float(dims[1]) * float(dims[2])
    return n_triangles / volume ** (2.0 / 3.0)


@dataclass(frozen=True)
class Choice:
    """A stored choice: the variant, the entry it came from, the file."""

    variant: str
    entry: dict[str, Any]
    path: Path

    def rule(self) -> str:
        """How the choice was made, for run statistics and messages."""
        e = self.entry
        return (f"calibrated on this renderer ({self.path}): fastest at F/N^2 = {e['density']:.3g} "
                f"({e.get('mesh', 'a mesh')} at {e['n']}^3)")


_cache: dict[Path, tuple[tuple[int, int], dict[str, list[dict]] | None]] = {}


def load(path: Path | None = None) -> dict[str, list[dict]]:
    """The renderers' entries of the store at ``path`` (:func:`store_path`), {} when there is
    none; a file that is not the layout of the module docstring warns once and reads as {}."""
    path = store_path() if path is None else Path(path)
    try:
        st = path.stat()
    except OSError:
        return {}
    key = (st.st_mtime_ns, st.st_size)
    hit = _cache.get(path)
    if hit is not None and hit[0] == key:
        return hit[1] or {}
    try:
        renderers = _parse(json.loads(path.read_text(encoding="utf-8")))
    except (OSError, UnicodeDecodeError, ValueError) as exc:
        warnings.warn(CalibrationWarning(f"ignoring the variant calibration {path} ({exc}); "
                                         f"`glvox calibrate` writes it anew"), stacklevel=2)
        renderers = None
    _cache[path] = (key, renderers)
    return renderers or {}


def _parse(doc: Any) -> dict[str, list[dict]]:
    """The checked ``renderers`` mapping of a decoded file; ValueError naming what is wrong."""
    if not isinstance(doc, dict) or doc.get("version") != VERSION:
        raise ValueError(f"not a version {VERSION} calibration file")
    renderers = doc.get("renderers")
    if not isinstance(renderers, dict):
        raise ValueError("no 'renderers' mapping")
    for renderer, entries in renderers.items():
        if not isinstance(entries, list):
            raise ValueError(f"the entries of {renderer!r} are not a list")
        for e in entries:
            ok = (isinstance(e, dict) and e.get("variant") in VARIANT_NAMES
                  and isinstance(e.get("density"), (int, float)) and math.isfinite(e["density"])
                  and e["density"] > 0 and isinstance(e.get("n"), int))
            if not ok:
                raise ValueError(f"an entry of {renderer!r} is not {{n, density > 0, variant}}: {e!r}"[:200])
    return renderers


def lookup(renderer: str, n_triangles: int, dims, path: Path | None = None) -> Choice | None:
    """The stored choice for ``renderer`` nearest (in ratio) to this mesh's density on
    ``dims``, or None when the store has none for this renderer."""
    path = store_path() if path is None else Path(path)
    entries = load(path).get(renderer)
    if not entries or n_triangles <= 0:
        return None
    d = density(n_triangles, dims)
    best = min(entries, key=lambda e: abs(math.log(d / e["density"])))
    return Choice(best["variant"], best, path)


def save(renderer: str, entries: list[dict[str, Any]], path: Path | None = None) -> Path:
    """Replace ``renderer``'s entries in the store (others kept; an unreadable file is
    replaced) and return its path.  Written to a temporary file, then renamed."""
    path = store_path() if path is None else Path(path)
    _parse({"version": VERSION, "renderers": {renderer: entries}})  # never write what load refuses
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", CalibrationWarning)
        renderers = dict(load(path))
    renderers[renderer] = entries
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    tmp.write_text(json.dumps({"version": VERSION, "renderers": renderers}, indent=1) + "\n", encoding="utf-8")
    os.replace(tmp, path)
    return path
