"""The one runner of ``glvox compare`` and ``glvox bench``: a :class:`~glvox.study.plan.Plan`, cell by cell.

Per mesh and grid size, every contender of the plan with a cell there:

* runs once *cold* (for glvox: the first call at this size, with shader
  compilation when the method has not run in this process yet);
* then in up to ``repeat`` timed warm rounds in which the contenders take
  turns (the order rotates each round), so a burst of load from elsewhere on
  a shared machine slows all of them alike; a contender stops repeating once
  its warm runs in the cell add up to the plan's ``budget`` seconds, and not
  before :data:`~glvox.tolerances.MIN_WARM_RUNS` runs;
* its time is the median wall clock of its warm runs, beside the best, with
  a *bimodal* flag when the runs fall into two clusters
  (:data:`~glvox.tolerances.BIMODAL_RATIO` apart): for glvox, the whole
  ``run_method`` call (validation, GPU work, readback); for a peer, the one
  library call (:meth:`glvox.study.peers.Peer.run`), with the mesh already in
  the library's type; converting a peer's result to glvox's grid is
  reported apart (``convert_ms``) and not counted;
* a glvox run whose result came from a cache (``result.run.stats['cached']``:
  reference-gwn keeps the last winding fields per mesh and grid) is no
  computation's time: the row says so (``cached``: a warm run was served
  from a cache; ``cold_cached``: the cold run was), and the reports mark
  such rows and leave them out of timing plots;
* its last result is compared with its exact CPU reference on the same grid
  (:func:`glvox.metrics.agreement`: missing / extra voxels, IoU, mismatches
  that are not proven ties); references and tie sets are computed once per
  mesh and grid.

A row per cell holds the timings (median, best, spread, GPU, per stage, cold,
compile), the voxel count, the agreement, the method's statistics and the
GPU buffer bytes glvox held after its cold run.  The layers above add their
own analyses through ``analyses`` (``glvox compare``: separability) and their
own reports.
"""

from __future__ import annotations

import json
import os
import platform
import statistics
import time
import warnings
from dataclasses import dataclass, field
from typing import Any, Callable, Iterable, Sequence

import moderngl
import numpy as np

from glvox._version import __version__
from glvox.errors import GlvoxError, NotWatertightWarning, SuspiciousResultWarning
from glvox.gl.context import get_context
from glvox.gpu.buffers import gpu_bytes
from glvox.grid import GridSpec, grid_for, pack_bits, popcount
from glvox.mesh import clean_twin, load_mesh
from glvox.methods import get_method, run_method
from glvox.methods.envelope import INSIDE_KINDS
from glvox.metrics import agreement, tie_set
from glvox.results.voxels import VoxelGrid
from glvox.tolerances import BIMODAL_RATIO, MIN_WARM_RUNS

from .calibration import Calibration
from .peers import get_peer
from .plan import Contender, Plan, mesh_label

#: Errors that end a contender's cell (the row says which) rather than the run.
RUN_ERRORS = (GlvoxError, MemoryError, ValueError, RuntimeError)

#: ``analyses`` hook: ``(row, grid, references)`` after the row's agreement is
#: in; ``grid`` is the contender's last result as a VoxelGrid (None for an LDI).
Analysis = Callable[[dict, "VoxelGrid | None", "References"], None]


def machine() -> dict[str, Any]:
    """The GL renderer and the versions that produced a result."""
    import trimesh  # lazy: slow to import, only its version is wanted here

    ctx = get_context()
    return {"glvox": __version__, "python": platform.python_version(),
            "numpy": np.__version__, "moderngl": moderngl.__version__, "trimesh": trimesh.__version__,
            "platform": platform.platform(), "cpu_count": os.cpu_count(),
            "gl": {"vendor": ctx.vendor, "renderer": ctx.renderer, "version": ctx.version,
                   "backend": ctx.backend, "device": ctx.device}}


# ---------------------------------------------------------------------------
# samples of one contender, and the timing helper of the compare/ scripts
# ---------------------------------------------------------------------------


def _median_ms(values: Sequence[float]) -> float | None:
    return statistics.median(values) * 1e3 if values else None


def _spread_ms(values: Sequence[float]) -> float | None:
    return (max(values) - min(values)) * 1e3 if values else None


