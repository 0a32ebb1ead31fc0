"""Every tolerance glvox uses, named once, with why it is what it is.

The modules that apply them import them from here (and re-export the names
they always had, e.g. ``glvox.reference.TIE_EPS``).  Units: ``voxels`` are
voxel-space lengths (1 = one voxel edge); ``relative`` is a fraction of the
quantity it is compared with.

The GPU methods compute in float32 (2^-24 relative precision) on vertices
transformed into voxel space; the CPU references compute in float64.  The
tolerances below separate the float32 rounding of a correct GPU result from
a real disagreement.
"""

from __future__ import annotations

# -- agreement with the references ---------------------------------------------

#: Tie tolerance (voxels).  float32 has a 2**-24 (6e-8) relative precision,
#: so vertex coordinates in voxel space up to a few thousand voxels carry
#: rounding errors below ~1e-4 voxel after the world->voxel transform and a
#: few operations; anything beyond that is a real disagreement, not rounding.
#: A surface voxel is a tie when its verdict flips with the box half-size
#: 0.5 +/- TIE_EPS, a solid voxel when its center lies within TIE_EPS of the
#: surface (docs/design.md, "Ties"; :mod:`glvox.reference.ties`).
TIE_EPS = 1e-4

#: (voxels) Attribute ties: a voxel's source triangle (the overlapping
#: triangle nearest to its center, glvox/grid.py) may differ between the GPU
#: and the float64 reference only where two candidates' distances are within
#: this of each other, or where a candidate's overlap itself is a TIE_EPS tie.
#: The GPU computes the distances in double from the same float32 voxel-space
#: vertices and keeps them in 2^-31 voxel fixed point for its atomicMin
#: (attributes/pair.glsl): two distances that round to the same key differ by
#: less than 5e-10 voxel, and double rounding adds ~1e-16; 1e-6 is the
#: issue's bound, far above both.
ATTR_TIE_EPS = 1e-6

#: (RGBA8 units) Colours of the GPU against the reference's float64 value
#: rounded to 8 bits: both round a value that may sit at a half step, and
#: llvmpipe filters RGBA8 textures with 8-bit weights, so one unit (1/255).
ATTR_COLOR_TOL = 1

#: (unit vectors) Normals: float32 interpolation and normalization of
#: float64-exact inputs stay within ~1e-7 per component; 1e-5 is the issue's bound.
ATTR_NORMAL_TOL = 1e-5

#: (voxels) --fill-attributes nearest is a jump flood (JFA+1), approximate by
#: design: the surface voxel whose attributes an interior voxel takes may be
#: farther than the exact nearest one (k-d tree) by at most this.  Measured on
#: the fuze's gwn-solid at 64^3: exact for 99.98% of the interior voxels,
#: worst 0.27 voxel (tests/test_attributes.py).
JFA_SLACK = 0.5

#: (voxels) The plane snap, the one tie policy for geometry on voxel planes
#: (:func:`glvox.grid.snap_to_planes`, ``shaders/common/snap.glsl``): a
#: voxel-space vertex coordinate within this distance of a multiple of 1/2
#: voxel (a voxel face plane, where surface verdicts turn, or a voxel center
#: plane, where solid verdicts turn) is moved onto it, on the CPU in float64
#: and on the GPU in double before the float32 rounding, before any method or
#: reference sees it.  Rounding alone puts a face that lies on a voxel plane
#: (the default fit puts the bounding box on the grid's boundary planes) at
#: +-1e-17 voxel on the CPU and up to 2^-25 N voxel off on the GPU (the float32
#: upload relative to the mesh's center, N voxels across: 1.2e-4 at 4096), on
#: either side, so rounding kept or dropped the touching layer.  2^-11
#: (4.9e-4) is four times that rounding at 4096 voxels (the largest ss-octree
#: grid) and twice it at 8192; about five times TIE_EPS, so a coordinate left
#: unsnapped lies farther than TIE_EPS from every such plane for CPU and GPU
#: alike; a power of two, so the GLSL literal is the same number.  It moves
#: geometry by less than 1/2000 voxel: only verdicts that close to a knife
#: edge can change, which is what it is for.
SNAP_EPS = 2.0 ** -11

