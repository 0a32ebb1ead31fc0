"""NRRD, NIfTI, VTK image data and OpenVDB: each file read back by the format's
own library (pynrrd, nibabel, VTK, OpenVDB), placement to float32 precision,
mesh vertices landing in the voxels glvox set, glvox's readers, refusals."""

from __future__ import annotations

import importlib
import warnings

import numpy as np
import pytest
from conftest import VDB, needs_vdb

import glvox
from glvox import io
from glvox.errors import FormatError, FormatWarning
from glvox.formats import check_writable, format_for
from glvox.grid import GridSpec
from glvox.results import SparseOctree, VoxelGrid


#: A non-cubic grid, origin and voxel size that are not round numbers.
SPEC = GridSpec((13, 7, 5), (12.3456, -7.891, 0.123), 0.0371)

DENSE_SUFFIXES = [".nrrd", ".nii", ".nii.gz", ".vti", pytest.param(".vdb", marks=needs_vdb)]


def random_grid(spec=SPEC, seed=0, p=0.4, extras=()):
    rng = np.random.default_rng(seed)
    ex = {name: VoxelGrid(rng.random(spec.dims) < 0.5, spec) for name in extras}
    return VoxelGrid(rng.random(spec.dims) < p, spec, extras=ex)


def f32_tol(spec: GridSpec) -> float:
    """float32 precision of the largest world coordinate of the grid (NIfTI-1 stores float32)."""
    return 4 * float(np.finfo(np.float32).eps) * float(np.abs(spec.bounds).max())


# -- each format's own library: occupancy [i, j, k], centers of indices, world -> voxel ---------------


def needs_vtk() -> None:
    """Skip where VTK is absent (it comes with the test extra, which CI installs): glvox
    writes .vti itself; VTK's own reader and writer are the independent check."""
    pytest.importorskip("vtkmodules", reason="VTK (pip install -e '.[test]') checks .vti against its own reader")


def read_with_library(path):
    """(occupancy bool [i, j, k], centers(ijk (M, 3)) -> (M, 3) world, voxel_of(points) -> (M, 3) float
    index whose nearest integer is the voxel), all from the format's own library."""
    suffix = format_for(path).suffixes[0]
    if suffix == ".nrrd":
        import nrrd

        data, header = nrrd.read(str(path))                     # index order F: data[i, j, k]
        d, o = np.asarray(header["space directions"]), np.asarray(header["space origin"])
        assert header["space"] == "right-anterior-superior" and header["centerings"] == ["cell"] * 3
        return data != 0, lambda ijk: o + ijk @ d, lambda p: np.linalg.solve(d.T, (p - o).T).T
    if suffix == ".nii":
        import nibabel as nib

        img = nib.load(str(path))
        a = img.affine
        q, qcode = img.get_qform(coded=True)
        s, scode = img.get_sform(coded=True)
        assert qcode == scode == 2 and np.allclose(q, a, rtol=0, atol=1e-6) and np.allclose(s, a, rtol=0, atol=1e-6)
        inv = np.linalg.inv(a)
        return (np.asanyarray(img.dataobj) != 0, lambda ijk: ijk @ a[:3, :3].T + a[:3, 3],
                lambda p: p @ inv[:3, :3].T + inv[:3, 3])
    if suffix == ".vti":
        needs_vtk()
        from vtkmodules.util.numpy_support import vtk_to_numpy
        from vtkmodules.vtkIOXML import vtkXMLImageDataReader

        r = vtkXMLImageDataReader()
        r.SetFileName(str(path))
        r.Update()
        img = r.GetOutput()
        dims = tuple(n - 1 for n in img.GetDimensions())        # cells
        occ = vtk_to_numpy(img.GetCellData().GetArray("occupancy")).reshape(dims, order="F") != 0

        def centers(ijk):
            out = []
            for i, j, k in ijk.tolist():
                b = img.GetCell(img.ComputeCellId([int(i), int(j), int(k)])).GetBounds()
                out.append([(b[0] + b[1]) / 2, (b[2] + b[3]) / 2, (b[4] + b[5]) / 2])
            return np.array(out)

        def voxel_of(points):
            out = []
            for p in points.tolist():
                ijk, pc = [0, 0, 0], [0.0, 0.0, 0.0]
                assert img.ComputeStructuredCoordinates(p, ijk, pc)
                out.append(ijk)
            return np.array(out, dtype=np.float64)

        return occ, centers, voxel_of
    assert suffix == ".vdb"
    grid = VDB.read(str(path), "occupancy")
    assert grid.valueTypeName == "bool"
    nx, ny, nz = (int(x) for x in grid["glvox_dims"].split())
    acc = grid.getConstAccessor()
    occ = np.array([[[acc.isValueOn((i, j, k)) and bool(acc.getValue((i, j, k))) for k in range(nz)]
                     for j in range(ny)] for i in range(nx)], dtype=bool)
    assert grid.activeVoxelCount() == occ.sum()               # nothing outside glvox_dims
    t = grid.transform
    return (occ, lambda ijk: np.array([t.indexToWorld(tuple(map(float, v))) for v in ijk]),
            lambda p: np.array([t.worldToIndex(tuple(map(float, v))) for v in p]))


