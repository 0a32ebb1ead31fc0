"""Pictures of voxelizations, rendered headless in glvox's own GL context.

* :func:`render_voxels`: the exposed voxels of a grid as lit cubes
  (instanced), in the voxels' own colours when the grid carries them
  (``attributes['color']``), optionally with the mesh's edges drawn over
  them, seen from a three-quarter view that frames the grid.
* :func:`disagreement_slice`: one slice of two grids colored by where they
  agree and where each has voxels the other lacks (like Zhang et al. Fig. 15c).

Both return uint8 RGB images (H, W, 3); :func:`save_png` writes them.
"""

from __future__ import annotations

from pathlib import Path

import moderngl
import numpy as np

from glvox.formats.colors import filled, has_colors, voxel_colors
from glvox.gl.shaders import render_program
from glvox.results.voxels import VoxelGrid

#: Exposed voxels rendered at most; beyond, the grid is max-pooled by 2 until
#: it fits (llvmpipe draws a few million cubes in seconds, not more).
MAX_CUBES = 1_500_000

_CUBE = None


def _cube() -> np.ndarray:
    """36 vertices (position, normal) of the unit cube [-0.5, 0.5]^3, float32."""
    global _CUBE
    if _CUBE is None:
        out = []
        for axis in range(3):
            for sign in (-1.0, 1.0):
                n = np.zeros(3)
                n[axis] = sign
                u, v = np.eye(3)[(axis + 1) % 3], np.eye(3)[(axis + 2) % 3]
                c = n * 0.5
                quad = [c - u / 2 - v / 2, c + u / 2 - v / 2, c + u / 2 + v / 2, c - u / 2 + v / 2]
                order = [0, 1, 2, 0, 2, 3] if sign > 0 else [0, 2, 1, 0, 3, 2]
                out += [np.concatenate([quad[i], n]) for i in order]
        _CUBE = np.array(out, dtype="f4")
    return _CUBE


def exposed(occ: np.ndarray) -> np.ndarray:
    """Set voxels with at least one empty (or out-of-grid) 6-neighbour."""
    p = np.pad(occ, 1)
    inner = p[:-2, 1:-1, 1:-1] & p[2:, 1:-1, 1:-1] & p[1:-1, :-2, 1:-1] & p[1:-1, 2:, 1:-1] \
        & p[1:-1, 1:-1, :-2] & p[1:-1, 1:-1, 2:]
    return occ & ~inner


def _look_at(eye, target, up) -> np.ndarray:
    f = target - eye
    f = f / np.linalg.norm(f)
    s = np.cross(f, up)
    s = s / np.linalg.norm(s)
    u = np.cross(s, f)
    m = np.eye(4)
    m[0, :3], m[1, :3], m[2, :3] = s, u, -f
    m[:3, 3] = -m[:3, :3] @ eye
    return m


def _perspective(fovy_deg, aspect, near, far) -> np.ndarray:
    f = 1.0 / np.tan(np.radians(fovy_deg) / 2)
    m = np.zeros((4, 4))
    m[0, 0], m[1, 1] = f / aspect, f
    m[2, 2], m[2, 3] = (far + near) / (near - far), 2 * far * near / (near - far)
    m[3, 2] = -1.0
    return m


def camera(extent: np.ndarray, size: tuple[int, int], direction=(0.9, 0.65, 1.25),
           up=(0.0, 1.0, 0.0)) -> np.ndarray:
    """View-projection matrix framing a box of ``extent`` centered at the origin."""
    r = 0.5 * float(np.linalg.norm(extent))
    d = np.asarray(direction, float)
    eye = d / np.linalg.norm(d) * r * 2.6
    proj = _perspective(36.0, size[0] / size[1], 0.05 * r, 8.0 * r)
    return proj @ _look_at(eye, np.zeros(3), np.asarray(up, float))


