"""``solid``: the solid method a user wants without knowing the mesh.

An alias, resolved per mesh (:meth:`glvox.methods.Method.resolve`):
``ss-solid`` (exact parity, the fastest solid) when the mesh is watertight,
else ``gwn-solid`` (generalized winding numbers, defined for any mesh).
:func:`glvox.methods.run_method` runs the method it picks, so the run info
(``result.run.method``) and a batch manifest's ``method`` column name the
one that ran; ``result.run.stats['requested']`` is ``'solid'``.
"""

from __future__ import annotations

from ..base import _REGISTRY, Method, MethodInfo, register
from ..ss.solid import _REQUIRES

#: What ``solid`` runs on watertight meshes and on the others.
CLOSED_METHOD, OPEN_METHOD = "ss-solid", "gwn-solid"


@register
class AutoSolid(Method):
    info = MethodInfo(
        name="solid", kind="solid", pipeline="compute",
        paper=f"alias: {CLOSED_METHOD} (Schwarz & Seidel 2010, Sec. 4.1) on watertight meshes, {OPEN_METHOD} "
              "(Jacobson et al. 2013; Barill et al. 2018) on the others",
        summary=f"solid of any mesh: {CLOSED_METHOD} when the mesh is watertight, else {OPEN_METHOD}; the run "
                "info names the one that ran",
        reference="reference-solid", any_mesh=True,
        requires=_REQUIRES,
    )

    def resolve(self, mesh) -> str:
        return CLOSED_METHOD if mesh.watertight else OPEN_METHOD

    def release(self, ctx) -> None:
        # the buffers are the resolved methods': they release their own
        for name in (CLOSED_METHOD, OPEN_METHOD):
            _REGISTRY[name].release(ctx)

    def run(self, mesh, spec, *, ctx, timer):
        # run_method runs the resolved method itself (with its own checks and run
        # info); this serves callers of Method.run, once every module has registered
        return _REGISTRY[self.resolve(mesh)].run(mesh, spec, ctx=ctx, timer=timer)
