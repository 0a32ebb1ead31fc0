"""The exact tie functions of ss-solid and eisemann-solid on the GPU against their model.

Where a column center lies exactly on a projected edge or vertex, the solid
methods decide it by the top-left rule on edge functions.  Both take their
exact signs from integer products on fixed-point coordinates
(``shaders/common/fixed.glsl``, through ``shaders/ss/solid.glsl`` and
``shaders/eisemann/column.glsl``), and their crossings from those edge
functions in double.  The model makes the same decisions in Python's integers
and numpy float64, so on any GL that computes integers as GLSL demands and
those doubles as IEEE 754 does, every method agrees with it there.  An NVIDIA
H100 (driver 580) did not, when both decided in double: ss-solid set a voxel
half a voxel outside a box whose faces lie on voxel center planes,
eisemann-solid one outside a tetrahedron (``glvox selftest``'s tie cases).

:func:`probe` evaluates those functions on the GPU for every (triangle,
column center) pair of a mesh (``shaders/testing/tie_probe.glsl``: the
orientation, the normal component along the ray, the three oriented edge
functions, the three top-left flags, the verdict and the first voxel
flipped), in a compute shader and, for eisemann, in a fragment shader as the
method runs them, and compares every word with :func:`model`, the same
decisions in Python's integers and numpy float64.  A
difference names the pair and the quantity, so a GPU that decides a tie
otherwise is pinned to the operation that differs (``compare/probe_ties.py``
prints them).

:func:`trace` goes one step further, into the methods themselves: it runs
ss-solid's voxelize pass and eisemann-solid's render on the mesh with a trace
compiled in, which records every crossing ss-solid flips and every fragment
the render draws (covered or not), and compares them with the model's covered
pairs.  A pair the model covers and the render drew no fragment for is the
rasterizer's (the grown proxy missed the center); one drawn and decided
otherwise is the fragment stage's; a crossing ss-solid flips that the probe
does not is the voxelize pass's own.  The render's later steps are checked
too, on grids of one tile and one target: every pixel of the target must hold
the XOR of the masks of the fragments traced there (the masks written and
the logic op), and the packed grid those masks' slices (the pack).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import GlvoxError
from ..gl.timing import StageTimer
from ..gpu.behaviours import broken
from ..gpu.buffers import buffer_pool, clear_buffer
from ..gpu.transform import gpu_vertices_voxel
from ..grid import unpack_bits
from ..gpu.fixed_point import fixed_bits
from ..methods.eisemann.passes import (SLICES_PER_TARGET, SliceRender, last_pass_targets, mask_table,
                                       render_slice_masks, tile_limit)
from ..methods.ss.solid import parity_on_gpu
from ..methods.ss.solid_tuning import ORDER_MIN_BYTES
from .harness import run_compute, run_fragment

#: uint32 words per pair (``PROBE_WORDS`` of the shader).
WORDS = 14
#: What each word range holds (the shader's layout).
FIELDS = {"takes part": slice(0, 1), "normal component": slice(1, 3), "edge functions": slice(3, 9),
          "top-left flags": slice(9, 12), "covered": slice(12, 13), "first voxel": slice(13, 14)}
#: The probes: (name, method family, shader stage).
KINDS = (("ss-solid (compute)", "ss", "compute"), ("eisemann (compute)", "eis", "compute"),
         ("eisemann (fragment)", "eis", "fragment"))


@dataclass
class Difference:
    """One pair whose GPU words differ from the model's."""

    kind: str
    triangle: int
    center: tuple[float, float]
    fields: list[str]
    gpu: np.ndarray
    model: np.ndarray

    def __str__(self) -> str:
        return (f"{self.kind}: triangle {self.triangle}, center {self.center}: {', '.join(self.fields)} differ "
                f"(gpu {self.gpu.tolist()}, model {self.model.tolist()})")


def _bits(x: float) -> tuple[int, int]:
    b = int(np.float64(x).view(np.uint64))
    return b & 0xFFFFFFFF, b >> 32


