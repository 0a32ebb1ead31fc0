"""Per-stage timings: wall clock always, GPU time from timer queries.

A method wraps each stage in ``with timer.stage("name"):``.  On a GPU stage
the timer brackets the commands with two ``GL_TIMESTAMP`` queries and waits
for the GPU at the end of the stage, so the wall time of the stage includes
the GPU work it issued (stages are coarse; the one sync per stage is the price
of honest wall times).  Stages do not nest.

``GLVOX_STAGE_SYNC=0`` (or :func:`stage_sync`) leaves the waits out: each stage
takes its own pair of queries, read once the run ends, so its GPU time stays
right but its wall time is only the time spent issuing its commands (the wait
for the GPU moves to whatever reads a result), and the CPU issues the next
stage while the GPU runs the last.  That is how much the syncs cost a call,
measured with ``compare/bench_sync.py``.  Each timestamp is followed by a
``glFlush``, which waits for nothing: llvmpipe takes a timestamp only when its
scene is flushed.
"""

from __future__ import annotations

import contextlib
import os
import time
from dataclasses import dataclass, field
from typing import Any, Iterator


_forced_sync: list[bool] = []


@contextlib.contextmanager
def stage_sync(on: bool) -> Iterator[None]:
    """Inside the block, new :class:`StageTimer` s wait for the GPU per stage (``on``)
    or not, whatever ``GLVOX_STAGE_SYNC`` says."""
    _forced_sync.append(bool(on))
    try:
        yield
    finally:
        _forced_sync.pop()


def stage_sync_default() -> bool:
    """Whether stages wait for the GPU: :func:`stage_sync`'s, else ``GLVOX_STAGE_SYNC``
    (default 1: they do)."""
    if _forced_sync:
        return _forced_sync[-1]
    return os.environ.get("GLVOX_STAGE_SYNC", "1").strip() != "0"


@dataclass
class Stage:
    name: str
    wall_s: float
    gpu_s: float | None = None


@dataclass
class Timings:
    """Stages of one run, in order.

    Attributes
    ----------
    stages : list of Stage
    cold : bool
        True when the run compiled shaders (the first run of a method in a
        context); ``compile_s`` is the time spent compiling.
    """

    stages: list[Stage] = field(default_factory=list)
    cold: bool = False
    compile_s: float = 0.0

    @property
    def wall_s(self) -> float:
        return sum(s.wall_s for s in self.stages)

    @property
    def gpu_s(self) -> float | None:
        vals = [s.gpu_s for s in self.stages if s.gpu_s is not None]
        return sum(vals) if vals else None

    def stage(self, name: str) -> Stage:
        for s in self.stages:
            if s.name == name:
                return s
        raise KeyError(f"no stage {name!r}; stages are {[s.name for s in self.stages]}")

    def to_dict(self) -> dict[str, Any]:
        return {
            "cold": self.cold,
            "compile_s": self.compile_s,
            "wall_s": self.wall_s,
            "gpu_s": self.gpu_s,
            "stages": [{"name": s.name, "wall_s": s.wall_s, "gpu_s": s.gpu_s} for s in self.stages],
        }

    def summary(self) -> str:
        parts = []
        for s in self.stages:
            g = f", gpu {s.gpu_s * 1e3:.2f} ms" if s.gpu_s is not None else ""
            parts.append(f"{s.name} {s.wall_s * 1e3:.2f} ms{g}")
        head = f"cold (compile {self.compile_s * 1e3:.1f} ms): " if self.cold else ""
        return head + "; ".join(parts)