@pytest.mark.parametrize("suffix", DENSE_SUFFIXES)
def test_library_reads_occupancy_and_voxel_centers(tmp_path, suffix):
    g = random_grid()
    path = io.save(g, tmp_path / f"g{suffix}")
    occ, centers, _ = read_with_library(path)
    assert occ.shape == SPEC.dims
    np.testing.assert_array_equal(occ, g.dense())
    ijk = np.argwhere(np.ones(SPEC.dims, bool)).astype(np.float64)
    want = SPEC.origin + ijk * SPEC.voxel_size + SPEC.voxel_size / 2
    np.testing.assert_allclose(centers(ijk), want, rtol=0, atol=f32_tol(SPEC))


@pytest.mark.parametrize("suffix", DENSE_SUFFIXES)
def test_mesh_vertices_land_in_the_voxels_glvox_set(tmp_path, suffix):
    mesh = glvox.load_mesh("gen:torus")
    mesh = glvox.load_mesh((mesh.vertices * [1.7, 1.2, 1.0] + [40.25, -13.5, 7.0], mesh.faces))
    spec = glvox.grid_for(mesh, voxel_size=0.31, padding=1)          # tight: non-cubic, non-zero origin
    assert len(set(spec.dims)) == 3
    g = glvox.voxelize(mesh, grid=spec, method="reference-conservative")
    occ, _, voxel_of = read_with_library(io.save(g, tmp_path / f"m{suffix}"))
    u = voxel_of(mesh.vertices)
    ijk = np.floor(u + 0.5).astype(np.int64)
    hit = occ[tuple(ijk.T)]
    # a vertex within float32 rounding of a voxel face may round to the neighbour
    near_face = np.abs(np.abs(u + 0.5 - np.round(u + 0.5))).min(axis=1) < 1e-4
    assert (hit | near_face).all() and (~hit).sum() <= 2


@pytest.mark.parametrize("suffix", [".npz", ".vti", pytest.param(".vdb", marks=needs_vdb)])
def test_round_trip_keeps_extra_masks(tmp_path, suffix):
    g = random_grid(extras=("unclassifiable", "rim"))
    back = io.load(io.save(g, tmp_path / f"e{suffix}"))
    assert back.equal(g) and back.spec.same_placement(g.spec)
    assert set(back.extras) == {"unclassifiable", "rim"}
    for k in back.extras:
        assert back.extras[k].equal(g.extras[k])


def with_field(g: VoxelGrid, seed=1) -> VoxelGrid:
    """``g`` with a float32 field ``winding`` of distinct values (as gwn-solid's winding=true)."""
    w = np.random.default_rng(seed).normal(0.5, 0.7, g.dims).astype(np.float32)
    return VoxelGrid(g.dense(), g.spec, extras=g.extras, fields={"winding": w})


