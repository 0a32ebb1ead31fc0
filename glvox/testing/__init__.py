"""A harness to run and test GLSL headless (also glvox's own test fixtures).

Installed with glvox as a pytest plugin (entry point ``pytest11``), it gives
any project's tests:

* ``gl_context``: one shared headless :class:`~glvox.context.GLContext` for
  the session (skips, naming what is missing, where no backend works; with
  ``GLVOX_REQUIRE_GL=1`` that is an error instead);
* a check that no GL error is pending before and after every test that uses
  ``gl_context``;
* the marker ``@pytest.mark.requires_gl(version=450, extensions=(...),
  limits={...})`` that skips with a reason naming the missing capability;
* ``glvox_mesh``: ``glvox_mesh(name)`` gives the path of a mesh glvox knows by
  name (:mod:`glvox.datasets`: found on disk or downloaded), skipping with one
  line that says how to get it when it is not available, failing instead with
  ``GLVOX_REQUIRE_MESHES=1``; ``glvox_mesh_dir``, the first meshes folder;
* the helpers :func:`run_compute` and :func:`run_fragment` below.

Support for tests of ``glvox batch`` pipelines, imported on demand (they need
trimesh and glvox.batch, which this package does not import):

* :mod:`glvox.testing.datasets`: :func:`~glvox.testing.datasets.synthetic_dataset`,
  a folder of small meshes with deliberately broken files (:data:`~glvox.testing.datasets.BROKEN`);
* :mod:`glvox.testing.crash`: :class:`~glvox.testing.crash.CrashingTask`, a
  batch task that kills its own worker process on chosen meshes.

And :mod:`glvox.testing.cells`: boxes, L-shapes and stairs made of lattice
cells, with their exact conservative surfaces and parity solids computed from
the breakpoints alone (numpy only); :mod:`glvox.testing.hazards`:
``trace()``, which names every command that reads a shader's stores without
the memory barrier GL requires (llvmpipe never shows a missing one).
"""

from .harness import run_compute, run_fragment

__all__ = ["run_compute", "run_fragment"]
