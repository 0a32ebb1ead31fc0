"""glvox compare: the runner's rows, resumption, tables, plots and pictures."""

from __future__ import annotations

import csv
import json
import subprocess
import sys

import numpy as np
import pytest

import glvox
from glvox.cli import main as cli_main
from glvox.grid import GridSpec
from glvox.methods import method_names
from glvox.results.voxels import VoxelGrid
from glvox.study import compare, render, report
from glvox.datasets import SHARED_MESHES
from glvox.study.options import COMPARE_PRESETS


def run_cli(*args):
    return cli_main(["compare", "-q", *args])


@pytest.fixture(scope="module")
def small_run(tmp_path_factory, gl_context):
    out = tmp_path_factory.mktemp("cmp")
    argv = ["-m", "ss-conservative", "scanline-ilv", "ss-solid", "--meshes", "gen:torus", "gen:box",
            "-r", "12", "20", "--repeat", "2", "-o", str(out)]
    assert run_cli(*argv) == 0
    return out, argv


def test_outputs_and_rows(small_run):
    out, _ = small_run
    for name in ("machine.json", "results.jsonl", "results.csv", "results.json", "tables.md"):
        assert (out / name).is_file(), name
    machine = json.loads((out / "machine.json").read_text())
    assert machine["gl"]["renderer"] and machine["glvox"] == glvox.__version__
    rows = json.loads((out / "results.json").read_text())["rows"]
    assert len(rows) == 3 * 2 * 2
    with open(out / "results.csv") as f:
        assert len(list(csv.DictReader(f))) == len(rows)
    for r in rows:
        assert r["status"] == "ok", r
        assert r["wall_ms"] > 0 and r["gpu_ms"] > 0 and r["voxels"] > 0
        assert r["gpu_bytes"] >= glvox.grid_for(glvox.load_mesh(f"gen:{r['mesh'][4:]}"), r["n"]).n_words * 4
        assert r["reference"] in ("reference-conservative", "reference-solid")
    # exact methods differ from their references by proven ties only (the box's
    # faces lie on voxel planes: many ties there, so no IoU bound)
    exact = [r for r in rows if r["method"] in ("ss-conservative", "ss-solid")]
    assert all(r["not_ties"] == 0 for r in exact)
    assert all(r["iou"] == 1.0 for r in exact if r["mesh"] == "gen:torus")
    assert any(r["not_ties"] > 0 for r in rows if r["method"] == "scanline-ilv")
    # the conservative surface of a closed mesh separates it; the stats of the
    # methods travel with the rows
    conservative = [r for r in rows if r["method"] == "ss-conservative"]
    assert all(r["leaks_26"] == 0 for r in conservative)
    assert all("cases_1d_2d_3d" in r["stats"] for r in conservative)


def test_tables_plots_and_pictures(small_run):
    out, _ = small_run
    md = (out / "tables.md").read_text()
    for text in ("| model | grid |", "`ss-conservative`", "`scanline-ilv`", "12^3", "20^3", "IoU"):
        assert text in md
    plots = sorted(p.name for p in (out / "plots").glob("*.png"))
    assert plots == ["errors.png", "time_gen_box.png", "time_gen_torus.png", "voxel_counts.png"]
    pics = sorted(p.name for p in (out / "pictures").glob("*.png"))
    assert "gen_torus_ss-conservative_20.png" in pics and "gen_torus_ss-solid_20.png" in pics
    # scanline-ilv is approximate: a disagreement slice against its reference
    assert any(p.startswith("gen_torus_slice_scanline-ilv_vs_reference-conservative_20_z") for p in pics)
    import matplotlib.image as mpimg

    img = mpimg.imread(out / "pictures" / "gen_torus_ss-conservative_20.png")
    assert img.shape[:2] == (720, 960)
    assert (img[..., :3] < 0.95).any(axis=-1).mean() > 0.05  # the torus covers part of the picture