def test_vti_keeps_float_fields_where_vtk_reads_them(tmp_path):
    """A float field (gwn-solid's winding numbers) is a Float32 cell array ``field_<name>``:
    VTK's own reader finds each value at its voxel's cell (x fastest), glvox reads it back."""
    needs_vtk()
    from vtkmodules.util.numpy_support import vtk_to_numpy
    from vtkmodules.vtkIOXML import vtkXMLImageDataReader

    spec = GridSpec((5, 4, 3), (1.5, -2.0, 0.25), 0.5)
    g = with_field(random_grid(spec))
    path = io.save(g, tmp_path / "w.vti")
    reader = vtkXMLImageDataReader()
    reader.SetFileName(str(path))
    reader.Update()
    arr = reader.GetOutput().GetCellData().GetArray("field_winding")
    assert arr is not None and arr.GetDataType() == 10  # VTK_FLOAT
    got = vtk_to_numpy(arr).reshape(spec.dims, order="F")
    assert np.array_equal(got, g.fields["winding"])
    back = io.load(path)
    assert back.equal(g) and set(back.fields) == {"winding"} and back.fields["winding"].dtype == np.float32
    assert np.array_equal(back.fields["winding"], g.fields["winding"])


@pytest.mark.parametrize("suffix", [".nrrd", ".nii.gz", ".binvox", ".vox", ".points.ply", ".cubes.glb",
                                    pytest.param(".vdb", marks=needs_vdb)])
def test_formats_without_float_fields_name_them(tmp_path, suffix):
    spec = GridSpec((6, 6, 6), (1.5, 2.5, -3.0), 0.5)
    g = with_field(random_grid(spec, extras=("rim",)))
    masks = "" if suffix == ".vdb" else r"the extra masks \['rim'\] and "
    with pytest.warns(FormatWarning, match=masks + r"the float fields \['winding'\] are not written"):
        path = io.save(g, tmp_path / f"f{suffix}")
    if format_for(path).read is not None:
        back = io.load(path)
        assert back.equal(g) and not back.fields


@pytest.mark.parametrize("suffix", [".nrrd", ".nii", ".nii.gz", ".binvox"])
def test_one_array_formats_warn_what_they_drop(tmp_path, suffix):
    spec = GridSpec((6, 6, 6), (1.5, 2.5, -3.0), 0.5)
    g = random_grid(spec, extras=("unclassifiable",))
    with pytest.warns(FormatWarning, match=r"keeps the occupancy only; the extra masks \['unclassifiable'\]"):
        path = io.save(g, tmp_path / f"d{suffix}")
    back = io.load(path)
    assert back.equal(g) and back.spec.same_placement(g.spec) and not back.extras


@pytest.mark.parametrize("suffix", [".nrrd", ".nii.gz", ".vti", pytest.param(".vdb", marks=needs_vdb)])
def test_glvox_round_trip_edge_cases(tmp_path, suffix):
    # one voxel, an empty grid and a full one, on a far-away origin
    for spec, occ in [(GridSpec((1, 1, 1), (1e5, -2e5, 3e5), 0.125), np.ones((1, 1, 1), bool)),
                      (GridSpec((4, 3, 2), (1e5, -2e5, 3e5), 0.125), np.zeros((4, 3, 2), bool)),
                      (GridSpec((9, 17, 8), (-1.0, 0.0, 2.0), 0.25), np.ones((9, 17, 8), bool))]:
        g = VoxelGrid(occ, spec)
        back = io.load(io.save(g, tmp_path / f"x{suffix}"))
        assert back.equal(g) and back.spec.same_placement(g.spec), (spec, suffix)


# -- glvox's readers on files written by the libraries ------------------------------------------------

