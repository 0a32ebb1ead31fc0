"""``binvox-solid``: the solid of Patrick Min's binvox, on the GPU (docs/methods/binvox.md).

binvox (its documentation and its old public source) voxelizes with two
z-buffer methods, both by default:

* carving (``mode='carve'``, binvox ``-c``; Karabassi et al. 1999): the mesh is
  drawn with culling off from the six faces of the grid's bounding box, pixel
  centers on voxel centers; a voxel survives an axis when its center lies
  between the nearest crossings seen from the two faces (binvox keeps k with
  ``round(zb) <= k < round(zf)``), and survives when it survives all three.  A
  column with no crossing is carved entirely.  ``dilated=True`` (``-dc``) keeps
  one more voxel at each end of every column's interval.
* parity voting (``mode='vote'``, ``-v``; Nooruddin & Turk 2003): along each
  axis the parity of the crossings before a center and the parity of those
  beyond it are two votes, six in all.
* wireframe (``wire=True``, binvox ``-aw``, "also render the model in wireframe
  (helps with thin parts)"): every triangle edge is also drawn as a line into the
  carving z-buffers (``binvox/wire.*``; the line rule is
  :func:`glvox.reference.binvox.wire_hits`), so parts thinner than a voxel, which
  no pixel-center ray crosses, still stop the carving.

Default: a voxel surviving carving gets 3 votes and is set when it has more
than 2, i.e. ``carve | (votes >= 3)``.  ``down=1`` (binvox ``-down``) voxelizes
at twice the resolution and halves the grid (a voxel set when ``dmin`` = 4 of
its 8 are).  The defaults are ShapeNet's recipe (``binvox -aw -dc -down``:
``wire=True, dilated=True, down=1``), which reproduces its files best;
:data:`BINVOX_DEFAULTS` are binvox's own.  ``surface=True`` (not a binvox step,
off by default) also sets every voxel that holds a crossing of the pixel-center
rays: a stand-in for ``-aw`` (measured in docs/methods/binvox.md).  Winding
plays no part, so double-sided and inconsistently oriented meshes give the same
solid as their one-sided versions; on open meshes carving seals nothing that
the six views see through.

Crossings are decided in the fragment shader exactly as the CPU references
decide them (:mod:`glvox.methods.depth.raster`; ``reference-binvox`` is the
float64 twin), not by GL's coverage.  Stages per axis ``carve_<axis>`` (the
nearest and farthest z-buffers, recorded with ``binvox/record.comp``, a prefix
XOR ``depth/scan.comp``, ANDed by ``binvox/combine.comp``) and ``vote_<axis>``
(every crossing by depth peeling, recorded into the parity marks, the column's
total parity and the surface grid; the two votes added into bit-sliced
counters), then ``finish`` and ``readback``.
"""

from __future__ import annotations


import moderngl
import numpy as np

from ...gl.shaders import compute_program, render_program
from ...gpu.buffers import buffer_pool, clear_buffer, mesh_buffers, read_grid_words
from ...gpu.dispatch import barrier, bind, dispatch_1d, grid_uniforms, rendered, set_uniforms
from ...gpu.fixed_point import fixed_bits
from ...gpu.transform import gpu_vertices_voxel, snap_defines
from ...grid import GridSpec
from ...reference.binvox import empty_cause, fine_snap_eps
from ...results.voxels import VoxelGrid
from ..base import Method, MethodInfo, Option, Requirements, register
from ..depth.layers import prefix_xor
from ..depth.raster import RasterPass, depth_target, key_uniforms, peel_behind, tile_origins, tile_side

MODES = ("default", "carve", "vote")


_AXIS_NAMES = "xyz"
_REQUIRES = Requirements(gl_version=450, limits={"GL_MAX_SHADER_STORAGE_BUFFER_BINDINGS": 8},
                         compute=(("binvox/*.comp", {}), ("depth/scan.comp", {})))

