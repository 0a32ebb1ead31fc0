"""Near-surface samples with their signed distances, as learned-SDF datasets use them
(:func:`sdf_samples`, ``glvox sdf MESH --samples N``).

The mesh is normalized into the unit sphere (its bounding-box center to the
origin, its farthest vertex at distance 1); points are drawn on the surface
with probability proportional to area and moved by isotropic Gaussian
offsets of two scales (default standard deviations 0.0025 and 0.00025 of the
unit sphere, half the near points each), and a share of points is uniform in
the mesh's bounding box.  Every point's distance is exact (float64,
:func:`glvox.reference.sdf.point_distances`); its sign is the generalized
winding number's (libigl's fast winding number, >= 1/2 inside), and points
whose number lies within :data:`~glvox.tolerances.SDF_WINDING_UNCERTAIN` of
1/2 are flagged and warned about.  Everything is in the mesh's world units
and reproducible from ``seed`` (numpy's PCG64).
"""

from __future__ import annotations

import importlib.util
import warnings
from pathlib import Path

import numpy as np

from ...errors import GlvoxError, MethodError, SuspiciousResultWarning
from ...reference.sdf import point_distances
from ...tolerances import SDF_WINDING_UNCERTAIN

#: Standard deviations of the offsets from the surface, in units of the unit sphere.
DEFAULT_SIGMAS = (0.0025, 0.00025)
#: Share of the points drawn uniformly in the bounding box.
DEFAULT_UNIFORM = 0.06


def check_samples(n, sigmas=DEFAULT_SIGMAS, uniform=DEFAULT_UNIFORM) -> None:
    """MethodError unless ``n`` is a positive integer, the sigmas positive and ``uniform`` in [0, 1];
    GlvoxError when libigl (the sign's winding numbers) is missing."""
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n <= 0:
        raise MethodError(f"the number of samples must be a positive integer, got {n!r}")
    if not sigmas or any(not (s > 0 and np.isfinite(s)) for s in sigmas):
        raise MethodError(f"sigmas must be positive and finite, got {sigmas!r}")
    if not 0 <= uniform <= 1:
        raise MethodError(f"uniform must be a share in [0, 1], got {uniform!r}")
    if importlib.util.find_spec("igl") is None:
        raise GlvoxError("SDF samples take their sign from libigl's winding numbers: pip install 'glvox[peers]'")


def sdf_samples(mesh, n: int, *, seed: int = 0, sigmas=DEFAULT_SIGMAS, uniform: float = DEFAULT_UNIFORM) -> dict:
    """``n`` points near the surface and in the box, each with its signed distance.

    Parameters
    ----------
    mesh : Mesh
    n : int
        Points in all.
    seed : int
        numpy ``default_rng`` seed: the same seed gives the same points.
    sigmas : sequence of float
        Offset standard deviations in units of the unit sphere the mesh is normalized into.
    uniform : float
        Share of the points uniform in the bounding box.

    Returns
    -------
    dict
        ``points`` (n, 3) float32 world units; ``sdf`` (n,) float32 world
        units, negative inside; ``normals`` (n, 3) float32, the unit normal of
        the triangle each near point was drawn on (zeros for uniform points);
        ``uncertain`` (n,) bool; ``scale`` (float64: world units per unit of
        the unit sphere) and ``center`` (3,) float64.
    """
    import igl  # optional (the peers / test extras); check_samples says how to install it

    check_samples(n, sigmas, uniform)
    rng = np.random.default_rng(seed)
    tri = mesh.triangles()
    center = 0.5 * (mesh.bounds[0] + mesh.bounds[1])
    scale = float(np.linalg.norm(mesh.vertices[mesh.faces.ravel()] - center, axis=1).max())
    n_uniform = int(round(n * uniform))
    n_near = n - n_uniform
    cross = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    area = np.linalg.norm(cross, axis=1)
    face = rng.choice(len(tri), size=n_near, p=area / area.sum())
    r1, r2 = rng.random(n_near), rng.random(n_near)
    s = np.sqrt(r1)  # uniform on the triangle (Osada et al. 2002)
    on = ((1 - s)[:, None] * tri[face, 0] + (s * (1 - r2))[:, None] * tri[face, 1]
          + (s * r2)[:, None] * tri[face, 2])
    sig = np.repeat(np.asarray(sigmas, np.float64), -(-n_near // len(sigmas)))[:n_near] * scale
    near = on + rng.normal(size=(n_near, 3)) * sig[:, None]
    lo, hi = mesh.bounds
    box = lo + rng.random((n_uniform, 3)) * (hi - lo)
    # the distances are those of the points as written (float32), not of the float64 draws
    points = np.concatenate([near, box]).astype(np.float32).astype(np.float64)
    normals = np.zeros((n, 3))
    normals[:n_near] = cross[face] / area[face, None]
    dist = point_distances(mesh.vertices, mesh.faces, points)
    w = np.asarray(igl.fast_winding_number(np.ascontiguousarray(mesh.vertices, np.float64),
                                           np.ascontiguousarray(mesh.faces, np.int64), points), np.float64)
    uncertain = np.abs(w - 0.5) < SDF_WINDING_UNCERTAIN
    if uncertain.any():
        warnings.warn(f"{mesh.name}: the sign of {int(uncertain.sum())} of {n} samples is uncertain (winding number "
                      f"within {SDF_WINDING_UNCERTAIN} of 1/2): see the 'uncertain' array", SuspiciousResultWarning,
                      stacklevel=2)
    sdf = np.where(w >= 0.5, -dist, dist)
    return {"points": points.astype(np.float32), "sdf": sdf.astype(np.float32), "normals": normals.astype(np.float32),
            "uncertain": uncertain, "scale": np.float64(scale), "center": center.astype(np.float64)}


def save_samples(samples: dict, path) -> Path:
    """Write :func:`sdf_samples`' arrays to an ``.npz`` file (its keys as they are)."""
    path = Path(path)
    if path.suffix.lower() != ".npz":
        raise GlvoxError(f"SDF samples are written as .npz, got {path}")
    np.savez_compressed(path, **samples)
    return path
