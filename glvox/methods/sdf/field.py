"""Signed distance fields on the grid: :func:`signed_distance_field` (``glvox.sdf``, ``glvox sdf``).

* distance: the GPU band pass (:mod:`.band`, ``shaders/sdf/band.comp``) gives
  the exact distance from every voxel center within the band to the nearest
  triangle; with ``band='all'`` the voxels beyond it get theirs from the
  float64 reference's library (:func:`glvox.reference.sdf.point_distances`,
  libigl's AABB tree: exact, on the CPU, slower);
* sign: the occupancy of a solid method run on the same grid (``'solid'``, the
  alias that picks a method per mesh, by default): inside is negative;
* uncertainty: where the solid method returns generalized winding numbers
  (``gwn-solid``), voxels whose number lies within
  :data:`~glvox.tolerances.SDF_WINDING_UNCERTAIN` of 1/2; and the mesh's
  traits (:func:`glvox.traits.solid_outlook`) judge the method that gave the
  sign.  Either warns, with a count or the cause, never silently.
"""

from __future__ import annotations

import math
import re
import warnings
from typing import Any

import numpy as np

from ...errors import MethodError, SuspiciousResultWarning
from ...gl.context import get_context
from ...gl.timing import StageTimer
from ...grid import GridSpec
from ...reference.sdf import point_distances
from ...results.base import RunInfo
from ...results.sdf import SDFGrid
from ...tolerances import SDF_WINDING_UNCERTAIN
from ...traits import mesh_traits, solid_outlook
from .. import Request, get_method, run_method
from .band import band_distances

#: The default band half-width, voxels.
DEFAULT_BAND = 3.0


def parse_band(band: Any) -> float:
    """A band half-width in voxels from a number, a numeric string or ``'all'`` (``inf``).

    Raises
    ------
    MethodError
        Not a positive finite number nor ``'all'``.
    """
    if isinstance(band, str):
        if band.strip().lower() == "all":
            return math.inf
        try:
            band = float(band)
        except ValueError:
            raise MethodError(f"--band must be a number of voxels or 'all', got {band!r}") from None
    if isinstance(band, bool) or not isinstance(band, (int, float)) or not (0 < band < math.inf):
        raise MethodError(f"band must be a positive number of voxels or 'all', got {band!r}")
    return float(band)


_TRUNC = re.compile(r"^\s*([0-9.eE+-]+)\s*(vox|voxel|voxels|world)?\s*$")


def parse_truncation(truncation: Any) -> tuple[float, str] | None:
    """``(value, unit)`` from ``0.01`` / ``'0.01world'`` (world units) or ``'2vox'`` (voxels); None for None.

    Raises
    ------
    MethodError
        Not a positive finite number with an optional unit ``vox`` or ``world``.
    """
    if truncation is None:
        return None
    unit = "world"
    value = truncation
    if isinstance(truncation, str):
        m = _TRUNC.match(truncation)
        if m is None:
            raise MethodError(f"truncation must be a number with an optional unit vox or world "
                              f"(e.g. 2vox, 0.01), got {truncation!r}")
        value, unit = m.group(1), "vox" if (m.group(2) or "world").startswith("vox") else "world"
        try:
            value = float(value)
        except ValueError:
            raise MethodError(f"truncation must be a number with an optional unit vox or world, "
                              f"got {truncation!r}") from None
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not (0 < value < math.inf):
        raise MethodError(f"truncation must be positive and finite, got {truncation!r}")
    return float(value), unit


def sign_request(sign: str) -> Request:
    """The request of the solid method that gives the sign (a MethodError unless it is a solid method)."""
    method = get_method(sign)
    if method.info.kind != "solid":
        raise MethodError(f"the sign of an SDF comes from a solid method; {sign!r} is a {method.info.kind} "
                          "method (glvox methods --kind solid lists them)")
    return Request.make(sign)


