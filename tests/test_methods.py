"""The one method interface: every registered method honours the contract.

Tests iterate over the registry, so a method added later is covered here
without edits; method-specific correctness lives in each method's tests
(which use glvox.metrics.check_against_reference).
"""

from __future__ import annotations

import numpy as np
import pytest

import glvox
from glvox.errors import LimitError, MethodError
from glvox.grid import GridSpec
from glvox.mesh import load_mesh
from glvox.methods import (FAMILIES, KINDS, PIPELINES, Method, MethodInfo, get_method, method_infos, method_names,
                           register, run_method)
from glvox.metrics import check_against_reference, separation_leaks, tie_set
from glvox.results.voxels import VoxelGrid

VOXEL_KINDS = ("surface", "solid")


def test_registry_holds_the_references():
    assert {"reference-conservative", "reference-6sep", "reference-solid"} <= set(method_names())
    assert method_names(kind="solid", pipeline="cpu") == ["reference-binvox", "reference-carve", "reference-gwn",
                                                        "reference-solid", "reference-vote"]


@pytest.mark.parametrize("name", method_names())
def test_registry_entry_is_complete(name):
    info = get_method(name).info
    assert info.kind in KINDS and info.family in FAMILIES and info.pipeline in PIPELINES
    assert info.paper and info.summary
    assert info.reference in method_names()
    # a method is checked against a reference of its own kind (sparse solids against the solid one)
    assert get_method(info.reference).info.kind in (info.kind, "solid")
    assert name in [i.name for i in glvox.list_methods(kind=info.kind)]


@pytest.mark.parametrize("name", [i.name for i in method_infos() if i.kind in VOXEL_KINDS])
def test_method_contract_on_a_small_mesh(name, gl_context):
    mesh = load_mesh("gen:torus")
    spec = glvox.grid_for(mesh, 12, tight=True)
    g = run_method(name, mesh, spec)
    assert isinstance(g, VoxelGrid) and g.spec == spec
    run = g.run
    # an alias (solid) records the method it ran
    assert run.method == get_method(name).resolve(mesh) and run.kind == get_method(name).info.kind
    assert run.stats["voxels"] == g.count > 0
    assert run.stats["triangles"] == mesh.n_triangles
    assert len(run.timings.stages) >= 1 and run.timings.wall_s > 0
    if get_method(name).info.uses_gl:
        assert run.timings.gpu_s is not None
    # same input, same voxels
    assert run_method(name, mesh, spec).equal(g)


def test_dense_results_beyond_int32_voxels_are_refused_before_any_work():
    """Beyond MAX_VOXELS (int32 flat indices) a dense method is refused in one line that
    names the methods of its kind that take the grid (ss-conservative, ss-6sep, ss-solid and
    gwn-solid index packed words and stream z slabs: up to 2^36 voxels) and the sparse
    ss-octree."""
    mesh = load_mesh("gen:sphere")
    spec = glvox.grid_for(mesh, 2048)  # 2^33 voxels: a valid spec, too big for most methods
    for name in ("reference-solid", "carve-solid"):
        with pytest.raises(LimitError, match=r"more than the 2147483647 it keeps dense; use a smaller grid, "
                                             r"gwn-solid or ss-solid, or the sparse ss-octree$"):
            run_method(name, mesh, spec)
    # an open mesh: ss-solid takes the grid but has no inside for it, so only gwn-solid is offered
    box = load_mesh("gen:box")
    open_box = load_mesh((box.vertices, box.faces[:-2]))
    assert not open_box.watertight
    with pytest.raises(LimitError, match=r"more than the 2147483647 it keeps dense; use a smaller grid, gwn-solid, "
                                         r"or the sparse ss-octree$"):
        run_method("carve-solid", open_box, glvox.grid_for(open_box, 2048))
    # its winding field is dense float32: refused before any work
    with pytest.raises(LimitError, match=r"^winding=true returns a dense float32 field, and \(2048, 2048, 2048\) has "
                                         r"8589934592 voxels, more than the 2147483647 kept dense; use a smaller grid$"):
        run_method("gwn-solid", open_box, glvox.grid_for(open_box, 2048), winding=True)
    for name in ("reference-conservative", "scanline-ilv"):
        with pytest.raises(LimitError, match=r"more than the 2147483647 it keeps dense; use a smaller grid, "
                                             r"ss-6sep or ss-conservative, or the sparse ss-octree$"):
            run_method(name, mesh, spec)
    huge = glvox.grid_for(mesh, dims=(8192, 4096, 4096))  # 2^37
    with pytest.raises(LimitError, match=r"more than the 68719476736 it keeps dense; use a smaller grid or"):
        run_method("ss-conservative", mesh, huge)
    # the surface takes 2048^3, its per-voxel attributes do not: refused before any work
    with pytest.raises(LimitError, match=r"^per-voxel attributes are computed on grids of up to 2147483647 voxels, "
                                         r"and \(2048, 2048, 2048\) has 8589934592: use a smaller grid$"):
        run_method("ss-conservative", mesh, spec, attributes="normal")


