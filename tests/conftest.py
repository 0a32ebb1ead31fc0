"""Shared test helpers.  The GL fixtures (gl_context, glvox_mesh, glvox_mesh_dir, the GL
error check and the requires_gl marker) come from glvox's own pytest plugin,
installed with the package (entry point pytest11)."""

from __future__ import annotations

import os

import pytest

# The shared meshes (../shared/meshes/SOURCES.md), for `from conftest import
# SHARED_MESHES`: tests over "every shared mesh" are parametrized by these
# names and skip one that is absent.
from glvox.datasets import SHARED_MESHES  # noqa: F401

#: Heavier runs (large grids, every shared mesh) are opt-in.
SLOW = os.environ.get("GLVOX_SLOW", "") not in ("", "0")


def pytest_collection_modifyitems(config, items):
    if SLOW:
        return
    skip = pytest.mark.skip(reason="slow test: set GLVOX_SLOW=1 to run it")
    for item in items:
        if "slow" in item.keywords:
            item.add_marker(skip)


@pytest.fixture(scope="session")
def shared_mesh(glvox_mesh):
    """shared_mesh(name) -> path of a shared mesh, through glvox.datasets (the plugin's glvox_mesh:
    found or downloaded; skipped with one line when not available, failed with GLVOX_REQUIRE_MESHES=1)."""
    return glvox_mesh
