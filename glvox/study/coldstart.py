"""A method's cold start, in a fresh process: ``glvox bench --cold-start``.

    python -m glvox.study.coldstart METHOD MESH N [LAUNCHED]

prints one JSON object (milliseconds): ``import_ms`` (from LAUNCHED, the
``time.time()`` at which :func:`cold_start` launched the process, to this
module running: interpreter start and ``import glvox``; null without
LAUNCHED), ``context_ms`` (the GL
context), ``load_ms`` (mesh load and grid), ``first_ms`` (the first call:
compilation, LLVM code generation at the first dispatch, upload,
allocation), ``compile_ms`` (the GLSL compilation inside it) and
``second_ms`` (the second call).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
import warnings
from typing import Any, Sequence

import glvox
from glvox.gl.context import get_context
from glvox.methods import run_method


def measure(method: str, mesh_name: str, n: int) -> dict[str, float]:
    """Context, mesh load, first and second call of ``method`` in this process, in ms."""
    t1 = time.perf_counter()
    get_context()
    t2 = time.perf_counter()
    mesh = glvox.load_mesh(mesh_name)
    spec = glvox.grid_for(mesh, n)
    t3 = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        g = run_method(method, mesh, spec, allow_open=True)
        t4 = time.perf_counter()
        run_method(method, mesh, spec, allow_open=True)
        t5 = time.perf_counter()
    return {"context_ms": (t2 - t1) * 1e3, "load_ms": (t3 - t2) * 1e3, "first_ms": (t4 - t3) * 1e3,
            "compile_ms": g.run.timings.compile_s * 1e3, "second_ms": (t5 - t4) * 1e3}


def cold_start(method: str, mesh: str, n: int, disk_cache: bool = False) -> dict[str, Any]:
    """Run this module in a fresh interpreter for ``method`` on ``mesh`` at N = ``n``.

    ``disk_cache=False`` sets ``MESA_SHADER_CACHE_DISABLE=true``: Mesa keeps
    compiled shaders on disk between processes, which hides compilation from
    every run after the first on a machine.

    Returns
    -------
    dict
        ``method``, ``mesh``, ``n``, ``disk_cache`` and the module's timings
        (see the module docstring), or ``method`` and ``error``.
    """
    env = dict(os.environ)
    if not disk_cache:
        env["MESA_SHADER_CACHE_DISABLE"] = "true"
    launched = time.time()
    p = subprocess.run([sys.executable, "-m", "glvox.study.coldstart", method, mesh, str(n), repr(launched)],
                       capture_output=True, text=True, env=env, timeout=600)
    if p.returncode != 0:
        return {"method": method, "error": (p.stderr.strip().splitlines() or ["?"])[-1]}
    return {"method": method, "mesh": mesh, "n": n, "disk_cache": disk_cache,
            **json.loads(p.stdout.strip().splitlines()[-1])}


def main(argv: Sequence[str] | None = None) -> int:
    started = time.time()
    method, mesh, n, *launched = sys.argv[1:] if argv is None else argv
    out = {"import_ms": (started - float(launched[0])) * 1e3 if launched else None, **measure(method, mesh, int(n))}
    print(json.dumps(out))
    return 0


if __name__ == "__main__":
    sys.exit(main())
