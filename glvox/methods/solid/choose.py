"""``solid``: the solid method a user wants without knowing the mesh.

An alias, resolved per mesh (:meth:`glvox.methods.Method.resolve`), the
solid each mesh's defects leave defined:

* watertight, consistently oriented, no coincident faces: ``ss-solid``
  (exact parity, the fastest solid; results unchanged on closed meshes);
* mostly double-sided (half or more of the faces coincide with another) or
  inconsistently oriented: ``binvox-solid`` (binvox's carving and parity
  voting with its surface, ShapeNet's recipe; winding plays no part, and it
  is what datasets voxelized by binvox hold);
* open with a closed part inside out: ``binvox-solid`` too (its winding
  numbers are negative there);
* otherwise open, or with faces doubled in places: ``gwn-solid`` (the
  generalized winding number, defined for any mesh that is oriented: holes
  and a few doubled faces move it little).  :func:`glvox.methods.run_method`
runs the method it picks, so the run info (``result.run.method``) and a batch
manifest's ``method`` column name the one that ran;
``result.run.stats['requested']`` is ``'solid'``.

The traits are :func:`glvox.traits.mesh_traits` (computed once per mesh);
:func:`choice` says which decided.
"""

from __future__ import annotations

from ...traits import MOST_SHARE, mesh_traits
from ..base import _REGISTRY, Method, MethodInfo, register
from ..ss.solid import _REQUIRES

#: What ``solid`` runs on closed, consistently oriented meshes; on meshes whose orientation
#: cannot be trusted (double-sided, inconsistent); and on the other open ones.
CLOSED_METHOD, UNORIENTED_METHOD, OPEN_METHOD = "ss-solid", "binvox-solid", "gwn-solid"
PICKS = (CLOSED_METHOD, UNORIENTED_METHOD, OPEN_METHOD)


def choice(mesh) -> tuple[str, str]:
    """(method, why) for ``mesh``: the table of docs/methods/solid.md."""
    t = mesh_traits(mesh)
    doubled = t.opposite_share + t.duplicate_share
    if doubled >= MOST_SHARE:
        return UNORIENTED_METHOD, f"double-sided ({100 * doubled:.3g}% of faces coincide with another)"
    if t.inconsistent_parts:
        return UNORIENTED_METHOD, f"inconsistently oriented ({t.inconsistent_parts} of {t.parts} parts)"
    if t.watertight and not t.open_edges and doubled == 0:
        return CLOSED_METHOD, "watertight and consistently oriented"
    if t.inverted_parts:
        return UNORIENTED_METHOD, f"open, with {t.inverted_parts} of {t.parts} parts inside out"
    if doubled:
        return OPEN_METHOD, f"faces doubled in places ({100 * doubled:.3g}%), oriented"
    return OPEN_METHOD, f"not watertight ({t.open_edges} open edges), consistently oriented"


@register
class AutoSolid(Method):
    info = MethodInfo(
        name="solid", kind="solid", pipeline="compute",
        paper=f"alias: {CLOSED_METHOD} (Schwarz & Seidel 2010, Sec. 4.1) on closed, consistently oriented meshes, "
              f"{UNORIENTED_METHOD} (binvox: z-buffer carving and parity voting) on double-sided or inconsistently "
              f"oriented ones, {OPEN_METHOD} (generalized winding numbers) on the other open ones",
        summary=f"solid of any mesh: {CLOSED_METHOD} when watertight and consistently oriented, {UNORIENTED_METHOD} "
                f"when double-sided or inconsistently oriented, else {OPEN_METHOD}; the run info names the one "
                "that ran",
        reference="reference-solid", any_mesh=True,
        requires=_REQUIRES,
    )

    def resolve(self, mesh) -> str:
        return choice(mesh)[0]

    def why(self, mesh) -> str:
        return choice(mesh)[1]

    def release(self, ctx) -> None:
        # the buffers are the resolved methods': they release their own
        for name in PICKS:
            _REGISTRY[name].release(ctx)

    def run(self, mesh, spec, *, ctx, timer):
        # run_method runs the resolved method itself (with its own checks and run
        # info); this serves callers of Method.run, once every module has registered
        return _REGISTRY[self.resolve(mesh)].run(mesh, spec, ctx=ctx, timer=timer)
