"""Atomic writes: a file with its final name is always complete, whatever kills the process.

Each file is written to a hidden temporary file in its own folder
(``.NAME.part-PID-RANDOM.SUFFIX``), flushed to disk, and renamed over the
final name with :func:`os.replace`.  A rerun deletes the temporary files a
killed run left behind (:func:`glvox.batch.safety.remove_stale_parts`).
"""

from __future__ import annotations

import os
import uuid
from pathlib import Path
from typing import Callable

from .. import io

#: What names a temporary file, after its final name.
PART = ".part-"


def temp_path(out: Path) -> Path:
    """The hidden temporary file that ``out`` is written to before the rename."""
    # same folder (os.replace is atomic only within one file system), same
    # suffix (io.save picks the format by it; numpy would append .npz otherwise)
    return out.with_name(f".{out.name}{PART}{os.getpid()}-{uuid.uuid4().hex[:8]}{out.suffix}")


def _replace_when_written(out: Path, write: Callable[[Path], None]) -> Path:
    """Call ``write(tmp)``, which must leave ``tmp`` flushed to disk, then rename ``tmp`` to ``out``."""
    tmp = temp_path(out)
    try:
        write(tmp)
        os.replace(tmp, out)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    return out


def atomic_save(result, out: str | os.PathLike) -> Path:
    """Write ``result`` with :func:`glvox.io.save` to a temporary file, then rename it to ``out``.

    The file is flushed to disk before the rename, so ``out`` either does not
    exist or is complete, whatever kills the process.  Missing folders of
    ``out`` are made.
    """
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)

    def write(tmp: Path) -> None:
        io.save(result, tmp)
        with open(tmp, "rb+") as f:
            os.fsync(f.fileno())

    return _replace_when_written(out, write)


def atomic_write_text(path: str | os.PathLike, text: str) -> Path:
    """Write ``text`` to ``path`` (no newline translation) through a temporary file and a rename."""
    def write(tmp: Path) -> None:
        with open(tmp, "w", newline="") as f:
            f.write(text)
            f.flush()
            os.fsync(f.fileno())

    return _replace_when_written(Path(path), write)
