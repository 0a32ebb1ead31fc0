"""Shared test helpers.  The GL fixtures (gl_context, glvox_mesh, glvox_mesh_dir, the GL
error check and the requires_gl marker) come from glvox's own pytest plugin,
installed with the package (entry point pytest11)."""

from __future__ import annotations

import contextlib
import importlib
import importlib.util
import io
import os
from pathlib import Path

import pytest

# The shared meshes (../shared/meshes/SOURCES.md), for `from conftest import
# SHARED_MESHES`: tests over "every shared mesh" are parametrized by these
# names and skip one that is absent.
from glvox.datasets import SHARED_MESHES  # noqa: F401
from glvox.gpu.buffers import z_slabs
from glvox.grid import grid_for
from glvox.mesh import load_mesh
from glvox.methods import method_infos

#: The project's root (compare/ holds the scripts a researcher runs by hand).
ROOT = Path(__file__).resolve().parent.parent

#: Heavier runs (large grids, every shared mesh) are opt-in.
SLOW = os.environ.get("GLVOX_SLOW", "") not in ("", "0")


def _openvdb():
    """OpenVDB's Python module, or None (for `from conftest import VDB, needs_vdb`)."""
    with contextlib.redirect_stderr(io.StringIO()):  # Debian's module complains about numpy 2 on import
        try:
            return importlib.import_module("pyopenvdb")
        except ImportError:
            return None


VDB = _openvdb()
needs_vdb = pytest.mark.skipif(VDB is None, reason="OpenVDB's Python module (pyopenvdb) is not installed: not "
                                                   "on PyPI; .ci/setup installs Debian's python3-openvdb")


def pytest_collection_modifyitems(config, items):
    if SLOW:
        return
    skip = pytest.mark.skip(reason="slow test: set GLVOX_SLOW=1 to run it")
    for item in items:
        if "slow" in item.keywords:
            item.add_marker(skip)


@pytest.fixture(scope="session", autouse=True)
def no_user_calibration(tmp_path_factory):
    """A calibration the user stored (``glvox calibrate``) would change ss-conservative's
    ``auto`` variant under the tests: point the store at a file that does not exist
    (child processes inherit it); tests of the store set their own."""
    with pytest.MonkeyPatch.context() as m:
        m.setenv("GLVOX_CALIBRATION", str(tmp_path_factory.mktemp("calibration") / "none.json"))
        yield


@pytest.fixture(scope="session")
def shared_mesh(glvox_mesh):
    """shared_mesh(name) -> path of a shared mesh, through glvox.datasets (the plugin's glvox_mesh:
    found or downloaded; skipped with one line when not available, failed with GLVOX_REQUIRE_MESHES=1)."""
    return glvox_mesh


@pytest.fixture
def ssbo_limit(gl_context, monkeypatch):
    """GL_MAX_SHADER_STORAGE_BLOCK_SIZE of the context, capped at GL's guaranteed
    2**27 bytes (GL 4.5 core, Table 23.64) and the cap forced on the context for
    the test: llvmpipe and iris report 2**27, NVIDIA 2**31 - 1, where no dense grid
    glvox holds exceeds one block, so a test of the refusal reads this instead."""
    limits = gl_context.limits()
    real = int(limits["GL_MAX_SHADER_STORAGE_BLOCK_SIZE"])
    if real > 2**27:
        monkeypatch.setattr(gl_context, "limits", lambda: {**limits, "GL_MAX_SHADER_STORAGE_BLOCK_SIZE": 2**27})
    return min(real, 2**27)


def load_script(name: str):
    """compare/NAME.py as a module (compare/ holds scripts, not a package)."""
    spec = importlib.util.spec_from_file_location(name, ROOT / "compare" / f"{name}.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def gl_option_runs() -> list[tuple[str, dict]]:
    """Every GL method with its defaults, then with each other value of each choice option
    (for tests that hold every method and option to a property: barriers, bounds)."""
    runs = []
    for info in method_infos():
        if info.pipeline == "cpu":
            continue
        runs.append((info.name, {}))
        for name, opt in info.options.items():
            runs += [(info.name, {name: c}) for c in (opt.choices or ()) if c != opt.default]
    return runs


def run_ids(runs) -> list[str]:
    """Test ids for (method, options) pairs: ``name-option=value``."""
    return [n + "".join(f"-{k}={v}" for k, v in o.items()) for n, o in runs]


def slab_case(gl_context, monkeypatch):
    """gen:bunny-like on a 512 x 256 x 24 grid (16 KiB a slice) with the context's storage
    blocks limited to 6 slices, which the mesh's buffers fit: voxelized in 4 z slabs."""
    mesh = load_mesh("gen:bunny-like")
    spec = grid_for(mesh, dims=(512, 256, 24))
    real = gl_context.limits()
    per_slice = spec.dims[1] * spec.words_per_row * 4
    monkeypatch.setattr(gl_context, "limits", lambda: {**real, "GL_MAX_SHADER_STORAGE_BLOCK_SIZE": 6 * per_slice})
    assert len(z_slabs(gl_context, spec)) == 4
    return mesh, spec
