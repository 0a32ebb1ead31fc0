"""The wheel ships the shaders: build it, install it alone, run from another directory."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

SCRIPT = """
import numpy as np, glvox
from pathlib import Path
from glvox.gl.context import get_context
from glvox.gl.shaders import builtin_shader_dir
from glvox.testing import run_compute
root = builtin_shader_dir()
assert glvox.__file__.startswith(TARGET), glvox.__file__
assert str(root).startswith(TARGET), root
assert not str(root).startswith(CHECKOUT), root
lo = np.arange(8, dtype=np.uint32)
out = run_compute(get_context(), "testing/bits.comp", 1, buffers={0: lo, 1: lo, 2: (32, np.uint32)},
                  read=[2], uniforms={"u_count": 8})[2].reshape(8, 4)
assert out[3, 0] == (0xFFFFFFFF << 3) & 0xFFFFFFFF
g = glvox.voxelize("gen:sphere", 8, method="reference-solid")
print("OK", root, g.count)
"""


@pytest.mark.skipif(not (ROOT / "pyproject.toml").is_file(), reason="needs the source checkout")
def test_regular_install_finds_shaders_from_another_directory(tmp_path):
    # build a wheel from a clean copy (a stale build/ folder in the checkout would leak in)
    src = tmp_path / "src"
    shutil.copytree(ROOT, src, ignore=shutil.ignore_patterns(
        ".git", "build", "dist", "*.egg-info", "__pycache__", ".venv", ".pytest_cache", ".hypothesis"))
    pip = [sys.executable, "-m", "pip"]
    built = subprocess.run(pip + ["wheel", "--no-deps", "--no-build-isolation", "-q", "-w",
                                  str(tmp_path / "dist"), str(src)],
                           capture_output=True, text=True, timeout=600, cwd=tmp_path)
    assert built.returncode == 0, built.stdout + built.stderr
    wheel = next((tmp_path / "dist").glob("glvox-*.whl"))
    # install the wheel alone into a fresh folder; its dependencies come from this
    # environment, glvox itself from the folder (PYTHONPATH precedes site-packages
    # and the editable install of the checkout)
    target = tmp_path / "site"
    inst = subprocess.run(pip + ["install", "--no-deps", "--no-index", "-q", "--target", str(target),
                                 str(wheel)], capture_output=True, text=True, timeout=600)
    assert inst.returncode == 0, inst.stdout + inst.stderr
    assert (target / "glvox" / "_shaders" / "common" / "bits.glsl").is_file()
    assert (target / "glvox" / "_shaders" / "render" / "cubes.vert").is_file()
    # every package of the source tree is in the wheel (pyproject lists them by hand)
    packages = sorted(str(d.relative_to(ROOT)) for d in (ROOT / "glvox").rglob("__init__.py"))
    assert packages and not [p for p in packages if not (target / p).is_file()]
    # the study's scripts and one machine's timings stay in the checkout's compare/
    assert not (target / "glvox" / "compare").exists()
    assert not list(target.rglob("bench_baseline.json"))
    work = tmp_path / "elsewhere"
    work.mkdir()
    env = {k: v for k, v in os.environ.items() if k != "GLVOX_SHADER_PATH"}
    # the wheel's folder first; other PYTHONPATH entries stay (dependencies installed with
    # --target, as on a machine without a virtual environment), the checkout does not
    kept = [p for p in os.environ.get("PYTHONPATH", "").split(os.pathsep) if p and Path(p).resolve() != ROOT]
    env["PYTHONPATH"] = os.pathsep.join([str(target)] + kept)
    code = f"CHECKOUT = {str(ROOT)!r}\nTARGET = {str(target)!r}\n" + SCRIPT
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=600,
                         cwd=work, env=env)
    assert run.returncode == 0, run.stdout + run.stderr
    assert run.stdout.startswith("OK")
    cli = subprocess.run([sys.executable, "-m", "glvox", "methods"], capture_output=True, text=True,
                         timeout=600, cwd=work, env=env)
    assert cli.returncode == 0 and "reference-solid" in cli.stdout
    # the comparison ships too: one small run from the installed package
    cmp = subprocess.run([sys.executable, "-m", "glvox", "compare", "-q", "-m", "ss-solid", "--meshes",
                          "gen:sphere", "-r", "8", "--repeat", "1", "-o", str(work / "cmp")],
                         capture_output=True, text=True, timeout=600, cwd=work, env=env)
    assert cmp.returncode == 0, cmp.stdout + cmp.stderr
    assert (work / "cmp" / "tables.md").is_file()