def _first(x: float, lo: float, hi: float) -> int:
    """``int(clamp(floor(x + 0.5), lo, hi))`` as the shaders write it, as a uint32 word."""
    return int(min(max(math.floor(x + 0.5), lo), hi)) & 0xFFFFFFFF


def _exact(x) -> int:
    """A double with a power-of-two denominator up to 2^64 (the fixed-point coordinates,
    the column centers) as an integer in units of 2^-64, exactly."""
    num, den = float(x).as_integer_ratio()
    return num << (64 - (den.bit_length() - 1))


def _eis_sign(x) -> int:
    return (x > 0) - (x < 0)


def _model_fixed(t: np.ndarray, c: np.ndarray, lowest: float, by_area: bool) -> list[int]:
    """``common/fixed.glsl``'s decisions on vertices ``t`` (3, 3) as (u, v, along the ray),
    (u, v) already in the fixed point (:func:`triangles`), at the center ``c`` = (u, v).
    The orientation and the edge functions are exact integers (here in units of 2^-64
    voxel, there of 2^-F: a power of two apart, so their roundings to double and the
    crossing from them agree bit for bit), the crossing the shaders' barycentric formula
    (times the reciprocal of twice the projected area, rounded once, with ``by_area``,
    else divided by the weights' sum), its first voxel clamped below at ``lowest``."""
    p0, p1, p2 = t[0], t[1], t[2]
    e0, e1 = p1 - p0, p2 - p0
    n2 = e0[0] * e1[1] - e0[1] * e1[0]
    f = [(_exact(v[0]), _exact(v[1])) for v in t]
    cf = (_exact(c[0]), _exact(c[1]))
    area2 = (f[1][0] - f[0][0]) * (f[2][1] - f[0][1]) - (f[1][1] - f[0][1]) * (f[2][0] - f[0][0])
    sgn = _eis_sign(area2)
    out = [int(sgn != 0), *_bits(n2)]
    s_or = sgn if sgn != 0 else 1
    exact, ws, tls = [], [], []
    for i in range(3):
        a, b = f[i], f[(i + 1) % 3]
        d = (b[0] - a[0]) * (cf[1] - a[1]) - (b[1] - a[1]) * (cf[0] - a[0])
        exact.append(d * s_or)
        ws.append(float(d) * float(s_or))  # as the shader: a zero turned by -1 is -0.0
        nu, nv = -_eis_sign(b[1] - a[1]) * s_or, _eis_sign(b[0] - a[0]) * s_or
        tls.append(int(nu > 0 or (nu == 0 and nv < 0)))
    covered = sgn != 0 and all(d > 0 or (d == 0 and tl) for d, tl in zip(exact, tls))
    first = 0
    if covered:
        num = ws[0] * (p2[2] - p0[2]) + ws[2] * (p1[2] - p0[2])
        z = p0[2] + (num * (1.0 / float(abs(area2))) if by_area else num / (ws[0] + ws[1] + ws[2]))
        z = min(max(z, float(t[:, 2].min())), float(t[:, 2].max()))
        first = _first(z, lowest, 1073741824.0)
    return out + [w for v in ws for w in _bits(math.ldexp(v, -128))] + tls + [int(covered), first]


def _model_ss(t: np.ndarray, c: np.ndarray) -> list[int]:
    """``ss/solid.glsl`` on float32 vertices ``t`` (3, 3) whose (y, z) are already its
    fixed-point values (:func:`triangles`), center ``c`` = (y, z)."""
    return _model_fixed(t.astype(np.float64)[:, [1, 2, 0]], c, -1.0, True)


def _model_eis(t: np.ndarray, c: np.ndarray) -> list[int]:
    """``eisemann/column.glsl`` (render axis z) on double vertices ``t`` (3, 3) whose (x, y)
    are already its fixed-point values (:func:`triangles`), center ``c`` = (x, y)."""
    return _model_fixed(t, c, -2.0, False)


def model(family: str, tris: np.ndarray, centers: np.ndarray) -> np.ndarray:
    """(triangles * centers, WORDS) uint32: the words the probe shader must write."""
    fn = _model_ss if family == "ss" else _model_eis
    return np.array([fn(t, c) for t in tris for c in centers], dtype=np.uint64).astype(np.uint32)


