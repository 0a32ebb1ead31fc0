"""Every solid method on the defects of dataset meshes: right, or it says so.

ShapeNet-style models hold every face twice with opposite winding or orient
parts inconsistently.  Each registered solid method, run on tiny hand-made
cubes with these defects (glvox.testing.defects), must either give the solid
of the intact mesh (its own reference run on the intact cube: the exact
parity / winding / carved solid) or warn with a SuspiciousResultWarning
naming the cause and the method to use instead: never a silent empty or
wrong grid.
"""

from __future__ import annotations

import re
import warnings

import numpy as np
import pytest

from glvox.errors import NotWatertightError, SuspiciousResultWarning
from glvox.grid import GridSpec
from glvox.mesh import load_mesh
from glvox.methods import get_method, method_names, run_method
from glvox.testing import defects

# voxel centers at odd multiples of 1/16 (h = 1/8 from -1/4): none on a cube face, so no ties
H, LO = 0.125, -0.25

CASES = {
    # defect -> (mesh, intact mesh, x voxels, the cause a warning must name)
    "double_sided": (defects.double_sided_cube, defects.cube, 12, "double-sided faces cancel"),
    "flipped_face": (defects.flipped_face_cube, defects.cube, 12, "inconsistent orientation"),
    "one_inside_out": (defects.two_cubes_one_inside_out,
                       lambda: (lambda v, f: (v, np.vstack([f[:12], f[12:, ::-1]])))(*defects.two_cubes_one_inside_out()),
                       28, "1 of 2 parts inside out"),
}


def _spec(nx: int) -> GridSpec:
    return GridSpec(dims=(nx, 12, 12), origin=(LO, LO, LO), voxel_size=H)


def _run(method, mesh, spec):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        result = run_method(method, mesh, spec, allow_open=True)
    return result, [str(w.message) for w in caught if issubclass(w.category, SuspiciousResultWarning)]


_INTACT: dict = {}


def _intact(case: str, reference: str) -> np.ndarray:
    """The reference's solid of the intact mesh (computed once per case and reference)."""
    key = (case, reference)
    if key not in _INTACT:
        _, intact, nx, _ = CASES[case]
        _INTACT[key] = run_method(reference, load_mesh(intact(), name="intact"), _spec(nx)).dense()
    return _INTACT[key]


def test_the_intact_solids_are_the_known_ones():
    """The expectations themselves: reference-solid of the intact cubes is the set of voxel
    centers inside them, worked out from the placement alone."""
    for case, boxes in (("double_sided", ((0, 0, 0),)), ("one_inside_out", ((0, 0, 0), (2, 0, 0)))):
        want = defects.cube_solid(_spec(CASES[case][2]), boxes)
        assert want.sum() == 512 * len(boxes)
        assert np.array_equal(_intact(case, "reference-solid"), want)


@pytest.mark.parametrize("case", sorted(CASES))
@pytest.mark.parametrize("method", method_names(kind="solid"))
def test_right_or_warned(method, case):
    build, _, nx, cause = CASES[case]
    mesh = load_mesh(build(), name=case)
    result, said = _run(method, mesh, _spec(nx))
    ran = result.run.method  # the alias `solid` names the method it picked: its reference decides
    want = _intact(case, get_method(ran).info.reference)
    right = np.array_equal(result.dense(), want)
    assert right != bool(said), (f"{ran}: {'right, yet warned' if right else 'wrong, silently'} "
                                 f"({result.count} voxels, {int(want.sum())} expected) {said}")
    if said:
        assert len(said) == 1 and said[0].startswith(f"{case}: {result.count} voxels"), said
        assert f"from {ran}: {cause}" in said[0] and "use -m binvox-solid or -m carve-solid" in said[0], said
        assert "\n" not in said[0]


@pytest.mark.parametrize("method", ["ss-solid", "gwn-solid", "vote-solid"])
@pytest.mark.filterwarnings("ignore::glvox.errors.NotWatertightWarning")
def test_double_sided_cube_warns_with_the_cause(method):
    mesh = load_mesh(defects.double_sided_cube(), name="two_faced.obj")
    with pytest.warns(SuspiciousResultWarning,
                      match=rf"^two_faced\.obj: 0 voxels \(empty\) from {method}: double-sided faces cancel \(100% "
                            r"of faces doubled with opposite winding\); use -m binvox-solid or -m carve-solid$"):
        result = run_method(method, mesh, _spec(12), allow_open=True)
    assert result.count == 0 and result.run.stats["suspicious"].startswith("0 voxels (empty)")


def test_a_healthy_solid_does_not_warn():
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        result = run_method("ss-solid", load_mesh(defects.cube()), _spec(12))
    assert result.count == 512 and "suspicious" not in result.run.stats


def test_an_empty_solid_of_a_healthy_mesh_warns():
    """Nothing in the traits is wrong, yet no voxel center is inside: still a warning."""
    tiny = load_mesh(defects.cube(lo=(0.01, 0.01, 0.01), size=0.02), name="speck")
    with pytest.warns(SuspiciousResultWarning, match=r"^speck: 0 voxels \(empty\) from ss-solid: no voxel center"):
        run_method("ss-solid", tiny, _spec(12))


def test_refusal_of_a_double_sided_mesh_names_the_cause():
    """Without allow_open, the watertight check refuses a double-sided mesh (its edges hold
    four faces) and says why a parity method would find it empty, rather than 'not watertight'."""
    mesh = load_mesh(defects.double_sided_cube(), name="two_faced.obj")
    with pytest.raises(NotWatertightError, match=re.escape(
            "two_faced.obj is double-sided (every face twice, coincident), so the solid method 'ss-solid' "
            "would find it empty (the crossings cancel); use -m binvox-solid or -m carve-solid")):
        run_method("ss-solid", mesh, _spec(12))
