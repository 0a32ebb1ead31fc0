"""vote-solid: the majority of the x, y and z parities.

vote-solid's three parities use ss-solid's arithmetic along each axis, so on
any mesh it must equal reference-vote (the vote of reference-solid along x,
y and z), and on closed meshes reference-solid itself, every mismatch a
proven solid tie.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest
import trimesh
from conftest import SHARED_MESHES

import glvox
from glvox.errors import NotWatertightWarning
from glvox.grid import GridSpec
from glvox.mesh import load_mesh
from glvox.methods import run_method
from glvox.methods.ss import solid as ss_solid
from glvox.metrics import check_against_reference


def closed_shared():
    return [n for n in SHARED_MESHES if n.startswith(("cad_", "stanford_armadillo", "depth_reduced"))]


def check_vote(mesh, spec):
    """vote-solid against reference-vote (the three-axis vote of reference-solid), mismatches
    proven ties; reference-vote itself against its definition."""
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # any mesh: no NotWatertightWarning
        g = run_method("vote-solid", mesh, spec)
        ref = run_method("reference-vote", mesh, spec)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", NotWatertightWarning)  # the parities of an open mesh, on purpose
        x, y, z = (run_method("reference-solid", mesh, spec, axis=a, allow_open=True).dense() for a in range(3))
    assert np.array_equal(ref.dense(), (x.astype(int) + y + z) >= 2)
    c = check_against_reference(g, mesh)
    assert c.reference == "reference-vote"
    assert c.ok, f"{mesh.name} {spec.dims}: {c.describe()}"
    assert g.count == g.run.stats["voxels"] == int(np.bitwise_count(g.words()).sum())
    return g


@pytest.mark.parametrize("dims", [(45, 70, 33), (100, 37, 64), (32, 32, 96), (7, 9, 130), (64, 20, 9)])
def test_every_word_width_and_partial_words(gl_context, dims):
    """Rows of 1, 2 and 4 words (the fills and the vote move 1, 2 or 4 words per load),
    full and partial last words, y and z crossings packed into x words."""
    mesh = load_mesh("gen:bunny-like")
    check_vote(mesh, glvox.grid_for(mesh, dims=dims))


def test_long_columns_take_several_segments(gl_context, monkeypatch):
    """The running XOR along y and z continues across segments (a dispatch each)."""
    monkeypatch.setattr(ss_solid, "AXIS_SEGMENT", 5)
    mesh = load_mesh("gen:torus")
    check_vote(mesh, glvox.grid_for(mesh, dims=(33, 41, 23)))


@pytest.mark.parametrize("name", ["stanford_bunny_bun_zipper.ply", "messy_teapot_newell.obj",
                                  "messy_tower_holes.obj", "depth_cycloidal_drive.ply"])
def test_open_shared_meshes(gl_context, shared_mesh, name):
    mesh = load_mesh(shared_mesh(name))
    assert not mesh.watertight
    check_vote(mesh, glvox.grid_for(mesh, 64))


def check_closed(mesh, spec):
    g = check_vote(mesh, spec)
    c = check_against_reference(g, mesh, "reference-solid")
    assert c.ok, f"{mesh.name}: {c.describe()}"


@pytest.mark.parametrize("name", closed_shared())
def test_closed_shared_meshes_equal_the_parity_solid(gl_context, shared_mesh, name):
    mesh = load_mesh(shared_mesh(name))
    assert mesh.watertight
    check_closed(mesh, glvox.grid_for(mesh, 64))


@pytest.mark.slow
@pytest.mark.parametrize("name", closed_shared())
def test_closed_shared_meshes_equal_the_parity_solid_large(gl_context, shared_mesh, name):
    check_closed(load_mesh(shared_mesh(name)), glvox.grid_for(load_mesh(shared_mesh(name)), 128))


def test_a_hole_seen_along_one_axis_is_outvoted(gl_context):
    """A box [3, 17]^3 (faces between voxel centers: no ties) with a hole [9, 12]^2 in
    its +x face: the x parity streaks from the hole to the grid's end; y and z see a
    closed box there, so the vote is the box."""
    box = trimesh.creation.box(bounds=[[3.0] * 3, [17.0] * 3])
    keep = ~np.isclose(box.triangles_center[:, 0], 17.0)
    v, f = list(box.vertices), [list(t) for t in box.faces[keep]]
    x = 17.0
    hole = [(x, 3, 3), (x, 17, 3), (x, 17, 17), (x, 3, 17), (x, 9, 9), (x, 12, 9), (x, 12, 12), (x, 9, 12)]
    n = len(v)
    v += hole
    # the +x face as a frame around the hole [8.5, 11.5]^2 (outward +x)
    for a, b in ((0, 1), (1, 2), (2, 3), (3, 0)):
        f += [[n + a, n + b, n + 4 + b], [n + a, n + 4 + b, n + 4 + a]]
    mesh = load_mesh((np.array(v, float), np.array(f)))
    assert not mesh.watertight
    spec = GridSpec((24, 20, 20), (0, 0, 0), 1.0)
    g = check_vote(mesh, spec)
    full = np.zeros(spec.dims, bool)
    full[3:17, 3:17, 3:17] = True  # centers inside [3, 17]^3
    assert np.array_equal(g.dense(), full)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        parity = run_method("ss-solid", mesh, spec, allow_open=True).dense()
    streak = parity & ~full
    assert streak[17:, 9:12, 9:12].all() and streak.sum() == 7 * 9, "x parity streaks through the hole"
