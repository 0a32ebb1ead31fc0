"""What part of a shader costs the time: a method's stages with one shader patched, beside the shader as it is.

No GPU profiler needed, on llvmpipe or a lent GPU: each side runs in its own
child process (the patched shader through ``GLVOX_SHADER_PATH``, an overlay
folder holding the patched copy), the two take turns ``--rounds`` times, and
each child times ``--repeat`` warm calls of ``run_method``.  The table gives
the best time per stage (stages repeated per slab summed), the whole call,
the GPU time and the voxel count of each side.

A patch usually makes the result wrong: that is the point.  It times what is
left when a loop, a load or a pass is gone (the count column shows how wrong).
This is how gwn-solid's barrier-laden listing pass and eisemann's transpose
loop were found (docs/methods/gwn.md, docs/methods/eisemann.md).

Usage::

    python compare/shader_probe.py -m gwn-solid --mesh stanford_bunny_bun_zipper.ply -r 512 \\
        --shader gwn/field.comp \\
        --replace "for (int r = u_roots.x; r < u_roots.y; ++r) {" "for (int r = u_roots.x; r < u_roots.x; ++r) {"
    python compare/shader_probe.py -m eisemann-solid --mesh stanford_bunny_bun_zipper.ply -r 256 \\
        --shader eisemann/slices.frag --replace "void main() {" "void main() { eis_write_suffix(0); return;"

Each ``--replace OLD NEW`` must match the shader text exactly once.  Solid
methods run with ``allow_open``, so open meshes may be probed too.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import subprocess
import sys
import tempfile
import time
import warnings
from pathlib import Path

import glvox
from glvox.datasets import mesh_dir
from glvox.gl.shaders import builtin_shader_dir
from glvox.methods import run_method


def _child(method: str, mesh_name: str, n: int, repeat: int) -> None:
    """Warm-up, then ``repeat`` timed calls; one JSON line: per-stage best ms, whole calls, count."""
    warnings.simplefilter("ignore")
    path = Path(mesh_name)
    mesh = glvox.load_mesh(str(path if path.exists() else mesh_dir() / mesh_name))
    spec = glvox.grid_for(mesh, n)
    run_method(method, mesh, spec, allow_open=True)  # compile and upload outside the timings
    stages: dict[str, list[float]] = {}
    walls, gpus, count = [], [], 0
    for _ in range(repeat):
        t0 = time.perf_counter()
        g = run_method(method, mesh, spec, allow_open=True)
        walls.append((time.perf_counter() - t0) * 1e3)
        gpus.append(sum(s.gpu_s or 0.0 for s in g.run.timings.stages) * 1e3)
        per: dict[str, float] = {}
        for s in g.run.timings.stages:
            per[s.name] = per.get(s.name, 0.0) + s.wall_s * 1e3
        for name, ms in per.items():
            stages.setdefault(name, []).append(ms)
        count = int(g.count)
        del g
    print(json.dumps({"stages": {k: min(v) for k, v in stages.items()}, "walls": walls, "gpu": min(gpus),
                      "count": count}), flush=True)


def _side(args, env_extra: dict[str, str]) -> dict:
    env = {**os.environ, **env_extra}
    cmd = [sys.executable, __file__, "--child", "-m", args.method, "--mesh", args.mesh, "-r", str(args.resolution),
           "--repeat", str(args.repeat)]
    p = subprocess.run(cmd, capture_output=True, text=True, env=env, timeout=3600)
    if p.returncode != 0:
        raise SystemExit(f"the child failed ({'patched' if env_extra else 'as is'}):\n{p.stderr[-3000:]}")
    return json.loads(p.stdout.strip().splitlines()[-1])


def _patch(shader: str, replaces: list[list[str]], folder: Path) -> Path:
    src = builtin_shader_dir() / shader
    if not src.is_file():
        raise SystemExit(f"no shader {shader} in {builtin_shader_dir()}")
    text = src.read_text()
    for old, new in replaces:
        n = text.count(old)
        if n != 1:
            raise SystemExit(f"--replace text occurs {n} times in {shader}, not once: {old!r}")
        text = text.replace(old, new)
    out = folder / shader
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(text)
    return folder


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("-m", "--method", required=True)
    ap.add_argument("--mesh", required=True, help="a path, or a name in GLVOX_MESHES")
    ap.add_argument("-r", "--resolution", type=int, default=256)
    ap.add_argument("--shader", help="the shader to patch, relative to the shader folder (gwn/field.comp)")
    ap.add_argument("--replace", nargs=2, action="append", default=[], metavar=("OLD", "NEW"))
    ap.add_argument("--repeat", type=int, default=3, help="warm calls per child")
    ap.add_argument("--rounds", type=int, default=2, help="turns of the two children")
    ap.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child:
        _child(args.method, args.mesh, args.resolution, args.repeat)
        return
    if not args.shader or not args.replace:
        ap.error("--shader and at least one --replace are needed")
    with tempfile.TemporaryDirectory(prefix="glvox-probe-") as tmp:
        overlay = _patch(args.shader, args.replace, Path(tmp))
        runs: dict[str, list[dict]] = {"as is": [], "patched": []}
        for _ in range(args.rounds):
            runs["as is"].append(_side(args, {}))
            runs["patched"].append(_side(args, {"GLVOX_SHADER_PATH": str(overlay)}))
    print(f"{args.method}, {args.mesh}, {args.resolution}^3, {args.shader} patched "
          f"({len(args.replace)} replacement(s)); {platform.node()}, {os.cpu_count()} CPUs; "
          f"best of {args.rounds} x {args.repeat} warm calls per side, ms")
    best = {side: {} for side in runs}
    for side, rs in runs.items():
        for r in rs:
            for name, ms in r["stages"].items():
                best[side][name] = min(ms, best[side].get(name, float("inf")))
    names = list(dict.fromkeys([*best["as is"], *best["patched"]]))
    print("| | as is | patched | patched / as is |\n|---|---|---|---|")
    for name in names:
        a, b = best["as is"].get(name), best["patched"].get(name)
        ratio = f"{b / a:.2f}" if a and b is not None else "-"
        print(f"| {name} | {'-' if a is None else f'{a:.1f}'} | {'-' if b is None else f'{b:.1f}'} | {ratio} |")
    for label, key in (("whole call (best)", min), ("whole call (median)", statistics.median)):
        a = key(sum((r["walls"] for r in runs["as is"]), []))
        b = key(sum((r["walls"] for r in runs["patched"]), []))
        print(f"| {label} | {a:.1f} | {b:.1f} | {b / a:.2f} |")
    a, b = min(r["gpu"] for r in runs["as is"]), min(r["gpu"] for r in runs["patched"])
    print(f"| GPU time (timer queries) | {a:.1f} | {b:.1f} | {b / a:.2f} |")
    print(f"| voxels | {runs['as is'][-1]['count']:,} | {runs['patched'][-1]['count']:,} | |")


if __name__ == "__main__":
    main()
