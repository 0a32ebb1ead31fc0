"""A batch task that records the worker's GL environment, to test how workers are set up.

``run_batch(..., workers=K, task=WorkerEnvTask())`` voxelizes as usual and
writes ``LP_NUM_THREADS``, ``GLVOX_THREADS`` and ``GLVOX_EGL_DEVICE`` as the worker process saw
them into each row's ``warnings`` column (``"LP_NUM_THREADS=1 GLVOX_THREADS=1 GLVOX_EGL_DEVICE=0"``),
so a test (or a user checking a multi-GPU machine) can read from the manifest
which settings each worker process ran with.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from typing import Any

from ..batch import BatchSettings, Job, voxelize_one

#: The variables recorded, in this order.
RECORDED = ("LP_NUM_THREADS", "GLVOX_THREADS", "GLVOX_EGL_DEVICE")


@dataclass(frozen=True)
class WorkerEnvTask:
    """:func:`glvox.batch.voxelize_one`, with the worker's :data:`RECORDED` variables in ``warnings``."""

    def __call__(self, job: Job, settings: BatchSettings) -> dict[str, Any]:
        row = voxelize_one(job, settings)
        row["warnings"] = " ".join(f"{k}={os.environ.get(k, '')}" for k in RECORDED)
        return row


__all__ = ["RECORDED", "WorkerEnvTask"]
