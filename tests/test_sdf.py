"""glvox sdf: signed distances on the grid (GPU band pass) against the float64 reference,
a hand-worked cube, band, truncation, sign, files, samples and bad input."""

from __future__ import annotations

import importlib
import math
import warnings

import numpy as np
import pytest
import trimesh

import glvox
from glvox.cli import main
from conftest import VDB, needs_vdb

from glvox.errors import SuspiciousResultWarning
from glvox.grid import GridSpec
from glvox.methods.sdf.samples import sdf_samples
from glvox.reference.sdf import point_distances, reference_sdf
from glvox.reference.winding import winding_direct
from glvox.tolerances import SDF_DISTANCE_TOL

pytestmark = pytest.mark.usefixtures("gl_context")



def _cube() -> glvox.Mesh:
    box = trimesh.creation.box(extents=(1, 1, 1))
    return glvox.load_mesh((box.vertices + 0.5, box.faces))


def _sdf(*args, **kwargs):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", SuspiciousResultWarning)
        return glvox.sdf(*args, **kwargs)


def _check_against_reference(mesh, result, truncation=None):
    """Every voxel: distance within SDF_DISTANCE_TOL voxel of the float64 reference, the band
    the reference's (up to centers within the tolerance of its edge), the sign the
    occupancy of the solid method that gave it, run again on its own."""
    spec, h = result.spec, result.voxel_size
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        inside = glvox.voxelize(mesh, grid=spec, method=result.run.stats["sign_method"], allow_open=True).dense()
    ref, exact = reference_sdf(mesh, spec, inside, band=result.band_width, truncation=truncation)
    err = np.abs(result.sdf - ref) / h
    edge = np.abs(np.abs(ref) / h - result.band_width) <= SDF_DISTANCE_TOL
    assert np.array_equal(result.band | edge, exact | edge)
    assert err.max() <= SDF_DISTANCE_TOL, f"max error {err.max():.3g} voxel at {np.argwhere(err == err.max())[0]}"
    surface = np.abs(ref) > SDF_DISTANCE_TOL * h  # on the surface the sign is moot
    assert np.array_equal((result.sdf < 0)[surface], inside[surface])


def test_unit_cube_by_hand():
    """Voxel centers at -0.5, -0.25, ..., 1.5 on each axis: the cube [0, 1]^3's center is
    -0.5 inside, a point 0.25 outside a face +0.25, beside an edge sqrt(2) / 4, beside a
    corner sqrt(3) / 4, and beyond the 3-voxel band (0.75) the clamp."""
    spec = GridSpec((9, 9, 9), np.array([-0.625] * 3), 0.25)
    r = _sdf(_cube(), grid=spec, sign="reference-solid")
    s = r.sdf
    assert s[4, 4, 4] == pytest.approx(-0.5, abs=1e-7)
    assert s[7, 4, 4] == pytest.approx(0.25, abs=1e-7)
    assert s[1, 4, 4] == pytest.approx(0.25, abs=1e-7)
    assert s[3, 4, 4] == pytest.approx(-0.25, abs=1e-7)
    assert s[7, 7, 4] == pytest.approx(math.sqrt(2) / 4, abs=1e-7)
    assert s[7, 7, 7] == pytest.approx(math.sqrt(3) / 4, abs=1e-7)
    assert s[6, 4, 4] == pytest.approx(0.0, abs=1e-7)
    assert s[0, 0, 0] == pytest.approx(0.75) and not r.band[0, 0, 0]  # sqrt(3) / 2 > 0.75: clamped
    assert r.band[7, 7, 7] and r.n_uncertain == 0


@pytest.mark.parametrize("name", ["gen:torus", "gen:sphere", "gen:bunny-like"])
def test_generated_meshes_match_the_reference(name):
    mesh = glvox.load_mesh(name)
    _check_against_reference(mesh, _sdf(mesh, 32))


@pytest.mark.parametrize("name, n", [("stanford_bunny_bun_zipper.ply", 40), ("stanford_armadillo_libigl_86k.obj", 32),
                                     ("messy_teapot_newell.obj", 40)])