def test_nrrd_in_lps_reads_to_the_same_world_voxels(tmp_path):
    import nrrd

    g = random_grid()
    h = SPEC.voxel_size
    c0 = SPEC.origin + h / 2
    # the same voxels described in LPS (x and y negated), x axis stored backwards
    data = np.asarray(g.dense(), np.uint8)[::-1]
    first = np.array([-(c0[0] + h * (SPEC.dims[0] - 1)), -c0[1], c0[2]])
    header = {"space": "left-posterior-superior", "space directions": np.diag([h, -h, h]),
              "space origin": first, "kinds": ["domain"] * 3}
    nrrd.write(str(tmp_path / "lps.nrrd"), data, header)
    back = io.load(tmp_path / "lps.nrrd")
    assert back.spec.same_placement(SPEC) and back.equal(g)


def test_nifti_with_permuted_flipped_axes_reads_to_the_same_world_voxels(tmp_path):
    import nibabel as nib

    g = random_grid()
    h = SPEC.voxel_size
    # file axes (z, x, y) with x reversed: file index (a, b, c) = voxel (nx-1-b, c, a)
    data = np.transpose(np.asarray(g.dense(), np.uint8)[::-1], (2, 0, 1))
    a = np.zeros((4, 4))
    a[2, 0], a[0, 1], a[1, 2], a[3, 3] = h, -h, h, 1
    a[:3, 3] = SPEC.origin + h / 2 + [h * (SPEC.dims[0] - 1), 0, 0]
    nib.save(nib.Nifti1Image(data, a), str(tmp_path / "perm.nii"))
    back = io.load(tmp_path / "perm.nii")
    assert back.spec.same_placement(SPEC) and back.equal(g)


def test_rotated_or_anisotropic_files_are_refused(tmp_path):
    import nibabel as nib

    data = np.ones((3, 4, 5), np.uint8)
    c, s = np.cos(0.01), np.sin(0.01)
    rot = np.array([[c, -s, 0, 0], [s, c, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]])
    nib.save(nib.Nifti1Image(data, rot), str(tmp_path / "rot.nii"))
    with pytest.raises(FormatError, match="axes are the world axes with one voxel size"):
        io.load(tmp_path / "rot.nii")
    nib.save(nib.Nifti1Image(data, np.diag([1.0, 1.0, 2.0, 1.0])), str(tmp_path / "aniso.nii"))
    with pytest.raises(FormatError, match="one voxel size"):
        io.load(tmp_path / "aniso.nii")


def _vtk_image(g: VoxelGrid, point_data: bool = False):
    needs_vtk()
    from vtkmodules.util.numpy_support import numpy_to_vtk
    from vtkmodules.vtkCommonDataModel import vtkImageData

    img = vtkImageData()
    h = g.voxel_size
    n = np.asarray(g.dims)
    img.SetDimensions(*(n if point_data else n + 1).tolist())
    img.SetOrigin(*(g.origin + (h / 2 if point_data else 0)).tolist())
    img.SetSpacing(h, h, h)
    arr = numpy_to_vtk(np.asarray(g.dense(), np.uint8).ravel(order="F"), deep=True)
    arr.SetName("occupancy")
    (img.GetPointData() if point_data else img.GetCellData()).AddArray(arr)
    return img


@pytest.mark.parametrize("mode", ["ascii", "binary", "appended-raw", "appended-base64"])
@pytest.mark.parametrize("compressor", ["none", "zlib", "lzma"])
@pytest.mark.parametrize("header", [32, 64])
def test_glvox_reads_vti_in_every_vtk_encoding(tmp_path, mode, compressor, header):
    needs_vtk()
    from vtkmodules.vtkIOXML import vtkXMLImageDataWriter

    g = random_grid()
    w = vtkXMLImageDataWriter()
    w.SetInputData(_vtk_image(g))
    w.SetFileName(str(tmp_path / "v.vti"))
    {"ascii": w.SetDataModeToAscii, "binary": w.SetDataModeToBinary}.get(mode, w.SetDataModeToAppended)()
    w.SetEncodeAppendedData(mode == "appended-base64")
    {"none": w.SetCompressorTypeToNone, "zlib": w.SetCompressorTypeToZLib,
     "lzma": w.SetCompressorTypeToLZMA}[compressor]()
    w.SetBlockSize(64)                                                      # several blocks, a partial last one
    w.SetHeaderTypeToUInt32() if header == 32 else w.SetHeaderTypeToUInt64()
    assert w.Write() == 1
    back = io.load(tmp_path / "v.vti")
    assert back.spec.same_placement(SPEC) and back.equal(g)


