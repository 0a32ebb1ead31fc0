"""Reading results back: mapped buffers the result owns against glGetBufferSubData, side by side.

One process alternates the two ways run by run (``forced_mode``; for a whole
process ``GLVOX_READBACK`` picks one): ``copy``, glGetBufferSubData into a fresh
numpy array, and ``mapped``, a GPU copy into a persistently mapped buffer from
the context's pool, which the result then views (glvox/gpu/readback.py).  Each run drops its
result before the next, as a loop over a dataset does.  Per cell: the first
call of each way (the mapped way then allocates and maps its buffer; the copy
way touches fresh pages), then the median of the warm calls, as the user waits
(``run_method``, the numpy words included), with the readback stage beside it.
The machine and GL renderer are printed first.

``--cuda`` adds a third way on a GPU that CUDA sees: ``device='cuda'``, the words
copied on the GPU into CUDA memory that the result owns (glvox/gpu/cuda.py, a
DLPack producer), timed to the point where they are there.

Usage::

    python compare/bench_readback.py                       # bunny surface, armadillo solid, 512^3 and 1024^3
    python compare/bench_readback.py -r 256 512 --repeat 9
    python compare/bench_readback.py --cuda                # and device='cuda' (pip install 'glvox[cuda]')
"""

from __future__ import annotations

import argparse
import gc
import os
import platform
import statistics
import time

import glvox
from glvox.datasets import mesh_dir
from glvox.errors import GlvoxError
from glvox.gl.context import get_context
from glvox.gpu.readback import forced_mode
from glvox.methods import run_method

CASES = [("stanford_bunny_bun_zipper.ply", "ss-conservative"), ("stanford_armadillo_libigl_86k.obj", "ss-solid")]


def _call(mesh, spec, method: str, mode: str) -> tuple[float, float]:
    device = "cuda" if mode == "cuda" else "host"
    with forced_mode("copy" if mode == "copy" else "mapped"):
        t = time.perf_counter()
        result = run_method(method, mesh, spec, device=device)
        wall = time.perf_counter() - t
    readback = sum(s.wall_s for s in result.run.timings.stages if s.name == "readback")
    del result
    gc.collect()
    return wall * 1e3, readback * 1e3


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("-r", "--resolutions", type=int, nargs="+", default=[512, 1024])
    ap.add_argument("--repeat", type=int, default=5, help="warm calls of each way per cell")
    ap.add_argument("--cuda", action="store_true", help="also device='cuda' (needs a GPU that CUDA sees)")
    args = ap.parse_args()
    ctx = get_context()
    modes = ("copy", "mapped", "cuda") if args.cuda else ("copy", "mapped")
    print(f"{platform.node()}, {os.cpu_count()} CPUs, {ctx.renderer}; load average {os.getloadavg()[0]:.2f}")
    print("ms: first call / median warm call (readback stage); ratio = mapped / copy of the warm medians")
    extra = " cuda | ratio cuda / copy, call |" if args.cuda else ""
    print(f"| mesh, method, N | copy | mapped | ratio, call | ratio, readback |{extra}")
    print("|---|---|---|---|---|" + ("---|---|" if args.cuda else ""))
    for name, method in CASES:
        mesh = glvox.load_mesh(str(mesh_dir() / name))
        for mode in modes:  # compile, upload and open CUDA outside the timings
            _call(mesh, glvox.grid_for(mesh, 64), method, mode)
        for n in args.resolutions:
            spec = glvox.grid_for(mesh, n)
            first = {mode: _call(mesh, spec, method, mode) for mode in modes}
            warm = {mode: [] for mode in modes}
            for i in range(args.repeat):
                for mode in (modes if i % 2 == 0 else modes[::-1]):
                    warm[mode].append(_call(mesh, spec, method, mode))
            med = {m: (statistics.median(w for w, _ in v), statistics.median(r for _, r in v)) for m, v in warm.items()}
            cells = [f"{first[m][0]:.0f} / {med[m][0]:.0f} ({first[m][1]:.1f} / {med[m][1]:.1f})" for m in modes]
            row = (f"| {name.split('_')[1]}, {method}, {n}^3 | {cells[0]} | {cells[1]} | "
                   f"{med['mapped'][0] / med['copy'][0]:.2f} | {med['mapped'][1] / max(med['copy'][1], 1e-9):.2f} |")
            if args.cuda:
                row += f" {cells[2]} | {med['cuda'][0] / med['copy'][0]:.2f} |"
            print(row)


if __name__ == "__main__":
    try:
        main()
    except GlvoxError as exc:  # e.g. --cuda where CUDA does not see the GL context
        raise SystemExit(f"bench_readback: {exc}") from None
