"""A batch task that kills its own worker process, to test how a batch survives a crash.

Pass it as ``run_batch(..., task=CrashingTask("torus_0002", log))``: Dask
workers unpickle it by this module's path, so it works on a local cluster as
on a remote one whose workers have glvox installed.
"""

from __future__ import annotations

import os
import signal
from dataclasses import dataclass
from typing import Any

from ..batch import BatchSettings, Job, voxelize_one


@dataclass(frozen=True)
class CrashingTask:
    """:func:`glvox.batch.voxelize_one`, except on meshes whose path contains ``token``.

    On those the process kills itself with SIGKILL (as the out-of-memory
    killer would: no cleanup, no exception) after appending ``"REL PID"`` to
    the file ``log``, one line per attempt.

    Attributes
    ----------
    token : str
        A substring of the absolute input path of the meshes to crash on.
    log : str, optional
        Path of a text file that records each attempt; none when None.
    """

    token: str
    log: str | None = None

    def __call__(self, job: Job, settings: BatchSettings) -> dict[str, Any]:
        if self.token in job.input:
            if self.log:
                with open(self.log, "a") as f:
                    f.write(f"{job.rel} {os.getpid()}\n")
            os.kill(os.getpid(), signal.SIGKILL)
        return voxelize_one(job, settings)


__all__ = ["CrashingTask"]