def bimodal(values: Sequence[float]) -> bool:
    """Two clusters of run times: sorted, two consecutive runs differ by :data:`BIMODAL_RATIO` or more."""
    s = sorted(values)
    return any(a > 0 and b / a >= BIMODAL_RATIO for a, b in zip(s, s[1:]))


def served_from_cache(result: Any) -> bool:
    """Whether a glvox result was taken from a cache rather than computed
    (``result.run.stats['cached']``, set by the methods that keep results)."""
    return bool(result.run.stats.get("cached", False))


@dataclass
class Samples:
    """The warm runs of one contender in one cell (seconds)."""

    walls: list[float] = field(default_factory=list)
    gpus: list[float] = field(default_factory=list)
    overheads: list[float] = field(default_factory=list)
    stages: dict[str, list[float]] = field(default_factory=dict)
    cached: int = 0

    def add(self, wall: float, result: Any = None) -> None:
        """One run's wall time, and the GPU and stage times of a glvox ``result``
        (and whether the result came from a cache: :func:`served_from_cache`)."""
        self.walls.append(wall)
        if result is None:
            return
        self.cached += served_from_cache(result)
        t = result.run.timings
        if t.gpu_s is not None:
            self.gpus.append(t.gpu_s)
        self.overheads.append(wall - t.wall_s)
        per_run: dict[str, float] = {}  # a stage repeated in a run (tiles, passes) counts once, summed
        for s in t.stages:
            per_run[s.name] = per_run.get(s.name, 0.0) + (s.gpu_s if s.gpu_s is not None else s.wall_s)
        for name, v in per_run.items():
            self.stages.setdefault(name, []).append(v)

    def summary(self) -> dict[str, Any]:
        """Milliseconds: median, best and spread of wall and GPU times, per-stage medians
        (GPU where timed, else wall; a stage's parts in one run summed), wall time outside
        the stages."""
        return {"runs": len(self.walls), "wall_ms": _median_ms(self.walls), "min_ms": min(self.walls) * 1e3,
                "spread_ms": _spread_ms(self.walls), "bimodal": bimodal(self.walls),
                "gpu_ms": _median_ms(self.gpus),
                "gpu_min_ms": min(self.gpus) * 1e3 if self.gpus else None, "gpu_spread_ms": _spread_ms(self.gpus),
                "overhead_ms": _median_ms(self.overheads),
                "stages_ms": {k: statistics.median(v) * 1e3 for k, v in self.stages.items()},
                "cached": self.cached > 0}


@dataclass
class Timed:
    """:func:`timed`'s answer: :meth:`Samples.summary`'s milliseconds and the last result."""

    wall_ms: float
    min_ms: float
    gpu_ms: float | None
    gpu_min_ms: float | None
    stages_ms: dict[str, float]
    result: Any


def timed(method: str, mesh, spec: GridSpec, repeat: int, **options: Any) -> Timed:
    """Warm runs of one glvox method, the timing protocol of the ``compare/`` scripts.

    One untimed run first (compilation, upload, allocation), then ``repeat``
    timed ``run_method`` calls (``options`` go to it, ``allow_open`` too).
    """
    run_method(method, mesh, spec, **options)
    samples, result = Samples(), None
    for _ in range(repeat):
        t0 = time.perf_counter()
        result = run_method(method, mesh, spec, **options)
        samples.add(time.perf_counter() - t0, result)
    s = samples.summary()
    return Timed(s["wall_ms"], s["min_ms"], s["gpu_ms"], s["gpu_min_ms"], s["stages_ms"], result)


# ---------------------------------------------------------------------------
# references of one mesh and grid
# ---------------------------------------------------------------------------