def test_glvox_reads_vti_point_data_as_voxel_centers(tmp_path):
    needs_vtk()
    from vtkmodules.vtkIOXML import vtkXMLImageDataWriter

    g = random_grid()
    w = vtkXMLImageDataWriter()
    w.SetInputData(_vtk_image(g, point_data=True))
    w.SetFileName(str(tmp_path / "p.vti"))
    assert w.Write() == 1
    back = io.load(tmp_path / "p.vti")
    assert back.spec.same_placement(SPEC) and back.equal(g)


def test_vti_block_sizes_vtk_reads(tmp_path, monkeypatch):
    # glvox's own blocks: several, the last one partial, and a size that is a whole number of blocks
    from glvox.formats import vti

    for block, dims in [(100, (13, 7, 5)), (91, (13, 7, 1))]:
        monkeypatch.setattr(vti, "BLOCK", block)
        spec = GridSpec(dims, SPEC.origin, SPEC.voxel_size)
        g = random_grid(spec)
        occ, _, _ = read_with_library(io.save(g, tmp_path / "b.vti"))
        np.testing.assert_array_equal(occ, g.dense())
        assert io.load(tmp_path / "b.vti").equal(g)


@needs_vdb
def test_vdb_written_by_openvdb_reads_by_active_bounding_box(tmp_path):
    grid = VDB.BoolGrid()
    grid.fill((-3, 2, 5), (-1, 4, 5), True, True)
    grid.getAccessor().setValueOn((0, 6, 7), True)
    t = VDB.createLinearTransform(voxelSize=0.5)
    t.translate((10.0, 20.0, 30.0))
    grid.transform = t
    grid.name = "density_mask"
    VDB.write(str(tmp_path / "other.vdb"), grids=[grid])
    back = io.load(tmp_path / "other.vdb")
    # no glvox_dims: the grid spans the active voxels, (-3, 2, 5) .. (0, 6, 7)
    assert back.dims == (4, 5, 3) and back.count == 3 * 3 + 1
    np.testing.assert_allclose(back.origin, [10 - 3 * 0.5 - 0.25, 20 + 2 * 0.5 - 0.25, 30 + 5 * 0.5 - 0.25])
    assert back.dense()[3, 4, 2] and back.dense()[0:3, 0:3, 0].all()
    # with glvox_dims, a voxel outside that extent is an error, not a silently cropped grid
    grid["glvox_dims"] = "2 9 9"
    VDB.write(str(tmp_path / "cropped.vdb"), grids=[grid])
    outside = r"active voxels in \(-3, 2, 5\)\.\.\(-3, 2, 5\), outside the extent \(0, 0, 0\)\.\.\(1, 8, 8\)"
    with pytest.raises(FormatError, match=outside):
        io.load(tmp_path / "cropped.vdb")


# -- octrees into OpenVDB without a dense grid ------------------------------------------------------

def _no_dense(monkeypatch):
    def refuse(self):
        raise AssertionError("the octree was decoded to a dense grid")

    monkeypatch.setattr(SparseOctree, "to_grid", refuse)
    monkeypatch.setattr(SparseOctree, "coverage", refuse)


def _vdb_dense(grid, dims):
    out = np.zeros(dims, dtype=np.float64)
    for it in grid.iterOnValues():
        a, b = it.min, it.max
        out[a[0]:b[0] + 1, a[1]:b[1] + 1, a[2]:b[2] + 1] = float(it.value)
    return out


