"""Pictures in the voxels' own colours (glvox.study.render and `glvox render`): pixels read back at
places known by hand, unlit (exact colours) and lit (the shader's Lambert factor, worked out below)."""

from __future__ import annotations

import re
import subprocess
import sys

import numpy as np
import pytest

from glvox import io
from glvox.formats.colors import DEFAULT_COLOR
from glvox.grid import GridSpec
from glvox.results import VoxelGrid
from glvox.study import render

#: A 3 x 3 x 1 slab seen along -z with +y up: voxel (i, j, 0) is the cell in column i (left to right)
#: and row j (bottom to top) of the slab's picture, its front face (normal +z) filling the cell.
SLAB = GridSpec((3, 3, 1), (-4.0, 2.5, 0.75), 0.5)
FRONT = dict(direction=(0.0, 0.0, 1.0), up=(0.0, 1.0, 0.0))


def colored(occ, spec, colors):
    """A VoxelGrid carrying ``colors`` (M, 4) uint8 as its 'color' attribute (the contract's layout)."""
    grid = VoxelGrid(np.asarray(occ, bool), spec)
    if colors is not None:
        grid.set_attributes({"color": np.asarray(colors, np.uint8)})
    return grid


def slab_colors():
    rng = np.random.default_rng(11)
    colors = rng.integers(0, 256, (9, 4), dtype=np.uint8)
    colors[:, 3] = 255
    colors[4, 3] = 0                                       # the middle voxel has no colour
    return colors


def cell_pixels(img, n=3, background=255):
    """The pixel at the center of each of the n x n cells of the picture's non-background box,
    as {(column, row from the bottom): RGB}."""
    ys, xs = np.nonzero((img != background).any(axis=-1))
    y0, y1, x0, x1 = ys.min(), ys.max() + 1, xs.min(), xs.max() + 1
    return {(i, j): img[int(y1 - (j + 0.5) * (y1 - y0) / n), int(x0 + (i + 0.5) * (x1 - x0) / n)].astype(int)
            for i in range(n) for j in range(n)}


def expected_slab(colors):
    want = colors[:, :3].astype(int).copy()
    want[colors[:, 3] == 0] = DEFAULT_COLOR[:3]
    return {(i, j): want[3 * i + j] for i in range(3) for j in range(3)}   # row 3i + j: C order of (3, 3, 1)


def test_flat_picture_shows_each_voxel_in_its_colour(gl_context):
    colors = slab_colors()
    img = render.render_voxels(gl_context, colored(np.ones(SLAB.dims), SLAB, colors), size=(240, 200),
                               flat=True, **FRONT)
    got, want = cell_pixels(img), expected_slab(colors)
    for cell in want:
        assert np.abs(got[cell] - want[cell]).max() <= 1, (cell, got[cell], want[cell])


def test_lit_picture_scales_each_colour_by_the_same_light(gl_context):
    """cubes.frag on a face with normal +z: tint (1, 1, 0.94), key light (0.6, 0.9, 0.8) normalized gives
    0.8 / |(0.6, 0.9, 0.8)| = 0.5946, the fill light faces away: factor 0.25 + 0.7 * 0.5946 = 0.6662."""
    colors = slab_colors()
    img = render.render_voxels(gl_context, colored(np.ones(SLAB.dims), SLAB, colors), size=(240, 200), **FRONT)
    got, want = cell_pixels(img), expected_slab(colors)
    key = 0.8 / np.linalg.norm([0.6, 0.9, 0.8])
    for cell in want:
        lit = want[cell] * np.array([1.0, 1.0, 0.94]) * (0.25 + 0.7 * key)
        assert np.abs(got[cell] - lit).max() <= 1.5, (cell, got[cell], lit)


def test_grid_without_colours_and_single_colour(gl_context):
    g = colored(np.ones(SLAB.dims), SLAB, None)
    img = render.render_voxels(gl_context, g, size=(120, 100), flat=True, **FRONT)
    assert all(np.abs(p - DEFAULT_COLOR[:3]).max() <= 1 for p in cell_pixels(img).values())
    g = colored(np.ones(SLAB.dims), SLAB, slab_colors())
    img = render.render_voxels(gl_context, g, size=(120, 100), flat=True, own_colors=False, color=(1, 0, 0), **FRONT)
    assert all(p.tolist() == [255, 0, 0] for p in cell_pixels(img).values())