class References:
    """Exact references and their tie sets for one mesh and grid, computed once, kept packed.

    For a generated defective mesh (``gen:double-sided-torus``: :data:`glvox.mesh.DEFECTIVE`)
    the references run on its clean twin (``twin``, the same vertices closed and consistently
    wound), whose solid is the defective mesh's true one: a winding number or a parity of
    the defective mesh itself cancels to nothing there.
    """

    def __init__(self, mesh, spec: GridSpec, twin: str | None = None):
        self.twin = twin
        self.mesh, self.spec = (load_mesh(twin) if twin else mesh), spec
        self._refs: dict[tuple, np.ndarray] = {}
        self._fields: dict[tuple, dict[str, np.ndarray]] = {}
        self._ties: dict[str, np.ndarray] = {}
        self.seconds = 0.0

    def words(self, name: str, options: tuple = ()) -> np.ndarray:
        """The reference ``name`` (run with ``options``), uint32 (nz, ny, words_per_row)."""
        key = (name, options)
        if key not in self._refs:
            t0 = time.perf_counter()
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", NotWatertightWarning)
                warnings.simplefilter("ignore", SuspiciousResultWarning)  # kept in the row: stats["suspicious"]
                result = run_method(name, self.mesh, self.spec, allow_open=True, **dict(options))
            self._refs[key] = result.words()
            self._fields[key] = getattr(result, "fields", {})
            self.seconds += time.perf_counter() - t0
        return self._refs[key]

    def field(self, name: str, field: str, options: tuple = ()) -> np.ndarray:
        """A float field the reference ``name`` returns (reference-gwn's ``'winding'``),
        (nx, ny, nz) float32."""
        self.words(name, options)
        return self._fields[(name, options)][field]

    def ties(self, name: str, options: tuple = ()) -> np.ndarray:
        """The tie set of the reference ``name`` (run with ``options``), packed like :meth:`words`."""
        key = (name, options)
        if key not in self._ties:
            t0 = time.perf_counter()
            self._ties[key] = pack_bits(tie_set(name, self.mesh, self.spec, **dict(options)))
            self.seconds += time.perf_counter() - t0
        return self._ties[key]


def reference_of(c: Contender, mesh) -> tuple[str | None, tuple]:
    """The reference a contender is checked against, with the options that make it comparable.

    On an open mesh, parity of crossings depends on the ray direction: a solid
    method with an ``axis`` option is compared with ``reference-solid`` along
    the same axis (on a closed mesh every axis gives the same solid).
    """
    if c.is_peer:
        return get_peer(c.peer).reference, ()
    info = get_method(get_method(c.method).resolve(mesh)).info  # an alias: the method it runs
    if info.reference == "reference-solid" and not mesh.watertight and "axis" in info.options:
        axis = dict(c.options).get("axis", info.options["axis"].default)
        return info.reference, (("axis", int(axis)),)
    if info.reference == "reference-gwn":
        # the reference's own options (threshold, shell) as the contender sets them
        ref = get_method(info.reference).info.options
        opts = {k: v.default for k, v in ref.items()}
        opts.update({k: v for k, v in dict(c.options).items() if k in ref})
        if opts != {k: v.default for k, v in ref.items()}:
            return info.reference, tuple(sorted(opts.items()))
        return info.reference, ()
    # other options the reference shares define the same thing there (carve's close)
    ref_options = get_method(info.reference).info.options
    return info.reference, tuple((k, v) for k, v in c.options if k in ref_options and k != "axis")


# ---------------------------------------------------------------------------
# one contender in one cell
# ---------------------------------------------------------------------------


class _Contestant:
    """Runs one contender on one mesh and grid and keeps its samples and last result."""

    def __init__(self, c: Contender, mesh, spec: GridSpec, ctx):
        self.c, self.mesh, self.spec, self.ctx = c, mesh, spec, ctx
        self.samples = Samples()
        self.last: Any = None
        self.cold_s = self.compile_s = self.prep_s = 0.0
        self.cold_cached = False
        self.gpu_bytes: int | None = None
        self.error: str | None = None
        self.calib = Calibration(ctx) if c.is_calibration else None
        self.peer = get_peer(c.peer) if c.is_peer else None
        if self.peer is not None:
            t0 = time.perf_counter()
            self.prepared = self.peer.prepare(mesh, spec)
            self.prep_s = time.perf_counter() - t0

    def once(self) -> float:
        """One run; its wall time in seconds."""
        if self.calib is not None:
            t0 = time.perf_counter()
            self.calib.run()
            return time.perf_counter() - t0
        if self.peer is not None:
            t0 = time.perf_counter()
            self.last = self.peer.run(self.prepared)
            return time.perf_counter() - t0
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", NotWatertightWarning)
            warnings.simplefilter("ignore", SuspiciousResultWarning)  # kept in the row: stats["suspicious"]
            t0 = time.perf_counter()
            self.last = run_method(self.c.method, self.mesh, self.spec, ctx=self.ctx, allow_open=True,
                                   **dict(self.c.options))
            return time.perf_counter() - t0

    @property
    def is_method(self) -> bool:
        return self.peer is None and self.calib is None

    def cold(self) -> None:
        try:
            self.cold_s = self.once()
        except RUN_ERRORS as exc:
            self.error = f"{type(exc).__name__}: {exc}"
            return
        if self.is_method:
            self.cold_cached = served_from_cache(self.last)
            self.compile_s = self.last.run.timings.compile_s
            self.gpu_bytes = gpu_bytes(self.ctx) if get_method(self.c.method).info.uses_gl else 0

    def warm(self) -> None:
        try:
            wall = self.once()
        except RUN_ERRORS as exc:
            self.error = f"{type(exc).__name__}: {exc}"
            return
        self.samples.add(wall, self.last if self.is_method else None)

    def release(self) -> None:
        """Free the calibration's buffer, or the method's pools of this size before the next size."""
        if self.calib is not None:
            self.calib.release()
        elif self.is_method:
            get_method(self.c.method).release(self.ctx)