#: The options of binvox-solid and reference-binvox (one definition: they are compared
#: with the same values).
OPTIONS = {
    "mode": Option("default", "binvox's methods: 'default' carving and parity voting (carve | votes >= 3 of 6), "
                              "'carve' (binvox -c), 'vote' (binvox -v)", MODES),
    "dilated": Option(True, "dilated carving (binvox -dc): keep one more voxel at each end of every column "
                            "(default true: ShapeNet's recipe; false for binvox's own default)"),
    "wire": Option(True, "binvox -aw: also draw the wireframe (every triangle edge as a line) into the carving "
                         "z-buffers, so that parts thinner than a voxel stop the carving (default true: "
                         "ShapeNet's recipe; false for binvox's own default)"),
    "surface": Option(False, "also set the voxels holding a crossing of the pixel-center rays (not a binvox "
                             "step: a stand-in for -aw without it)"),
    "down": Option(1, "binvox -down, repeated: voxelize at 2^down times the resolution, then halve the grid "
                      "that many times (0 to 2; default 1: ShapeNet's recipe; 0 for binvox's own default)",
                   (0, 1, 2)),
    "dmin": Option(4, "binvox -dmin: when halving, a voxel is set if at least dmin of its 8 are (1 to 8)",
                   tuple(range(1, 9))),
}

#: The options that give binvox's own defaults (``binvox -d N``), where OPTIONS' defaults
#: give ShapeNet's recipe (``binvox -dc -down``), which matches its files best.
BINVOX_DEFAULTS = {"mode": "default", "dilated": False, "wire": False, "surface": True, "down": 0, "dmin": 4}


def fine_spec(spec: GridSpec, down: int) -> GridSpec:
    """The grid voxelized before ``down`` halvings: the same box, 2^down times the dims."""
    f = 2 ** down
    return GridSpec(tuple(d * f for d in spec.dims), spec.origin, spec.voxel_size / f)


def gpu_triangles(mesh, spec: GridSpec, down: int) -> np.ndarray:
    """(T, 3, 3) float64: the triangles exactly as binvox-solid draws them, in the voxel
    units of ``spec``: the GPU's float32 vertices on :func:`fine_spec` (snapped there,
    within :func:`~glvox.reference.binvox.fine_snap_eps`), divided by ``2**down`` (exact).  :func:`glvox.reference.binvox.binvox_solid` on
    them gives binvox-solid's result voxel for voxel (tests/test_binvox.py)."""
    fine = gpu_vertices_voxel(mesh, fine_spec(spec, down), fine_snap_eps(down))
    return fine[mesh.faces].astype(np.float64) / 2 ** down


def gpu_cover_triangles(mesh, spec: GridSpec, down: int) -> list[np.ndarray]:
    """Per ray axis, the triangles binvox-solid's coverage test decides on, in the voxel
    units of ``spec``: :func:`gpu_triangles` with the two coordinates across the rays
    rounded to the fixed point of ``depth/raster.geom`` on the fine grid (multiples of
    2^-F fine voxel, F = :func:`~glvox.gpu.fixed_point.fixed_bits`; ties to even, as the
    shader's roundEven).  :func:`glvox.reference.binvox.binvox_solid` with these as
    ``cover`` gives binvox-solid's result voxel for voxel (tests/test_binvox.py)."""
    fine = fine_spec(spec, down)
    verts = gpu_vertices_voxel(mesh, fine, fine_snap_eps(down)).astype(np.float64)
    out = []
    for axis in range(3):
        bits = fixed_bits(mesh, fine, axis, warn=False)
        v = verts.copy()
        across = [(axis + 1) % 3, (axis + 2) % 3]
        v[:, across] = np.ldexp(np.round(np.ldexp(v[:, across], bits)), -bits)
        out.append(v[mesh.faces] / 2 ** down)
    return out


#: Texels per row of the wireframe's owner texture (GL guarantees 16384).
_OWNERS_WIDTH = 16384
_OWNERS_UNIT = 2  # texture unit of the owner texture (the raster pass's previous layer takes 0)