def test_shared_meshes_match_the_reference(shared_mesh, name, n):
    mesh = glvox.load_mesh(shared_mesh(name))
    _check_against_reference(mesh, _sdf(mesh, n))


def test_reference_libraries_agree():
    """libigl's AABB tree and the cKDTree-pruned exact fallback give the same distances."""
    pytest.importorskip("igl")
    mesh = glvox.load_mesh("gen:bunny-like")
    p = np.random.default_rng(1).uniform(mesh.bounds[0] - 0.1, mesh.bounds[1] + 0.1, (400, 3))
    a = point_distances(mesh.vertices, mesh.faces, p, library="igl")
    b = point_distances(mesh.vertices, mesh.faces, p, library="kdtree")
    assert np.allclose(a, b, rtol=1e-12, atol=1e-14)


def test_band_width_is_honoured():
    mesh = glvox.load_mesh("gen:torus")
    r = _sdf(mesh, 32, band=1.5)
    h = r.voxel_size
    assert r.band_width == 1.5 and np.abs(r.sdf).max() <= 1.5 * h + 1e-7
    assert np.all(np.abs(r.sdf[~r.band]) == np.float32(1.5 * h))
    _check_against_reference(mesh, r)


def test_band_all_is_exact_everywhere():
    mesh = glvox.load_mesh("gen:torus")
    r = _sdf(mesh, 24, band="all")
    assert r.band.all() and math.isinf(r.band_width)
    _check_against_reference(mesh, r)


@pytest.mark.parametrize("truncation, world", [("2vox", None), (0.05, 0.05), ("6vox", None)])
def test_truncation_clamps_and_widens_the_band(truncation, world):
    mesh = glvox.load_mesh("gen:torus")
    r = _sdf(mesh, 32, truncation=truncation)
    t = world if world is not None else float(truncation[:-3]) * r.voxel_size
    assert r.truncation == pytest.approx(t)
    assert np.abs(r.sdf).max() <= t * (1 + 1e-6)
    assert r.band_width == pytest.approx(max(3.0, t / r.voxel_size))
    _check_against_reference(mesh, r, truncation=t)


def test_open_mesh_sign_is_flagged_not_guessed():
    """A sphere with a cap cut off: voxels near the hole have winding numbers near 1/2,
    counted in result.uncertain and warned about."""
    s = trimesh.creation.icosphere(3)
    keep = s.triangles_center[:, 2] < 0.6
    mesh = glvox.load_mesh((s.vertices, s.faces[keep]))
    with pytest.warns(SuspiciousResultWarning, match=r"the sign of \d+ voxels is uncertain"):
        r = glvox.sdf(mesh, 32, sign="gwn-solid")
    assert r.n_uncertain > 0
    assert r.uncertain[:, :, -8:].any() and not r.uncertain[:, :, :8].any()  # at the hole, not far from it


@pytest.mark.parametrize("kwargs, match", [
    ({"band": -1}, "band must be a positive"), ({"band": "wide"}, "number of voxels or 'all'"),
    ({"truncation": "2km"}, "truncation must be a number"), ({"truncation": 0}, "truncation must be positive"),
    ({"sign": "ss-conservative"}, "comes from a solid method"), ({"sign": "nope"}, "nope"),
])
def test_bad_arguments_fail_in_one_line(kwargs, match):
    with pytest.raises(glvox.GlvoxError, match=match):
        glvox.sdf("gen:torus", 16, **kwargs)


