"""``glvox bench``: glvox against the voxelizers people use today, side by side.

    glvox bench --preset quick                     # the ratio table in a few minutes
    glvox bench --preset full -o results/bench     # bunny and dragon, 128^3 to 1024^3
    glvox bench --preset quick --check             # no-regression check against bench_baseline.json
    glvox bench --preset quick --save-baseline     # refresh compare/bench_baseline.json
    glvox bench --preset quick --against HEAD~1    # side by side with an earlier revision (:mod:`.ab`)

Every glvox GPU method and every installed peer (:mod:`.peers`) run in one
process on the same mesh and the same grid.  Per cell (mesh, N):

* each contender runs once *cold* (for glvox: the first call at this size,
  with shader compilation when the method has not run in this process yet);
* then up to ``repeat`` timed warm rounds in which the contenders take turns
  (the order rotates each round), so a burst of load from elsewhere on a
  shared machine slows all of them alike; a contender stops repeating once
  its warm runs in the cell add up to ``budget`` seconds (at least one run);
* the time of a contender is the median wall clock of its warm runs: for
  glvox, the whole ``run_method`` call (validation, GPU work, readback into a
  packed grid in host memory); for a peer, the one library call
  (:meth:`.peers.Peer.run`), with the mesh already in the library's type, as
  glvox's mesh is already on the GPU; converting a peer's result to glvox's
  grid is reported apart ("convert") and not counted;
* the last result of each contender is compared with glvox's exact CPU
  reference on the same grid (missing / extra voxels, IoU, and the
  mismatches that are not proven ties, ``glvox.metrics``).

The ratio of a glvox method is its median over the median of the fastest
peer of its kind (surface: Open3D, trimesh; solid: trimesh fill, PyVista,
libigl; glvox's sparse ss-octree counts as solid): below 1 is faster.
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import time
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Sequence

import numpy as np

import glvox
from glvox.errors import GlvoxError, NotWatertightWarning
from glvox.tolerances import REGRESSION_TOLERANCE

from . import harness
from .peers import PEERS, Peer, get_peer

#: Kinds a glvox method is benchmarked under (ss-octree's sparse solid decodes
#: to the same voxels as a dense solid, so it races the solid peers).
GROUP = {"surface": "surface", "solid": "solid", "sparse": "solid"}

#: Variants benchmarked beside a method's default (their own rows).
VARIANTS: dict[str, list[dict[str, Any]]] = {
    "ss-conservative": [{"variant": "simple"}, {"variant": "sorted"}],
}

#: Presets.  ``fallback``: a generated mesh used in place of a shared mesh that
#: is not on this machine (a clean install has no shared meshes), so the
#: quick preset always runs.
PRESETS: dict[str, dict[str, Any]] = {
    "quick": {"meshes": ["stanford_bunny_bun_zipper.ply", "stanford_armadillo_libigl_86k.obj"],
              "fallback": {"stanford_bunny_bun_zipper.ply": "gen:bunny-like",
                           "stanford_armadillo_libigl_86k.obj": "gen:torus"},
              "sizes": [64, 128], "repeat": 5, "budget": 3.0},
    "full": {"meshes": ["stanford_bunny_bun_zipper.ply", "stanford_dragon_vrip_res2.ply"],
             "fallback": {},
             "sizes": [128, 256, 512, 1024], "repeat": 5, "budget": 10.0},
}


#: Timed runs per side and cell of ``--against`` (the sides take turns).
AB_REPEAT = 10

#: The baseline of the quick preset, beside this module (compare/ in a checkout).
BASELINE = Path(__file__).resolve().parents[2] / "compare" / "bench_baseline.json"

#: Published figures for scale (not measured here): cuda_voxelizer, Schwarz &
#: Seidel conservative surface voxelization of the Stanford bunny (~70k
#: triangles), as quoted in glvox issue 9.
PUBLISHED = {
    "source": "cuda_voxelizer (Schwarz & Seidel conservative surface, Stanford bunny, ~70k triangles)",
    "cpu": {"hardware": "i7-8750H, 12 threads", "ms": {256: 118, 512: 309, 1024: 1048}},
    "gpu": {"hardware": "GTX 1050 Ti", "ms": {256: 0.6, 512: 1.8, 1024: 8.6}},
}


@dataclass(frozen=True)
class Contender:
    """A glvox method (with options) or a peer, as one row of a cell."""

    key: str
    group: str
    method: str | None = None
    options: tuple[tuple[str, Any], ...] = ()
    peer: str | None = None

    @property
    def is_peer(self) -> bool:
        return self.peer is not None

    @property
    def is_calibration(self) -> bool:
        return self.group == CALIBRATION


#: Group and key of the calibration pseudo-contender (see :class:`_Calibration`).
CALIBRATION = "calibration"
CALIBRATION_KEY = "calibration:gl-busy"

#: The calibration workload: ``shaders/testing/busy.comp`` (a fixed chain of
#: sines per invocation) over this many work groups of 64, this many iterations
#: each: about 17 ms on a quiet 2-core llvmpipe, well under the loop budget.
CALIBRATION_GROUPS, CALIBRATION_ITERATIONS = 128, 1000


class _Calibration:
    """A fixed compute workload on the benchmark's GL context, timed in every
    round beside the contenders.

    Other work on a shared machine slows llvmpipe's threads far more than it
    slows a single-threaded peer, so the peers alone misjudge how busy the
    GL device was; the ratio of this workload's best time now to its best
    time in the baseline is the machine factor of the regression check.
    """

    def __init__(self, ctx):
        from glvox.gl.shaders import compute_program

        self.ctx = ctx
        self.prog = compute_program(ctx, "testing/busy.comp")
        self.buf = ctx.mgl.buffer(reserve=CALIBRATION_GROUPS * 64 * 4)

    def run(self) -> None:
        self.ctx.make_current()
        self.buf.bind_to_storage_buffer(0)
        self.prog["u_iterations"].value = CALIBRATION_ITERATIONS
        self.prog.run(CALIBRATION_GROUPS)
        self.ctx.mgl.finish()

    def release(self) -> None:
        self.buf.release()


def glvox_contenders(methods: Sequence[str] | None = None, variants: bool = True) -> list[Contender]:
    """The glvox GPU methods of kinds surface, solid and sparse (all registered ones
    when ``methods`` is None), each default plus the :data:`VARIANTS` beside it."""
    from glvox.methods import get_method, method_names

    names = list(methods) if methods else method_names()
    out = []
    for name in names:
        info = get_method(name).info  # unknown names: one error listing the known ones
        if info.kind not in GROUP or (methods is None and not info.uses_gl):
            continue
        out.append(Contender(name, GROUP[info.kind], method=name))
        for opts in (VARIANTS.get(name, []) if variants else []):
            items = tuple(sorted(opts.items()))
            label = ",".join(f"{k}={v}" for k, v in items)
            out.append(Contender(f"{name}[{label}]", GROUP[info.kind], method=name, options=items))
    return out


def peer_contenders(names: Sequence[str] | None, log: Callable[[str], None]) -> list[Contender]:
    """The installed peers among ``names`` (all when None); a line per missing one."""
    out = []
    for name in (names if names is not None else list(PEERS)):
        p = get_peer(name)
        why = p.missing()
        if why:
            log(why)
            continue
        out.append(Contender(f"peer:{p.name}", p.kind, peer=p.name))
    return out


@dataclass
class Plan:
    """What to run: contenders x meshes x sizes, and how."""

    meshes: Sequence[str]
    sizes: Sequence[int]
    contenders: Sequence[Contender]
    repeat: int = 5
    budget: float = 10.0
    check_max: int | None = None
    peer_max: dict[str, int | None] = field(default_factory=dict)

    def peer_limit(self, name: str) -> int | None:
        return self.peer_max.get(name, get_peer(name).max_n)


# ---------------------------------------------------------------------------
# agreement with the references, on packed words
# ---------------------------------------------------------------------------


def _popcount(words: np.ndarray) -> int:
    return int(np.bitwise_count(words).sum(dtype=np.int64))


def agreement(words: np.ndarray, ref_words: np.ndarray, tie_words: np.ndarray | None) -> dict[str, Any]:
    """Missing / extra voxels, IoU and mismatches outside the tie set, from packed grids.

    Parameters
    ----------
    words, ref_words : uint32 (nz, ny, words_per_row)
        A result and its reference in glvox's packed layout (same GridSpec).
    tie_words : uint32, same shape, or None
        The reference's proven tie set, packed; None to skip that count.
    """
    w = np.asarray(words, np.uint32)
    r = np.asarray(ref_words, np.uint32)
    inter, union = _popcount(w & r), _popcount(w | r)
    out = {"missing": _popcount(r & ~w), "extra": _popcount(w & ~r),
           "iou": 1.0 if union == 0 else inter / union, "reference_voxels": _popcount(r)}
    if tie_words is not None:
        out["not_ties"] = _popcount((w ^ r) & ~np.asarray(tie_words, np.uint32))
        out["ties"] = _popcount(tie_words)
    return out


class References:
    """Exact references and their tie sets for one mesh and grid, computed once, kept packed."""

    def __init__(self, mesh, spec):
        self.mesh, self.spec = mesh, spec
        self._refs: dict[tuple, np.ndarray] = {}
        self._ties: dict[str, np.ndarray] = {}
        self.seconds = 0.0

    def words(self, name: str, options: tuple = ()) -> np.ndarray:
        from glvox.methods import run_method

        key = (name, options)
        if key not in self._refs:
            t0 = time.perf_counter()
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", NotWatertightWarning)
                self._refs[key] = run_method(name, self.mesh, self.spec, allow_open=True,
                                             **dict(options)).words()
            self.seconds += time.perf_counter() - t0
        return self._refs[key]

    def ties(self, name: str) -> np.ndarray:
        from glvox.grid import pack_bits
        from glvox.metrics import tie_set

        if name not in self._ties:
            t0 = time.perf_counter()
            self._ties[name] = pack_bits(tie_set(name, self.mesh, self.spec))
            self.seconds += time.perf_counter() - t0
        return self._ties[name]


def _reference_of(c: Contender, mesh) -> tuple[str | None, tuple]:
    """The reference a contender is checked against, with the options that make it comparable.

    On an open mesh, parity of crossings depends on the ray direction: a solid
    method with an ``axis`` option is compared with ``reference-solid`` along
    the same axis (on a closed mesh every axis gives the same solid).
    """
    if c.is_peer:
        return get_peer(c.peer).reference, ()
    from glvox.methods import get_method

    info = get_method(c.method).info
    ref = info.reference
    if ref is None and info.kind == "sparse":
        ref = "reference-solid"
    opts = dict(c.options)
    if ref == "reference-solid" and not mesh.watertight and "axis" in info.options:
        axis = opts.get("axis", info.options["axis"].default)
        return ref, (("axis", int(axis)),)
    return ref, ()


# ---------------------------------------------------------------------------
# one cell: every contender on one mesh and grid
# ---------------------------------------------------------------------------


def _words_of(result) -> np.ndarray:
    if hasattr(result, "words"):
        return result.words()
    return result.to_grid().words()  # sparse results (ss-octree)


class _Runner:
    """Runs one contender on one cell and keeps its samples."""

    def __init__(self, c: Contender, mesh, spec, ctx):
        self.c, self.mesh, self.spec, self.ctx = c, mesh, spec, ctx
        self.walls: list[float] = []
        self.gpus: list[float] = []
        self.overheads: list[float] = []
        self.stages: dict[str, list[float]] = {}
        self.last: Any = None
        self.cold_s = self.compile_s = 0.0
        self.prep_s = 0.0
        self.error: str | None = None
        self.calib = _Calibration(ctx) if c.is_calibration else None
        if c.is_peer:
            t0 = time.perf_counter()
            self.peer: Peer | None = get_peer(c.peer)
            self.prepared = self.peer.prepare(mesh, spec)
            self.prep_s = time.perf_counter() - t0
        else:
            self.peer = None

    def once(self) -> float:
        from glvox.methods import run_method

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
            t0 = time.perf_counter()
            self.last = run_method(self.c.method, self.mesh, self.spec, ctx=self.ctx, allow_open=True,
                                   **dict(self.c.options))
            wall = time.perf_counter() - t0
        return wall

    def cold(self) -> None:
        try:
            self.cold_s = self.once()
            if self.peer is None and self.calib is None:
                self.compile_s = self.last.run.timings.compile_s
        except (GlvoxError, MemoryError, ValueError, RuntimeError) as exc:
            self.error = f"{type(exc).__name__}: {exc}"

    def timed(self) -> None:
        try:
            wall = self.once()
        except (GlvoxError, MemoryError, ValueError, RuntimeError) as exc:
            self.error = f"{type(exc).__name__}: {exc}"
            return
        self.walls.append(wall)
        if self.peer is None and self.calib is None:
            t = self.last.run.timings
            if t.gpu_s is not None:
                self.gpus.append(t.gpu_s)
            self.overheads.append(wall - t.wall_s)
            for s in t.stages:
                self.stages.setdefault(s.name, []).append(s.gpu_s if s.gpu_s is not None else s.wall_s)


def run_cell(plan: Plan, mesh, mesh_name: str, n: int, ctx, log: Callable[[str], None],
             only: Sequence[str] | None = None) -> list[dict[str, Any]]:
    """Every contender of ``plan`` (or the keys in ``only``) on ``mesh`` at N = ``n``; one row each."""
    from glvox.methods import get_method

    spec = glvox.grid_for(mesh, n)
    base = {"mesh": mesh_name, "triangles": mesh.n_triangles, "watertight": mesh.watertight, "n": n,
            "dims": list(spec.dims)}
    rows: list[dict[str, Any]] = []
    runners: list[_Runner] = []
    contenders = list(plan.contenders)
    if only is None or CALIBRATION_KEY in only:
        contenders.append(Contender(CALIBRATION_KEY, CALIBRATION))
    for c in contenders:
        if only is not None and c.key not in only:
            continue
        row = {"key": c.key, "group": c.group, "peer": c.is_peer, "method": c.method or c.peer or c.key,
               "options": dict(c.options), **base, "status": "ok", "error": None}
        if c.is_peer:
            limit = plan.peer_limit(c.peer)
            if limit is not None and n > limit:
                row.update(status="skipped", error=f"N = {n} over this peer's limit {limit} (--peer-max "
                                                   f"{c.peer}=N runs it; see compare/peers.py for why)")
                rows.append(row)
                continue
        try:
            runners.append(_Runner(c, mesh, spec, ctx))
        except (MemoryError, ValueError, RuntimeError) as exc:
            row.update(status="error", error=f"{type(exc).__name__}: {exc}")
        rows.append(row)
    by_key = {r.c.key: r for r in runners}
    for r in runners:
        log(f"{mesh_name} {n}^3: cold {r.c.key}")
        r.cold()
    active = [r for r in runners if r.error is None]
    for rnd in range(plan.repeat):
        if not active:
            break
        order = active[rnd % len(active):] + active[:rnd % len(active)]
        for r in order:
            r.timed()
        active = [r for r in active if r.error is None and sum(r.walls) < plan.budget]
    refs = References(mesh, spec)
    for row in rows:
        r = by_key.get(row["key"])
        if r is None:
            continue
        if r.error is not None:
            row.update(status="error", error=r.error)
            continue
        row.update({
            "runs": len(r.walls),
            "wall_ms": statistics.median(r.walls) * 1e3,
            "min_ms": min(r.walls) * 1e3,
            "spread_ms": (max(r.walls) - min(r.walls)) * 1e3,
            "cold_ms": r.cold_s * 1e3,
        })
        if r.calib is not None:
            continue
        if r.peer is None:
            info = get_method(r.c.method).info
            row.update({
                "exact": info.exact, "kind": info.kind,
                "compile_ms": r.compile_s * 1e3,
                "gpu_ms": statistics.median(r.gpus) * 1e3 if r.gpus else None,
                "overhead_ms": statistics.median(r.overheads) * 1e3,
                "stages_ms": {k: statistics.median(v) * 1e3 for k, v in r.stages.items()},
            })
            words = _words_of(r.last)
        else:
            t0 = time.perf_counter()
            pg = r.peer.to_grid(r.last, spec)
            row.update({"exact": None, "kind": r.peer.kind, "convert_ms": (time.perf_counter() - t0) * 1e3,
                        "prepare_ms": r.prep_s * 1e3, "outside": pg.outside, "call": r.peer.call})
            words = pg.grid.words()
        r.last = None  # large results go as soon as they are counted
        row["voxels"] = _popcount(words)
        ref, ref_opts = _reference_of(r.c, mesh)
        if ref is not None and (plan.check_max is None or n <= plan.check_max):
            log(f"{mesh_name} {n}^3: checking {r.c.key} against {ref}")
            row["reference"] = ref + (f"[{','.join(f'{k}={v}' for k, v in ref_opts)}]" if ref_opts else "")
            row.update(agreement(words, refs.words(ref, ref_opts), refs.ties(ref)))
    for r in runners:
        if r.calib is not None:
            r.calib.release()
        elif r.peer is None:
            get_method(r.c.method).release(ctx)  # pools of this size: free before the next size
    for row in rows:
        row["reference_s"] = refs.seconds
    return rows


def add_ratios(rows: list[dict[str, Any]]) -> None:
    """Put on each glvox row its ratio to the fastest peer of its group in its cell
    (``ratio``, ``fastest_peer``) and to every peer of that group (``ratios``)."""
    cells: dict[tuple, list[dict]] = {}
    for r in rows:
        cells.setdefault((r["mesh"], r["n"], r["group"]), []).append(r)
    for group_rows in cells.values():
        peers = [r for r in group_rows if r["peer"] and r["status"] == "ok"]
        if not peers:
            continue
        fastest = min(peers, key=lambda r: r["wall_ms"])
        for r in group_rows:
            if r["peer"] or r["status"] != "ok":
                continue
            r["fastest_peer"] = fastest["method"]
            r["ratio"] = r["wall_ms"] / fastest["wall_ms"]
            r["ratios"] = {p["method"]: r["wall_ms"] / p["wall_ms"] for p in peers}


def run_plan(plan: Plan, *, log: Callable[[str], None] = lambda s: None,
             progress: Callable[[str], None] = lambda s: None) -> list[dict[str, Any]]:
    """Every cell of ``plan``; rows in mesh, size, contender order, ratios added."""
    from glvox.gl.context import get_context

    ctx = get_context()
    rows: list[dict[str, Any]] = []
    for mesh_path in plan.meshes:
        mesh = glvox.load_mesh(mesh_path)
        name = Path(mesh_path).name if not mesh_path.startswith("gen:") else mesh_path
        if not mesh.watertight:
            log(f"{name} is not watertight: glvox's solid methods run with allow_open=True (parity of "
                f"crossings) and are checked against reference-solid along their own axis; the solid peers "
                f"apply their own rules for holes")
        for n in plan.sizes:
            rows += run_cell(plan, mesh, name, n, ctx, progress)
    add_ratios(rows)
    return rows


# ---------------------------------------------------------------------------
# cold start: a fresh process per method
# ---------------------------------------------------------------------------

#: Run in a fresh interpreter by :func:`cold_start`: import, context, mesh
#: load, then the method's first and second call, as JSON on stdout.
_COLD_SCRIPT = """
import json, sys, time, warnings
t0 = time.perf_counter()
import glvox
from glvox.gl.context import get_context
from glvox.methods import run_method
t1 = time.perf_counter()
get_context()
t2 = time.perf_counter()
mesh = glvox.load_mesh(sys.argv[2])
spec = glvox.grid_for(mesh, int(sys.argv[3]))
t3 = time.perf_counter()
warnings.simplefilter("ignore")
a = time.perf_counter()
g = run_method(sys.argv[1], mesh, spec, allow_open=True)
b = time.perf_counter()
run_method(sys.argv[1], mesh, spec, allow_open=True)
c = time.perf_counter()
print(json.dumps({"import_ms": (t1 - t0) * 1e3, "context_ms": (t2 - t1) * 1e3, "load_ms": (t3 - t2) * 1e3,
                  "first_ms": (b - a) * 1e3, "compile_ms": g.run.timings.compile_s * 1e3,
                  "second_ms": (c - b) * 1e3}))