def test_unknown_method_and_options():
    mesh = load_mesh("gen:box")
    spec = glvox.grid_for(mesh, 4)
    with pytest.raises(MethodError, match=r"unknown method 'ss-magic'; known methods: .*reference-solid"):
        run_method("ss-magic", mesh, spec)
    with pytest.raises(MethodError, match=r"method 'reference-conservative' has no option axis; its options: none"):
        run_method("reference-conservative", mesh, spec, axis=1)
    with pytest.raises(MethodError, match=r"option axis must be a int, got 'x'"):
        run_method("reference-solid", mesh, spec, axis="x")


def test_registering_a_name_twice_is_refused():
    class Dup(Method):
        info = MethodInfo(name="reference-solid", kind="solid", pipeline="cpu", paper="-", summary="-")

    with pytest.raises(ValueError, match="registered twice"):
        register(Dup)


def test_a_method_outside_a_family_package_is_refused():
    """A method's family is the package that registers it: one defined elsewhere has none."""
    class Stray(Method):
        info = MethodInfo(name="stray-solid", kind="solid", pipeline="cpu", paper="-", summary="-")

    with pytest.raises(ValueError, match=r"from a family package glvox.methods.<family> .*not from test_methods"):
        register(Stray)
    assert "stray-solid" not in method_names()


def test_reference_check_accepts_ties_and_catches_real_errors():
    """The tie proof: a result differing only on ties passes; one wrong voxel fails."""
    # the plane x + y + z = 3 passes through voxel corners: voxel (1, 1, 1) only
    # touches it at its corner (1, 1, 1), a slanted knife edge that rounding decides
    mesh = load_mesh((np.array([[3, 0, 0.0], [0, 3, 0.0], [0, 0, 3.0]]), np.array([[0, 1, 2]])))
    spec = GridSpec((4, 4, 3), (0, 0, 0), 1.0)
    ref = run_method("reference-conservative", mesh, spec)
    ties = tie_set("reference-conservative", mesh, spec)
    assert ties[1, 1, 1] and ref.dense()[1, 1, 1]
    # drop every tie voxel: still correct up to ties
    on_ties = VoxelGrid(ref.dense() & ~ties, spec)
    on_ties.run = ref.run
    assert check_against_reference(on_ties, mesh).ok
    # a voxel far from the triangle is a real error
    wrong = np.array(ref.dense())
    wrong[3, 3, 2] = not wrong[3, 3, 2]
    bad = VoxelGrid(wrong, spec)
    bad.run = ref.run
    check = check_against_reference(bad, mesh)
    assert not check.ok and check.unexplained.tolist() == [[3, 3, 2]]
    assert "1 mismatches are not ties" in check.describe()


def test_separability_helper_on_a_hand_made_shell():
    inside = np.zeros((7, 7, 7), bool)
    inside[2:5, 2:5, 2:5] = True
    shell = np.zeros_like(inside)
    shell[1:6, 1:6, 1:6] = True
    shell[2:5, 2:5, 2:5] = False
    assert len(separation_leaks(shell, inside, 26)) == 0
    holed = shell.copy()
    holed[1, 3, 3] = False  # a face hole: a 6-path gets in
    assert len(separation_leaks(holed, inside, 6)) > 0
    # an edge voxel missing: (1, 1, 3) touches the inside voxel (2, 2, 3) only
    # along an edge, so a 26-path gets in and a 6-path does not
    edge = shell.copy()
    edge[1, 1, 3] = False
    assert len(separation_leaks(edge, inside, 26)) > 0
    assert len(separation_leaks(edge, inside, 6)) == 0


def test_a_filter_that_names_nothing_is_refused():
    """method_infos(family='compute') once selected nothing, silently: 'compute' is a pipeline."""
    with pytest.raises(MethodError, match=r"unknown family .compute.; known: depth, .*reference"):
        method_infos(family="compute")
    with pytest.raises(MethodError, match=r"unknown pipeline 'ss'"):
        method_names(pipeline="ss")
    assert method_names(family="ss") and method_names(pipeline="compute")
