"""The result types every method returns, on one base (:mod:`.base`).

=============  ==================  ===========================================
kind           type                made by
=============  ==================  ===========================================
surface/solid  :class:`VoxelGrid`  dense bit grid (every surface and solid method)
sparse         :class:`SparseOctree`  ``ss-octree``: a solid without a dense grid
ldi            :class:`LDI`        layered depth images (``*-ldi`` methods)
sdf            :class:`SDFGrid`    signed distance field (:func:`glvox.sdf`)
=============  ==================  ===========================================
"""

from .base import Result, RunInfo, read_npz
from .ldi import LDI
from .octree import SparseOctree
from .sdf import SDFGrid
from .voxels import Comparison, DeviceWords, VoxelGrid

__all__ = ["Comparison", "DeviceWords", "LDI", "Result", "RunInfo", "SDFGrid", "SparseOctree", "VoxelGrid", "read_npz"]