def _rounds(plan: Plan, runners: Sequence[_Contestant]) -> None:
    """The interleaved timed rounds (see the module docstring)."""
    active = [r for r in runners if r.error is None]
    for rnd in range(plan.repeat):
        if not active:
            return
        k = rnd % len(active)
        for r in active[k:] + active[:k]:
            r.warm()
        active = [r for r in active if r.error is None
                  and (plan.budget is None or len(r.samples.walls) < MIN_WARM_RUNS
                       or sum(r.samples.walls) < plan.budget)]


# ---------------------------------------------------------------------------
# rows
# ---------------------------------------------------------------------------


def _base_row(c: Contender, mesh, name: str, n: int, spec: GridSpec) -> dict[str, Any]:
    row: dict[str, Any] = {"key": c.key, "group": c.group, "peer": c.is_peer,
                           "method": c.method or c.peer or c.key, "options": dict(c.options)}
    if c.method is not None:
        info = get_method(c.method).info
        row.update(kind=info.kind, family=info.family, pipeline=info.pipeline, exact=info.exact)
    elif c.is_peer:
        row.update(kind=get_peer(c.peer).kind, family="peer", pipeline="peer", exact=None)
    row.update(mesh=name, triangles=mesh.n_triangles, watertight=mesh.watertight, n=n, dims=list(spec.dims),
               status="ok", error=None)
    return row


def _not_run(plan: Plan, c: Contender, mesh, n: int) -> str | None:
    """Why a contender gives a skipped row on this mesh at this size, or None."""
    if c.is_peer:
        limit = plan.peer_limit(c.peer)
        if limit is not None and n > limit:
            return (f"N = {n} over this peer's limit {limit} (--peer-max {c.peer}=N runs it; see "
                    "glvox/study/peers.py for why)")
    elif c.method is not None and not plan.open_solids and not mesh.watertight \
            and get_method(c.method).info.kind in INSIDE_KINDS and not get_method(c.method).info.any_mesh:
        return "mesh not watertight: inside is undefined for a solid method"
    return None


def _jsonable(v) -> bool:
    try:
        json.dumps(v)
        return True
    except TypeError:
        return False


def _result_grid(r: _Contestant, row: dict[str, Any]) -> VoxelGrid | None:
    """The contender's last result as a VoxelGrid (None for an LDI), with the row's
    method fields (compile, stats, GPU bytes) or peer fields (convert, outside)."""
    if r.is_method:
        info = get_method(r.c.method).info
        row.update(compile_ms=r.compile_s * 1e3, gpu_bytes=r.gpu_bytes,
                   stats={k: v for k, v in r.last.run.stats.items() if _jsonable(v)})
        if info.kind == "ldi":  # an LDI has its own checks (conservativeness), not a grid's
            return None
        return r.last if isinstance(r.last, VoxelGrid) else r.last.to_grid()
    t0 = time.perf_counter()
    pg = r.peer.to_grid(r.last, r.spec)
    row.update(convert_ms=(time.perf_counter() - t0) * 1e3, prepare_ms=r.prep_s * 1e3, outside=pg.outside,
               call=r.peer.call)
    if pg.stats:
        row["peer_stats"] = dict(pg.stats)
    return pg.grid