def test_rerun_resumes_and_extends(small_run):
    out, argv = small_run
    before = (out / "results.jsonl").read_text().splitlines()
    assert run_cli(*argv, "--no-pictures") == 0
    assert (out / "results.jsonl").read_text().splitlines() == before  # nothing recomputed
    # a line cut by an interruption is recomputed; a new size adds only its cells
    with open(out / "results.jsonl", "a") as f:
        f.write('{"key": "ss-solid[]|gen:box|28", "trunc')
    extended = [a if a != "20" else "20 28" for a in argv]
    extended = " ".join(extended).split()
    assert run_cli(*extended, "--no-pictures") == 0
    rows = compare.load_rows(out)
    assert len(rows) == len(before) + 3 * 2
    assert {r["n"] for r in rows} == {12, 20, 28}


def test_unknown_method_and_missing_mesh_are_one_line_errors(tmp_path, capsys):
    assert run_cli("-m", "nope", "--meshes", "gen:box", "-r", "8", "-o", str(tmp_path)) == 1
    assert "unknown method 'nope'" in capsys.readouterr().err
    assert run_cli("--meshes", "no_such_mesh.ply", "-r", "8", "-o", str(tmp_path)) == 1
    assert "mesh file not found: no_such_mesh.ply (nor is it a mesh name glvox knows" in capsys.readouterr().err


def test_presets_cover_the_registry():
    PRESETS = COMPARE_PRESETS
    assert PRESETS["quick"]["sizes"][-1] == 128 and len(PRESETS["quick"]["meshes"]) == 2
    assert PRESETS["paper"]["sizes"] == [128, 256, 512, 1024]
    plan = compare.compare_plan(method_names(), meshes=["gen:box"], sizes=[128, 512], cpu_max=256)
    cells = plan.cells()
    assert {c.method for c in cells if c.n == 128} == set(method_names())
    assert not any(c.method.startswith("reference-") for c in cells if c.n == 512)