@needs_vdb
@pytest.mark.parametrize("mesh, dims", [("gen:torus", (37, 22, 13)), ("gen:sphere", (64, 64, 64))])
def test_octree_to_vdb_equals_its_decoded_grid_and_coverage(tmp_path, monkeypatch, mesh, dims):
    o = glvox.voxelize(mesh, method="ss-octree", dims=dims)
    want, cov = o.to_grid().dense(), o.coverage(0)
    with monkeypatch.context() as m:
        _no_dense(m)
        path = io.save(o, tmp_path / "o.vdb")
    occ, centers, _ = read_with_library(path)
    np.testing.assert_array_equal(occ, want)
    grid = VDB.read(str(path), "coverage")
    assert grid.valueTypeName == "float" and grid.transform.voxelSize()[0] == pytest.approx(4 * o.voxel_size)
    np.testing.assert_array_equal(_vdb_dense(grid, cov.shape).astype(np.float32), cov)
    c = np.array(grid.transform.indexToWorld((1.0, 2.0, 0.0)))
    np.testing.assert_allclose(c, o.origin + (4 * np.array([1, 2, 0]) + 2) * o.voxel_size, atol=1e-12)
    assert io.load(path).equal(o.to_grid())


@needs_vdb
def test_octree_to_vdb_with_every_sub_grid_pattern(tmp_path):
    # random level-0 sub-grids (rows with up to four runs, full and empty rows, slabs and blocks)
    o = glvox.voxelize("gen:torus", method="ss-octree", dims=(37, 22, 13))
    rng = np.random.default_rng(7)
    data = rng.integers(0, 2**64, size=len(o.data), dtype=np.uint64, endpoint=False)
    data[::5] = np.uint64(0xFFFFFFFFFFFFFFFF)
    data[1::7] = 0
    data[2::9] &= np.uint64(0x0000FFFF0000FFFF)            # full and empty z slabs
    o.data[:] = data
    path = io.save(o, tmp_path / "r.vdb", coverage=False)
    occ, _, _ = read_with_library(path)
    np.testing.assert_array_equal(occ, o.to_grid().dense())


@needs_vdb
def test_octree_solid_to_the_grid_faces_gives_fractional_coverage(tmp_path):
    # a grid inside a box, dims not multiples of 4: uniform inside nodes are cut by the +faces
    spec = GridSpec((30, 27, 18), (-0.9, -0.5, -0.3), 0.02)
    o = glvox.voxelize("gen:box", grid=spec, method="ss-octree")
    assert o.count == spec.n_voxels
    lv1 = o.levels[1]
    uniform = lv1.coords()[(lv1.child == 0xFFFFFFFF) & lv1.inside]
    assert (8 * uniform.max(axis=0) + 8 > np.asarray(spec.dims)).all()       # reaching past every +face
    path = io.save(o, tmp_path / "box.vdb")
    cov = o.coverage(0)
    assert {0.5, 0.75, 0.375} <= set(np.unique(cov).tolist())               # 2/4, 3/4, 2/4 * 3/4
    np.testing.assert_array_equal(_vdb_dense(VDB.read(str(path), "coverage"), cov.shape).astype(np.float32), cov)
    occ, _, _ = read_with_library(path)
    np.testing.assert_array_equal(occ, o.to_grid().dense())


@needs_vdb
@pytest.mark.parametrize("n", [512, pytest.param(4096, marks=pytest.mark.slow)])
def test_large_octree_becomes_a_vdb_without_a_dense_grid(tmp_path, monkeypatch, n):
    # 4096^3 (6.9e10 voxels) is 32 times what glvox keeps dense
    o = glvox.voxelize("gen:sphere", n, method="ss-octree")
    _no_dense(monkeypatch)
    monkeypatch.setattr(VoxelGrid, "__init__", lambda *a, **k: pytest.fail("a VoxelGrid was made"))
    path = io.save(o, tmp_path / "big.vdb", coverage=False)
    grid = VDB.read(str(path), "occupancy")
    assert grid.activeVoxelCount() == o.count
    (a, b) = grid.evalActiveVoxelBoundingBox()
    assert min(a) >= 0 and max(b) < n


