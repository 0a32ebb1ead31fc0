"""``glvox calibrate``: time ``ss-conservative``'s variants on this GPU and store the fastest.

    glvox calibrate                                  # the bunny at 64^3 .. 512^3
    glvox calibrate --mesh gen:torus --sizes 64 128 256 512 1024 --repeat 7
    glvox calibrate --show                           # what is stored for this renderer

Each variant (simple, specialized, sorted; sorted only where one indirect
dispatch holds the triangles) runs once to compile and allocate, then
``--repeat`` interleaved rounds (the order rotating) of the whole
``run_method`` call; the best wall time decides.  The winners are stored per
density band (F / N^2, :mod:`glvox.methods.ss.variant_store`) under this
context's GL_RENDERER, replacing what was stored for it; ``variant='auto'``
uses them on this renderer from then on, and says so in the run statistics
(``variant_rule``).  The bands come from one mesh at several sizes: a mesh
of another density takes the nearest band.
"""

from __future__ import annotations

import json
import os
import time
from typing import Any

from ..datasets import resolve_mesh
from ..gl.context import get_context
from ..grid import grid_for
from ..mesh import load_mesh
from ..methods import run_method
from ..methods.ss import variant_store
from ..methods.ss.surface import LOCAL_SIZE, VARIANTS, auto_variant

def measure(ctx, mesh, sizes, repeat: int, mesh_name: str, say=print) -> list[dict[str, Any]]:
    """One store entry per size: best wall ms of each variant and the fastest one."""
    max_groups = int(ctx.limits()["GL_MAX_COMPUTE_WORK_GROUP_COUNT"][0])
    variants = [v for v in VARIANTS if v != "sorted" or mesh.n_triangles <= max_groups * LOCAL_SIZE]
    entries = []
    for n in sizes:
        spec = grid_for(mesh, n)
        for v in variants:  # warm-up: compilation and buffers
            run_method("ss-conservative", mesh, spec, ctx=ctx, variant=v)
        times: dict[str, list[float]] = {v: [] for v in variants}
        for rnd in range(repeat):
            k = rnd % len(variants)
            for v in variants[k:] + variants[:k]:
                t0 = time.perf_counter()
                run_method("ss-conservative", mesh, spec, ctx=ctx, variant=v)
                times[v].append(time.perf_counter() - t0)
        best = {v: round(min(t) * 1e3, 3) for v, t in times.items()}
        winner = min(best, key=best.get)
        entries.append({"n": int(n), "dims": list(spec.dims), "triangles": int(mesh.n_triangles),
                        "density": variant_store.density(mesh.n_triangles, spec.dims), "variant": winner,
                        "best_ms": best, "mesh": mesh_name, "repeat": int(repeat)})
        say(f"{n:>5}^3  F/N^2 {entries[-1]['density']:8.3f}  "
            + "  ".join(f"{v} {best[v]:9.2f} ms" for v in variants) + f"  fastest: {winner}")
    return entries


def main(args) -> int:
    ctx = get_context()
    renderer = ctx.renderer
    path = variant_store.store_path()
    if args.show:
        entries = variant_store.load(path).get(renderer, [])
        if args.json:
            print(json.dumps({"renderer": renderer, "path": str(path), "entries": entries}, indent=1))
        else:
            print(f"renderer: {renderer}\nstore:    {path}")
            for e in entries or []:
                print(f"  F/N^2 {e['density']:8.3f} ({e.get('mesh', '?')} at {e['n']}^3): {e['variant']}")
            if not entries:
                print("  nothing stored: auto uses the llvmpipe rule (`glvox calibrate` measures this GPU)")
        return 0
    mesh = load_mesh(resolve_mesh(args.mesh))
    say = (lambda *_: None) if args.json or args.quiet else print
    say(f"renderer: {renderer}; {args.mesh} ({mesh.n_triangles} triangles); best of {args.repeat} "
        f"interleaved runs per variant; load average {os.getloadavg()[0]:.2f}")
    entries = measure(ctx, mesh, args.sizes, args.repeat, args.mesh, say)
    saved = variant_store.save(renderer, entries, path)
    max_groups = int(ctx.limits()["GL_MAX_COMPUTE_WORK_GROUP_COUNT"][0])
    picks = [auto_variant(mesh.n_triangles, e["dims"], max_groups, renderer)[0] for e in entries]
    if args.json:
        print(json.dumps({"renderer": renderer, "path": str(saved), "entries": entries,
                          "load_average": os.getloadavg()[0]}, indent=1))
    else:
        chosen = ", ".join(f"{e['n']}^3: {p}" for e, p in zip(entries, picks))
        say(f"stored in {saved}; auto now picks {chosen} on this renderer; "
            f"load average {os.getloadavg()[0]:.2f}")
    return 0