"""


def cold_start(method: str, mesh: str, n: int, disk_cache: bool = False) -> dict[str, Any]:
    """A method's cold start in a fresh process: import, context creation, mesh
    load, first call (compilation, LLVM code generation at the first dispatch,
    upload, allocation) and second call, in ms.

    ``disk_cache=False`` sets ``MESA_SHADER_CACHE_DISABLE=true``: Mesa keeps
    compiled shaders on disk between processes, which hides compilation from
    every run after the first on a machine.
    """
    import os
    import subprocess

    env = dict(os.environ)
    if not disk_cache:
        env["MESA_SHADER_CACHE_DISABLE"] = "true"
    p = subprocess.run([sys.executable, "-c", _COLD_SCRIPT, method, mesh, str(n)], capture_output=True,
                       text=True, env=env, timeout=600)
    if p.returncode != 0:
        return {"method": method, "error": (p.stderr.strip().splitlines() or ["?"])[-1]}
    return {"method": method, "mesh": mesh, "n": n, "disk_cache": disk_cache,
            **json.loads(p.stdout.strip().splitlines()[-1])}


def cold_table(colds: Sequence[dict]) -> str:
    out = ["| method | import ms | context ms | mesh load ms | first call ms (GLSL compile) | second call ms |",
           "|---|---|---|---|---|---|"]
    for c in colds:
        if "error" in c:
            out.append(f"| {c['method']} | error: {c['error']} | | | | |")
        else:
            out.append(f"| {c['method']} | {_ms(c['import_ms'])} | {_ms(c['context_ms'])} | {_ms(c['load_ms'])} | "
                       f"{_ms(c['first_ms'])} ({_ms(c['compile_ms'])}) | {_ms(c['second_ms'])} |")
    return "\n".join(out) + "\n"


# ---------------------------------------------------------------------------
# regression check against a baseline
# ---------------------------------------------------------------------------


def _cell_key(r: dict[str, Any]) -> str:
    return f"{r['key']}|{r['mesh']}|{r['n']}"


def machine_factor(rows: Sequence[dict], baseline: Sequence[dict]) -> float | None:
    """How much slower the machine is now than when the baseline was taken.

    The median over cells present in both of (best time now / best time then)
    of the GL calibration workload (:class:`_Calibration`), which feels the
    load on llvmpipe's threads as the glvox methods do; of the peers' cells
    when the baseline has no calibration; None when neither is common.
    """
    base = {_cell_key(r): r for r in baseline if r.get("status") == "ok"}

    def ratios(pick):
        return [r["min_ms"] / base[_cell_key(r)]["min_ms"] for r in rows
                if pick(r) and r["status"] == "ok" and _cell_key(r) in base]

    got = ratios(lambda r: r["group"] == CALIBRATION) or ratios(lambda r: r["peer"])
    return statistics.median(got) if got else None


def check_regressions(rows: Sequence[dict], baseline: Sequence[dict], factor: float | None,
                      tolerance: float = REGRESSION_TOLERANCE) -> list[dict[str, Any]]:
    """glvox cells whose best warm time regressed against the baseline.

    A cell regresses when its best time (the least of its warm runs: noise on
    a shared machine only ever adds time) exceeds the baseline's by more than
    ``tolerance`` after dividing by the machine factor where that is above 1:
    a busier machine slows the fixed GL workload too, and a change in glvox
    slows glvox alone.  A factor below 1 (a quieter machine than the
    baseline's) is not applied: methods do not all speed up alike when cores
    free up (measured here: compute methods and the GL workload up to 2x, the
    raster methods not at all), so it would accuse methods of what is only
    noise.  Rows missing from either side are ignored (new methods, peers
    not installed).

    Returns
    -------
    list of dict
        key, mesh, n, base_ms, now_ms, raw (now / base), normalized (raw / factor).
    """
    base = {_cell_key(r): r for r in baseline if r.get("status") == "ok" and not r.get("peer")}
    out = []
    for r in rows:
        b = base.get(_cell_key(r))
        if r["peer"] or r["group"] == CALIBRATION or r["status"] != "ok" or b is None:
            continue
        raw = r["min_ms"] / b["min_ms"]
        norm = raw / max(1.0, factor or 1.0)
        if norm > 1 + tolerance:
            out.append({"key": r["key"], "mesh": r["mesh"], "n": r["n"], "base_ms": b["min_ms"],
                        "now_ms": r["min_ms"], "raw": raw, "normalized": norm})
    return out


def load_baseline(path: Path) -> dict[str, Any]:
    if not Path(path).is_file():
        raise GlvoxError(f"no benchmark baseline at {path}: run `glvox bench --preset quick --save-baseline "
                         f"{path}` on the version to compare against, or pass --check PATH")
    data = json.loads(Path(path).read_text())
    if not isinstance(data, dict) or "rows" not in data:
        raise GlvoxError(f"{path} is not a glvox bench results file (expected an object with 'rows')")
    return data


# ---------------------------------------------------------------------------
# tables
# ---------------------------------------------------------------------------


def _ms(v) -> str:
    if v is None:
        return "-"
    return f"{v:.0f}" if v >= 100 else f"{v:.1f}" if v >= 1 else f"{v:.2f}"


def _load(v) -> str:
    return "/".join(f"{x:.1f}" for x in v)


def _ratio(v) -> str:
    if v is None:
        return "-"
    return f"{v:.3f} ({1 / v:.1f}x faster)" if v < 1 else f"{v:.2f} ({v:.1f}x slower)"


def _ordered(rows: Sequence[dict]) -> list[dict]:
    """Rows by mesh (run order), kind (surface first), glvox before peers, then N and run order."""
    meshes = list(dict.fromkeys(r["mesh"] for r in rows))
    return sorted(rows, key=lambda r: (meshes.index(r["mesh"]), r["group"] != "surface", r["peer"], r["n"]))


def cell_tables(rows: Sequence[dict]) -> str:
    """One markdown table per (mesh, N, group): every contender's times and agreement."""
    out = []
    cells: dict[tuple, list[dict]] = {}
    for r in sorted(_ordered(rows), key=lambda r: r["n"]):
        cells.setdefault((r["mesh"], r["n"], r["group"]), []).append(r)
    meshes = list(dict.fromkeys(r["mesh"] for r in rows))
    for (mesh, n, group), rs in sorted(cells.items(), key=lambda kv: (meshes.index(kv[0][0]), kv[0][1],
                                                                       kv[0][2] != "surface")):
        tri = rs[0]["triangles"]
        ref = next((r.get("reference") for r in rs if r.get("reference") and not r["peer"]), None)
        refv = next((r.get("reference_voxels") for r in rs if r.get("reference_voxels") is not None), None)
        head = f"#### {mesh} ({tri:,} triangles{'' if rs[0]['watertight'] else ', open'}), {n}^3, {group}"
        if refv is not None:
            head += f" (reference {ref}: {refv:,} voxels)"
        out += [head, "",
                "| contender | median ms | min ms | runs | cold ms | GPU ms | overhead ms | voxels | missing "
                "| extra | not ties | IoU | vs fastest peer |",
                "|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
        for r in rs:
            label = f"peer {r['method']}" if r["peer"] else r["key"]
            if r["status"] != "ok":
                out.append(f"| {label} | {r['status']}: {r['error']} |" + " |" * 11)
                continue
            agree = [f"{r[k]:,}" if r.get(k) is not None else "-" for k in ("missing", "extra", "not_ties")]
            iou = f"{r['iou']:.6f}" if r.get("iou") is not None else "-"
            conv = f" (+{_ms(r['convert_ms'])} convert)" if r["peer"] else ""
            vs = _ratio(r.get("ratio")) + (f" vs {r['fastest_peer']}" if r.get("fastest_peer") else "")
            out.append(f"| {label} | {_ms(r['wall_ms'])}{conv} | {_ms(r['min_ms'])} | {r['runs']} | "
                       f"{_ms(r['cold_ms'])} | {_ms(r.get('gpu_ms'))} | {_ms(r.get('overhead_ms'))} | "
                       f"{r['voxels']:,} | {' | '.join(agree)} | {iou} | {vs if not r['peer'] else ''} |")
        out.append("")
    return "\n".join(out)


def ratio_table(rows: Sequence[dict]) -> str:
    """Method x size, per mesh: ratio to the fastest peer of its kind (median / median)."""
    sizes = sorted({r["n"] for r in rows})
    out = ["| mesh | kind | method | " + " | ".join(f"{n}^3" for n in sizes) + " |",
           "|---|---|---|" + "---|" * len(sizes)]
    by: dict[tuple, dict[int, dict]] = {}
    for r in _ordered(rows):
        by.setdefault((r["mesh"], r["group"], r["key"], r["peer"]), {})[r["n"]] = r
    for (mesh, group, key, is_peer), cells in by.items():
        vals = []
        for n in sizes:
            r = cells.get(n)
            if r is None:
                vals.append("")
            elif r["status"] != "ok":
                vals.append(r["status"])
            elif is_peer:
                vals.append(f"{_ms(r['wall_ms'])} ms")
            elif r.get("ratio") is None:
                vals.append(f"{_ms(r['wall_ms'])} ms (no peer)")
            else:
                vals.append(f"{r['ratio']:.3f} ({_ms(r['wall_ms'])} ms)")
        label = f"peer {key[5:]}" if is_peer else key
        out.append(f"| {mesh} | {group} | {label} | " + " | ".join(vals) + " |")
    return "\n".join(out) + "\n"


def time_table(rows: Sequence[dict]) -> str:
    """Where each glvox method's time goes: stage medians (GPU time from timestamp
    queries, wall for CPU stages such as readback), the wall time outside every
    stage (validation, uniforms, result objects: Python overhead), the cold run
    and the shader compilation inside it."""
    out = ["| mesh | N | method | median ms | GPU ms | stages (ms) | outside stages ms | cold ms (compile) |",
           "|---|---|---|---|---|---|---|---|"]
    for r in _ordered(rows):
        if r["peer"] or r["status"] != "ok":
            continue
        stages = ", ".join(f"{k} {_ms(v)}" for k, v in r.get("stages_ms", {}).items())
        out.append(f"| {r['mesh']} | {r['n']} | {r['key']} | {_ms(r['wall_ms'])} | {_ms(r.get('gpu_ms'))} | "
                   f"{stages} | {_ms(r.get('overhead_ms'))} | {_ms(r['cold_ms'])} ({_ms(r.get('compile_ms'))}) |")
    return "\n".join(out) + "\n"


def targets(rows: Sequence[dict]) -> list[tuple[str, bool | None, str]]:
    """The issue's speed targets, evaluated on ``rows``: (target, met or None when not measured, detail)."""
    out = []
    cons = [r for r in rows if r["key"] == "ss-conservative" and r["status"] == "ok"]
    lines, met = [], True
    measured = False
    for r in cons:
        o3d = (r.get("ratios") or {}).get("open3d")
        if o3d is None:
            continue
        measured = True
        exact = r.get("not_ties")
        ok = o3d < 1 and exact in (0, None)
        met &= ok
        peer = next((p for p in rows if p["key"] == "peer:open3d" and p["mesh"] == r["mesh"]
                     and p["n"] == r["n"] and p["status"] == "ok"), None)
        best = f"; best runs {r['min_ms']:.0f} vs {peer['min_ms']:.0f} ms" if peer else ""
        lines.append(f"{r['mesh']} {r['n']}^3: {r['wall_ms']:.0f} ms vs Open3D {r['wall_ms'] / o3d:.0f} ms "
                     f"(ratio {o3d:.3f}{best}), "
                     + ("not checked" if exact is None else f"{exact} mismatches that are not ties")
                     + ("" if ok else "  <-- NOT MET"))
    out.append(("ss-conservative (default variant) faster than Open3D at every grid size, and exact",
                met if measured else None, "\n".join(lines) or "Open3D not measured"))
    lines, met, measured = [], True, False
    cells: dict[tuple, list[dict]] = {}
    for r in rows:
        if r["group"] == "solid" and r["n"] >= 256 and r["status"] == "ok":
            cells.setdefault((r["mesh"], r["n"]), []).append(r)
    for (mesh, n), rs in cells.items():
        peers = [r for r in rs if r["peer"]]
        exact = [r for r in rs if not r["peer"] and r.get("exact") and r.get("not_ties", 0) == 0]
        if not peers or not exact:
            continue
        measured = True
        best, peer = min(exact, key=lambda r: r["wall_ms"]), min(peers, key=lambda r: r["wall_ms"])
        speedup = peer["wall_ms"] / best["wall_ms"]
        ok = speedup >= 10
        met &= ok
        b_min, p_min = min(r["min_ms"] for r in exact), min(r["min_ms"] for r in peers)
        lines.append(f"{mesh} {n}^3: {best['key']} {best['wall_ms']:.0f} ms vs {peer['method']} "
                     f"{peer['wall_ms']:.0f} ms: {speedup:.1f}x (best runs: {p_min / b_min:.1f}x)"
                     + ("" if ok else "  <-- NOT MET"))
    out.append(("fastest exact solid method at least 10x faster than the fastest solid peer at 256^3 and above",
                met if measured else None, "\n".join(lines) or "no solid cell at 256^3 or above"))
    return out


def published_note() -> str:
    p = PUBLISHED
    cpu = ", ".join(f"{v} ms at {n}^3" for n, v in p["cpu"]["ms"].items())
    gpu = ", ".join(f"{v} ms at {n}^3" for n, v in p["gpu"]["ms"].items())
    return (f"For scale, published and not measured here: {p['source']}: CPU ({p['cpu']['hardware']}) {cpu}; "
            f"GPU ({p['gpu']['hardware']}) {gpu}.")


def report(rows: Sequence[dict], machine: dict[str, Any], plan: Plan, regressions=None,
           factor: float | None = None, baseline_path: Path | None = None,
           colds: Sequence[dict] | None = None, common: int | None = None) -> str:
    gl = machine.get("gl", {})
    peers = ", ".join(f"{k} {v}" for k, v in machine.get("peers", {}).items()) or "none installed"
    calib = [r["wall_ms"] for r in rows if r["group"] == CALIBRATION and r["status"] == "ok"]
    rows = [r for r in rows if r["group"] != CALIBRATION]
    out = ["# glvox bench", "",
           f"Renderer: {gl.get('renderer')} ({gl.get('version')}, {gl.get('backend')}); "
           f"{machine.get('cpu_count')} CPUs; glvox {machine.get('glvox')}; peers: {peers}."
           + (f" Load average (1, 5, 15 min) at the start {_load(machine['load_average_start'])}, at the end "
              f"{_load(machine['load_average_end'])}." if "load_average_end" in machine else ""),
           f"Times are wall clock, the median of up to {plan.repeat} warm runs per contender taken in "
           f"interleaved rounds (at most {plan.budget:g} s of runs each per cell); ratio = glvox median / "
           "median of the fastest peer of the same kind, below 1 is faster."
           + (f" A fixed GL workload timed in every round (`shaders/testing/busy.comp`, the machine factor of "
              f"the regression check) took {_ms(min(calib))}-{_ms(max(calib))} ms (median per cell)."
              if calib else ""), "",
           "## Ratio to the fastest peer of each kind", "", ratio_table(rows),
           "## Targets", ""]
    for name, met, detail in targets(rows):
        verdict = "not measured" if met is None else ("MET" if met else "NOT MET")
        out += [f"- **{verdict}**: {name}", "", "  " + detail.replace("\n", "\n  "), ""]
    if regressions is not None:
        f = f"{factor:.2f}" if factor else "none (no common calibration or peer cell)"
        if common == 0:
            out.append(f"- **not measured**: no method regresses by more than {REGRESSION_TOLERANCE:.0%}: no "
                       f"glvox cell of this run is in {baseline_path} (other meshes or sizes?)")
        elif regressions:
            out.append(f"- **NOT MET**: no method regresses by more than {REGRESSION_TOLERANCE:.0%} against "
                       f"{baseline_path} (machine factor, applied when above 1: {f}):")
            out += [f"  - {g['key']} on {g['mesh']} {g['n']}^3: best {g['base_ms']:.1f} -> {g['now_ms']:.1f} ms "
                    f"(x{g['raw']:.2f}, x{g['normalized']:.2f} after the machine factor)" for g in regressions]
        else:
            out.append(f"- **MET**: no method regresses by more than {REGRESSION_TOLERANCE:.0%} against "
                       f"{baseline_path} (machine factor, applied when above 1: {f})")
        out.append("")
    out += [published_note(), "", "## Every cell", "", cell_tables(rows),
            "## Where the time goes", "", time_table(rows)]
    if colds:
        c0 = colds[0]
        out += ["## Cold start", "",
                f"A fresh process per method, Mesa's shader disk cache {'on' if c0.get('disk_cache') else 'off'}, "
                f"{Path(str(c0.get('mesh', ''))).name} at {c0.get('n')}^3:", "", cold_table(colds)]
    return "\n".join(out)


# ---------------------------------------------------------------------------
# command line
# ---------------------------------------------------------------------------


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--preset", choices=sorted(PRESETS), default=None,
                   help="quick: every method and peer on two shared meshes at 64^3 and 128^3 (generated "
                        "meshes when the shared ones are absent); full: bunny and dragon, 128^3 to 1024^3")
    p.add_argument("-m", "--methods", nargs="+", default=None,
                   help="glvox methods (default: every GPU method of kind surface, solid or sparse)")
    p.add_argument("--no-variants", action="store_true",
                   help="only each method's default (not ss-conservative's simple and sorted variants too)")
    p.add_argument("--peers", nargs="*", default=None, choices=list(PEERS),
                   help=f"peers to run (default all installed: {', '.join(PEERS)})")
    p.add_argument("--meshes", nargs="+", default=None,
                   help="mesh files, names in GLVOX_MESHES, or gen:torus|sphere|box|bunny-like")
    p.add_argument("-r", "--sizes", nargs="+", type=int, default=None, help="grid resolutions N (N^3)")
    p.add_argument("--repeat", type=int, default=None, help="timed warm rounds per cell (median reported)")
    p.add_argument("--budget", type=float, default=None,
                   help="seconds of warm runs after which a contender stops repeating in a cell")
    p.add_argument("--check-max", type=int, default=None,
                   help="largest N compared with the CPU references (default: every size)")
    p.add_argument("--peer-max", action="append", default=[], metavar="PEER=N",
                   help="run a peer up to N^3 instead of its default limit (PEER=none: no limit)")
    p.add_argument("-o", "--out", default=None, help="folder for bench.md and results.json")
    p.add_argument("--check", nargs="?", const=str(BASELINE), default=None, metavar="BASELINE",
                   help=f"compare with a baseline results file (default {BASELINE.name} beside this "
                        f"module); exit status 3 when a method regressed by more than "
                        f"{REGRESSION_TOLERANCE * 100:.0f}%%")  # argparse formats help with %
    p.add_argument("--save-baseline", nargs="?", const=str(BASELINE), default=None, metavar="PATH",
                   help=f"write the results as the new baseline (default {BASELINE})")
    p.add_argument("--against", default=None, metavar="REV",
                   help="A/B check: time the plan's glvox methods with glvox at git revision REV and with this "
                        "checkout, run by run in two processes (no peers; --repeat runs per side, default "
                        f"{AB_REPEAT}); exit status 3 when a method's best and median times grew by more than "
                        f"{REGRESSION_TOLERANCE * 100:.0f}%%. Immune to machine drift, unlike --check")
    p.add_argument("--cold-start", action="store_true",
                   help="also time each method's first call in a fresh process (Mesa's shader disk cache off) "
                        "on the first mesh at the smallest size")
    p.add_argument("--json", action="store_true", help="print the rows as JSON instead of the tables")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress messages")


def _peer_max(items: Sequence[str]) -> dict[str, int | None]:
    out: dict[str, int | None] = {}
    for item in items:
        name, _, val = item.partition("=")
        get_peer(name)
        if not val:
            raise GlvoxError(f"--peer-max takes PEER=N, got {item!r}")
        if val.lower() == "none":
            out[name] = None
        else:
            try:
                out[name] = int(val)
            except ValueError:
                raise GlvoxError(f"--peer-max takes PEER=N with N an integer or 'none', got {item!r}") from None
    return out


def plan_from(args, log: Callable[[str], None]) -> Plan:
    preset = PRESETS.get(args.preset or "", {})
    meshes = args.meshes or preset.get("meshes")
    sizes = args.sizes or preset.get("sizes")
    if not meshes or not sizes:
        raise GlvoxError("give --preset quick|full, or --meshes and -r/--sizes")
    resolved = []
    for m in meshes:
        try:
            resolved.append(harness.resolve_mesh(m))
        except GlvoxError:
            alt = preset.get("fallback", {}).get(m)
            if alt is None or args.meshes:
                raise
            log(f"shared mesh {m} not found in {harness.mesh_dir()} (set GLVOX_MESHES); using {alt} instead")
            resolved.append(alt)
    if any(n < 1 for n in sizes):
        raise GlvoxError(f"grid sizes must be positive, got {sizes}")
    contenders = glvox_contenders(args.methods, variants=not args.no_variants)
    contenders += peer_contenders(args.peers, log)
    return Plan(meshes=resolved, sizes=sorted(set(sizes)), contenders=contenders,
                repeat=args.repeat or preset.get("repeat", 5), budget=args.budget or preset.get("budget", 10.0),
                check_max=args.check_max, peer_max=_peer_max(args.peer_max))


def machine_info(plan: Plan) -> dict[str, Any]:
    import os

    m = harness.machine()
    m["peers"] = {c.peer: get_peer(c.peer).version() for c in plan.contenders if c.is_peer}
    # other work on a shared machine moves absolute times; say how busy it was
    m["load_average_start"] = list(os.getloadavg())
    return m


def main(args) -> int:
    def log(msg: str) -> None:
        if not args.quiet:
            print(msg, file=sys.stderr, flush=True)

    t_start = time.perf_counter()

    def progress(msg: str) -> None:
        if not args.quiet:
            print(f"[{time.perf_counter() - t_start:7.1f} s] {msg}", file=sys.stderr, flush=True)

    if getattr(args, "against", None):
        from .ab import run_against

        plan = plan_from(args, log)
        plan.repeat = args.repeat or AB_REPEAT
        ab_rows, text = run_against(plan, args.against, REGRESSION_TOLERANCE, progress)
        if args.out:
            out = Path(args.out)
            out.mkdir(parents=True, exist_ok=True)
            (out / "ab.md").write_text(text + "\n")
            log(f"wrote {out / 'ab.md'}")
        print(text)
        log(f"done in {time.perf_counter() - t_start:.0f} s")
        return 3 if any(r.get("regressed") for r in ab_rows) else 0

    plan = plan_from(args, log)
    baseline = load_baseline(Path(args.check)) if args.check else None
    machine = machine_info(plan)
    log(f"{len(plan.contenders)} contenders x {len(plan.meshes)} meshes x sizes {list(plan.sizes)}; "
        f"renderer {machine['gl']['renderer']}")
    rows = run_plan(plan, log=log, progress=progress)
    regressions = factor = common = None
    if baseline is not None:
        base_keys = {_cell_key(r) for r in baseline["rows"] if r.get("status") == "ok"}
        common = sum(1 for r in rows if not r["peer"] and r["group"] != CALIBRATION and r["status"] == "ok"
                     and _cell_key(r) in base_keys)
        factor = machine_factor(rows, baseline["rows"])
        regressions = check_regressions(rows, baseline["rows"], factor)
        if regressions:
            # confirm: measure the suspects again (twice the rounds) and keep each one's best
            suspects = {g["key"] for g in regressions}
            log(f"possible regressions in {sorted(suspects)}: measuring them again")
            again = Plan(plan.meshes, plan.sizes, [c for c in plan.contenders if c.key in suspects],
                         repeat=2 * plan.repeat, budget=2 * plan.budget, check_max=0, peer_max=plan.peer_max)
            best = {_cell_key(r): r["min_ms"] for r in run_plan(again, progress=progress) if r["status"] == "ok"}
            for r in rows:
                k = _cell_key(r)
                if k in best:
                    r["min_ms"] = min(r["min_ms"], best[k])
            regressions = check_regressions(rows, baseline["rows"], factor)
    import os

    machine["load_average_end"] = list(os.getloadavg())
    colds = None
    if args.cold_start:
        methods = list(dict.fromkeys(c.method for c in plan.contenders if not c.is_peer))
        colds = []
        for m in methods:
            progress(f"cold start of {m} in a fresh process")
            colds.append(cold_start(m, plan.meshes[0], min(plan.sizes)))
    result = {"machine": machine, "plan": {"meshes": list(plan.meshes), "sizes": list(plan.sizes),
                                           "repeat": plan.repeat, "budget": plan.budget,
                                           "preset": args.preset},
              "rows": rows, "cold_start": colds, "seconds": time.perf_counter() - t_start}
    text = report(rows, machine, plan, regressions, factor, Path(args.check) if args.check else None, colds,
                  common)
    if args.out:
        out = Path(args.out)
        out.mkdir(parents=True, exist_ok=True)
        (out / "results.json").write_text(json.dumps(result, indent=1))
        (out / "bench.md").write_text(text)
        log(f"wrote {out / 'bench.md'} and {out / 'results.json'}")
    if args.save_baseline:
        Path(args.save_baseline).write_text(json.dumps(result, indent=1))
        log(f"wrote the baseline {args.save_baseline}")
    print(json.dumps(result, indent=1) if args.json else text)
    log(f"done in {time.perf_counter() - t_start:.0f} s")
    return 3 if regressions else 0


def cli(argv: Sequence[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="glvox bench", description=__doc__.splitlines()[0])
    add_arguments(p)
    return main(p.parse_args(argv))
