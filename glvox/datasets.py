"""The shared meshes by name, and the checkout glvox runs from.

The shared meshes (``../shared/meshes/SOURCES.md``) live outside the
repository.  Everything that looks for them (``glvox compare``, ``glvox
bench``, the scripts in ``compare/``, the pytest plugin, the tests) asks
:func:`mesh_dir` or :func:`resolve_mesh`.
"""

from __future__ import annotations

import os
from pathlib import Path

from .errors import GlvoxError

#: The shared meshes by file name, sorted; tests and scripts over "every
#: shared mesh" iterate over these and skip one that is absent.
SHARED_MESHES = (
    "cad_fandisk.off", "cad_featuretype.stl", "cad_rocker_arm.obj", "cad_wingnut.obj",
    "depth_cycloidal_drive.ply", "depth_gyroid_tpms_sheet.stl", "depth_reduced_diamond_lattice.stl",
    "messy_not_convex.obj", "messy_soup_synthetic.stl", "messy_teapot_newell.obj",
    "messy_tower_holes.obj", "messy_wallhole.obj", "stanford_armadillo_libigl_86k.obj",
    "stanford_bunny_bun_zipper.ply", "stanford_dragon_vrip_res2.ply", "stanford_dragon_vrip_res3.ply",
    "stanford_happy_buddha_113k.obj",
)

#: The folder that holds the glvox package: the checkout's root when glvox
#: runs from one (an editable install), site-packages otherwise.
_ROOT = Path(__file__).resolve().parents[1]


def checkout_root() -> Path | None:
    """The git checkout glvox is imported from, or None for an installed glvox."""
    if (_ROOT / ".git").exists() and (_ROOT / "shaders").is_dir() and (_ROOT / "glvox").is_dir():
        return _ROOT
    return None


def mesh_dir() -> Path:
    """The shared meshes folder: ``GLVOX_MESHES``, else ``../shared/meshes`` beside the checkout."""
    env = os.environ.get("GLVOX_MESHES")
    return Path(env) if env else _ROOT.parent / "shared" / "meshes"


def resolve_mesh(name: str | os.PathLike) -> str:
    """A generated mesh (``gen:...``) as is, an existing path, or a file name in :func:`mesh_dir`.

    Returns
    -------
    str
        ``name`` itself for ``gen:`` meshes, else an absolute path.

    Raises
    ------
    GlvoxError
        When ``name`` is neither an existing path nor a file in :func:`mesh_dir`.
    """
    name = str(name)
    if name.startswith("gen:"):
        return name
    if os.path.exists(name):
        return os.path.abspath(name)
    path = mesh_dir() / name
    if not path.is_file():
        raise GlvoxError(f"mesh {name!r} is neither a path nor a file in {mesh_dir()} (GLVOX_MESHES)")
    return str(path)
