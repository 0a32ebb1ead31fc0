"""The child of ``compare/before_after.py``: timed glvox operations of one source tree, a JSON request a line.

Run as ``python -S before_after_child.py`` with ``PYTHONPATH`` = the tree and
the parent's site-packages (``glvox.study.ab.child_env``), from a folder of
its own, so ``import glvox`` finds that tree.  Uses only the API every
revision has: ``load_mesh``, ``grid_for``, ``run_method``, ``dense()``,
``points()``.  Prints ``{"ready": glvox.__file__}``, then answers each
request ``{"op": "load" | "e2e" | "dense", "path", ...}``.
"""

import json
import sys
import time
import warnings

import numpy as np

import glvox
from glvox.methods import run_method

warnings.simplefilter("ignore")
print(json.dumps({"ready": glvox.__file__}), flush=True)
for line in sys.stdin:
    req = json.loads(line)
    op = req["op"]
    try:
        t0 = time.perf_counter()
        if op == "load":
            mesh = glvox.load_mesh(req["path"])
            if req.get("closed"):
                mesh.watertight  # noqa: B018 - a lazy verdict in newer trees, a field in older ones
            out = {"s": time.perf_counter() - t0}
        elif op == "e2e":
            mesh = glvox.load_mesh(req["path"])
            g = run_method(req.get("method", "ss-conservative"), mesh, glvox.grid_for(mesh, req["n"]), allow_open=True)
            g.dense()
            out = {"s": time.perf_counter() - t0}
        elif op == "dense":
            mesh = glvox.load_mesh(req["path"])
            spec = glvox.grid_for(mesh, req["n"])
            g = run_method(req["method"], mesh, spec, allow_open=True, **req.get("options", {}))
            wall = time.perf_counter() - t0
            st = {s.name: s.wall_s for s in g.run.timings.stages}
            t1 = time.perf_counter(); d = g.dense(); td = time.perf_counter() - t1
            t1 = time.perf_counter(); p = g.points(); tp = time.perf_counter() - t1
            out = {"run_s": wall, "readback_s": st.get("readback"), "dense_s": td, "points_s": tp,
                   "count": int(g.count)}
            del d, p, g
            # what any dense result pays: nx * ny * nz bytes written into fresh memory (no glvox)
            t1 = time.perf_counter(); a = np.ones(int(np.prod(spec.dims)), dtype=bool)
            out["floor_s"] = time.perf_counter() - t1
            del a
        else:
            out = {"error": f"unknown op {op}"}
    except Exception as exc:
        out = {"error": f"{type(exc).__name__}: {exc}"}
    print(json.dumps(out), flush=True)
