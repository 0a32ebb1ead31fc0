"""The wheel ships the shaders: install into a fresh venv, run from elsewhere."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import venv
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

SCRIPT = """
import numpy as np, glvox
from pathlib import Path
from glvox.context import get_context
from glvox.shaders import builtin_shader_dir
from glvox.testing import run_compute
root = builtin_shader_dir()
assert "site-packages" in str(root), root
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
    # build from a clean copy: a stale build/ folder in the checkout would leak in
    src = tmp_path / "src"
    shutil.copytree(ROOT, src, ignore=shutil.ignore_patterns(
        ".git", "build", "dist", "*.egg-info", "__pycache__", ".venv", ".pytest_cache", ".hypothesis"))
    env_dir = tmp_path / "venv"
    # system site packages give moderngl/numpy/trimesh without a download; glvox
    # itself is installed from the checkout, not taken from the editable install
    venv.EnvBuilder(system_site_packages=True, with_pip=True).create(env_dir)
    py = env_dir / "bin" / "python"
    proc = subprocess.run([str(py), "-m", "pip", "install", "--no-deps", "--no-build-isolation",
                           "--no-index", "-q", str(src)], capture_output=True, text=True, timeout=600,
                          cwd=tmp_path)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    work = tmp_path / "elsewhere"
    work.mkdir()
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "GLVOX_SHADER_PATH")}
    code = f"CHECKOUT = {str(ROOT)!r}\n" + SCRIPT
    run = subprocess.run([str(py), "-c", code], capture_output=True, text=True, timeout=600, cwd=work,
                         env=env)
    assert run.returncode == 0, run.stdout + run.stderr
    assert run.stdout.startswith("OK")
    cli = subprocess.run([str(env_dir / "bin" / "glvox"), "methods"], capture_output=True, text=True,
                         timeout=600, cwd=work, env=env)
    assert cli.returncode == 0 and "reference-solid" in cli.stdout
