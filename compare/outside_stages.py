"""Where a call's time outside its timed stages goes: whole calls profiled, the functions that hold it.

    python compare/outside_stages.py                          # ss-conservative, the bunny at 1024^3
    python compare/outside_stages.py -m ss-solid -r 256 --repeat 9

Every glvox run times its stages (``run.timings``), and ``glvox bench`` reports
what a whole ``run_method`` call takes besides them ("overhead ms"): on the
H100 about 5 ms of a 10 ms call at 1024^3 (docs/performance.md), with no stage
to name.  This script runs the method warm, then ``--repeat`` calls under
``cProfile`` with the profiler paused inside every stage (``StageTimer.stage``
wrapped), and prints the medians of the whole call, of its stages and of the
rest, then the functions with the most time of their own outside the stages,
per call, and the profile's total there.  Each stage is given per call (summed
where it runs once per slab or pass) with its GPU time from the timer queries
where the context has them: where a GPU's wall time of a stage is far above its
GPU time, the stage waits on something else (a sync, the CPU's issue).  Last,
``--repeat`` calls without the profiler give the calling thread's CPU time per
call (``time.thread_time``): the host's own work (Python, the driver's issue
of the commands), which no GPU shortens.  It is the floor of a call on a fast
GPU, measurable on any machine: llvmpipe runs the shaders on threads of its
own, and a driver that sleeps while it waits for the GPU adds nothing (one
that spins adds its wait).  Short enough for the last lines of a report:
``compare/gpu_report.py`` runs it as its ``outside`` step.
"""

from __future__ import annotations

import argparse
import contextlib
import cProfile
import pstats
import statistics
import time
import warnings
from pathlib import Path

from glvox import grid_for, load_mesh, run_method
from glvox.gl.timing import StageTimer

BUNNY = "stanford_bunny_bun_zipper.ply"


def profile_calls(method: str, mesh, n: int, repeat: int) -> tuple[dict, pstats.Stats]:
    """Medians (ms) of whole calls, their stages and the rest, each stage per call (wall and,
    where timed, GPU), and the calls' profile."""
    spec = grid_for(mesh, n)
    call = {"allow_open": True}  # as glvox bench runs the parity solids on an open mesh
    for _ in range(2):  # compile, upload, allocate
        run_method(method, mesh, spec, **call)
    walls, stages, names = [], [], {}
    prof = cProfile.Profile()
    timed_stage = StageTimer.stage

    @contextlib.contextmanager
    def paused(self, *a, **k):  # a stage's own time is in its table, not in the profile
        prof.disable()
        try:
            with timed_stage(self, *a, **k):
                yield
        finally:
            prof.enable()

    StageTimer.stage = paused
    try:
        for _ in range(repeat):
            prof.enable()
            t0 = time.perf_counter()
            result = run_method(method, mesh, spec, **call)
            wall = time.perf_counter() - t0
            prof.disable()
            t = result.run.timings
            walls.append(wall)
            stages.append(t.wall_s)
            # a stage that runs several times a call (per slab, per pass) counts once, summed
            per_call: dict[str, list] = {}
            for s in t.stages:
                total = per_call.setdefault(s.name, [0.0, None])
                total[0] += s.wall_s
                if s.gpu_s is not None:
                    total[1] = (total[1] or 0.0) + s.gpu_s
            for name, (wall_s, gpu_s) in per_call.items():
                names.setdefault(name, []).append((wall_s, gpu_s))
            del result
    finally:
        StageTimer.stage = timed_stage
    med = {"wall_ms": statistics.median(walls) * 1e3, "stages_ms": statistics.median(stages) * 1e3,
           "outside_ms": statistics.median(w - s for w, s in zip(walls, stages)) * 1e3,
           "stages": {k: statistics.median(w for w, _ in v) * 1e3 for k, v in names.items()},
           "gpu": {k: statistics.median(g for _, g in v) * 1e3 for k, v in names.items()
                   if all(g is not None for _, g in v)}}
    return med, pstats.Stats(prof)


def host_cpu(method: str, mesh, n: int, repeat: int) -> dict[str, float]:
    """Medians (ms) of ``repeat`` warm calls without the profiler: the whole call's
    wall time and the calling thread's CPU time."""
    spec = grid_for(mesh, n)
    run_method(method, mesh, spec, allow_open=True)
    walls, cpus = [], []
    for _ in range(repeat):
        c0, t0 = time.thread_time(), time.perf_counter()
        run_method(method, mesh, spec, allow_open=True)
        walls.append(time.perf_counter() - t0)
        cpus.append(time.thread_time() - c0)
    return {"wall_ms": statistics.median(walls) * 1e3, "cpu_ms": statistics.median(cpus) * 1e3}


def top_functions(stats: pstats.Stats, calls: int, count: int) -> list[tuple[float, int, str]]:
    """The ``count`` functions with the most time of their own: (ms per call, calls per call, name)."""
    rows = []
    for (path, line, func), (_, ncalls, tottime, _, _) in stats.stats.items():
        where = func if path == "~" else f"{Path(path).name}:{line}({func})"
        rows.append((tottime * 1e3 / calls, ncalls // calls, where))
    rows.sort(reverse=True)
    return rows[:count]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("-m", "--method", default="ss-conservative")
    ap.add_argument("--mesh", default=BUNNY, help="a mesh file, a shared mesh's name or gen:NAME")
    ap.add_argument("-r", "--size", type=int, default=1024)
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--top", type=int, default=12)
    args = ap.parse_args(argv)
    warnings.simplefilter("ignore")  # an open mesh's parity warning, once per call
    mesh = load_mesh(args.mesh)
    med, stats = profile_calls(args.method, mesh, args.size, args.repeat)
    stages = ", ".join(f"{k} {v:.2f}" + (f" (GPU {med['gpu'][k]:.2f})" if k in med["gpu"] else "")
                       for k, v in med["stages"].items())
    print(f"{args.method} on {mesh.name} at {args.size}^3, median of {args.repeat} profiled calls: "
          f"whole {med['wall_ms']:.2f} ms, stages {med['stages_ms']:.2f} ms ({stages}), "
          f"outside them {med['outside_ms']:.2f} ms (cProfile's own cost included)")
    print("| ms per call (own) | calls per call | function |")
    print("|---|---|---|")
    for ms, n, name in top_functions(stats, args.repeat, args.top):
        print(f"| {ms:.3f} | {n} | `{name}` |")
    print(f"profiled outside the stages: {stats.total_tt * 1e3 / args.repeat:.2f} ms per call")
    host = host_cpu(args.method, mesh, args.size, args.repeat)
    print(f"unprofiled, median of {args.repeat} calls: whole {host['wall_ms']:.2f} ms, the calling thread's "
          f"CPU {host['cpu_ms']:.2f} ms per call")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
