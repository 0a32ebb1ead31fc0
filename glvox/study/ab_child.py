"""The child process of ``glvox bench --against`` (:mod:`glvox.study.ab`): one glvox source tree's runs.

Not imported by glvox: :func:`glvox.study.ab.Side` copies this file beside
the extracted revision and runs it as a script with ``python -S``, with
``PYTHONPATH`` = the source tree followed by the parent's site-packages, so
that ``import glvox`` finds the tree's glvox and nothing else (no site, so no
editable-install finder of the checkout).  It uses only the library API every
glvox revision has (``load_mesh``, ``grid_for``, ``run_method``).

    python -S ab_child.py SRC

First checks that glvox and its shaders were imported from SRC (exits with
a message otherwise) and prints ``{"ready": glvox.__file__}``; then answers
each request line ``{"mesh", "n", "method", "options", "runs"}`` on stdin with
``{"ms": [...]}`` (wall milliseconds of each ``run_method`` call) or
``{"error": "..."}``.
"""

from __future__ import annotations

import json
import sys
import time
import warnings
from pathlib import Path

import glvox
from glvox.mesh import load_mesh
from glvox.methods import run_method

try:  # the shader loader's module moved with the renovation of issue 17
    from glvox.gl.shaders import builtin_shader_dir
except ImportError:
    from glvox.shaders import builtin_shader_dir


def _check_origin(src: Path) -> str:
    """glvox's file, after checking that it and its shaders come from ``src``."""
    where = [Path(glvox.__file__).resolve(), Path(builtin_shader_dir()).resolve()]
    bad = [str(p) for p in where if src not in p.parents]
    if bad:
        sys.exit(f"imported {bad} from outside {src}")
    return glvox.__file__


def _serve() -> None:
    meshes = {}
    for line in sys.stdin:
        req = json.loads(line)
        try:
            mesh = meshes.get(req["mesh"])
            if mesh is None:
                mesh = meshes[req["mesh"]] = load_mesh(req["mesh"])
            spec = glvox.grid_for(mesh, req["n"])
            ms = []
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                for _ in range(req["runs"]):
                    t = time.perf_counter()
                    run_method(req["method"], mesh, spec, allow_open=True, **req["options"])
                    ms.append((time.perf_counter() - t) * 1e3)
            out = {"ms": ms}
        except Exception as exc:  # reported to the parent, which skips the cell
            out = {"error": f"{type(exc).__name__}: {exc}"}
        print(json.dumps(out), flush=True)


if __name__ == "__main__":
    print(json.dumps({"ready": _check_origin(Path(sys.argv[1]).resolve())}), flush=True)
    _serve()