def test_cli_refuses_before_any_work(capsys, tmp_path):
    assert main(["sdf", "no_such_mesh.ply", "-r", "16", "-o", str(tmp_path / "a.binvox")]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "saved as .npz, .nrrd, .nii(.gz), .vti or .vdb" in err
    assert main(["sdf", "gen:torus", "-r", "4000", "-o", str(tmp_path / "a.npz")]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "GiB" in err and "use a smaller -r" in err
    assert main(["sdf", "gen:torus", "-r", "16", "-o", str(tmp_path / "a.npz"), "--band", "x"]) == 1
    assert "'all'" in capsys.readouterr().err
    assert not any(tmp_path.iterdir())


def test_files_hold_the_field(tmp_path):
    pytest.importorskip("nrrd")
    nib = pytest.importorskip("nibabel")
    import nrrd

    r = _sdf("gen:torus", 20)
    back = glvox.load(glvox.save(r, tmp_path / "t.npz"))
    assert isinstance(back, glvox.SDFGrid) and np.array_equal(back.sdf, r.sdf)
    assert np.array_equal(back.band, r.band) and back.band_width == r.band_width
    assert np.allclose(back.origin, r.origin) and back.voxel_size == r.voxel_size
    with np.load(tmp_path / "t.npz") as z:
        assert z["sdf"].dtype == np.float32 and z["sdf"].shape == r.dims
    vti = glvox.load(glvox.save(r, tmp_path / "t.vti"))
    assert np.array_equal(vti.fields["sdf"], r.sdf) and np.array_equal(vti.extras["band"].dense(), r.band)
    with pytest.warns(glvox.errors.FormatWarning, match="band and uncertain"):
        glvox.save(r, tmp_path / "t.nrrd")
    data, header = nrrd.read(str(tmp_path / "t.nrrd"), index_order="F")
    assert np.array_equal(data, r.sdf) and np.allclose(header["space origin"], r.origin + r.voxel_size / 2)
    with pytest.warns(glvox.errors.FormatWarning):
        glvox.save(r, tmp_path / "t.nii.gz")
    img = nib.load(str(tmp_path / "t.nii.gz"))
    assert np.array_equal(np.asarray(img.dataobj), r.sdf)


def test_cli_writes_an_sdf(tmp_path):
    out = tmp_path / "t.npz"
    assert main(["sdf", "gen:torus", "-r", "16", "-o", str(out), "--truncation", "2vox", "-q"]) == 0
    r = glvox.load(out)
    assert isinstance(r, glvox.SDFGrid) and np.abs(r.sdf).max() <= 2 * r.voxel_size * (1 + 1e-6)


def _level_set(path):
    """The one grid of a .vdb file glvox wrote for an SDF, and its values on the grid's voxels:
    (grid, active bool (dims), dense float (dims) of every voxel's value, active or not)."""
    grids, _ = VDB.readAll(str(path))
    assert len(grids) == 1
    g = grids[0]
    dims = tuple(int(x) for x in str(g["glvox_dims"]).split())
    active = np.zeros(dims, bool)
    for item in g.iterOnValues():
        (x0, y0, z0), (x1, y1, z1) = item.min, item.max
        active[x0:x1 + 1, y0:y1 + 1, z0:z1 + 1] = True
    acc = g.getConstAccessor()
    values = np.array([acc.getValue(tuple(p)) for p in np.indices(dims).reshape(3, -1).T.tolist()],
                      dtype=np.float32).reshape(dims)
    return g, active, values


@needs_vdb
@pytest.mark.parametrize("kwargs", [{}, {"band": 2}, {"truncation": "1.5vox"}])
def test_vdb_level_set(tmp_path, kwargs):
    spec = GridSpec((40, 39, 11), (-1.4123, -1.3871, -0.39), 0.0713)  # the torus, not round numbers
    r = _sdf("gen:torus", grid=spec, **kwargs)
    h = spec.voxel_size
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # the torus has no uncertain voxels: nothing is dropped
        glvox.save(r, tmp_path / "t.vdb")
    g, active, values = _level_set(tmp_path / "t.vdb")
    assert g.gridClass == VDB.GridClass.LEVEL_SET and g.name == "surface" and g.valueTypeName == "float"
    bg = r.truncation if r.truncation is not None else r.band_width * h
    assert g.background == pytest.approx(bg, rel=1e-6)
    assert g.activeVoxelCount() == r.band.sum() > 0
    assert np.array_equal(active, r.band)
    assert np.array_equal(values[r.band], r.sdf[r.band])              # the exact distances, bit for bit
    inside, outside = (r.sdf < 0) & ~r.band, (r.sdf > 0) & ~r.band
    assert inside.any() and outside.any()
    assert np.allclose(values[inside], -bg) and np.allclose(values[outside], bg)
    for ijk in ([0, 0, 0], [39, 38, 10], [5, 27, 3]):
        world = g.transform.indexToWorld(tuple(float(v) for v in ijk))
        assert np.allclose(world, spec.centers(np.array([ijk]))[0], atol=1e-9 * h, rtol=0)


@needs_vdb
def test_vdb_level_set_by_hand(tmp_path):
    """Single inside voxels off the band (no x run to fill) still hold -background."""
    spec = GridSpec((6, 5, 4), (1.0, 2.0, 3.0), 0.5)
    sdf = np.full(spec.dims, 1.0, np.float32)
    band = np.zeros(spec.dims, bool)
    sdf[2, 2, 2] = sdf[4, 1, 1] = -1.0                     # inside, off the band, alone in their x rows
    sdf[3, 2, 2], sdf[1, 2, 2] = -0.25, 0.375
    band[3, 2, 2] = band[1, 2, 2] = True
    glvox.save(glvox.SDFGrid(sdf, spec, band, band_width=2.0), tmp_path / "h.vdb")
    g, active, values = _level_set(tmp_path / "h.vdb")
    assert g.background == 1.0 and np.array_equal(active, band)
    assert np.array_equal(values, np.where(band, sdf, np.sign(sdf)).astype(np.float32))


@needs_vdb
def test_vdb_level_set_from_the_cli_and_not_read_back(tmp_path):
    out = tmp_path / "t.vdb"
    assert main(["sdf", "gen:torus", "-r", "16", "-o", str(out), "-q"]) == 0
    g, active, _ = _level_set(out)
    assert g.gridClass == VDB.GridClass.LEVEL_SET and active.any()
    with pytest.raises(glvox.GlvoxError, match="holds the level set 'surface': glvox reads OpenVDB occupancy"):
        glvox.load(out)


def test_vdb_level_set_without_openvdb_is_one_line(tmp_path, monkeypatch, capsys):
    real = importlib.import_module

    def fake(name, *a, **k):
        if name in ("pyopenvdb", "openvdb"):
            raise ImportError(f"No module named {name!r}")
        return real(name, *a, **k)

    monkeypatch.setattr(importlib, "import_module", fake)
    assert main(["sdf", "gen:torus", "-r", "16", "-o", str(tmp_path / "t.vdb")]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "apt-get install python3-openvdb" in err
    assert not any(tmp_path.iterdir())


def test_samples_are_reproducible_and_exact(tmp_path):
    pytest.importorskip("igl")
    mesh = glvox.load_mesh("gen:torus")
    a, b = sdf_samples(mesh, 600, seed=7), sdf_samples(mesh, 600, seed=7)
    assert all(np.array_equal(a[k], b[k]) for k in a)
    assert not np.array_equal(a["points"], sdf_samples(mesh, 600, seed=8)["points"])
    d = point_distances(mesh.vertices, mesh.faces, a["points"].astype(np.float64), library="kdtree")
    assert np.allclose(np.abs(a["sdf"]), d, rtol=2e-7, atol=0)  # the stored points' distances, rounded once
    w = winding_direct(mesh.triangles(), a["points"].astype(np.float64))
    assert np.array_equal(a["sdf"] < 0, w >= 0.5)
    near = np.abs(a["sdf"][:564]) / float(a["scale"])
    assert np.median(near) < 0.0025 and np.abs(a["sdf"][564:]).max() > 10 * 0.0025 * float(a["scale"])
    out = tmp_path / "s.npz"
    assert main(["sdf", "gen:torus", "--samples", "300", "--seed", "3", "-o", str(out), "-q"]) == 0
    with np.load(out) as z:
        assert z["points"].shape == (300, 3) and z["sdf"].shape == (300,)
        assert np.array_equal(z["points"], sdf_samples(mesh, 300, seed=3)["points"])


def test_render_draws_a_slice(tmp_path):
    pytest.importorskip("matplotlib")
    out = tmp_path / "t.npz"
    glvox.save(_sdf("gen:torus", 24), out)
    assert main(["render", str(out), "-o", str(tmp_path / "t.png"), "-q"]) == 0
    import matplotlib.image

    img = matplotlib.image.imread(tmp_path / "t.png")
    assert img.shape[0] > 300 and img[..., :3].std() > 0.05  # a picture, not a blank
