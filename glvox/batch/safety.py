"""What keeps a batch safe to interrupt and to rerun: the output lock, stale parts, held signals."""

from __future__ import annotations

import contextlib
import os
import signal
import threading
from pathlib import Path
from typing import Sequence

from ..errors import GlvoxError
from .atomic import PART
from .jobs import Job

try:
    import fcntl
except ImportError:  # not POSIX: the output folder is not locked
    fcntl = None

#: The lock file in the output folder.
LOCK_NAME = ".glvox-batch.lock"


class OutputLock:
    """An exclusive lock on the output folder, released when the process ends however it ends."""

    def __init__(self, out: Path):
        self.path = out / LOCK_NAME
        self.f = None

    def __enter__(self):
        if fcntl is None:
            return self
        self.f = open(self.path, "a+")
        try:
            fcntl.flock(self.f.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            self.f.close()
            self.f = None
            raise GlvoxError(f"another glvox batch is writing into {self.path.parent} "
                             f"(it holds {self.path}); wait for it or use another output folder") from None
        return self

    def __exit__(self, *exc):
        if self.f is not None:
            self.f.close()
            self.f = None


def remove_stale_parts(jobs: Sequence[Job], out: Path, manifest: Path) -> int:
    """Delete the temporary files a killed run left: outputs in the output
    folders, and the manifest's own in its folder."""
    n = 0
    folders = {Path(j.output).parent for j in jobs} | {out}
    for folder in sorted(folders | {manifest.parent}):
        if not folder.is_dir():
            continue
        ours = folder in folders
        for entry in os.scandir(folder):
            name = entry.name
            if (name.startswith(f".{manifest.name}{PART}") if not ours
                    else name.startswith(".") and PART in name) and entry.is_file():
                os.unlink(entry.path)
                n += 1
    return n


@contextlib.contextmanager
def signals_held():
    """Hold SIGINT and SIGTERM through a step that must not be cut in two, and act on them right after.

    Used around whatever an interrupt must not cut in two: a LocalCluster
    interrupted half-way through its start cannot be closed (distributed
    prints a traceback at exit); imports and mesh loaders that catch
    BaseException would swallow the interrupt or record it as a bad mesh.  A
    second signal interrupts at once.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    got: list[int] = []

    def hold(signum, frame):
        if got:
            raise KeyboardInterrupt
        got.append(signum)

    previous = {s: signal.signal(s, hold) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield
    finally:
        for s, h in previous.items():
            signal.signal(s, h)
    if got:
        raise KeyboardInterrupt
