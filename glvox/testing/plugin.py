"""pytest plugin of glvox (registered through the ``pytest11`` entry point).

pytest loads this module in every session of every project where glvox is
installed, so it imports glvox itself (and with it moderngl) only inside the
fixtures that need it: a project that never asks for ``gl_context`` pays nothing.
"""

from __future__ import annotations

import os
from pathlib import Path

import pytest


def pytest_addoption(parser) -> None:
    parser.addini("glvox_require_gl", type="bool", default=False,
                  help="fail (instead of skip) tests needing a GL context when none can be made")


def pytest_configure(config) -> None:
    config.addinivalue_line(
        "markers",
        "requires_gl(version=450, extensions=(), limits={}): skip unless the GL context "
        "has this version, these extensions and at least these limits",
    )


def _require_gl(config) -> bool:
    return bool(config.getini("glvox_require_gl")) or os.environ.get("GLVOX_REQUIRE_GL", "") not in ("", "0")


@pytest.fixture(scope="session")
def gl_context(request):
    """The process's shared headless GL context (glvox.gl.context.get_context())."""
    from glvox.errors import BackendError
    from glvox.gl.context import get_context

    try:
        ctx = get_context()
    except BackendError as exc:
        if _require_gl(request.config):
            pytest.fail(f"a GL context is required (glvox_require_gl / GLVOX_REQUIRE_GL) but: {exc}",
                        pytrace=False)
        pytest.skip(f"no headless OpenGL context: {exc}")
    return ctx


@pytest.fixture(autouse=True)
def _glvox_gl_error_check(request):
    """No GL error pending before and after each test that uses gl_context."""
    if "gl_context" not in request.fixturenames:
        yield
        return
    ctx = request.getfixturevalue("gl_context")
    ctx.make_current()  # an earlier test may have left a private context current
    before = ctx.mgl.error
    assert before == "GL_NO_ERROR", f"GL error pending before the test: {before}"
    yield
    after = ctx.mgl.error
    assert after == "GL_NO_ERROR", f"GL error left pending by the test: {after}"


@pytest.fixture(autouse=True)
def _glvox_requires_gl(request):
    marker = request.node.get_closest_marker("requires_gl")
    if marker is None:
        yield
        return
    from glvox.methods import Requirements

    ctx = request.getfixturevalue("gl_context")
    kw = dict(marker.kwargs)
    req = Requirements(gl_version=kw.get("version", 450),
                       extensions=tuple(kw.get("extensions", ())),
                       limits=dict(kw.get("limits", {})))
    missing = req.missing(ctx)
    if missing:
        pytest.skip(f"GL context ({ctx.renderer}) lacks: {'; '.join(missing)}")
    yield


def _require_meshes() -> str | None:
    """Why a mesh that is not available fails the test instead of skipping it, or None:
    ``GLVOX_REQUIRE_MESHES=1``, or ``CI=true`` (a CI run must not pass by skipping its mesh
    tests; ``GLVOX_REQUIRE_MESHES=0`` lets one skip them anyway)."""
    req = os.environ.get("GLVOX_REQUIRE_MESHES", "")
    if req not in ("", "0"):
        return "GLVOX_REQUIRE_MESHES is set"
    if req == "" and os.environ.get("CI", "").strip().lower() in ("true", "1", "yes"):
        return "CI is set (GLVOX_REQUIRE_MESHES=0 skips instead)"
    return None


def _looked_in() -> str:
    from glvox.datasets import search_dirs

    return f"looked in {', '.join(str(d) for d in search_dirs())}"


def mesh_or_skip(name: str) -> Path:
    """The path of mesh ``name`` (:func:`glvox.datasets.fetch`: GLVOX_MESHES, else ../shared/meshes
    beside the checkout, else the user cache, else a download); when it is not available, skip
    the calling test with one line naming it, where it was looked for and how to get it, or fail
    it when ``GLVOX_REQUIRE_MESHES=1`` or ``CI=true`` (sites that must not pass by skipping)."""
    from glvox.datasets import fetch
    from glvox.errors import DatasetError

    try:
        return fetch(name, quiet=True)
    except DatasetError as exc:
        msg = f"{exc} ({_looked_in()})"
    why = _require_meshes()  # outside the except: one line, not a chained traceback
    if why:
        pytest.fail(f"{why} and {msg}", pytrace=False)
    pytest.skip(msg)


@pytest.fixture(scope="session")
def glvox_mesh():
    """``glvox_mesh(name)`` -> Path of a mesh glvox knows by name (see :func:`mesh_or_skip`)."""
    return mesh_or_skip


@pytest.fixture(scope="session")
def glvox_mesh_dir() -> Path:
    """The first meshes folder glvox looks in (:func:`glvox.datasets.mesh_dir`); a mesh by name is
    better asked of ``glvox_mesh``, which also finds it in the cache or downloads it."""
    from glvox.datasets import mesh_dir

    path = mesh_dir()
    if not path.is_dir():
        msg = f"no meshes folder at {path} ({_looked_in()}): `glvox data fetch --all`, or set GLVOX_MESHES"
        why = _require_meshes()
        if why:
            pytest.fail(f"{why} and {msg}", pytrace=False)
        pytest.skip(msg)
    return path