def _fixed(x: np.ndarray, bits: int) -> np.ndarray:
    """``x`` rounded to multiples of 2^-``bits`` (ties to even), as the shaders round a
    vertex: a product by a power of two, exact, then one rounding."""
    return np.ldexp(np.round(np.ldexp(x, bits)), -bits).astype(x.dtype)


def fixed_bits_of(mesh, spec, family: str) -> int:
    """F of the family's fixed point on ``mesh`` and ``spec``: ss-solid's rays run along x,
    the probed eisemann render's along z."""
    return fixed_bits(mesh, spec, 0 if family == "ss" else 2)


def triangles(mesh, spec, family: str) -> tuple[np.ndarray, np.ndarray]:
    """The voxel-space triangles each family decides coverage on, and the column centers
    of the grid: ss-solid's float32 vertices with (y, z) rounded to its fixed point (as
    ``ss/solid.glsl`` rounds them: a float32 rounded to a coarser step stays a float32)
    and centers in (y, z); eisemann's double vertices (render axis z) with (x, y) rounded
    to its fixed point (as ``common/transform.comp`` rounds them for it) and centers in
    (x, y).  F: :func:`fixed_bits_of`."""
    ny, nz = spec.dims[1], spec.dims[2]
    bits = fixed_bits_of(mesh, spec, family)
    if family == "ss":
        tris = gpu_vertices_voxel(mesh, spec)[mesh.faces]
        tris[..., 1:] = _fixed(tris[..., 1:].astype(np.float64), bits).astype(np.float32)
        grid = np.stack(np.meshgrid(np.arange(ny), np.arange(nz), indexing="ij"), -1).reshape(-1, 2)
    else:
        tris = gpu_vertices_voxel(mesh, spec, double=True)[mesh.faces]
        tris[..., :2] = _fixed(tris[..., :2], bits)
        grid = np.stack(np.meshgrid(np.arange(spec.dims[0]), np.arange(ny), indexing="ij"), -1).reshape(-1, 2)
    return tris, grid.astype(np.float32) + np.float32(0.5)


