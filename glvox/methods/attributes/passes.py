"""Per-voxel attributes on the GPU: source triangles, then what they carry.

The rule (glvox/grid.py's convention, docs/design.md, "Attributes"): a set voxel's
source triangle is, among the triangles overlapping its box, the one whose
closest point to the voxel center is nearest (ties: the lowest index); its
attributes are evaluated at that closest point.  Any method's grid gets them
the same way, after the method (surface and solid alike; interior voxels of a
solid overlap no triangle and get none):

``attr_rank``
    set voxels per grid row, an exclusive scan over the rows
    (:func:`glvox.gpu.sort.exclusive_scan`), each word's first slot: the slot
    of a set voxel is its rank in the grid's word order.
``attr_pairs`` (two passes)
    the conservative (triangle, voxel) pairs of ``ss/surface.comp``
    (the sorted or specialized variant, as ss-conservative's ``auto`` picks) revisited with ``attributes/pair.glsl`` instead of
    the writes: pass 1 ``atomicMin`` of the distance from the voxel center to
    the closest point (double, kept as 2^-31 voxel fixed point), pass 2 ``atomicMin`` of
    the index among the pairs at that minimum.  No 64-bit atomics on
    llvmpipe (no GL_NV_shader_atomic_int64), hence two passes.
``attr_evaluate``
    one invocation per slot: colour and normal at the closest point, with
    the first texture; one more pass per further texture, each image
    uploaded once as a GL texture and sampled with its filter and wrap.
``attr_readback``
    the slots' triangle, colour and normal read back; reordered into C order
    (:meth:`VoxelGrid.indices`) with one argsort; ``triangle`` and
    ``material`` are gathers of per-face arrays.
"""

from __future__ import annotations

import weakref

import moderngl
import numpy as np

from ...errors import MethodError
from ...gl.shaders import compute_program
from ...gpu.buffers import buffer_pool, check_buffer_size, clear_buffer, object_cache
from ...gpu.dispatch import barrier, bind, dispatch_1d, grid_uniforms, set_uniforms
from ...gpu.sort import exclusive_scan
from ...gpu.transform import transform_vertices
from ...reference.attributes import index_attribute
from ...results.voxels import ATTRIBUTE_DTYPES
from ...visuals import COLOR_TEXTURE
from ..ss.surface import LOCAL_SIZE, auto_variant, sort_by_case, surface_defines, voxelize_sorted, voxelize_unsorted

#: The attributes a result can carry (``--attributes``).
ATTRIBUTE_NAMES = tuple(ATTRIBUTE_DTYPES)
#: ``--normals``: the source triangle's normal or the interpolated vertex normals.
NORMAL_MODES = ("face", "vertex")
_NONE = 0xFFFFFFFF
_POOL = "attributes"