class StageTimer:
    """Records :class:`Stage` entries into a :class:`Timings`.

    Parameters
    ----------
    ctx : GLContext or None
        With a context, stages marked ``gpu=True`` are timed by a timer query.
    debug : bool
        Check ``glGetError`` after every stage and raise GLError naming the
        method and the stage (``GLVOX_DEBUG=1`` turns this on).
    method : str
        For error messages.
    progress : callable, optional
        ``progress(done, total)`` after each slab of a grid worked in slabs (:meth:`slab_done`).
    sync : bool, optional
        Wait for the GPU at the end of each stage (the module's docstring); default
        :func:`stage_sync_default`.
    """

    def __init__(self, ctx=None, *, debug: bool = False, method: str = "", progress=None,
                 sync: bool | None = None):
        self.ctx = ctx
        self.debug = debug
        self.method = method
        #: ``progress(done, total)``: called by methods that work a grid in slabs, after each
        #: slab (``glvox voxelize`` shows it for long runs); None ignores them
        self.progress = progress
        self.timings = Timings()
        #: statistics a method reports beside its result (counts, case shares)
        self.stats: dict[str, Any] = {}
        self._compile0 = ctx.compile_seconds if ctx is not None else 0.0
        self.sync = stage_sync_default() if sync is None else bool(sync)
        # GPU stages whose times are not read yet (an unsynced timer's, until the end)
        self._pending: list[tuple[Stage, tuple[int, int]]] = []

    @contextlib.contextmanager
    def stage(self, name: str, gpu: bool = True) -> Iterator[None]:
        pair = self.ctx.take_query_pair() if gpu and self.ctx is not None else None
        t0 = time.perf_counter()
        if pair is not None:
            self.ctx.raw.timestamp(pair[0])
            self._settle()
        try:
            yield
        except BaseException:
            if pair is not None:
                self.ctx.give_query_pair(pair)
            raise
        stage = Stage(name, 0.0, None)
        if pair is not None:
            self.ctx.raw.timestamp(pair[1])
            self._settle()
            self._pending.append((stage, pair))
        stage.wall_s = time.perf_counter() - t0
        self.timings.stages.append(stage)
        if self.sync:
            self._resolve()
        if self.debug and self.ctx is not None:
            self.ctx.check_error(f"method {self.method!r}, stage {name!r}")

    def _settle(self) -> None:
        """After a timestamp: wait for the GPU (a synced timer), else only flush.
        llvmpipe records a timestamp issued while a framebuffer is bound when its
        deferred scene is flushed, so without either the start of a compute-only
        stage would be stamped after its work (seen once a raster method had bound
        one: compute stages then measured ~0 ms).  A flush waits for nothing, and a
        GPU's driver submits what it has."""
        if self.sync:
            self.ctx.mgl.finish()
        else:
            self.ctx.raw.flush()

    def slab_done(self, done: int, total: int) -> None:
        """Slab ``done`` of ``total`` is voxelized (a grid worked in z slabs)."""
        if self.progress is not None and total > 1:
            self.progress(done, total)

    def _resolve(self) -> None:
        """Read the GPU times of the stages not read yet (waits for the GPU) and give
        their queries back to the context."""
        raw = self.ctx.raw if self.ctx is not None else None
        for stage, pair in self._pending:
            stage.gpu_s = (raw.query_result_ns(pair[1]) - raw.query_result_ns(pair[0])) * 1e-9
            self.ctx.give_query_pair(pair)
        self._pending.clear()

    def merge_repeats(self) -> None:
        """Sum the stages that share a name into one, in the order of their first run
        (a method that runs its passes several times: ss-conservative slab by slab)."""
        self._resolve()
        merged: dict[str, Stage] = {}
        for s in self.timings.stages:
            m = merged.get(s.name)
            gpu = None if m is not None and (m.gpu_s is None or s.gpu_s is None) else \
                (s.gpu_s if m is None else m.gpu_s + s.gpu_s)
            merged[s.name] = Stage(s.name, s.wall_s + (m.wall_s if m else 0.0), gpu)
        self.timings.stages[:] = list(merged.values())

    def finish(self) -> Timings:
        self._resolve()
        if self.ctx is not None:
            self.timings.compile_s = self.ctx.compile_seconds - self._compile0
            self.timings.cold = self.timings.compile_s > 0
        return self.timings