def wire_owners(faces: np.ndarray) -> np.ndarray:
    """(F,) uint8: which of its edges each triangle draws into the wireframe.

    Edge k of triangle t joins its vertices k and (k + 1) % 3.  An edge that several
    triangles share (the same two vertex indices) is one line, drawn by one of them:
    bits 0-2 mark the first occurrence in primitive order (t, k), which the nearest
    z-buffer keeps of equal keys (depth test LESS), bits 3-5 the last, which the farthest
    keeps (LEQUAL).  ``binvox/wire.geom`` draws only the marked edges, and the z-buffers
    end exactly as with every copy drawn.
    """
    f = np.asarray(faces, dtype=np.int64)
    if len(f) == 0:
        return np.zeros(0, np.uint8)
    a, b = f, np.roll(f, -1, axis=1)
    key = (np.minimum(a, b) * (int(f.max()) + 1) + np.maximum(a, b)).ravel()  # edges in (t, k) order
    n = len(key)
    first = np.unique(key, return_index=True)[1]
    last = n - 1 - np.unique(key[::-1], return_index=True)[1]
    bits = np.zeros(n, np.uint8)
    bits[first] |= 1
    bits[last] |= 8
    bits = bits.reshape(-1, 3) << np.arange(3, dtype=np.uint8)
    return np.bitwise_or.reduce(bits, axis=1).astype(np.uint8)


