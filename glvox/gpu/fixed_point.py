"""The fixed point the parity solids decide coverage in (``shaders/common/fixed.glsl``).

ss-solid (with ss-solid-tiled, ss-octree, vote-solid and gwn-solid's crossings),
eisemann-solid and leung-wang-ldi round each vertex's two coordinates across the
rays once per run to multiples of 2^-F voxel and decide which column centers a
triangle covers in integers.  :func:`fixed_bits` picks F for a mesh and grid.
"""

from __future__ import annotations

import warnings

import numpy as np

from ..errors import LimitError, SuspiciousResultWarning

#: The most magnitude bits a fixed-point coordinate may take: every coordinate and
#: column center below 2^29 units, so their differences stay below 2^30 and
#: imulExtended's products below 2^60.
FIXED_RANGE_BITS = 29

#: Below this F the fixed point's rounding (2^-(F+1) voxel) reaches a third of TIE_EPS:
#: :func:`fixed_bits` warns.
FIXED_BITS_WARN = 14


def fixed_bits(mesh, spec, axis: int, warn: bool = True) -> int:
    """F: coverage is decided on the two coordinates across rays along grid axis
    ``axis`` rounded to multiples of 2^-F voxel, in integers.  The largest F that keeps
    every vertex and column center within 2^:data:`FIXED_RANGE_BITS` units: 18 for a
    mesh in a 1024-voxel grid (rounding by at most 2^-19 voxel), 22 at 64.  The
    vertices' reach is taken from the mesh's bounds in voxel space plus one voxel (the
    GPU's float32 rounding and the plane snap move them far less).

    Raises
    ------
    LimitError
        The mesh reaches 2^28 voxels or more from the grid's origin across the rays.

    Warns
    -----
    SuspiciousResultWarning
        With ``warn``, where F < :data:`FIXED_BITS_WARN` (the mesh reaches past 2^15
        voxels): voxels that close to the surface may differ from the reference's.
    """
    u, v = (axis + 1) % 3, (axis + 2) % 3
    vox = (np.asarray(mesh.bounds, np.float64) - np.asarray(spec.origin)) / float(spec.voxel_size)
    reach = max(float(np.abs(vox[:, [u, v]]).max()) if np.isfinite(vox).all() else np.inf,
                spec.dims[u], spec.dims[v]) + 1.0
    if not reach < 2.0 ** (FIXED_RANGE_BITS - 1):
        raise LimitError(f"the mesh reaches {reach:.3g} voxels from the grid's origin across the rays; "
                         f"the GPU solids' exact coverage takes at most 2^{FIXED_RANGE_BITS - 1}: "
                         f"use a grid nearer the mesh, or reference-solid (CPU)")
    bits = FIXED_RANGE_BITS - int(np.ceil(np.log2(reach)))
    if warn and bits < FIXED_BITS_WARN:
        warnings.warn(f"the mesh reaches {reach:.3g} voxels from the grid's origin: the GPU solids decide "
                      f"coverage on vertices rounded to 2^-{bits} voxel, so voxels within {2.0 ** -(bits + 1):.2g} "
                      f"voxel of the surface may differ from the references'", SuspiciousResultWarning, stacklevel=3)
    return bits