def signed_distance_field(mesh, spec: GridSpec, *, band: Any = DEFAULT_BAND, sign: str = "solid",
                          truncation: Any = None, ctx=None, backend: str | None = None,
                          allow_open: bool = False) -> SDFGrid:
    """The signed distance field of ``mesh`` at the voxel centers of ``spec``.

    Parameters
    ----------
    mesh : Mesh
    spec : GridSpec
    band : float or 'all'
        Half-width in voxels of the band where distances are exact; beyond
        it the value is ``+-band * h`` (clamped).  ``'all'``: exact everywhere.
        A truncation wider than the band widens the band to it.
    sign : str
        The solid method whose occupancy gives the sign (inside negative).
    truncation : float, str or None
        Clamp to ``+-truncation``: world units, or voxels with ``'2vox'``.
    ctx, backend, allow_open
        As :func:`glvox.methods.run_method`.

    Returns
    -------
    SDFGrid
        ``.sdf`` float32 (nx, ny, nz) world units; ``.band``, ``.uncertain``
        bool masks; ``.run`` with the stages' timings and ``stats['sign_method']``.
    """
    width = parse_band(band)
    trunc = parse_truncation(truncation)
    request = sign_request(sign)
    h = spec.voxel_size
    t_world = None if trunc is None else (trunc[0] * h if trunc[1] == "vox" else trunc[0])
    radius = DEFAULT_BAND if math.isinf(width) else width
    if t_world is not None and t_world / h > radius:
        radius = t_world / h  # the band covers the truncation: every unclamped value is exact
    ctx = ctx if ctx is not None else get_context(backend)
    ctx.make_current()
    timer = StageTimer(ctx, method="sdf")
    tri_vox = (mesh.triangles() - spec.origin) / h
    dist = band_distances(ctx, tri_vox, spec.dims, radius, timer)
    with timer.stage("sdf_sign", gpu=False):
        picked = request.method.resolve(mesh)
        if "winding" in get_method(picked).info.options:
            request = Request.make(picked, {"winding": True})
        solid = run_method(request, mesh, spec, ctx=ctx, allow_open=allow_open)
        inside = solid.dense()
        ran = solid.run.method
    with timer.stage("sdf_combine", gpu=False):
        exact = np.isfinite(dist)
        if math.isinf(width):
            far = np.flatnonzero(~exact)
            if len(far):
                centers = spec.centers(np.stack(np.unravel_index(far, spec.dims), axis=1))
                dist.reshape(-1)[far] = point_distances(mesh.vertices, mesh.faces, centers) / h
            exact = np.ones(spec.dims, bool)
        else:
            np.minimum(dist, np.float32(radius), out=dist)
        dist *= np.float32(h)
        sdf = np.where(inside, -dist, dist).astype(np.float32, copy=False)
        if t_world is not None:
            np.clip(sdf, -t_world, t_world, out=sdf)
        uncertain = np.zeros(spec.dims, bool)
        w = solid.fields.get("winding")
        if w is not None:
            uncertain = np.abs(w - 0.5) < SDF_WINDING_UNCERTAIN
    _warn_sign(mesh, ran, uncertain)
    stats = {"sign_method": ran, "band_voxels": int(np.count_nonzero(exact)), "uncertain": int(uncertain.sum()),
             "inside": int(solid.count), **{k: v for k, v in timer.stats.items()}}
    result = SDFGrid(sdf, spec, exact, uncertain=uncertain, band_width=math.inf if math.isinf(width) else radius,
                     truncation=t_world)
    result.run = RunInfo("sdf", "sdf", spec, timer.finish(), stats,
                         {"band": "all" if math.isinf(width) else radius, "sign": sign, "truncation": t_world})
    return result


def _warn_sign(mesh, method: str, uncertain: np.ndarray) -> None:
    """Warn when the sign cannot be trusted: voxels with a winding number near 1/2, or
    traits of the mesh that the sign's method gets wrong (never a silent guess)."""
    n = int(np.count_nonzero(uncertain))
    if n:
        warnings.warn(f"{mesh.name}: the sign of {n} voxels is uncertain (winding number within "
                      f"{SDF_WINDING_UNCERTAIN} of 1/2; holes, flipped or doubled faces): see result.uncertain",
                      SuspiciousResultWarning, stacklevel=3)
    verdict = solid_outlook(mesh_traits(mesh)).get(method, "ok")
    if verdict != "ok":
        warnings.warn(f"{mesh.name}: the sign comes from {method}, which on this mesh is {verdict}; "
                      "try --sign binvox-solid or carve-solid", SuspiciousResultWarning, stacklevel=3)
