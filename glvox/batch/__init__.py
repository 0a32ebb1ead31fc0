"""Dataset-scale batch voxelization: ``glvox batch``.

Every mesh of a folder (searched recursively by suffix) or of a text file
listing mesh paths is voxelized with the same method and grid options, and
written under an output folder that mirrors the input tree::

    glvox batch shapenet/ -o voxels/ -r 128 -m ss-solid --format binvox --workers 2

Each mesh goes through exactly what ``glvox voxelize MESH -r N -m METHOD -o
OUT`` does (:func:`glvox.mesh.load_mesh`, :func:`glvox.grid.grid_for`,
:func:`glvox.methods.run_method`, :func:`glvox.io.save`), so a batch output
holds the same occupancy, origin, voxel size, method and kind as the
single-file command's (binvox files are byte-identical).

Execution
---------
With ``workers=K`` (default 1) the meshes go to K local worker processes
(:mod:`glvox.batch.pool`: started from a forkserver that has imported glvox,
several small meshes per message, one row back per mesh), each with its own
GL context and compiled programs for the whole batch, llvmpipe's threads
divided among them (``LP_NUM_THREADS``, and glvox's own host threads,
``GLVOX_THREADS``) and, with ``egl_devices``, one EGL
device each.  With ``scheduler`` the batch runs on that existing Dask
cluster instead (its workers need glvox installed and the input and output
folders at the same paths); inside a Dask worker every GL call runs on one
dedicated thread, the one that made the context current.  ``workers=0``
runs in the calling process: no start-up cost, but no crash isolation.

Resume and safety
-----------------
Outputs are written to a hidden temporary file in their folder
(``.NAME.part-PID-RANDOM.SUFFIX``) and renamed over the final name
(:func:`os.replace`), so a file with the final name is always complete.  A
rerun skips meshes whose output exists (unless ``overwrite``), and deletes
the temporary files a killed run left behind.  The manifest (CSV, one row per
mesh, :data:`MANIFEST_COLUMNS`) is rewritten atomically at start, every few
seconds and at the end; a rerun refuses to mix outputs of different settings
(method, grid, options) in one folder.  A lock file keeps two batches from
writing into the same output folder at once.

Failures
--------
A mesh that cannot be voxelized (unreadable, empty, NaN vertices, open for a
solid method, ...) is recorded as ``failed`` with the glvox error class as the
reason (``MeshLoadError``, ``EmptyMeshError``, ``NonFiniteVertexError``,
``FaceIndexError``, ``NotWatertightError``, ...) and the error message, and
the batch goes on.  A mesh whose worker process dies (segfault, out of
memory) is retried once on a fresh worker and then recorded with the reason
``WorkerCrashed`` (with local workers; an external scheduler applies its own
``distributed.scheduler.allowed-failures``).

Another task than :func:`voxelize_one` can handle each mesh
(``run_batch(..., task=...)``); the tests use one that crashes its worker
(:mod:`glvox.testing.crash`).

Modules
-------
``jobs``      BatchSettings, Job; finding the meshes and planning their outputs
``worker``    one mesh: :func:`voxelize_one`, the GL thread, the Dask task
``atomic``    writes through a temporary file and a rename
``manifest``  the CSV manifest and the summary
``safety``    the output-folder lock, stale temporary files, held signals
``pool``      the local worker processes (chunks, threads and devices per worker, crash retry)
``cluster``   the Dask runner (an existing scheduler, crash retry)
``run``       :func:`run_batch`: resume, run in this process, in local workers or on Dask, keep the manifest

The progress bar is the package's one reporter, :class:`glvox.progress.Progress`.
"""

from __future__ import annotations

from ..progress import LOG_INTERVAL_S, Progress
from .atomic import atomic_save
from .cluster import WORKER_CRASHED
from .jobs import SAVED_KINDS, BatchSettings, Job, find_meshes, mesh_suffixes, plan_jobs
from .manifest import MANIFEST_COLUMNS, BatchSummary, read_manifest, write_manifest
from .run import MANIFEST_INTERVAL_S, run_batch
from .safety import LOCK_NAME
from .worker import Task, dask_task, voxelize_one

__all__ = ["BatchSettings", "BatchSummary", "Job", "LOCK_NAME", "LOG_INTERVAL_S", "MANIFEST_COLUMNS",
           "MANIFEST_INTERVAL_S", "Progress", "SAVED_KINDS", "Task", "WORKER_CRASHED", "atomic_save",
           "dask_task", "find_meshes", "mesh_suffixes", "plan_jobs", "read_manifest", "run_batch",
           "voxelize_one", "write_manifest"]
