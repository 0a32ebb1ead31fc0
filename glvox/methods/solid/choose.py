"""``solid``: the solid method a user wants without knowing the mesh.

An alias, resolved per mesh (:meth:`glvox.methods.Method.resolve`):
``ss-solid`` (exact parity, the fastest solid) when the mesh is watertight and
consistently oriented, else ``binvox-solid`` (binvox's carving and parity
voting with its surface, ShapeNet's recipe; winding plays no part, so it is
defined for double-sided, inconsistently oriented and open meshes, and it is
what datasets voxelized by binvox hold).  :func:`glvox.methods.run_method`
runs the method it picks, so the run info (``result.run.method``) and a batch
manifest's ``method`` column name the one that ran;
``result.run.stats['requested']`` is ``'solid'``.

The traits are :func:`glvox.traits.mesh_traits` (computed once per mesh);
:func:`choice` says which decided.
"""

from __future__ import annotations

from ...traits import mesh_traits
from ..base import _REGISTRY, Method, MethodInfo, register
from ..ss.solid import _REQUIRES

#: What ``solid`` runs on closed, consistently oriented meshes and on the others.
CLOSED_METHOD, OTHER_METHOD = "ss-solid", "binvox-solid"


def choice(mesh) -> tuple[str, str]:
    """(method, why) for ``mesh``: the table of docs/methods/solid.md."""
    t = mesh_traits(mesh)
    if t.opposite_pairs or t.duplicate_share:
        return OTHER_METHOD, (f"double-sided ({100 * (t.opposite_share + t.duplicate_share):.3g}% of faces "
                              "coincide with another)")
    if t.open_edges or not t.watertight:
        return OTHER_METHOD, f"not watertight ({t.open_edges} open edges)"
    if t.inconsistent_parts:
        return OTHER_METHOD, f"inconsistently oriented ({t.inconsistent_parts} of {t.parts} parts)"
    return CLOSED_METHOD, "watertight and consistently oriented"


@register
class AutoSolid(Method):
    info = MethodInfo(
        name="solid", kind="solid", pipeline="compute",
        paper=f"alias: {CLOSED_METHOD} (Schwarz & Seidel 2010, Sec. 4.1) on closed, consistently oriented meshes, "
              f"{OTHER_METHOD} (binvox: z-buffer carving and parity voting) on the others",
        summary=f"solid of any mesh: {CLOSED_METHOD} when the mesh is watertight and consistently oriented, else "
                f"{OTHER_METHOD}; the run info names the one that ran",
        reference="reference-solid", any_mesh=True,
        requires=_REQUIRES,
    )

    def resolve(self, mesh) -> str:
        return choice(mesh)[0]

    def why(self, mesh) -> str:
        return choice(mesh)[1]

    def release(self, ctx) -> None:
        # the buffers are the resolved methods': they release their own
        for name in (CLOSED_METHOD, OTHER_METHOD):
            _REGISTRY[name].release(ctx)

    def run(self, mesh, spec, *, ctx, timer):
        # run_method runs the resolved method itself (with its own checks and run
        # info); this serves callers of Method.run, once every module has registered
        return _REGISTRY[self.resolve(mesh)].run(mesh, spec, ctx=ctx, timer=timer)