def pooled_colors(indices: np.ndarray, colors: np.ndarray, level: int, dims, cells: np.ndarray) -> np.ndarray:
    """The mean RGB of the coloured voxels in each cell of a grid pooled ``level`` times by 2.

    Parameters
    ----------
    indices : (M, 3) int64
        Set voxels of the full grid.
    colors : (M, 4) uint8
        Their RGBA; alpha 0 (no colour) rows count as :data:`~glvox.formats.colors.DEFAULT_COLOR`.
    level : int
        Poolings by 2 (cell = index // 2**level).
    dims : (3,) int
        Dims of the pooled grid.
    cells : (K, 3) int64
        Pooled cells whose colour is wanted (each holds a set voxel).

    Returns
    -------
    (K, 3) float32 RGB in [0, 1]
    """
    rgb = filled(colors, len(indices))[:, :3].astype(np.float64)
    lin = np.ravel_multi_index((indices >> level).T, dims)
    keys, inverse = np.unique(lin, return_inverse=True)
    total = np.bincount(inverse, minlength=len(keys)).astype(np.float64)
    means = np.stack([np.bincount(inverse, rgb[:, c], minlength=len(keys)) for c in range(3)], axis=1)
    rows = np.searchsorted(keys, np.ravel_multi_index(cells.T, dims))
    return (means[rows] / total[rows, None] / 255.0).astype("f4")


