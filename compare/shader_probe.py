"""What part of a shader costs the time: a method's stages with one shader patched, beside the shader as it is.

No GPU profiler needed, on llvmpipe or a lent GPU: each side runs in its own
child process (the patched shader through ``GLVOX_SHADER_PATH``, an overlay
folder holding the patched copy), the two take turns ``--rounds`` times, and
each child times ``--repeat`` warm calls of ``run_method``.  The table gives
per stage the GPU time where timed, else the wall time (stages repeated
per slab summed; the median of a child's calls, the best child), the whole
call, and the voxel count of each side.

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
import subprocess
import sys
import tempfile
import warnings
from pathlib import Path

import glvox
from glvox.datasets import resolve_mesh
from glvox.gl.shaders import builtin_shader_dir
from glvox.study.harness import timed


def _child(method: str, mesh_name: str, n: int, repeat: int) -> None:
    """The compare/ scripts' timing protocol (:func:`glvox.study.harness.timed`); one JSON line."""
    warnings.simplefilter("ignore")
    mesh = glvox.load_mesh(resolve_mesh(mesh_name, quiet=True))
    t = timed(method, mesh, glvox.grid_for(mesh, n), repeat, allow_open=True)
    print(json.dumps({"stages": t.stages_ms, "wall": t.wall_ms, "min": t.min_ms, "gpu": t.gpu_min_ms,
                      "count": int(t.result.count)}), flush=True)


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
    try:
        args.mesh = resolve_mesh(args.mesh, quiet=True)  # a bad name stops here, not in the children
    except glvox.GlvoxError as exc:
        raise SystemExit(f"shader_probe: {exc}") from None
    with tempfile.TemporaryDirectory(prefix="glvox-probe-") as tmp:
        overlay = _patch(args.shader, args.replace, Path(tmp))
        runs: dict[str, list[dict]] = {"as is": [], "patched": []}
        for _ in range(args.rounds):
            runs["as is"].append(_side(args, {}))
            runs["patched"].append(_side(args, {"GLVOX_SHADER_PATH": str(overlay)}))
    print(f"{args.method}, {args.mesh}, {args.resolution}^3, {args.shader} patched "
          f"({len(args.replace)} replacement(s)); {platform.node()}, {os.cpu_count()} CPUs; "
          f"{args.rounds} children x {args.repeat} warm calls per side, ms")
    best = {side: {} for side in runs}  # per stage: the best of the rounds' medians
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
    for label, key in (("whole call (best)", "min"), ("whole call (median)", "wall")):
        a, b = min(r[key] for r in runs["as is"]), min(r[key] for r in runs["patched"])
        print(f"| {label} | {a:.1f} | {b:.1f} | {b / a:.2f} |")
    if all(r["gpu"] is not None for rs in runs.values() for r in rs):
        a, b = min(r["gpu"] for r in runs["as is"]), min(r["gpu"] for r in runs["patched"])
        print(f"| GPU time (timer queries, best) | {a:.1f} | {b:.1f} | {b / a:.2f} |")
    print(f"| voxels | {runs['as is'][-1]['count']:,} | {runs['patched'][-1]['count']:,} | |")


if __name__ == "__main__":
    main()