#: (voxels) ss-conservative and ss-6sep treat a triangle as a sliver (no plane test,
#: projection tests over its bounding box: ``shaders/ss/setup.glsl``) when every
#: projection's signed area is within what moving its vertices by this much can change.
#: Half of TIE_EPS: every such triangle is then one whose projections' orientations are
#: all ambiguous under TIE_EPS (``glvox.reference.ties.orientation_ambiguous``), whose tie
#: set holds what the projections alone allow; and a triangle whose plane is trusted has
#: an area at least ~1e-4 of its edges', far above float32's rounding of it.  Found by the
#: fuzz tests (issue 20): needles whose float32 normal is rounding set voxels 0.01 voxel
#: and more away from them through the dominant-axis columns.
SLIVER_EPS = TIE_EPS / 2

#: (multiples of :func:`glvox.reference.ties.float32_motion`) A projected edge
#: shorter than this many times the float32 motion of its end points can turn
#: by more than ~0.02 rad under rounding; the projection test it belongs to is
#: then decided by rounding (an edge of 2e-5 voxel in depth_cycloidal_drive.ply
#: turned by 10 degrees).
SHORT_EDGE_MOTIONS = 100.0

#: (turns: winding number units) A voxel of a winding-number solid is a tie
#: when the exact w at its center lies within this of the threshold (beside
#: the centers within TIE_EPS of the surface, where w jumps by 1).  The GPU
#: sums the strips of the boundary edges in float32, each atan2 within a few
#: 1e-7 rad, and holds the mesh in float32 (a TIE_EPS-sized motion moves w by
#: ~1e-5 at a voxel from a boundary edge): measured below 1e-5 on the shared
#: meshes (up to 1,280 boundary edges), so 1e-4 leaves a margin for chains
#: ten times longer.  gwn-solid refines every voxel whose expansion could be
#: off by its error bound plus this margin, so only these ties can differ.
WINDING_TIE = 1e-4

# -- input ----------------------------------------------------------------------

#: (relative to the squared longest bounding-box extent) A triangle is
#: degenerate (dropped) when twice its area is at most this.  1e-14 is ~100
#: ulps of float64 relative to the model size: only triangles that are
#: zero-area up to rounding (repeated or exactly collinear vertices) are
#: dropped; needles and slivers stay.
DEGENERATE_AREA_RTOL = 1e-14

# -- placement ------------------------------------------------------------------

#: (relative to h) Two placements are the same when origin and h agree within
#: this fraction of h: text formats (binvox headers) round-trip floats to ~7
#: digits, far below any voxel-sized difference.
PLACEMENT_RTOL = 1e-5

#: (relative to h) Files of other tools (NIfTI, NRRD, VTK image data) give a
#: grid's placement as an index-to-world matrix; glvox reads one whose axes are
#: the world axes (up to order and sign) with one voxel size.  NIfTI-1 stores
#: the matrix in float32 (6e-8 relative) and its qform as a quaternion, whose
#: round trip costs a few 1e-7; 1e-6 keeps a margin over that and still refuses
#: a rotation of 1e-4 degree (2e-6 rad) or anisotropic spacing.
FORMAT_AXIS_RTOL = 1e-6

#: (voxels) A fit's dims are ceil(extent / h - FIT_CEIL_SLACK): an extent that
#: is a whole number of voxels up to float64 rounding of the division does not
#: get one more, empty, voxel.
FIT_CEIL_SLACK = 1e-9

# -- the projected optimal scanline (Zhang et al. 2018) -------------------------

#: Scanline spacing as a fraction of the bound of Theorem 4.1.  Exactly the
#: bound leaves no margin: a voxel between two scanlines d^ apart may touch
#: both at corners only, and float rounding of the end points could then
#: miss it although the triangle crosses it.  0.1 % below the bound gives
#: every such voxel a crossing ~1e-3 voxel deep, far above float32 rounding
#: (~1e-5 voxel at 256^3), and changes the scanline count only when a
#: layer's width is within 0.1 % below a multiple of d^.
SCANLINE_SLACK = 0.999