def run_probe(ctx, family: str, stage: str, tris: np.ndarray, centers: np.ndarray,
              fix_bits: int | None = None) -> np.ndarray:
    """(pairs, WORDS) uint32 written by ``testing/tie_probe`` on this GL, its coverage
    decided in multiples of 2^-``fix_bits`` voxel (required: the tris must be multiples
    already, as :func:`triangles` makes them)."""
    pairs = len(tris) * len(centers)
    if fix_bits is None or not 1 <= fix_bits <= 28:
        raise ValueError(f"the probe needs its fixed point's bits (1..28), got {fix_bits!r}")
    uniforms = {"u_pairs": pairs, "u_centers": len(centers),
                "u_eis_fix_bits" if family == "eis" else "u_solid_fix_bits": fix_bits}
    cen = np.ascontiguousarray(centers, np.float32)
    out = (pairs * WORDS, np.uint32)
    if family == "ss":
        buffers = {"ProbeTris": np.ascontiguousarray(tris, np.float32).reshape(-1), "ProbeCenters": cen,
                   "ProbeOut": out}
    else:
        buffers = {"EisVox": np.ascontiguousarray(tris, np.float64).reshape(-1),
                   "EisFaces": np.arange(3 * len(tris), dtype=np.uint32), "ProbeCenters": cen, "ProbeOut": out}
    if stage == "compute":
        got = run_compute(ctx, "testing/tie_probe.comp", -(-pairs // 64), buffers=buffers, read=["ProbeOut"],
                          uniforms=uniforms, defines={"PROBE_EIS": int(family == "eis")})
    else:
        width = min(pairs, 1024)
        _, got = run_fragment(ctx, "testing/tie_probe.frag", (width, -(-pairs // width)), buffers=buffers,
                              read=["ProbeOut"], uniforms={**uniforms, "u_width": width})
    return got["ProbeOut"].reshape(pairs, WORDS)


def probe(ctx, mesh, spec, model_fn=model) -> tuple[int, list[Difference]]:
    """Every pair of ``mesh`` on ``spec`` through each of :data:`KINDS`: (pairs probed,
    the differences from ``model_fn``)."""
    total, diffs = 0, []
    for kind, family, stage in KINDS:
        tris, centers = triangles(mesh, spec, family)
        got = run_probe(ctx, family, stage, tris, centers, fixed_bits_of(mesh, spec, family))
        want = model_fn(family, tris, centers)
        total += len(got)
        for p in np.flatnonzero((got != want).any(axis=1)):
            fields = [name for name, sl in FIELDS.items() if (got[p, sl] != want[p, sl]).any()]
            c = centers[p % len(centers)]
            diffs.append(Difference(kind, int(p // len(centers)), (float(c[0]), float(c[1])), fields,
                                    got[p], want[p]))
    return total, diffs


#: The pipelines :func:`trace` runs: (name, model family).
TRACED = (("ss-solid voxelize", "ss"), ("eisemann-solid render", "eis"))

#: The bit of a trace record's column u that marks a fragment drawn over a center its
#: triangle does not cover (eisemann/slices.frag).
NOT_COVERED = 0x80000000

_OWNER = "tie-trace"


@dataclass
class TraceDifference:
    """A (triangle, column) where a method's own pass did other than the model; ``triangle``
    None: a column whose masks or packed voxels differ from what its traced fragments make."""

    kind: str
    triangle: int | None
    column: tuple[int, int]
    what: str

    def __str__(self) -> str:
        at = f"column {self.column}" if self.triangle is None else f"triangle {self.triangle}, column {self.column}"
        return f"{self.kind}: {at}: {self.what}"


def _expected(family: str, tris: np.ndarray, centers: np.ndarray,
              model_fn=model) -> dict[tuple[int, int, int], int]:
    """(triangle, column u, column v) -> first voxel, for the pairs ``model_fn`` covers."""
    words = model_fn(family, tris, centers)
    out = {}
    for p in np.flatnonzero(words[:, FIELDS["covered"].start]):
        c = centers[p % len(centers)]
        out[(int(p // len(centers)), int(c[0]), int(c[1]))] = int(words[p, FIELDS["first voxel"].start])
    return out


def _after_the_fragments(ctx, spec, records: np.ndarray, grid) -> list[TraceDifference]:
    """The render's next steps on a one-tile, one-target grid: each pixel of the target must
    hold the XOR of the suffix masks of the covered fragments traced there (the masks the
    fragment shader writes and the logic op), and the packed grid must hold those masks'
    slices (the pack).  Not where the context gets the logic op wrong
    (:mod:`glvox.gpu.behaviours`): eisemann-solid is refused there."""
    nu, nv, na = spec.dims
    if broken(ctx, "integer-logic-op") is not None or na > SLICES_PER_TARGET or max(nu, nv) > tile_limit(ctx):
        return []
    tex = last_pass_targets(ctx)[0]
    masks = np.frombuffer(tex.read(), dtype="<u4").reshape(tex.size[1], tex.size[0], 4)[:nv, :nu]
    want = np.zeros((nv, nu, 4), np.uint32)
    suffix = mask_table("xor", 1)[:, 0]  # row r: the words of slices >= r
    for _, u, v, first in records.tolist():
        first = int(np.uint32(first).view(np.int32))
        if not u & NOT_COVERED and first < SLICES_PER_TARGET:
            want[v, u] ^= suffix[max(first, 0)]
    kind = TRACED[1][0]
    diffs = [TraceDifference(kind, None, (int(u), int(v)), "the render target holds other masks than the XOR of the "
                                                          "fragments traced there (the masks written or the logic op)")
             for v, u in np.argwhere((masks != want).any(axis=-1))]
    slices = np.unpackbits(np.ascontiguousarray(masks).view(np.uint8), axis=-1, bitorder="little")[..., :na]
    packed = unpack_bits(np.frombuffer(grid.read(size=spec.n_words * 4), dtype="<u4"), spec.dims)
    diffs += [TraceDifference(kind, None, (int(u), int(v)), "the packed grid differs from the render target's "
                                                           "masks (the pack)")
              for u, v in np.argwhere((packed != slices.transpose(1, 0, 2).astype(bool)).any(axis=-1))]
    return diffs


def _run_traced(ctx, mesh, spec, family: str, capacity: int) -> tuple[np.ndarray, list[TraceDifference]]:
    """(records, 4) uint32: the traced pass of ``family`` on ``mesh``; and for the render,
    the differences of its later steps (:func:`_after_the_fragments`)."""
    pool = buffer_pool(ctx, _OWNER)
    buf = pool.get("trace", 4 + 16 * capacity, clear=False)
    clear_buffer(ctx, buf, 4)
    timer = StageTimer(ctx)
    if family == "ss":
        if spec.n_words * 4 >= ORDER_MIN_BYTES:  # the pass would read its faces reordered by row
            raise GlvoxError(f"the tie trace runs grids under {ORDER_MIN_BYTES} bytes of bits, got {spec.dims}")
        parity_on_gpu(ctx, mesh, spec, timer, pool, trace=buf)
    else:
        grid, _ = render_slice_masks(ctx, mesh, spec, SliceRender("xor", axis=2, trace=buf), timer=timer,
                                     owner=_OWNER)
    n = int(np.frombuffer(buf.read(size=4), dtype="<u4")[0])
    if n > capacity:
        raise GlvoxError(f"the {family} trace holds {capacity} records, the pass wrote {n}")
    records = np.zeros((0, 4), np.uint32) if n == 0 else \
        np.frombuffer(buf.read(size=16 * n, offset=4), dtype="<u4").reshape(n, 4)
    return records, [] if family == "ss" else _after_the_fragments(ctx, spec, records, grid)


def trace(ctx, mesh, spec, model_fn=model) -> tuple[int, list[TraceDifference]]:
    """ss-solid's crossings and eisemann-solid's fragments on ``mesh`` against the
    covered pairs of ``model_fn``: (pairs it covers, the differences).  Small grids
    (the selftest's tie cases): the pass must read the mesh's own face order."""
    total, diffs = 0, []
    try:
        for kind, family in TRACED:
            tris, centers = triangles(mesh, spec, family)
            want = _expected(family, tris, centers, model_fn)
            got, later = _run_traced(ctx, mesh, spec, family, len(tris) * len(centers))
            uncovered = (got[:, 1] & NOT_COVERED) != 0
            if family == "eis":
                # the render culls a triangle whose crossings all lie past the grid's slices, and
                # a fragment past them flips nothing: those pairs are left out on both sides
                beyond = spec.dims[2]
                want = {k: f for k, f in want.items() if np.int32(np.uint32(f)) < beyond}
                keep = uncovered | (got[:, 3].view(np.int32) < beyond)
                got, uncovered = got[keep], uncovered[keep]
            total += len(want)
            drawn: dict[tuple[int, int, int], list[int | None]] = {}
            for (t, u, v, first), out in zip(got.tolist(), uncovered.tolist()):
                drawn.setdefault((t, u & ~NOT_COVERED, v), []).append(None if out else first)
            for key in sorted(set(want) | set(drawn)):
                firsts = drawn.get(key, [])
                covered = [f for f in firsts if f is not None]
                if len(firsts) > 1:
                    what = f"{len(firsts)} records of one pair"
                elif key in want and not firsts:
                    what = ("no fragment drawn over a center the model covers" if family == "eis"
                            else "no crossing where the model covers the center")
                elif key in want and not covered:
                    what = "drawn, but the render's coverage test said not covered (the model: covered)"
                elif key not in want and covered:
                    what = f"covered by the pass (first voxel {covered[0]}), not by the model"
                elif key in want and covered[0] != want[key]:
                    what = f"first voxel {covered[0]}, the model's {want[key]}"
                else:
                    continue
                diffs.append(TraceDifference(kind, key[0], (key[1], key[2]), what))
            diffs += later
    finally:
        buffer_pool(ctx, _OWNER).release()
    return total, diffs