# -- refusals before any work ---------------------------------------------------------------------------

def test_check_writable_refuses_before_work(tmp_path):
    with pytest.raises(FormatError, match=r"unknown voxel file suffix '.ply'.*use .npz, .binvox, .nrrd"):
        check_writable(tmp_path / "x.ply")
    with pytest.raises(FormatError, match="an LDI is saved as .npz"):
        check_writable(tmp_path / "x.nrrd", kind="ldi")
    with pytest.raises(FormatError, match=r"binvox stores cubic grids only, got dims \(4, 5, 6\)"):
        check_writable(tmp_path / "x.binvox", kind="solid", dims=(4, 5, 6))
    with pytest.raises(FormatError, match=r"stores dense grids .* save it as .npz or .vdb"):
        check_writable(tmp_path / "x.nii", kind="sparse", dims=(4096, 4096, 4096))
    check_writable(tmp_path / "x.npz", kind="sparse", dims=(4096, 4096, 4096))
    with pytest.raises(FormatError, match="output folder .*missing.* does not exist"):
        check_writable(tmp_path / "missing" / "x.vti")
    (tmp_path / "afolder.vti").mkdir()
    with pytest.raises(FormatError, match="is a folder"):
        check_writable(tmp_path / "afolder.vti")
    with pytest.raises(FormatError, match=r"takes no option \['coverage'\]"):
        io.save(random_grid(), tmp_path / "x.nrrd", coverage=False)


@pytest.mark.parametrize("suffix, module, hint", [
    (".nrrd", "nrrd", r"pip install 'glvox\[formats\]'"),
    (".nii.gz", "nibabel", r"pip install 'glvox\[formats\]'"),
    (".vdb", "pyopenvdb", "apt-get install python3-openvdb"),
])
def test_missing_library_is_one_line_naming_how_to_get_it(tmp_path, monkeypatch, suffix, module, hint):
    real = importlib.import_module

    def fake(name, *a, **k):
        if name in (module, "openvdb"):
            raise ImportError(f"No module named {name!r}")
        return real(name, *a, **k)

    monkeypatch.setattr(importlib, "import_module", fake)
    for call in (lambda: check_writable(tmp_path / f"x{suffix}"),
                 lambda: io.save(random_grid(), tmp_path / f"x{suffix}")):
        with pytest.raises(FormatError, match=hint) as exc:
            call()
        assert "\n" not in str(exc.value)
    assert not (tmp_path / f"x{suffix}").exists()


def test_ldi_and_huge_octree_refused_by_dense_formats(tmp_path):
    ldi = glvox.ldi("gen:sphere", 8, method="reference-ldi")
    for suffix in (".nrrd", ".vti", ".nii"):
        with pytest.raises(FormatError, match="an LDI is saved as .npz"):
            io.save(ldi, tmp_path / f"l{suffix}")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert io.load(io.save(ldi, tmp_path / "l.npz")).counts.sum() == ldi.counts.sum()


# -- glvox convert ------------------------------------------------------------------------------------

ALL_SUFFIXES = [".npz", ".binvox", ".nrrd", ".nii", ".nii.gz", ".vti"] + ([".vdb"] if VDB is not None else [])
KEEP_EXTRAS = {".npz", ".vti", ".vdb"}


def run_cli(capsys, *args) -> tuple[int, str, str]:
    from glvox.cli import main

    rc = main([str(a) for a in args])
    out, err = capsys.readouterr()
    return rc, out, err


