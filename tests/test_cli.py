"""The command line: info, methods, voxelize, and one-line errors."""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys

import numpy as np
import pytest
import trimesh

from glvox import io, voxelize
from glvox.cli import build_parser
from glvox.cli import main as cli_main
from glvox.methods import request
from glvox.methods.gwn import plan
from glvox.study.compare import plan_from
from glvox.methods import method_names


def glvox(*args, cwd=None):
    return subprocess.run([sys.executable, "-m", "glvox", *map(str, args)], capture_output=True,
                          text=True, timeout=600, cwd=cwd)


def test_info_reports_renderer_and_limits():
    p = glvox("info")
    assert p.returncode == 0, p.stderr
    assert "renderer:" in p.stdout and "GL_MAX_SHADER_STORAGE_BLOCK_SIZE" in p.stdout
    assert "\nbehaviours:\n  integer-logic-op" in p.stdout and "\n  uniform-update " in p.stdout
    d = json.loads(glvox("info", "--json").stdout)
    assert d["version"].startswith("4.")
    assert d["behaviours"] == {"integer-logic-op": None, "uniform-update": None}  # probed here: done right
    assert "\ndriver settings:\n  ZINK_INLINE_UNIFORMS=" in p.stdout
    assert d["driver_settings"]["ZINK_INLINE_UNIFORMS"]["value"] == os.environ.get("ZINK_INLINE_UNIFORMS", "0")
    if d["software"]:
        assert "llvmpipe" in d["renderer"]


def test_methods_lists_the_registry():
    p = glvox("methods")
    assert p.returncode == 0
    for name in method_names():
        assert name in p.stdout
    d = json.loads(glvox("methods", "--json").stdout)
    assert {m["name"] for m in d} == set(method_names())


def test_voxelize_armadillo_npz_and_binvox_round_trip(tmp_path, shared_mesh):
    mesh = shared_mesh("stanford_armadillo_libigl_86k.obj")
    npz, bv = tmp_path / "x.npz", tmp_path / "x.binvox"
    p = glvox("voxelize", mesh, "-r", 64, "-m", "reference-solid", "-o", npz, "--json")
    assert p.returncode == 0, p.stderr
    d = json.loads(p.stdout)
    assert d["method"] == "reference-solid" and d["grid"]["dims"] == [64, 64, 64]
    assert d["stats"]["voxels"] > 0 and d["timings"]["wall_s"] > 0
    p2 = glvox("voxelize", mesh, "-r", 64, "-m", "reference-solid", "-o", bv, "-q")
    assert p2.returncode == 0, p2.stderr
    a, b = io.load(npz), io.load(bv)
    assert a.equal(b) and a.count == d["stats"]["voxels"]
    t = trimesh.load(bv)
    np.testing.assert_array_equal(t.matrix, a.dense())
    np.testing.assert_allclose(np.sort(t.points, axis=0), np.sort(a.points(), axis=0), atol=1e-9)
    # placement follows the documented fit: centered cubic grid, h = max extent / 64
    m = trimesh.load(mesh, force="mesh")
    h = m.extents.max() / 64
    assert a.voxel_size == pytest.approx(h)
    np.testing.assert_allclose(a.origin + 32 * h, m.bounds.mean(axis=0), atol=1e-9)


def test_voxelize_shows_progress_on_stderr(tmp_path):
    p = glvox("voxelize", "gen:sphere", "-r", 16, "-m", "reference-conservative", "-o", tmp_path / "s.npz")
    assert p.returncode == 0
    assert "loading gen:sphere" in p.stderr and "voxels set" in p.stderr and "wrote" in p.stderr