def test_the_command_line_does_not_import_the_study():
    """Every subcommand's parser is built at start-up (glvox info too): only the
    study's light options module may be imported by it."""
    code = ("import sys, glvox.cli; glvox.cli.build_parser(); "
            "print(sorted(m for m in sys.modules if m.startswith('glvox.study')))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "['glvox.study', 'glvox.study.options']"


def test_render_frames_a_single_voxel(gl_context):
    occ = np.zeros((5, 5, 5), bool)
    occ[2, 2, 2] = True
    g = VoxelGrid(occ, GridSpec((5, 5, 5), (0.0, 0.0, 0.0), 1.0))
    img = render.render_voxels(gl_context, g, size=(200, 150))
    assert img.shape == (150, 200, 3) and img.dtype == np.uint8
    lit = (img < 250).any(axis=-1)
    assert lit[75, 100]  # the cube is in the middle of the picture
    assert not lit[0, 0] and not lit[-1, -1]
    ys, xs = np.nonzero(lit)
    assert 20 < xs.max() - xs.min() < 190  # framed, not a speck nor clipped


def test_disagreement_slice_colors():
    spec = GridSpec((4, 3, 2), (0.0, 0.0, 0.0), 1.0)
    a = np.zeros(spec.dims, bool)
    b = np.zeros(spec.dims, bool)
    a[0, 0, 1] = b[0, 0, 1] = True  # both
    a[3, 2, 1] = True                # only a
    b[1, 1, 1] = True                # only b
    img, k = render.disagreement_slice(VoxelGrid(a, spec), VoxelGrid(b, spec), scale=1)
    assert k == 1 and img.shape == (3, 4, 3)
    # rows grow upwards: y = 0 is the last row
    assert tuple(img[2, 0]) == render.BOTH
    assert tuple(img[0, 3]) == render.ONLY_A
    assert tuple(img[1, 1]) == render.ONLY_B
    assert tuple(img[2, 3]) == render.NONE


def test_progress_when_stderr_is_not_a_terminal(tmp_path):
    """A log gets plain progress lines (here only the final one: the run is shorter than the
    10 s between lines), people's names for the steps, no redraws and no 'nan'."""
    p = subprocess.run([sys.executable, "-m", "glvox", "compare", "--meshes", "gen:box", "-r", "8",
                        "-m", "ss-conservative", "reference-conservative", "--repeat", "1", "--no-pictures",
                        "-o", str(tmp_path / "out")], capture_output=True, text=True, timeout=600)
    assert p.returncode == 0, p.stderr
    lines = [ln for ln in p.stderr.splitlines() if "% |" in ln]
    assert len(lines) == 1 and "2/2 100% |" in lines[0] and "cell/s" in lines[0], p.stderr
    assert "\r" not in p.stderr and "nan" not in p.stderr.lower()
    assert lines[0].endswith("gen:box 8^3: checking reference-conservative against reference-conservative")


def test_progress_names_contenders_as_people_read_them():
    from glvox.study.plan import CALIBRATION_CONTENDER, Contender

    variant = Contender.of_method("ss-conservative", {"variant": "simple"})
    assert variant.key == "ss-conservative[variant=simple]" and variant.label == "ss-conservative (variant simple)"
    assert Contender.of_peer("trimesh-subdivide").label == "peer trimesh-subdivide"
    assert CALIBRATION_CONTENDER.label == "the calibration workload"


def test_open_mesh_study(tmp_path, gl_context, shared_mesh):
    """Every solid method against reference-gwn on open meshes: rows with IoU, missing,
    extra and the uncertain share; gwn-solid agrees up to ties, a parity method does not;
    a slice picture for each method that differs; the study's table."""
    from glvox.inspect import uncertain_share

    meshes = [str(shared_mesh("messy_teapot_newell.obj")), str(shared_mesh("messy_soup_synthetic.stl"))]
    plan = compare.compare_plan(["gwn-solid", "ss-solid", "carve-solid", "vote-solid", "solid"], meshes, [24],
                                repeat=1, reference="reference-gwn", open_solids=True)
    rows = compare.run(plan, tmp_path, quiet=True)
    assert len(rows) == 10 and all(r["status"] == "ok" for r in rows), [r["error"] for r in rows]
    assert all(r["reference"] == "reference-gwn" and r["iou"] is not None for r in rows)
    by = {(r["method"], r["mesh"]): r for r in rows}
    for mesh in ("messy_teapot_newell.obj", "messy_soup_synthetic.stl"):
        assert by[("gwn-solid", mesh)]["not_ties"] == 0 and by[("solid", mesh)]["not_ties"] == 0
        m = glvox.load_mesh(shared_mesh(mesh))
        w = glvox.voxelize(m, 24, method="reference-gwn").fields["winding"]
        assert by[("ss-solid", mesh)]["uncertain_share"] == uncertain_share(w)[1]
    assert by[("ss-solid", "messy_soup_synthetic.stl")]["not_ties"] > 0  # parity of a soup is not w
    md = report.markdown(rows, {"gl": {}})
    assert "### Open meshes at 24^3 against `reference-gwn`" in md and "*uncertain share*" in md
    pics = compare.pictures(plan, tmp_path, lambda s: None)
    names = [p.name for p in pics]
    assert any(n.startswith("messy_soup_synthetic_slice_ss-solid_vs_reference-gwn_24_z") for n in names)
    assert not any("slice_gwn-solid" in n for n in names if n.startswith("messy_teapot"))


def test_defective_meshes_are_checked_against_their_clean_twin(tmp_path, gl_context):
    """The open-mesh study's generated dataset-style meshes: the reference runs on the clean
    twin (the same vertices, closed and consistently wound), so a parity method that the
    doubled faces cancel shows as empty against the true solid, and a carving method that
    does not depend on orientation agrees with it; on the defective mesh itself the reference
    would be empty and every method would look wrong in the other direction."""
    plan = compare.compare_plan(["ss-solid", "carve-solid"], ["gen:double-sided-torus"], [20], repeat=1,
                                reference="reference-gwn", open_solids=True)
    rows = compare.run(plan, tmp_path, quiet=True)
    by = {r["method"]: r for r in rows}
    # the cancelled parity's warning is kept in its row (not printed over the study's progress)
    assert "double-sided faces cancel" in by["ss-solid"]["stats"]["suspicious"]
    assert "suspicious" not in by["carve-solid"]["stats"]
    assert all(r["reference_mesh"] == "gen:torus" for r in rows), rows
    truth = glvox.voxelize("gen:torus", 20, method="reference-gwn").count
    assert truth > 0
    assert by["ss-solid"]["voxels"] == 0 and by["ss-solid"]["missing"] == truth
    # carving keeps the conservative surface's shell: it contains the true solid, and the
    # doubled faces change nothing for it
    assert by["carve-solid"]["missing"] == 0 and by["carve-solid"]["extra"] > 0
    assert by["carve-solid"]["voxels"] == glvox.voxelize("gen:torus", 20, method="carve-solid").count


def test_open_preset_plan(shared_mesh):
    """--preset open: every solid method but the reference, on the shared meshes that are open."""
    preset = COMPARE_PRESETS["open"]
    methods = compare.preset_methods(preset)
    assert "reference-gwn" not in methods and preset["reference"] == "reference-gwn" and preset["open_solids"]
    assert set(methods) == set(method_names(kind="solid") + method_names(kind="sparse")) - {"reference-gwn"}
    for name in SHARED_MESHES:
        assert (name in preset["meshes"]) == (not glvox.load_mesh(shared_mesh(name)).watertight), name


def test_times_served_from_a_cache_are_marked_and_not_plotted(tmp_path, gl_context):
    """reference-gwn keeps its winding field per mesh and grid: its warm runs reuse the cold
    run's, so their time is no computation's.  The row says so, the tables mark it, and the
    timing plot's series leave it out; a method that computes every run is kept."""
    out = tmp_path / "cmp"
    assert run_cli("-m", "reference-gwn", "ss-solid", "--meshes", "gen:torus", "-r", "16", "32",
                   "--repeat", "2", "-o", str(out)) == 0
    rows = json.loads((out / "results.json").read_text())["rows"]
    assert len(rows) == 4 and all(r["status"] == "ok" for r in rows)
    for r in rows:
        gwn = r["method"] == "reference-gwn"
        assert r["stats"]["cached"] is gwn if gwn else "cached" not in r["stats"]
        assert r["cached"] is gwn and r["cold_cached"] is False, r  # the first run computes
    with open(out / "results.csv") as f:
        assert {(r["method"], r["cached"]) for r in csv.DictReader(f)} == {("reference-gwn", "True"),
                                                                           ("ss-solid", "False")}
    md = (out / "tables.md").read_text()
    time_rows = [ln for ln in md.split("### Time (ms)")[1].split("###")[0].splitlines() if ln.startswith("| gen")]
    assert len(time_rows) == 2 and all(ln.count(report.CACHED_MARK) == 1 for ln in time_rows), time_rows
    assert report.CACHED_NOTE in md
    series = report.timing_series(rows, "gen:torus")
    assert list(series) == ["ss-solid"] and [n for n, _ in series["ss-solid"]] == [16, 32]


def test_every_method_and_peer_has_its_own_plot_style():
    from glvox.study.peers import PEERS

    names = sorted(set(method_names()) | set(PEERS))
    styles = [tuple(sorted(report.style_for(n).items())) for n in names]
    assert len(set(styles)) == len(names)                                   # pairwise distinct
    assert len({s[0] for s in styles}) == min(20, len(names))               # tab20 used up before reuse
    assert [tuple(sorted(report.style_for(n).items())) for n in names] == styles   # stable
    # a CPU reference dashed, a GPU method solid, a peer dotted, options dash-dotted with the colour kept
    assert report.style_for("reference-solid")["linestyle"] == "--"
    assert report.style_for("ss-solid")["linestyle"] == "-"
    assert {report.style_for(p)["linestyle"] for p in PEERS} == {":"}
    opt = report.style_for("ss-solid (axis=1)")
    assert opt["color"] == report.style_for("ss-solid")["color"] and opt["linestyle"] == "-."
    assert opt["marker"] != report.style_for("ss-solid")["marker"]
    unknown = report.style_for("some-future-method")
    assert unknown == report.style_for("some-future-method")
    assert tuple(sorted(unknown.items())) not in styles
