"""Time glvox.gpu_sort on this machine: stable radix sort of 1M and 4M uint32
pairs with 4-bit and 8-bit digits, and the exclusive scan of 4M uint32.

Configurations are run interleaved, best of --rounds (the machine may be shared),
each result checked against numpy once.  Usage:

    python compare/bench_gpu_sort.py [--rounds 5] [BITS,WG,ITEMS ...]
"""
from __future__ import annotations

import argparse
import time

import numpy as np

import glvox.gpu.sort as gs
from glvox.gl.context import get_context


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("configs", nargs="*", help="BITS,WG,ITEMS (default: glvox.gpu_sort.RADIX_CONFIGS)")
    args = ap.parse_args()
    configs = ([tuple(int(x) for x in c.split(",")) for c in args.configs]
               or [(b, *wi) for b, wi in sorted(gs.RADIX_CONFIGS.items())])
    ctx = get_context()
    print(f"{ctx.renderer}; {ctx.version}")
    rng = np.random.default_rng(0)

    def timed(fn) -> float:
        ctx.mgl.finish()
        t0 = time.perf_counter()
        fn()
        ctx.mgl.finish()
        return time.perf_counter() - t0

    for n in (1 << 20, 1 << 22):
        keys = rng.integers(0, 2**32, n, dtype=np.uint32)
        values = np.arange(n, dtype=np.uint32)
        order = np.argsort(keys, kind="stable")
        kb, vb = ctx.mgl.buffer(keys.tobytes()), ctx.mgl.buffer(values.tobytes())
        best = dict.fromkeys(configs, float("inf"))
        for r in range(args.rounds + 1):
            for c in configs:
                gs.RADIX_CONFIGS[c[0]] = (c[1], c[2])
                kb.write(keys.tobytes())
                vb.write(values.tobytes())
                dt = timed(lambda: gs.sort_pairs(ctx, kb, vb, n, digit_bits=c[0]))
                if r == 0:  # warm-up round: compile, grow the pool, check
                    assert (np.frombuffer(vb.read(), np.uint32) == order).all(), c
                else:
                    best[c] = min(best[c], dt)
        for c in configs:
            print(f"sort_pairs n={n:>8} {c[0]}-bit digits (wg {c[1]}, {c[2]} keys/invocation): "
                  f"{best[c] * 1e3:7.1f} ms")
        t0 = time.perf_counter()
        np.argsort(keys, kind="stable")
        print(f"  numpy argsort(kind='stable') n={n}: {(time.perf_counter() - t0) * 1e3:.1f} ms")
        kb.release()
        vb.release()

    n = 1 << 22
    a = rng.integers(0, 1000, n, dtype=np.uint32)
    src, dst, total = ctx.mgl.buffer(a.tobytes()), ctx.mgl.buffer(reserve=4 * n), ctx.mgl.buffer(reserve=4)
    gs.exclusive_scan(ctx, src, dst, n, total=total)
    assert int(np.frombuffer(total.read(), np.uint32)[0]) == int(a.sum())
    t = min(timed(lambda: gs.exclusive_scan(ctx, src, dst, n, total=total)) for _ in range(args.rounds))
    t_in = min(timed(lambda: gs.exclusive_scan(ctx, dst, dst, n, total=total)) for _ in range(args.rounds))
    t0 = time.perf_counter()
    np.cumsum(a)
    print(f"exclusive_scan n={n}: {t * 1e3:.1f} ms (in place {t_in * 1e3:.1f} ms); "
          f"numpy cumsum {(time.perf_counter() - t0) * 1e3:.1f} ms")


if __name__ == "__main__":
    main()