class _BinvoxRun(RasterPass):
    """The raster pass with binvox's recording (``binvox/record.comp``) and, for ``-aw``,
    the wireframe (``binvox/wire.*``) drawn into the carving z-buffers."""

    def __init__(self, ctx, bufs, uniforms, record: dict, bufs_out: dict, wire: bool, snap: dict,
                 faces: np.ndarray):
        super().__init__(ctx, bufs, uniforms, snap)
        #: binvox/record.comp by stencil mode (0, or 1: the tile's largest count too)
        self.record, self.out = record, bufs_out
        self.wire = None
        self.wire_vao = None
        self.owners = None
        self._faces = faces
        if wire:
            self.wire = render_program(ctx, "depth/raster.vert", "binvox/wire.frag", "binvox/wire.geom",
                                       defines=snap)
            set_uniforms(self.wire, {**uniforms, "u_owners": _OWNERS_UNIT})

    def __enter__(self) -> "_BinvoxRun":
        super().__enter__()
        if self.wire is not None:
            self.wire_vao = self.ctx.mgl.vertex_array(self.wire, [(self.bufs.vertices, "3f", "in_pos")],
                                                      index_buffer=self.bufs.faces, index_element_size=4)
            owners = wire_owners(self._faces)
            width = max(1, min(len(owners), _OWNERS_WIDTH))
            rows = -(-len(owners) // width)
            data = np.zeros(width * max(rows, 1), np.uint8)
            data[:len(owners)] = owners
            self.owners = self.ctx.mgl.texture((width, max(rows, 1)), 1, data.tobytes(), dtype="u1")
            self.owners.filter = (moderngl.NEAREST, moderngl.NEAREST)  # integer textures are incomplete otherwise
        return self

    def __exit__(self, *exc) -> None:
        if self.wire_vao is not None:
            self.wire_vao.release()
            self.wire_vao = None
        if self.owners is not None:
            self.owners.release()
            self.owners = None
        super().__exit__(*exc)

    def set_view(self, spec, axis: int, size: tuple[int, int], fix_bits: int) -> None:
        super().set_view(spec, axis, size, fix_bits)
        if self.wire is not None:  # the same depth key as the triangles'
            set_uniforms(self.wire, {"u_axis": axis, "u_target_size": size, **key_uniforms(spec.dims[axis])})

    def set_tile(self, origin: tuple[int, int]) -> None:
        super().set_tile(origin)
        if self.wire is not None:
            set_uniforms(self.wire, {"u_tile_origin": origin})

    def carve_buffer(self, target, layer: int, *, far: bool = False) -> None:
        """One carving z-buffer: the triangles (:meth:`draw`), then, with ``-aw``, the
        wireframe on top of them (same depth test, no clear)."""
        self.draw(target, layer, far=far)
        if self.wire is not None:
            target.fbos[layer].use()
            set_uniforms(self.wire, {"u_far": far})
            self.owners.use(_OWNERS_UNIT)
            self.wire_vao.render(moderngl.TRIANGLES)
            rendered(self.ctx)
            self.passes += 1

    def record_layer(self, target, size, layer: int, kind: int, *, stencil: bool = False) -> int | None:
        """Record ``target.layers[layer]`` as ``kind`` (0 nearest, 1 farthest, 2 vote);
        ``stencil`` returns the tile's largest stencil count."""
        out = self.out
        record = self.record[1 if stencil else 0]
        target.layers[layer].use(0)
        target.stencil.use(1)
        set_uniforms(record, {"u_record": kind})
        bind(record, Flips=out["flips_carve" if kind < 2 else "flips_vote"], Stats=out["stats"],
             Total=out["total"], Surface=out["surface"])
        if stencil:
            clear_buffer(self.ctx, out["stats"], 4)
        record.run((size[0] + 7) // 8, (size[1] + 7) // 8, 1)
        if stencil:
            barrier(self.ctx)
            return int(np.frombuffer(out["stats"].read(size=4), dtype="<u4")[0])
        return None


@register
class BinvoxSolid(Method):
    info = MethodInfo(
        name="binvox-solid", kind="solid", pipeline="raster",
        paper="binvox (P. Min): z-buffer carving from six directions (Karabassi et al. 1999) and z-buffer "
              "parity voting along three axes (Nooruddin & Turk 2003), as binvox documents them",
        summary="binvox-compatible solid of any mesh: carving | parity votes >= 3 of 6, surface included "
                "(mode=carve|vote, dilated=-dc); pair with --fit binvox for binvox's placement",
        reference="reference-binvox", exact=False, any_mesh=True, requires=_REQUIRES,
        options={**OPTIONS, "tile": Option(0, "largest render-target side in pixels (0: the context's limits)")},
    )

    def run(self, mesh, spec, *, ctx, timer, mode, dilated, surface, down, dmin, wire, tile):
        side = tile_side(ctx, tile)
        target_spec, spec = spec, fine_spec(spec, down)
        # the fixed point of each view's coverage test (refuses a mesh out of its range)
        fix = {axis: fixed_bits(mesh, spec, axis) for axis in range(3)}
        pool = buffer_pool(ctx, self.info.name)
        what = f"the {spec.dims} bit grid"
        nw = spec.n_words
        carve, vote = mode in ("default", "carve"), mode in ("default", "vote")
        peel = vote or surface
        out = {name: pool.get(name, nw * 4, what=what) for name in
               ("flips_carve", "flips_vote", "carve", "v0", "v1", "v2", "surface")}
        most = max(spec.dims[(a + 1) % 3] * spec.dims[(a + 2) % 3] for a in range(3))
        out["total"] = pool.get("total", most * 4, what="per-column crossing parities")
        out["stats"] = pool.get("stats", 16)
        out["count"] = pool.get("count", 8)
        bufs = mesh_buffers(ctx, mesh)
        uniforms = grid_uniforms(spec, bufs.anchor)
        # one program per stencil mode, so that each declares only the buffers it touches
        record = {mode: compute_program(ctx, "binvox/record.comp", {"STENCIL_MODE": mode}) for mode in (0, 1)}
        records = tuple(record.values())
        scan = compute_program(ctx, "depth/scan.comp")
        combine = compute_program(ctx, "binvox/combine.comp")
        finish = compute_program(ctx, "binvox/finish.comp")
        for prog in (*records, scan, combine, finish):
            set_uniforms(prog, uniforms)
        for prog in records:
            set_uniforms(prog, {"u_layer": 0, "u_stencil": 1, "u_dilate": int(bool(dilated))})
        layers: dict[str, int] = {}
        tiles: dict[str, int] = {}
        with _BinvoxRun(ctx, bufs, uniforms, record, out, wire and carve, snap_defines(fine_snap_eps(down)),
                        mesh.faces) as run:
            for axis in range(3):
                name = _AXIS_NAMES[axis]
                n_u, n_v = spec.dims[(axis + 1) % 3], spec.dims[(axis + 2) % 3]
                size, origins = tile_origins(n_u, n_v, side)
                target = depth_target(ctx, size)
                tiles[name] = len(origins)
                run.set_view(spec, axis, size, fix[axis])
                for prog in records:
                    set_uniforms(prog, {"u_axis": axis, "u_view_size": (n_u, n_v)})
                if carve:
                    with timer.stage(f"carve_{name}"):
                        for origin in origins:
                            run.set_tile(origin)
                            for prog in records:
                                set_uniforms(prog, {"u_tile_origin": origin})
                            run.carve_buffer(target, 0)
                            run.record_layer(target, size, 0, 0)
                            run.carve_buffer(target, 1, far=True)
                            run.record_layer(target, size, 1, 1)
                        barrier(ctx)
                        self._combine(ctx, spec, axis, 0 if axis == 0 else 1, scan, combine, out["flips_carve"], out)
                if peel:
                    out["total"].clear()
                    most_layers = 0
                    with timer.stage(f"vote_{name}"):
                        for origin in origins:
                            run.set_tile(origin)
                            for prog in records:
                                set_uniforms(prog, {"u_tile_origin": origin})
                            run.draw(target, 0, count="restart")
                            counted = run.record_layer(target, size, 0, 2, stencil=True)
                            n = peel_behind(run, target, counted,
                                            lambda layer, _: run.record_layer(target, size, layer, 2))
                            most_layers = max(most_layers, n)
                        barrier(ctx)
                        if vote:
                            self._combine(ctx, spec, axis, 2, scan, combine, out["flips_vote"], out)
                        else:
                            out["flips_vote"].clear()
                    layers[name] = most_layers
            passes = run.passes
        set_uniforms(finish, {"u_carve": carve, "u_vote": vote, "u_surface": bool(surface)})
        with timer.stage("finish"):
            bind(finish, Carve=out["carve"], V0=out["v0"], V1=out["v1"], V2=out["v2"], Surface=out["surface"],
                 Count=out["count"])
            dispatch_1d(ctx, finish, nw, 256)
            barrier(ctx)
        result = out["carve"]
        if down:
            with timer.stage("down"):
                result = self._down(ctx, pool, target_spec, down, dmin, result, out["count"])
        with timer.stage("readback", gpu=False):
            words = read_grid_words(ctx, result, target_spec)
            voxels = int(np.frombuffer(out["count"].read(size=4), dtype="<u4")[0])
        if voxels == 0:
            # binvox's own output would be empty too; the run envelope warns with this cause
            # (SuspiciousResultWarning) rather than return it silently
            timer.stats["suspicious"] = empty_cause("binvox-solid", mode, target_spec.dims)
        timer.stats.update({"mode": mode, "dilated": bool(dilated), "wire": bool(wire), "surface": bool(surface),
                            "down": down,
                            "passes": passes, "layers": layers, "tiles": tiles})
        return VoxelGrid(words=words, spec=target_spec, count=voxels)

    @staticmethod
    def _down(ctx, pool, spec, down, dmin, fine, count):
        """``down`` halvings of the packed grid ``fine`` on ``fine_spec(spec, down)``
        (``binvox/down.comp``) down to ``spec``;
        ``count`` ends up holding the last one's voxels.  Returns the buffer of the result."""
        prog = compute_program(ctx, "binvox/down.comp")
        for step in range(down):
            coarse_spec = fine_spec(spec, down - 1 - step)
            coarse = pool.get(f"down{step}", coarse_spec.n_words * 4, what=f"the {coarse_spec.dims} bit grid",
                              clear=False)
            clear_buffer(ctx, count, 4)
            set_uniforms(prog, {**grid_uniforms(coarse_spec, np.zeros(3)), "u_dmin": dmin})
            bind(prog, Fine=fine, Coarse=coarse, Count=count)
            dispatch_1d(ctx, prog, coarse_spec.n_words, 64)
            barrier(ctx)
            fine = coarse
        return fine

    @staticmethod
    def _combine(ctx, spec, axis, mode, scan, combine, flips, out) -> None:
        """Prefix XOR of ``flips`` along ``axis`` (segments along y and z), then
        ``binvox/combine.comp`` in ``mode`` (0/1 carve first/and, 2 vote)."""
        prefix_xor(ctx, spec, axis, scan, flips)
        set_uniforms(combine, {"u_axis": axis, "u_mode": mode})
        bind(combine, Flips=flips, Carve=out["carve"], V0=out["v0"], V1=out["v1"], V2=out["v2"], Total=out["total"])
        dispatch_1d(ctx, combine, spec.n_words, 256)
        barrier(ctx)