def test_pooled_cells_take_the_mean_colour(gl_context, monkeypatch):
    """Past MAX_CUBES the grid is pooled by 2: a 6 x 6 x 1 slab becomes 3 x 3 cells, each drawn in
    the mean colour of its four voxels (one cell mixes red and blue voxels: (127.5, 0, 127.5))."""
    spec = GridSpec((6, 6, 1), (0.0, 0.0, 0.0), 1.0)
    ijk = np.argwhere(np.ones(spec.dims, bool))
    block = np.random.default_rng(3).integers(0, 256, (3, 3, 3))
    colors = np.concatenate([block[ijk[:, 0] // 2, ijk[:, 1] // 2], np.full((len(ijk), 1), 255)], axis=1)
    mixed = (ijk[:, 0] // 2 == 2) & (ijk[:, 1] // 2 == 0)
    colors[mixed, :3] = np.where((ijk[mixed, 0] % 2 == 0)[:, None], [255, 0, 0], [0, 0, 255])
    monkeypatch.setattr(render, "MAX_CUBES", 20)           # 32 exposed voxels > 20 >= 9 cells
    img = render.render_voxels(gl_context, colored(np.ones(spec.dims), spec, colors.astype(np.uint8)),
                               size=(240, 200), flat=True, **FRONT)
    got = cell_pixels(img)
    for (i, j), p in got.items():
        want = [127.5, 0, 127.5] if (i, j) == (2, 0) else block[i, j]
        assert np.abs(p - want).max() <= 1, ((i, j), p, want)


def glvox(*args):
    return subprocess.run([sys.executable, "-m", "glvox", *map(str, args)], capture_output=True, text=True,
                          timeout=600)


def test_render_command_writes_the_picture(tmp_path):
    pytest.importorskip("matplotlib")
    io.save(colored(np.ones(SLAB.dims), SLAB, None), tmp_path / "slab.npz")
    p = glvox("render", tmp_path / "slab.npz", "-o", tmp_path / "slab.png", "--size", 90, 70,
              "--direction", 0, 0, 1, "--flat", "-q")
    assert p.returncode == 0, p.stderr
    import matplotlib.image

    img = (matplotlib.image.imread(tmp_path / "slab.png")[..., :3] * 255).round().astype(int)
    assert img.shape == (70, 90, 3)
    assert all(np.abs(px - DEFAULT_COLOR[:3]).max() <= 1 for px in cell_pixels(img).values())


@pytest.mark.parametrize("args, message", [
    (["-o", "{tmp}/a.jpg"], r"unknown picture file suffix '\.jpg' for .*: use \.png"),
    (["-o", "{tmp}/a.png", "--size", "0", "10"], r"--size must be two integers in 1\.\.16384"),
    (["-o", "{tmp}/a.png", "--direction", "0", "2", "0"], r"--up \[0\.0, 1\.0, 0\.0\] must not be parallel"),
    (["-o", "{tmp}/nowhere/a.png"], r"the picture's folder .* does not exist"),
])
def test_render_command_refusals(tmp_path, args, message):
    io.save(colored(np.ones(SLAB.dims), SLAB, None), tmp_path / "slab.npz")
    p = glvox("render", tmp_path / "slab.npz", *[a.format(tmp=tmp_path) for a in args])
    assert p.returncode == 1 and p.stderr.count("\n") == 1
    assert p.stderr.startswith("glvox: error: ") and re.search(message, p.stderr), p.stderr


def test_render_command_refuses_an_ldi(tmp_path):
    p = glvox("ldi", "gen:box", "-r", 8, "-m", "reference-ldi", "-o", tmp_path / "l.npz", "-q")
    assert p.returncode == 0, p.stderr
    p = glvox("render", tmp_path / "l.npz", "-o", tmp_path / "l.png")
    assert p.returncode == 1 and "glvox render draws voxel grids" in p.stderr, p.stderr


def test_render_command_refuses_an_empty_grid(tmp_path):
    """A double-sided cube's parity solid is empty: voxelize warns with the cause, and render
    says there is nothing to draw (exit 1) instead of writing a blank picture."""
    from glvox.testing.defects import double_sided_cube, write_obj

    write_obj(tmp_path / "two_faced.obj", double_sided_cube())
    p = glvox("voxelize", tmp_path / "two_faced.obj", "-r", 8, "-m", "reference-solid", "--allow-open",
              "-o", tmp_path / "s.npz", "-q")
    assert p.returncode == 0, p.stderr
    assert re.search(r"glvox: warning: two_faced\.obj: 0 voxels \(empty\) from reference-solid: double-sided "
                     r"faces cancel .*; use -m binvox-solid or -m carve-solid", p.stderr), p.stderr
    p = glvox("render", tmp_path / "s.npz", "-o", tmp_path / "s.png", "-q")
    assert p.returncode == 1 and p.stderr.count("\n") == 1, p.stderr
    assert re.match(r"glvox: error: .*s\.npz holds no voxels \(its \d+x\d+x\d+ grid is empty\): nothing to draw",
                    p.stderr), p.stderr
    assert not (tmp_path / "s.png").exists()