def _finish_row(plan: Plan, row: dict[str, Any], r: _Contestant, refs: References,
                analyses: Sequence[Analysis], progress: Callable[[str], None]) -> None:
    """Timings, voxel count, agreement and the layers' analyses of one contender."""
    if r.error is not None:
        row.update(status="error", error=r.error)
        return
    row.update(r.samples.summary(), cold_ms=r.cold_s * 1e3, cold_cached=r.cold_cached)
    if r.calib is not None:
        return
    grid = _result_grid(r, row)
    r.last = None  # large results go as soon as they are counted
    if grid is None:
        return
    words = grid.words()
    row["voxels"] = popcount(words)
    ref, ref_opts = (plan.reference, ()) if plan.reference else reference_of(r.c, r.mesh)
    if ref is not None and plan.checks(row["n"]):
        progress(f"{row['mesh']} {row['n']}^3: checking {r.c.label} against {ref}")
        row["reference"] = ref + (f"[{','.join(f'{k}={v}' for k, v in ref_opts)}]" if ref_opts else "")
        row["reference_mesh"] = refs.twin or row["mesh"]
        ties = refs.ties(ref, ref_opts) if get_method(ref).has_ties else None
        row.update(agreement(words, refs.words(ref, ref_opts), ties))
    for analyse in analyses:
        analyse(row, grid, refs)


def run_cell(plan: Plan, mesh, mesh_path: str, n: int, contenders: Sequence[Contender], ctx,
             progress: Callable[[str], None] = lambda s: None,
             analyses: Sequence[Analysis] = ()) -> list[dict[str, Any]]:
    """``contenders`` on ``mesh`` at N = ``n``: one row each, in their order."""
    spec = grid_for(mesh, n)
    name = mesh_label(mesh_path)
    rows: list[dict[str, Any]] = []
    runners: dict[str, _Contestant] = {}
    for c in contenders:
        row = _base_row(c, mesh, name, n, spec)
        rows.append(row)
        why = _not_run(plan, c, mesh, n)
        if why is not None:
            row.update(status="skipped", error=why)
            continue
        try:
            runners[c.key] = _Contestant(c, mesh, spec, ctx)
        except RUN_ERRORS as exc:
            row.update(status="error", error=f"{type(exc).__name__}: {exc}")
    for r in runners.values():
        progress(f"{name} {n}^3: first run of {r.c.label}")
        r.cold()
    progress(f"{name} {n}^3: timed runs of {len(runners)} contenders")
    _rounds(plan, list(runners.values()))
    refs = References(mesh, spec, clean_twin(mesh_path))
    for row in rows:
        if row["key"] in runners and row["status"] == "ok":
            _finish_row(plan, row, runners[row["key"]], refs, analyses, progress)
    for r in runners.values():
        r.release()
    for row in rows:
        row["reference_s"] = refs.seconds
    return rows


def run_plan(plan: Plan, *, done: Iterable[str] = (), on_rows: Callable[[list[dict]], None] | None = None,
             log: Callable[[str], None] = lambda s: None, progress: Callable[[str], None] = lambda s: None,
             analyses: Sequence[Analysis] = ()) -> list[dict[str, Any]]:
    """Every cell of ``plan`` whose key is not in ``done``; the new rows in plan order.

    Parameters
    ----------
    done : iterable of str
        Cell keys (:attr:`glvox.study.plan.Cell.key`) already measured: not run again.
    on_rows : callable, optional
        Called with the rows of each mesh and size as soon as they are complete.
    log, progress : callable
        One-line messages: notes about the meshes, and each step as it starts.
    analyses : sequence of callable
        Per row, after its agreement (see :data:`Analysis`).
    """
    done = set(done)
    todo: dict[str, dict[int, list[Contender]]] = {}
    for cell in plan.cells():
        if cell.key not in done:
            todo.setdefault(cell.mesh, {}).setdefault(cell.n, []).append(cell.contender)
    ctx = get_context()
    rows: list[dict[str, Any]] = []
    for mesh_path, by_size in todo.items():
        mesh = load_mesh(mesh_path)
        if not mesh.watertight and plan.open_solids:
            log(f"{mesh_label(mesh_path)} is not watertight: glvox's solid methods run with allow_open=True "
                f"(parity of crossings) and are checked against reference-solid along their own axis; the "
                f"solid peers apply their own rules for holes")
        for n, contenders in by_size.items():
            new = run_cell(plan, mesh, mesh_path, n, contenders, ctx, progress, analyses)
            if on_rows is not None:
                on_rows(new)
            rows += new
    return rows