def test_voxelize_shows_the_slabs_of_a_long_run(gl_context, tmp_path, monkeypatch, capsys):
    """A method that works the grid in z slabs reports each one, and glvox voxelize shows
    them: off a terminal, a line now and then and one at the end (gwn-solid forced into
    slabs of 4 slices here); --quiet shows none."""
    monkeypatch.setattr(plan, "SLAB_CELLS", 32 * 24 * 4 // 8)  # 4 slices of 24 rows of 32 voxels at most
    out = tmp_path / "t.npz"
    assert cli_main(["voxelize", "gen:torus", "-r", "24", "-m", "gwn-solid", "-o", str(out)]) == 0
    err = capsys.readouterr().err
    lines = [line for line in err.splitlines() if " slab/s" in line]
    done = re.search(r"\] (\d+)/(\d+) 100%", lines[-1]) if lines else None
    assert done and done[1] == done[2] and int(done[1]) > 1, err
    assert cli_main(["voxelize", "gen:torus", "-r", "24", "-m", "gwn-solid", "-o", str(out), "-q"]) == 0
    assert "slab" not in capsys.readouterr().err
    # the same from Python
    calls = []
    voxelize("gen:torus", 24, method="gwn-solid", progress=lambda done, total: calls.append((done, total)))
    assert len(calls) > 1 and calls[-1][0] == calls[-1][1] == len(calls)


def test_voxelize_grid_options(tmp_path):
    out = tmp_path / "t.npz"
    p = glvox("voxelize", "gen:box", "-r", 10, "--tight", "--padding", "1", "-m", "reference-solid",
              "-o", out, "-q")
    assert p.returncode == 0, p.stderr
    g = io.load(out)
    # box 2 x 1.2 x 0.8; padding keeps N = 10 along x, so h = 2 / (10 - 2) = 0.25 and the
    # tight dims are ceil((8, 4.8, 3.2)) + 2 = (10, 7, 6)
    assert g.dims == (10, 7, 6) and g.voxel_size == pytest.approx(0.25)
    assert not g.dense()[0].any() and not g.dense()[-1].any()
    p = glvox("voxelize", "gen:box", "--dims", 5, 4, 3, "-m", "reference-solid", "-o", out, "-q")
    assert p.returncode == 0 and io.load(out).dims == (5, 4, 3)
    # method options as --KEY VALUE: the parity axis changes nothing on a closed mesh
    p = glvox("voxelize", "gen:box", "--dims", 5, 4, 3, "-m", "reference-solid", "--axis", 2,
              "--json", "-q")
    assert p.returncode == 0, p.stderr
    assert json.loads(p.stdout)["options"] == {"axis": 2}


@pytest.mark.parametrize("args, msg", [
    (["voxelize", "/nonexistent/mesh.obj", "-r", "8"], "mesh file not found: /nonexistent/mesh.obj"),
    (["voxelize", "gen:torus", "-r", "8", "-m", "nope"], "unknown method 'nope'; known methods:"),
    (["voxelize", "gen:torus", "-r", "8", "-m", "reference-solid", "-O", "axis=7"],
     "option axis must be one of [0, 1, 2], got 7"),
    (["voxelize", "gen:torus", "-r", "8", "-m", "reference-solid", "-O", "speed=9"],
     "method 'reference-solid' has no option speed; its options: axis"),
    (["voxelize", "gen:torus", "-r", "8", "-o", "x.stl"], "unknown voxel file suffix '.stl'"),
    (["voxelize", "gen:torus", "--dims", "8", "8", "4", "-o", "x.binvox"],
     "binvox stores cubic grids only, got dims (8, 8, 4)"),
    (["voxelize", "gen:torus", "-r", "8", "-m", "leung-wang-ldi", "-o", "x.binvox"],
     "an LDI is saved as .npz (depths per ray), not binvox"),
    (["voxelize", "gen:torus", "-r", "8", "--padding", "4"], "padding 4 leaves no voxel inside a grid of resolution 8"),
    (["voxelize", "gen:torus", "--voxel-size", "-1"], "voxel_size must be a finite positive number, got -1.0"),
    (["voxelize", "gen:torus", "-r", "8", "-o", "no_such_folder/x.npz"],
     "output folder no_such_folder does not exist"),
    (["ldi", "gen:torus", "-r", "8", "--lod-c", "0"], "--lod-c must be a positive integer, got 0"),
    (["batch", "/nonexistent/glvox-batch-in", "-o", "out", "-r", "8"],
     "batch input not found: /nonexistent/glvox-batch-in"),
    (["batch", ".", "-o", "out", "-r", "8", "--tight", "--format", "binvox"], "binvox stores cubic grids only"),
    (["compare", "--meshes", "gen:torus", "-r", "0"], "compare grid sizes must be a positive integer, got 0"),
    (["compare", "--meshes", "no_such_mesh.obj", "-r", "8"], "mesh file not found: no_such_mesh.obj"),
    (["bench", "--meshes", "gen:torus", "-r", "8", "--check-max", "-1"],
     "--check-max must be 0 (no reference checks) or a positive integer, got -1"),
    (["bench", "--preset", "quick", "--check", "no_baseline.json"], "no benchmark baseline at no_baseline.json"),
    (["data", "fetch", "no_such_mesh.obj"], "unknown mesh name 'no_such_mesh.obj'; `glvox data list` shows"),
    (["voxelize", "gen:torus", "-r", "8", "-m", "reference-solid", "--axis"], "method option --axis needs a value"),
    (["voxelize", "gen:torus", "-r", "8", "-m", "reference-solid", "--axis", "3"],
     "option axis must be one of [0, 1, 2], got 3"),
    (["voxelize", "gen:torus", "-r", "0"], "resolution must be a positive integer, got 0"),
    # the default grid (-r 128) is checked like a given one, and its note is not printed before the error
    (["voxelize", "gen:torus", "--padding", "64"], "padding 64 leaves no voxel inside a grid of resolution 128"),
])
def test_errors_are_one_line_and_non_zero(tmp_path, args, msg):
    """Each error is found before any work: the one line is all stderr holds (no "loading ..." before it)."""
    p = glvox(*args, cwd=tmp_path)
    assert p.returncode == 1
    lines = p.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("glvox: error: ") and msg in lines[0], p.stderr
    assert p.stdout == "" and not any(tmp_path.iterdir())   # nothing written either


#: Each command that writes something, with its output option pointed where nothing can be
#: written (/proc takes no new files, even for root), and a mesh argument that does not
#: exist: the output is checked first, so the error names the output, not the mesh.
BAD_OUTPUT = {
    "voxelize": ["voxelize", "/nonexistent.obj", "-r", "8", "-o", "/proc/glvox_x.npz"],
    "voxelize-binvox": ["voxelize", "/nonexistent.obj", "-r", "8", "-o", "/proc/glvox_x.binvox"],
    "batch": ["batch", "/nonexistent", "-r", "8", "-o", "/proc/glvox_x"],
    "batch-manifest": ["batch", "/nonexistent", "-r", "8", "-o", "out", "--manifest", "/proc/glvox_m.csv"],
    "ldi": ["ldi", "/nonexistent.obj", "-r", "8", "-o", "/proc/glvox_x.npz"],
    "volume": ["volume", "/nonexistent.obj", "gen:box", "-r", "8", "-o", "/proc/glvox_x.npz"],
    "compare": ["compare", "--meshes", "/nonexistent.obj", "-r", "8", "-o", "/proc/glvox_x"],
    "bench": ["bench", "--meshes", "/nonexistent.obj", "-r", "8", "-o", "/proc/glvox_x"],
    "bench-baseline": ["bench", "--meshes", "/nonexistent.obj", "-r", "8", "--save-baseline", "/proc/glvox_b.json"],
    "render": ["render", "/nonexistent.npz", "-o", "/proc/glvox_x.png"],
    "sdf": ["sdf", "/nonexistent.obj", "-r", "8", "-o", "/proc/glvox_x.npz"],
}


@pytest.mark.parametrize("case", sorted(BAD_OUTPUT))
def test_every_command_refuses_an_unwritable_output_before_work(tmp_path, case):
    p = glvox(*BAD_OUTPUT[case], cwd=tmp_path)
    lines = p.stderr.strip().splitlines()
    assert p.returncode == 1 and len(lines) == 1, p.stderr
    assert lines[0].startswith("glvox: error: cannot write the ") and "in /proc: creating a file there fails" \
        in lines[0], p.stderr
    assert not any(tmp_path.iterdir())


def test_every_command_with_an_output_has_a_bad_output_case():
    """A command added later with an output option gets a case in BAD_OUTPUT (and a validate function)."""
    from glvox.cli import build_parser

    sub = next(a for a in build_parser()._actions if a.__class__.__name__ == "_SubParsersAction")
    writers = {name for name, p in sub.choices.items()
               if any(set(a.option_strings) & {"-o", "--output", "--out"} for a in p._actions)}
    assert writers == {c.split("-")[0] for c in BAD_OUTPUT}
    assert all(p.get_default("validate") is not None for name, p in sub.choices.items()
               if name not in ("info", "methods"))


@pytest.mark.parametrize("var, value, msg", [
    ("GLVOX_THREADS", "four", "GLVOX_THREADS must be a positive integer, got 'four'"),
    ("GLVOX_READBACK", "dma", "GLVOX_READBACK must be one of mapped, copy, got 'dma'"),
])
def test_bad_environment_settings_are_one_line_before_work(tmp_path, var, value, msg):
    """Read where they are used (a dense array, a read-back), but checked before any work: the
    npz writer of a small grid touches neither, and would have written the file."""
    env = {**os.environ, var: value}
    p = subprocess.run([sys.executable, "-m", "glvox", "voxelize", "gen:torus", "-r", "8", "-o", "t.npz"],
                       capture_output=True, text=True, timeout=600, cwd=tmp_path, env=env)
    assert p.returncode == 1 and p.stderr.strip().splitlines() == [f"glvox: error: {msg}"], p.stderr
    assert not any(tmp_path.iterdir())


def test_usage_errors_are_one_line_too():
    p = glvox("voxelize", "gen:torus", "-r", "x")
    assert p.returncode == 2 and p.stderr.strip().splitlines() == [
        "glvox: error: argument -r/--resolution: invalid int value: 'x' (see `glvox voxelize --help`)"]
    p = glvox("bench", "--save-baseline")  # names the file it writes: never the checkout's unasked
    assert p.returncode == 2 and "--save-baseline: expected one argument" in p.stderr


def test_a_grid_known_only_from_the_mesh_is_checked_before_voxelizing(tmp_path):
    p = glvox("voxelize", "gen:torus", "-r", "8", "--tight", "-o", tmp_path / "t.binvox")
    assert p.returncode == 1 and "loading gen:torus" in p.stderr and "voxelizing" not in p.stderr
    assert p.stderr.strip().splitlines()[-1] == (
        "glvox: error: binvox stores cubic grids only, got dims (8, 8, 3); save as .npz instead")


def test_voxelize_with_an_ldi_method_says_what_it_made(tmp_path):
    p = glvox("voxelize", "gen:box", "-r", "8", "-m", "reference-ldi")
    assert p.returncode == 0, p.stderr
    # gen:box is 2 x 1.2 x 0.8 in a centered 8^3 grid of h = 0.25: of the rays along z through
    # the column centers, 8 along x and 4 along y (centers +-0.125, +-0.375; +-0.625 miss the
    # box's +-0.6) cross it twice, so 64 samples and a volume of 32 columns x h^2 x 0.8 = 1.6
    out = p.stdout.strip()
    assert out.startswith("n_max 2, 64 samples, volume ") and "?" not in p.stderr and "None" not in out
    assert float(out.rsplit(" ", 1)[1]) == pytest.approx(32 * 0.25 ** 2 * 0.8, rel=1e-6)


def test_bench_help_speaks_to_users():
    p = glvox("bench", "--help")
    assert p.returncode == 0 and "issue" not in p.stdout


def test_nan_mesh_file_is_refused(tmp_path):
    bad = tmp_path / "nan.obj"
    bad.write_text("v 0 0 0\nv 1 0 0\nv nan 1 0\nf 1 2 3\n")
    p = glvox("voxelize", bad, "-r", 8)
    assert p.returncode == 1 and "NaN or infinite" in p.stderr and "Traceback" not in p.stderr


def test_open_mesh_with_solid_method(tmp_path, shared_mesh):
    p = glvox("voxelize", shared_mesh("stanford_bunny_bun_zipper.ply"), "-r", 16, "-m", "reference-solid")
    assert p.returncode == 1 and "is not watertight" in p.stderr and "--allow-open" in p.stderr
    assert "for the solid method 'reference-solid'" in p.stderr
    p = glvox("voxelize", shared_mesh("stanford_bunny_bun_zipper.ply"), "-r", 16, "-m", "reference-ldi")
    assert p.returncode == 1 and "for the LDI method 'reference-ldi'" in p.stderr


@pytest.mark.parametrize("given, checked", [(None, [32, 64, 128]), ("0", []), ("64", [32, 64])])
def test_compare_check_max_zero_means_no_reference_checks(given, checked):
    """``--check-max 0`` checks nothing (the README's bench commands use it); unset: the default."""
    argv = ["compare", "--meshes", "gen:torus", "-r", "32", "64", "128"] + (["--check-max", given] if given else [])
    plan = plan_from(build_parser().parse_args(argv))
    assert [n for n in plan.sizes if plan.checks(n)] == checked


# ---------------------------------------------------------------------------
# the default grid: -r DEFAULT_RESOLUTION when no grid option is given
# ---------------------------------------------------------------------------


def test_voxelize_without_a_grid_uses_the_default_and_says_so(tmp_path):
    from glvox.grid import DEFAULT_RESOLUTION
    from glvox.preflight import DEFAULT_GRID_NOTE

    assert DEFAULT_RESOLUTION == 128 and "-r 128 (default" in DEFAULT_GRID_NOTE
    out = tmp_path / "t.npz"
    p = glvox("voxelize", "gen:torus", "-m", "ss-conservative", "-o", out)
    assert p.returncode == 0, p.stderr
    assert p.stderr.splitlines()[0] == DEFAULT_GRID_NOTE, p.stderr  # before any work
    assert max(io.load(out).dims) == 128
    # a grid option given, --quiet or --json: no note
    for args in (["-r", "16"], ["--dims", "8", "8", "8"], ["--voxel-size", "0.5"], ["-q"], ["--json"]):
        p = glvox("voxelize", "gen:torus", "-m", "ss-conservative", *args)
        assert p.returncode == 0 and "default" not in p.stderr, (args, p.stderr)
    assert json.loads(p.stdout)["grid"]["dims"] == [128, 128, 128]


@pytest.mark.parametrize("argv, given", [
    (["ldi", "gen:torus"], False), (["ldi", "gen:torus", "-r", "8"], True),
    (["volume", "gen:torus", "gen:box"], False), (["volume", "gen:torus", "gen:box", "--dims", "4", "4", "4"], True),
    (["batch", ".", "-o", "out"], False), (["batch", ".", "-o", "out", "--voxel-size", "0.1"], True),
])
def test_every_command_that_needs_a_grid_has_the_default(argv, given, capsys, tmp_path, monkeypatch):
    """ldi, volume and batch fill in -r 128 in their checks (run here without the command)."""
    from glvox.preflight import DEFAULT_GRID_NOTE

    from glvox.methods import DEFAULT_METHOD

    def parse(argv):
        args = build_parser().parse_args(argv)
        if getattr(args, "method", "x") is None:  # as glvox.cli.main does
            args.method = DEFAULT_METHOD
        return args

    monkeypatch.chdir(tmp_path)
    args = parse(argv)
    checked = args.validate(args)
    err = capsys.readouterr().err
    assert (err == "") if given else (err == DEFAULT_GRID_NOTE + "\n"), err
    assert (args.resolution == 128) is (not given)
    if argv[0] == "batch":
        assert checked.params().startswith(f"-m {args.method} " + ("--voxel-size" if given else "-r 128"))
    args = parse(argv + ["--json"])
    args.validate(args)
    assert capsys.readouterr().err == ""


def test_python_voxelize_without_a_grid_uses_the_default():
    import glvox

    assert glvox.DEFAULT_RESOLUTION == 128
    g = glvox.voxelize("gen:torus", method="ss-conservative")
    assert g.dims == (128, 128, 128)
    assert glvox.voxelize("gen:torus", 16, method="ss-conservative").dims == (16, 16, 16)


def test_voxelize_checks_each_thing_once(tmp_path, monkeypatch):
    """One validated request per command: preflight builds the Request (method, options,
    attributes) and checks the output once; the command and run_method use them as they are."""
    calls = {"make": 0, "lookup": 0, "attributes": 0, "writable": 0}

    def counting(key, fn):
        def wrapped(*a, **k):
            calls[key] += 1
            return fn(*a, **k)
        return wrapped

    make = request.Request.make.__func__
    monkeypatch.setattr(request.Request, "make", classmethod(counting("make", make)))
    monkeypatch.setattr(request, "get_method", counting("lookup", request.get_method))
    monkeypatch.setattr(request, "parse_attributes", counting("attributes", request.parse_attributes))
    monkeypatch.setattr(io, "check_writable", counting("writable", io.check_writable))
    assert cli_main(["voxelize", "gen:torus", "-r", "8", "-o", str(tmp_path / "t.npz"), "-q"]) == 0
    assert calls == {"make": 1, "lookup": 1, "attributes": 1, "writable": 1}, calls