def c_order(words: np.ndarray, dims) -> np.ndarray:
    """The permutation taking the set voxels from the grid's word order (k, j, i)
    to C order (i, j, k): ``attr_c = attr_words[perm]`` (from the words alone,
    for grids where some set voxel has no source triangle)."""
    nx, ny, nz = dims
    wpr = (nx + 31) // 32
    flat = np.ascontiguousarray(np.asarray(words).reshape(-1).astype("<u4", copy=False))
    nonzero = np.flatnonzero(flat)
    bits = np.unpackbits(flat[nonzero].view(np.uint8).reshape(-1, 4), axis=1, bitorder="little")
    row, bit = np.nonzero(bits)  # word order, then bit order: the slots' order
    word = nonzero[row]
    return _c_perm((word % wpr) * 32 + bit, (word // wpr) % ny)


def _c_perm(i: np.ndarray, j: np.ndarray) -> np.ndarray:
    """C order of voxels listed in word order (sorted by k, then j, then i), from
    their i and j: stable sorts by j, then by i (numpy's radix sort for 16-bit
    keys, O(M))."""
    key_type = np.uint16 if max(int(i.max(initial=0)), int(j.max(initial=0))) < 1 << 16 else np.uint32
    i, j = i.astype(key_type), j.astype(key_type)
    perm = np.argsort(j, kind="stable")
    return perm[np.argsort(i[perm], kind="stable")]


def _slot_indices(slot_voxel, words, spec, count) -> tuple[np.ndarray, np.ndarray]:
    """(perm, indices): the slots' C-order permutation and the (M, 3) int64 C-ordered
    voxel indices, from the coordinates pass 2 recorded (every slot with a source
    triangle), else from the grid words."""
    sv = np.frombuffer(slot_voxel.read(size=count * 8), dtype="<u4").reshape(count, 2)
    if (sv[:, 0] != _NONE).all():
        ijk = np.empty((count, 3), np.int64)
        ijk[:, 0], ijk[:, 1], ijk[:, 2] = sv[:, 0] & 0xFFFF, sv[:, 0] >> 16, sv[:, 1]
        perm = _c_perm(ijk[:, 0], ijk[:, 1])
        return perm, ijk[perm]
    return c_order(words, spec.dims), None


def _release_faces(cache: dict) -> None:
    for entry in cache.values():
        for buf in entry[1]:
            buf.release()
    cache.clear()


def _face_buffers(ctx, mesh, vertex_normals: bool):
    """Per-face data of the evaluation (info, corner UVs, corner colours, normals), uploaded
    once per mesh and context (freed with the mesh, as its vertex buffers are)."""
    cache = object_cache(ctx, _POOL, _release_faces)
    key = (id(mesh), vertex_normals)
    entry = cache.get(key)
    if entry is not None and entry[0]() is mesh:
        return entry[1]
    vis = mesh.visuals
    n = mesh.n_triangles
    info = np.zeros((n, 4), np.uint32)
    if vis is not None:
        info[:, 0] = vis.color_source
        info[:, 1] = np.maximum(vis.texture, 0)
        info[:, 3] = vis.face_color.view(np.uint32).ravel()
        uv = vis.corner_uv.astype(np.float32)
        cc = np.ascontiguousarray(vis.corner_color).view(np.uint32).reshape(n, 3)
    else:
        uv, cc = np.zeros((n, 3, 2), np.float32), np.zeros((n, 3), np.uint32)
    tri = mesh.triangles()
    fn = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    fn /= np.maximum(np.linalg.norm(fn, axis=1, keepdims=True), 1e-300)
    normals = np.zeros((n, 12), np.float32)
    normals[:, :3] = fn
    if vertex_normals and vis is not None:
        normals[:, 3:] = vis.corner_normal.reshape(n, 9)
    for arr, what in ((info, "per-face colour sources"), (uv, "UVs"), (cc, "vertex colours"),
                      (normals, "normals")):
        check_buffer_size(ctx, arr.nbytes, what)
    bufs = [ctx.mgl.buffer(np.ascontiguousarray(a)) for a in (info, uv, cc, normals)]

    def drop(cache=cache, key=key):
        old = cache.pop(key, None)
        if old is not None and not ctx.released:
            for buf in old[1]:
                buf.release()

    cache[key] = (weakref.ref(mesh), bufs)
    weakref.finalize(mesh, drop)
    return bufs


def _rank(ctx, spec, grid, count, pool, timer):
    """Stage ``attr_rank``: each word's first slot (block Offsets), by row counts, a scan
    over the rows and the rows' words (``attributes/rank.comp``)."""
    rows = spec.dims[1] * spec.dims[2]
    offsets = pool.get("attr_offsets", spec.n_words * 4, what="the set voxels' ranks", clear=False)
    row_count = pool.get("attr_rows", rows * 4, what="the rows' counts", clear=False)
    prog = compute_program(ctx, "attributes/rank.comp")
    set_uniforms(prog, {"u_rows": rows, "u_total": count, "u_dims": tuple(int(d) for d in spec.dims)})
    with timer.stage("attr_rank"):
        bind(prog, Grid=grid, Offsets=offsets, Rows=row_count)
        set_uniforms(prog, {"u_mode": 0})
        dispatch_1d(ctx, prog, rows, 64)
        barrier(ctx)
        exclusive_scan(ctx, row_count, row_count, rows)
        barrier(ctx)
        bind(prog, Grid=grid, Offsets=offsets, Rows=row_count)  # the scan bound its own buffers
        set_uniforms(prog, {"u_mode": 1})
        dispatch_1d(ctx, prog, rows, 64)
        barrier(ctx)
    return offsets


def _pairs(ctx, mesh, spec, grid, offsets, count, pool, timer):
    """Stage ``attr_pairs``: the source triangle of every slot (block BestTri) and its
    voxel (block SlotVoxel), through ss-conservative's variant ``auto`` picks."""
    n = mesh.n_triangles
    max_groups = int(ctx.limits()["GL_MAX_COMPUTE_WORK_GROUP_COUNT"][0])
    # the llvmpipe rule, not a stored calibration: that timed the surface pass, not this one
    variant, _ = auto_variant(n, spec.dims, max_groups)
    variant = "specialized" if variant == "simple" else variant  # simple: the same pairs, tested per voxel
    best_dist = pool.get("attr_dist", count * 4, what="the set voxels' distances", clear=False)
    best_tri = pool.get("attr_tri", count * 4, what="the set voxels' source triangles", clear=False)
    slot_voxel = pool.get("attr_slot_voxel", count * 8, what="the set voxels' coordinates", clear=False)
    clear_buffer(ctx, slot_voxel, count * 8, 0xFFFFFFFF)  # NONE: no triangle recorded it
    clear_buffer(ctx, best_dist, count * 4, 0xFFFFFFFF)
    clear_buffer(ctx, best_tri, count * 4, 0xFFFFFFFF)
    bufs, vox = transform_vertices(ctx, mesh, spec, timer, pool, stage="attr_transform")
    stats = pool.get("stats", 8 * 4)
    per_tri = pool.get("per_triangle", n * 4, what="per-triangle work", clear=False)
    args = pool.get("args", 9 * 4, clear=False)
    keys = pool.get("keys", n * 4, what="sort keys", clear=False)
    defines = surface_defines(0, variant)
    common = {**grid_uniforms(spec, bufs.anchor), "u_triangles": n, "u_tri_offset": 0,
              "u_local_size": LOCAL_SIZE, "u_max_groups": max_groups}
    classify = compute_program(ctx, "ss/classify.comp", defines)
    set_uniforms(classify, common)
    with timer.stage("attr_classify"):
        bind(classify, VoxVerts=vox, Faces=bufs.faces, Stats=stats, TriChunks=per_tri, Keys=keys)
        dispatch_1d(ctx, classify, n, LOCAL_SIZE)
        barrier(ctx)
    # ss/surface.comp's blocks with SS_ATTR_PASS defined (attributes/pair.glsl instead of its writes)
    blocks = {"VoxVerts": vox, "Faces": bufs.faces, "Grid": grid, "Offsets": offsets, "BestDist": best_dist,
              "BestTri": best_tri, "SlotVoxel": slot_voxel}
    if variant == "sorted":
        ranges = sort_by_case(ctx, timer, pool, n, (stats, per_tri, keys, args), max_groups, prefix="attr_")
        blocks.update(SortedTris=per_tri, Ranges=ranges)
    else:
        blocks.update(TriChunks=per_tri)
    for p in (1, 2):
        pass_defines = {**defines, "SS_ATTR_PASS": p}
        if variant == "sorted":
            voxelize_sorted(ctx, timer, pass_defines, common, blocks, args, stage=f"attr_pairs{p}")
        else:
            voxelize_unsorted(ctx, timer, n, pass_defines, common, blocks, stats, args, max_groups,
                              stage=f"attr_pairs{p}")
    return bufs, vox, best_tri, slot_voxel


def _evaluate(ctx, mesh, spec, buffers, count, pool, timer, want_color, normals):
    """Stage ``attr_evaluate``: colour (uint32 RGBA8) and normal (3 float32) per slot."""
    bufs, vox, best_tri, slot_voxel = buffers
    color = pool.get("attr_color", count * 4, what="the set voxels' colours")
    normal = pool.get("attr_normal", count * 12, what="the set voxels' normals", clear=False)
    face = _face_buffers(ctx, mesh, normals == "vertex")
    prog = compute_program(ctx, "attributes/evaluate.comp")
    set_uniforms(prog, {"u_slots": count, "u_color": want_color,
                        "u_normal": normals is not None, "u_vertex_normals": normals == "vertex",
                        "u_tex": 0, "u_factor": (1.0, 1.0, 1.0, 1.0)})
    bind(prog, VoxVerts=vox, Faces=bufs.faces, BestTri=best_tri, SlotVoxel=slot_voxel, FaceInfo=face[0],
         CornerUV=face[1], CornerColor=face[2], Normals=face[3], OutColor=color, OutNormal=normal)
    textures = mesh.visuals.textures if (want_color and mesh.visuals is not None) else []
    used = sorted(set(np.unique(mesh.visuals.texture[mesh.visuals.color_source == COLOR_TEXTURE]).tolist())
                  if textures else ())
    with timer.stage("attr_evaluate"):
        # the first pass does the normals, the untextured colours and the first texture
        for n, k in enumerate(used or [-1]):
            if k >= 0:
                _texture(ctx, textures[k]).use(0)
            set_uniforms(prog, {"u_tex_index": k, "u_first": n == 0,
                                "u_factor": tuple(float(x) for x in textures[k].factor) if k >= 0 else (1.0,) * 4})
            dispatch_1d(ctx, prog, count, 64)
            barrier(ctx)
    return color, normal


def _texture(ctx, tex):
    """``tex`` as a GL texture, uploaded once per texture and context (freed with it):
    RGBA8, rows flipped so UV (0, 0) is the image's bottom-left, its filter and
    wrap, no mipmaps."""
    cache = object_cache(ctx, _POOL + "-textures", _release_textures)
    entry = cache.get(id(tex))
    if entry is not None and entry[0]() is tex:
        return entry[1]
    img = np.ascontiguousarray(tex.image[::-1])
    t = ctx.mgl.texture((img.shape[1], img.shape[0]), 4, img)
    f = moderngl.LINEAR if tex.filter == "linear" else moderngl.NEAREST
    t.filter = (f, f)
    t.repeat_x = t.repeat_y = tex.wrap == "repeat"

    def drop(cache=cache, key=id(tex)):
        old = cache.pop(key, None)
        if old is not None and not ctx.released:
            old[1].release()

    cache[id(tex)] = (weakref.ref(tex), t)
    weakref.finalize(tex, drop)
    return t


def _release_textures(cache: dict) -> None:
    for _, t in cache.values():
        t.release()
    cache.clear()


def _flood(ctx, spec, grid, offsets, best_tri, count, pool, timer):
    """Stage ``attr_fill``: the slot of each set voxel's nearest surface voxel by a
    jump flood (``attributes/flood.comp``), uint32 per slot (NONE: none reachable)."""
    seeds = [pool.get(f"attr_seed{n}", count * 8, what="the jump flood's seeds", clear=False) for n in (0, 1)]
    seed_slot = pool.get("attr_seed_slot", count * 4, what="the jump flood's seeds", clear=False)
    prog = compute_program(ctx, "attributes/flood.comp")
    set_uniforms(prog, {**grid_uniforms(spec, np.zeros(3)), "u_words": spec.n_words})
    steps = []
    step = 1 << max(int(max(spec.dims)) - 1, 1).bit_length()
    while step > 1:
        step //= 2
        steps.append(step)
    steps.append(1)  # JFA+1: one more step of 1 repairs most of the flood's misses
    with timer.stage("attr_fill"):
        cur = 0
        for mode, step in [(0, 0)] + [(1, s) for s in steps] + [(2, 0)]:
            bind(prog, Grid=grid, Offsets=offsets, BestTri=best_tri, SeedSlot=seed_slot,
                 SeedIn=seeds[cur], SeedOut=seeds[1 - cur])
            set_uniforms(prog, {"u_mode": mode, "u_step": step})
            dispatch_1d(ctx, prog, spec.n_words, 64)
            barrier(ctx)
            if mode != 2:
                cur = 1 - cur
    return seed_slot


def gpu_attributes(ctx, mesh, result, timer, names, normals: str = "face", fill: str = "none") -> dict:
    """The attributes ``names`` of ``result``'s set voxels, by the rule of the module docstring.

    Parameters
    ----------
    ctx : GLContext
    mesh : Mesh
        With ``visuals`` where colour or vertex normals are asked for.
    result : VoxelGrid
        The method's grid (its words are uploaded once).
    timer : StageTimer
    names : sequence of str
        Of :data:`ATTRIBUTE_NAMES`.
    normals : {'face', 'vertex'}
    fill : {'none', 'nearest'}
        Voxels without a source triangle (a solid's interior) keep none, or
        take the attributes of the surface voxel the jump flood finds nearest.

    Returns
    -------
    dict of name to array, one row per set voxel in C order
    (:data:`glvox.results.voxels.ATTRIBUTE_DTYPES`).
    """
    spec, count = result.spec, result.count
    names = list(names)
    if count == 0:
        return {k: np.zeros((0, *ATTRIBUTE_DTYPES[k][1]), ATTRIBUTE_DTYPES[k][0]) for k in names}
    pool = buffer_pool(ctx, _POOL)
    words = result.words()
    grid = pool.get("attr_grid", spec.n_words * 4, what=f"the {spec.dims} bit grid", clear=False)
    grid.write(np.ascontiguousarray(words))  # the array itself: no bytes copy of 128 MiB at 1024^3
    offsets = _rank(ctx, spec, grid, count, pool, timer)
    bufs, vox, best_tri, slot_voxel = _pairs(ctx, mesh, spec, grid, offsets, count, pool, timer)
    want_color = "color" in names
    want_normal = normals if "normal" in names else None
    if want_color or want_normal:
        color, normal = _evaluate(ctx, mesh, spec, (bufs, vox, best_tri, slot_voxel), count, pool,
                                  timer, want_color, want_normal)
    seed_slot = _flood(ctx, spec, grid, offsets, best_tri, count, pool, timer) if fill == "nearest" else None
    with timer.stage("attr_readback", gpu=False):
        # word order first (the slots), then the fill's gather, then C order
        rows = np.arange(count)
        if seed_slot is not None:
            seed = np.frombuffer(seed_slot.read(size=count * 4), dtype="<u4").astype(np.int64)
            rows = np.where(seed == _NONE, rows, seed)
        perm, indices = _slot_indices(slot_voxel, words, spec, count)
        take = rows[perm]
        tri = np.frombuffer(best_tri.read(size=count * 4), dtype="<u4")[take].astype(np.int64)
        tri[tri == _NONE] = -1
        out: dict[str, np.ndarray] = {}
        for name in names:
            if name in ("triangle", "material"):
                out[name] = index_attribute(mesh, name, tri)
            elif name == "color":
                out[name] = np.frombuffer(color.read(size=count * 4), np.uint8).reshape(count, 4)[take]
            elif name == "normal":
                out[name] = np.frombuffer(normal.read(size=count * 12), np.float32).reshape(count, 3)[take]
    if indices is not None:
        result.cache_indices(indices)
    return out


#: ``--fill-attributes``: interior voxels of a solid carry none, or those of the nearest surface voxel.
FILL_MODES = ("none", "nearest")


def parse_attributes(value) -> tuple[str, ...]:
    """``'triangle,color'`` or a sequence of names as a checked tuple (MethodError otherwise)."""
    if value is None:
        return ()
    names = [v.strip() for v in value.split(",")] if isinstance(value, str) else [str(v) for v in value]
    names = [n for n in names if n]
    unknown = [n for n in names if n not in ATTRIBUTE_NAMES]
    if unknown:
        raise MethodError(f"unknown attribute {', '.join(map(repr, unknown))}; known: {', '.join(ATTRIBUTE_NAMES)}")
    return tuple(dict.fromkeys(names))


def check_request(info, names, normals: str, fill: str) -> None:
    """MethodError unless ``info``'s method can carry ``names`` with these modes (before any work)."""
    if normals not in NORMAL_MODES:
        raise MethodError(f"normals must be one of {', '.join(NORMAL_MODES)}, got {normals!r}")
    if fill not in FILL_MODES:
        raise MethodError(f"fill_attributes must be one of {', '.join(FILL_MODES)}, got {fill!r}")
    if names and info.kind not in ("surface", "solid"):
        raise MethodError(f"method {info.name!r} (kind {info.kind!r}) returns no voxel grid to carry attributes; "
                          "use a surface or solid method")
    if fill != "none" and info.kind != "solid":
        raise MethodError(f"fill_attributes={fill!r} fills a solid's interior; {info.name!r} is a "
                          f"{info.kind} method")
    if fill != "none" and not names:
        raise MethodError("fill_attributes needs attributes to fill (attributes=[...], --attributes)")


def check_mesh(mesh, names, normals: str) -> None:
    """MethodError when ``mesh`` lacks what ``names`` need: colours for ``color``,
    visuals for vertex normals (a one-line error, no silent grey)."""
    vis = mesh.visuals
    if "color" in names and (vis is None or not vis.has_color):
        raise MethodError(f"{mesh.name} carries no colours (no face or vertex colours, no texture); "
                          "drop 'color' from the attributes")
    if "normal" in names and normals == "vertex" and vis is None:
        raise MethodError(f"{mesh.name} was loaded without its visuals: vertex normals need the file "
                          "(glvox.voxelize(path, attributes=...)) or normals='face'")