#: (voxels) ILV snaps a vertex coordinate within this distance outside the
#: grid to the boundary voxel (:func:`glvox.reference.scanline.lattice_points`).
#: 1/64 voxel is exact in float32 next to any grid size up to the ILV limit and
#: covers the float32 rounding of a vertex that lies exactly on a grid face (at
#: most 2^-9 voxel at 16000 voxels); ILV itself moves every vertex by up to a
#: voxel, so the snap is invisible beside it.
ILV_BOUNDARY_SNAP = 1.0 / 64.0

#: (voxels) RLV's voxel of a coordinate within this distance outside the grid
#: is the boundary voxel (:func:`glvox.reference.scanline.cell`): the grid's
#: closed maximum faces belong to its last voxels.  TIE_EPS keeps RLV within
#: the conservative set up to ties, and covers float32's rounding of a vertex
#: lying on a grid face (below 1e-4 voxel up to ~1600 voxels).
RLV_BOUNDARY_SNAP = TIE_EPS

#: (relative) Size below which a float decision of the scanline's float path
#: counts as tied (:func:`glvox.reference.scanline.float_variant_ties`): the
#: gap between the two largest normal components (dominant axis), |n_a| +
#: |n_b| (parallel to the slicing plane), a layer's width in scanline
#: intervals next to an integer (the scanline count).  float32 rounds such
#: quantities by a few 1e-7 relative; 1e-5 keeps a wide margin and is still
#: rare on real meshes.
DECISION_RTOL = 1e-5

# -- benchmarks -------------------------------------------------------------------

#: (relative) ``glvox bench --check`` / ``--against``: a method regresses when
#: its best (and, side by side, median) warm time grows by more than this
#: fraction.  The same code measured twice on a quiet machine stays within a
#: few percent; a shared machine needs the recheck the bench does on a flag.
REGRESSION_TOLERANCE = 0.10

#: (ratio) A contender's warm runs are flagged *bimodal* when two consecutive
#: ones, sorted, differ by this factor: PyVista's 1024^3 call took 3.7-4.6 s
#: in one run and 0.86 s in another (issue 23), while load from other work
#: on this machine moved repeated runs by up to ~1.5x.
BIMODAL_RATIO = 2.0

#: Warm runs every contender gets in a cell of ``glvox bench`` / ``compare``,
#: even past its time budget, so that best, median and the bimodal flag mean
#: something for a slow peer too.
MIN_WARM_RUNS = 3

# -- mesh checks ----------------------------------------------------------------

#: Decimal digits to which vertex positions are rounded before duplicates are
#: merged for the watertight check (glvox.mesh.is_watertight): trimesh's
#: tol.merge = 1e-8, so glvox's answer is trimesh's on every mesh.
MERGE_DIGITS = 8

#: (relative to the bounding box's longest side) Vertices of the mesh traits
#: (glvox.traits) are welded when their positions, as multiples of this
#: fraction of the longest side from the box's minimum corner, round to the
#: same integers.  Coincident faces in dataset meshes repeat the very same
#: vertex positions (ShapeNet's doubled faces are exact copies), so any tiny
#: value finds them; 1e-9 is far above float64 rounding of coordinates (2e-16
#: relative) and far below any real feature (a 2^20-voxel grid's voxel is 1e-6),
#: and keeps the integer keys below 2^31.
WELD_RTOL = 1e-9

# -- signed distance fields ------------------------------------------------------

#: (voxels) glvox sdf: the GPU's distances agree with the float64 reference
#: within this.  The band pass computes the closest point in double and rounds
#: the distance once to float32 (2^-24 relative: 2e-7 voxel at a 3-voxel band;
#: 1e-5 voxel at 170 voxels, so ``band='all'`` rounds far voxels of large grids
#: beyond it, relative error still 6e-8).
SDF_DISTANCE_TOL = 1e-5

#: glvox sdf: a voxel's sign is uncertain where the generalized winding number
#: at its center lies within this of 1/2 (a closed, consistently oriented
#: surface gives 0 or 1 off the surface; holes, flipped or doubled faces give
#: values between).
SDF_WINDING_UNCERTAIN = 0.25