def test_convert_between_every_pair_keeps_placement_and_masks(tmp_path, capsys):
    spec = GridSpec((9, 9, 9), (-3.21, 4.56, 0.789), 0.173)                # cubic: binvox takes it
    g = random_grid(spec, extras=("unclassifiable",))
    for a in ALL_SUFFIXES:
        src = tmp_path / f"src{a}"
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", FormatWarning)
            io.save(g, src)
        for b in ALL_SUFFIXES:
            if a == b:
                continue
            dst = tmp_path / f"{a[1:]}_to{b}"
            rc, _, err = run_cli(capsys, "convert", src, dst, "-q")
            assert rc == 0, (a, b, err)
            back = io.load(dst)
            assert back.equal(g) and back.spec.same_placement(g.spec), (a, b)
            kept = a in KEEP_EXTRAS and b in KEEP_EXTRAS
            assert set(back.extras) == ({"unclassifiable"} if kept else set()), (a, b)
            if kept:
                assert back.extras["unclassifiable"].equal(g.extras["unclassifiable"])
            assert ("extra masks ['unclassifiable'] are not written" in err) == (a in KEEP_EXTRAS and not kept)


@needs_vdb
def test_convert_octree_npz_to_vdb_and_back_to_a_grid(tmp_path, capsys, monkeypatch):
    o = glvox.voxelize("gen:torus", method="ss-octree", dims=(40, 24, 12))
    src = io.save(o, tmp_path / "o.npz")
    with monkeypatch.context() as m:
        _no_dense(m)
        rc, _, err = run_cli(capsys, "convert", src, tmp_path / "o.vdb", "--no-coverage", "-q")
    assert rc == 0, err
    assert [g.name for g in VDB.readAll(str(tmp_path / "o.vdb"))[0]] == ["occupancy"]
    rc, _, err = run_cli(capsys, "convert", tmp_path / "o.vdb", tmp_path / "o.nii.gz", "-q")
    assert rc == 0, err
    back = io.load(tmp_path / "o.nii.gz")
    assert back.equal(o.to_grid()) and back.spec.same_placement(o.spec)


@pytest.mark.parametrize("args, message", [
    (["in.npz", "out.ply"], "unknown voxel file suffix '.ply'"),
    (["in.obj", "out.npz"], "unknown voxel file suffix '.obj'"),
    (["missing.npz", "out.vti"], "voxel file not found"),
    (["in.npz", "nofolder/out.vti"], "output folder nofolder does not exist"),
    (["in.npz", "in.npz"], "input and output are the same file"),
    (["in.npz", "out.nrrd"], r"needs the Python package 'nrrd'.*pip install 'glvox\[formats\]'"),
    (["in.npz", "out.vti", "--no-coverage"], "--no-coverage is an option of .vdb output"),
])
def test_convert_validates_before_reading(tmp_path, capsys, monkeypatch, args, message):
    import re

    import glvox.io

    monkeypatch.chdir(tmp_path)
    io.save(random_grid(), tmp_path / "in.npz")
    real = importlib.import_module

    def without_pynrrd(name, *a, **k):
        if name == "nrrd":
            raise ImportError(f"No module named {name!r}")
        return real(name, *a, **k)

    monkeypatch.setattr(importlib, "import_module", without_pynrrd)

    def never(*a, **k):
        raise AssertionError("the input was read before the arguments were checked")

    monkeypatch.setattr(glvox.io, "load", never)
    rc, out, err = run_cli(capsys, "convert", *args)
    assert rc == 1 and out == ""
    assert err.startswith("glvox: error: ") and err.count("\n") == 1 and re.search(message, err), err


def test_voxelize_checks_the_output_format_before_loading_the_mesh(tmp_path, capsys, monkeypatch):
    import glvox.commands

    def never(*a, **k):
        raise AssertionError("the mesh was loaded before the output was checked")

    monkeypatch.setattr(glvox.commands, "load_mesh", never)
    rc, _, err = run_cli(capsys, "voxelize", "gen:torus", "-r", "8", "-m", "reference-ldi",
                         "-o", tmp_path / "x.nrrd")
    assert rc == 1 and "an LDI is saved as .npz" in err
    rc, _, err = run_cli(capsys, "voxelize", "gen:torus", "-r", "8", "-o", tmp_path / "none" / "x.vti")
    assert rc == 1 and "does not exist" in err