def pooled_exposed(occ: np.ndarray) -> tuple[np.ndarray, np.ndarray, int]:
    """The exposed voxels of ``occ``, pooled by 2 per axis (a cell set when any of its
    voxels is) until at most :data:`MAX_CUBES` are left: ``(pooled occ, (K, 3) indices
    of its exposed cells, pooling level)``; cell size ``2 ** level`` voxels."""
    level = 0
    while True:
        vox = np.argwhere(exposed(occ))
        if len(vox) <= MAX_CUBES:
            return occ, vox, level
        pad = [(0, s % 2) for s in occ.shape]
        occ = np.pad(occ, pad).reshape(occ.shape[0] // 2 + pad[0][1], 2, occ.shape[1] // 2 + pad[1][1], 2,
                                       occ.shape[2] // 2 + pad[2][1], 2).any(axis=(1, 3, 5))
        level += 1


def render_voxels(ctx, grid: VoxelGrid, size: tuple[int, int] = (960, 720), mesh=None,
                  color=(0.55, 0.68, 0.86), background=(1.0, 1.0, 1.0), direction=(0.9, 0.65, 1.25),
                  up=(0.0, 1.0, 0.0), own_colors: bool = True, flat: bool = False) -> np.ndarray:
    """Lit cubes of ``grid``'s exposed voxels, optionally with ``mesh``'s edges.

    Parameters
    ----------
    ctx : glvox.context.GLContext
    grid : VoxelGrid
    size : (width, height) in pixels
    mesh : glvox.mesh.Mesh, optional
        Drawn as dark edges over the voxels.
    color : RGB in [0, 1]
        The cubes' colour, for grids without colours (and ``own_colors=False``).
    direction, up : 3-vectors
        Where the camera looks from (relative to the grid's center) and its up axis.
    own_colors : bool
        Draw each voxel in its ``attributes['color']`` when the grid has
        one (voxels with alpha 0 in :data:`~glvox.formats.colors.DEFAULT_COLOR`;
        where the grid is pooled, a cell in the mean of its voxels' colours).
    flat : bool
        Unlit: each face in its voxel's colour exactly (for pictures read back).

    Returns
    -------
    (height, width, 3) uint8
    """
    ctx.make_current()
    mgl = ctx.mgl
    occ = np.asarray(grid.dense())
    h, origin = grid.voxel_size, np.asarray(grid.origin, float)
    indices, colors = voxel_colors(grid, "render") if own_colors and has_colors(grid) else (None, None)
    occ, vox, level = pooled_exposed(occ)
    h *= 2.0 ** level
    if colors is not None:
        vox_rgb = pooled_colors(indices, colors, level, occ.shape, vox)
    else:
        vox_rgb = np.tile(np.asarray(color, "f4"), (len(vox), 1))
    # frame the set voxels (the grid is cubic around the mesh's longest side)
    if len(vox):
        lo, hi = vox.min(axis=0) * h + origin, (vox.max(axis=0) + 1) * h + origin
    else:
        lo, hi = origin, origin + np.asarray(grid.dims) * grid.voxel_size
    center, extent = 0.5 * (lo + hi), hi - lo
    mvp = camera(extent, size, direction, up).astype("f4")
    w, hgt = size
    color_tex = mgl.texture((w, hgt), 4)
    depth = mgl.depth_renderbuffer((w, hgt))
    fbo = mgl.framebuffer(color_attachments=[color_tex], depth_attachment=depth)
    objects = [color_tex, depth]
    try:
        fbo.use()
        fbo.viewport = (0, 0, w, hgt)
        fbo.clear(*background, 1.0)
        mgl.enable(moderngl.DEPTH_TEST | moderngl.CULL_FACE)
        if len(vox):
            prog = render_program(ctx, "render/cubes.vert", "render/cubes.frag")
            prog["u_mvp"].write(mvp.T.tobytes())
            prog["u_origin"].value = tuple(origin - center)
            prog["u_h"].value = float(h)
            prog["u_light"].value = (0.6, 0.9, 0.8)
            prog["u_flat"].value = bool(flat)
            vbo = mgl.buffer(_cube().tobytes())
            ibo = mgl.buffer(np.concatenate([vox.astype("f4"), vox_rgb], axis=1).tobytes())
            vao = mgl.vertex_array(prog, [(vbo, "3f 3f", "in_pos", "in_normal"),
                                          (ibo, "3f 3f/i", "in_voxel", "in_color")])
            objects += [vbo, ibo, vao]
            vao.render(moderngl.TRIANGLES, instances=len(vox))
        if mesh is not None:
            tris = np.asarray(mesh.vertices, float)[np.asarray(mesh.faces)]
            edges = np.concatenate([tris[:, [0, 1]], tris[:, [1, 2]], tris[:, [2, 0]]]).reshape(-1, 3)
            prog = render_program(ctx, "render/lines.vert", "render/lines.frag")
            prog["u_mvp"].write(mvp.T.tobytes())
            prog["u_color"].value = (0.1, 0.1, 0.12, 1.0)
            lbo = mgl.buffer((edges - center).astype("f4").tobytes())
            lvao = mgl.vertex_array(prog, [(lbo, "3f", "in_pos")])
            objects += [lbo, lvao]
            mgl.disable(moderngl.CULL_FACE)
            lvao.render(moderngl.LINES)
        data = color_tex.read()
    finally:
        mgl.disable(moderngl.DEPTH_TEST | moderngl.CULL_FACE)
        ctx.release_framebuffer(fbo)
        for o in reversed(objects):
            o.release()
    img = np.frombuffer(data, dtype=np.uint8).reshape(hgt, w, 4)[::-1, :, :3]
    return np.ascontiguousarray(img)


#: Slice colors: both set, only the first grid, only the second, neither.
BOTH, ONLY_A, ONLY_B, NONE = (120, 120, 120), (220, 50, 40), (40, 90, 220), (255, 255, 255)


def disagreement_slice(a: VoxelGrid, b: VoxelGrid, axis: int = 2, index: int | None = None,
                       scale: int | None = None) -> tuple[np.ndarray, int]:
    """One slice of two grids on the same spec, colored by agreement.

    Gray where both are set, red where only ``a`` is, blue where only ``b``
    is, white where neither.  ``index`` defaults to the slice with the most
    disagreement.  The image is upscaled by ``scale`` (default: to about 600 px).

    Returns
    -------
    image : (H, W, 3) uint8
        Rows along the slice's second axis, flipped so it grows upwards.
    index : int
        The slice shown.
    """
    if not a.spec.same_placement(b.spec):
        raise ValueError(f"grids on different placements: {a.spec} vs {b.spec}")
    da, db = np.asarray(a.dense()), np.asarray(b.dense())
    if index is None:
        diff = np.moveaxis(da != db, axis, 0).reshape(da.shape[axis], -1).sum(axis=1)
        index = int(np.argmax(diff)) if diff.any() else da.shape[axis] // 2
    sa, sb = np.take(da, index, axis=axis), np.take(db, index, axis=axis)
    img = np.empty(sa.shape + (3,), np.uint8)
    img[...] = NONE
    img[sa & sb] = BOTH
    img[sa & ~sb] = ONLY_A
    img[~sa & sb] = ONLY_B
    img = np.transpose(img, (1, 0, 2))[::-1]
    if scale is None:
        scale = max(1, 600 // max(img.shape[:2]))
    return np.repeat(np.repeat(img, scale, axis=0), scale, axis=1), index


def save_slice_png(img: np.ndarray, path: Path, a: str, b: str, title: str) -> Path:
    """A disagreement slice with its legend and title."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import Patch

    fig, ax = plt.subplots(figsize=(7, 7.6))
    ax.imshow(img, interpolation="nearest")
    ax.set_axis_off()
    ax.set_title(title, fontsize=10)
    handles = [Patch(color=np.array(c) / 255, label=lb) for c, lb in
               ((BOTH, "both"), (ONLY_A, f"only {a}"), (ONLY_B, f"only {b}"))]
    ax.legend(handles=handles, loc="upper center", bbox_to_anchor=(0.5, -0.01), ncol=3, fontsize=9,
              frameon=False)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return Path(path)


def save_png(img: np.ndarray, path: Path) -> Path:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    plt.imsave(path, img)
    return Path(path)


def save_sdf_slice_png(result, path: Path, axis: int = 2, index: int | None = None) -> Path:
    """A slice of a signed distance field: distances in a diverging colour map (blue inside,
    red outside, world units), the zero level drawn as a black line, voxels outside the
    exact band hatched grey and voxels with an uncertain sign marked.

    Parameters
    ----------
    result : SDFGrid
    path : path
        The PNG to write.
    axis : {0, 1, 2}
        The slice's normal; ``index`` the slice (default the middle one).
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    n = result.dims[axis]
    index = n // 2 if index is None else int(index)
    take = [slice(None)] * 3
    take[axis] = index
    sdf = np.asarray(result.sdf[tuple(take)], dtype=np.float64).T  # rows: the second remaining axis
    band = np.asarray(result.band[tuple(take)]).T
    unc = np.asarray(result.uncertain[tuple(take)]).T
    lim = float(np.abs(sdf).max()) or 1.0
    fig, ax = plt.subplots(figsize=(7, 6.4))
    im = ax.imshow(sdf, origin="lower", cmap="RdBu_r", vmin=-lim, vmax=lim, interpolation="nearest")
    if (~band).any():
        ax.imshow(np.where(band, np.nan, 1.0), origin="lower", cmap="Greys", vmin=0, vmax=3, alpha=0.35,
                  interpolation="nearest")
    if sdf.min() < 0 < sdf.max():
        ax.contour(sdf, levels=[0.0], colors="black", linewidths=1.2)
    if unc.any():
        v, u = np.nonzero(unc)
        ax.scatter(u, v, s=6, c="gold", marker="x", label=f"uncertain sign ({int(unc.sum())})")
        ax.legend(loc="upper right", fontsize=8)
    names = "xyz"
    rest = [names[a] for a in range(3) if a != axis]
    ax.set_xlabel(f"{rest[0]} (voxels)")
    ax.set_ylabel(f"{rest[1]} (voxels)")
    ax.set_title(f"signed distance, slice {names[axis]} = {index} of {n} (black: zero level; grey: clamped)",
                 fontsize=9)
    fig.colorbar(im, ax=ax, label="world units (negative inside)")
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return Path(path)
