"""The cuda_voxelizer peer of ``glvox bench``, run against a fake binary that behaves as
cuda_voxelizer does (its flags, its cube, its binvox and its printed times)."""

from __future__ import annotations

import json
import stat
import sys
import textwrap

import numpy as np
import pytest

import glvox
from glvox.cli import main
from glvox.study.bench_report import _ms
from glvox.study.peer_cuda import ENV, cube_placement, parse_output
from glvox.study.peers import get_peer

#: A stand-in for cuda_voxelizer: parses -f/-s/-o as it does, pads the mesh's box to a cube
#: and that by 1/10001 of its side (float32), sets the voxels glvox's CPU conservative reference
#: sets there, writes <mesh>_<N>.binvox (translate = cube minimum, scale = side, %g numbers,
#: runs x, z, y as its writer loops) and prints its [Perf] lines.  FAKE_MODE: drop (one voxel
#: less), fail (exit 3), cpu (its CPU fallback: no GPU time line), suffix (<mesh with its suffix>_<N>
#: .binvox, as its current source names the file).
FAKE = textwrap.dedent('''\
    #!{python}
    import os, sys
    import numpy as np
    import trimesh
    from glvox.reference import conservative_surface

    args = sys.argv[1:]
    opt = {{args[i]: args[i + 1] for i in range(0, len(args) - 1) if args[i] in ("-f", "-s", "-o")}}
    mode = os.environ.get("FAKE_MODE", "")
    print("## CUDA VOXELIZER (fake)")
    if mode == "fail":
        print("[Err] something went wrong"); sys.exit(3)
    n = int(opt.get("-s", 256))
    assert opt.get("-o") == "binvox", opt
    mesh = trimesh.load(opt["-f"], process=False)
    v = np.asarray(mesh.vertices, np.float32)
    lo, hi = v.min(0), v.max(0)
    side = (hi - lo).max()
    for a in range(3):
        if hi[a] - lo[a] != side:
            d = side - (hi[a] - lo[a])
            lo[a] -= d / np.float32(2); hi[a] += d / np.float32(2)
    eps = (hi - lo) / np.float32(10001)
    lo, hi = lo - eps, hi + eps
    unit = (hi - lo) / np.float32(n)
    tris = ((v - lo) / unit)[np.asarray(mesh.faces)].astype(np.float64)
    occ = conservative_surface(tris, (n, n, n))
    if mode == "drop":
        occ[tuple(np.argwhere(occ)[0])] = False
    flat = occ.transpose(0, 2, 1).reshape(-1)
    out = bytearray()
    value, count = int(flat[0]), 0
    for b in flat.tolist():
        if int(b) != value or count == 255:
            out += bytes([value, count]); value, count = int(b), 0
        count += 1
    out += bytes([value, count])
    base = opt["-f"] if mode == "suffix" else opt["-f"].rsplit(".", 1)[0]
    with open(f"{{base}}_{{n}}.binvox", "wb") as f:
        f.write(f"#binvox 1\\ndim {{n}} {{n}} {{n}}\\ntranslate {{lo[0]:g}} {{lo[1]:g}} {{lo[2]:g}}\\n"
                f"scale {{(hi - lo).max():g}}\\ndata\\n".encode() + bytes(out))
    if mode == "cpu":
        print("[Info] No suitable CUDA GPU was found: Falling back to CPU voxelization")
    else:
        print("[Perf] Voxelization GPU time: 1.5 ms")
    print("[Perf] Total runtime: 42.0 ms")
''')


@pytest.fixture
def fake(tmp_path):
    path = tmp_path / "cuda_voxelizer"
    path.write_text(FAKE.format(python=sys.executable))
    path.chmod(path.stat().st_mode | stat.S_IXUSR)
    peer = get_peer("cuda-voxelizer")
    peer.configure(path)
    yield path
    peer.configure(None)


def test_cube_placement_is_cuda_voxelizers_worked_example():
    # cuda_voxelizer's own comment: the box (1,2,3)-(4,4,4) becomes the cube (1,1.5,2)-(4,4.5,5),
    # then every side moves out by 3/10001
    spec = cube_placement(np.array([[1, 2, 3], [4, 4, 4]], dtype=float), 10)
    eps = 3 / 10001
    assert np.allclose(spec.origin, [1 - eps, 1.5 - eps, 2 - eps], rtol=0, atol=1e-6)
    assert spec.voxel_size == pytest.approx((3 + 2 * eps) / 10, rel=1e-6) and spec.dims == (10, 10, 10)


def test_parse_output_reads_its_perf_lines():
    assert parse_output("[Perf] Voxelization GPU time: 12.5 ms\n[Perf] Total runtime: 301.0 ms \n") == {
        "kernel_ms": 12.5, "total_ms": 301.0, "device": "gpu"}
    assert parse_output("[Info] Doing CPU voxelization (forced using command-line switch -cpu)\n") == {
        "kernel_ms": None, "total_ms": None, "device": "cpu"}


def run_peer(mesh, n):
    peer = get_peer("cuda-voxelizer")
    spec = glvox.grid_for(mesh, n)
    prepared = peer.prepare(mesh, spec)
    return peer.to_grid(peer.run(prepared), spec), spec


def test_the_peer_runs_the_binary_reads_its_binvox_and_checks_it(fake):
    mesh = glvox.load_mesh("gen:sphere")
    pg, spec = run_peer(mesh, 20)
    s = pg.stats
    assert s["kernel_ms"] == 1.5 and s["total_ms"] == 42.0 and s["device"] == "gpu"
    # on its own cube, glvox's ss-conservative sets the voxels the (fake's) conservative test sets
    assert s["count"] == s["glvox_count"] > 0 and s["iou"] == 1.0 and s["missing"] == s["extra"] == 0
    assert s["header_origin_error_voxels"] < 1e-3      # %g digits of its header, recomputed in float32
    assert s["header_voxel_size_ratio"] == pytest.approx(1, rel=1e-5)
    assert s["voxel_size_over_glvox"] == pytest.approx(1 + 2 / 10001, rel=1e-5)  # its padded cube
    # on glvox's grid: its voxels moved by at most 20 / 10001 voxel, so nearly glvox's own surface
    ours = glvox.voxelize(mesh, grid=spec, method="ss-conservative")
    assert pg.outside == 0 and pg.grid.count == s["count"]
    assert pg.grid.iou(ours) > 0.97


def test_a_voxel_it_misses_and_its_cpu_fallback_are_reported(fake, monkeypatch):
    mesh = glvox.load_mesh("gen:sphere")
    monkeypatch.setenv("FAKE_MODE", "drop")
    s = run_peer(mesh, 12)[0].stats
    assert s["missing"] == 1 and s["extra"] == 0 and s["count"] == s["glvox_count"] - 1
    monkeypatch.setenv("FAKE_MODE", "cpu")
    s = run_peer(mesh, 12)[0].stats
    assert s["device"] == "cpu" and s["kernel_ms"] is None and s["missing"] == 0


def test_its_current_file_name_with_the_mesh_suffix_is_read(fake, monkeypatch):
    """Its current source names the output after the whole mesh file name (mesh.ply_12.binvox):
    the first real run on an H100 found no mesh_12.binvox and reported an error for every cell."""
    mesh = glvox.load_mesh("gen:sphere")
    monkeypatch.setenv("FAKE_MODE", "suffix")
    s = run_peer(mesh, 12)[0].stats
    assert s["count"] == s["glvox_count"] > 0 and s["missing"] == s["extra"] == 0


def test_a_failing_binary_is_an_error_naming_its_output(fake, monkeypatch):
    monkeypatch.setenv("FAKE_MODE", "fail")
    with pytest.raises(RuntimeError, match=r"exited with status 3 without writing mesh_8.binvox or mesh.ply_8.binvox: "
                                           r".*something went wrong"):
        run_peer(glvox.load_mesh("gen:sphere"), 8)


def test_missing_says_how_to_name_the_binary(tmp_path, monkeypatch):
    peer = get_peer("cuda-voxelizer")
    peer.configure(None)
    monkeypatch.delenv(ENV, raising=False)
    assert "--cuda-voxelizer PATH or GLVOX_CUDA_VOXELIZER" in peer.missing()
    monkeypatch.setenv(ENV, str(tmp_path / "nope"))
    assert "not found" in peer.missing()
    (tmp_path / "plain").write_text("")
    monkeypatch.setenv(ENV, str(tmp_path / "plain"))
    assert "is not executable" in peer.missing()


def test_glvox_bench_runs_it_as_a_peer_in_one_command(fake, tmp_path, capsys, monkeypatch):
    monkeypatch.delenv(ENV, raising=False)
    out = tmp_path / "bench"
    code = main(["bench", "--meshes", "gen:sphere", "-r", "12", "-m", "ss-conservative", "--no-variants",
                 "--peers", "cuda-voxelizer", "--cuda-voxelizer", str(fake), "--repeat", "1", "-o", str(out), "-q"])
    assert code == 0
    rows = json.loads((out / "results.json").read_text())["rows"]
    row = next(r for r in rows if r["method"] == "cuda-voxelizer")
    assert row["status"] == "ok", row
    assert row["peer_stats"]["kernel_ms"] == 1.5 and row["peer_stats"]["iou"] == 1.0
    text = capsys.readouterr().out
    assert "cuda-voxelizer" in text and "## cuda_voxelizer on its own cube" in text
    # its kernel beside glvox's GPU time in the same cell, and the ratio the GPU-speed target is about
    ours = next(r for r in rows if r["method"] == "ss-conservative")
    assert f"| 1.5 | {_ms(ours['gpu_ms'])} ({ours['key']}) | {ours['gpu_ms'] / 1.5:.2f} | gpu |" \
        in (out / "bench.md").read_text()


def test_bench_refuses_a_missing_binary_before_work(tmp_path, capsys):
    assert main(["bench", "--meshes", "gen:sphere", "-r", "8", "--cuda-voxelizer", str(tmp_path / "none")]) == 1
    err = capsys.readouterr().err
    assert err.strip() == f"glvox: error: cuda_voxelizer binary {tmp_path / 'none'} not found (--cuda-voxelizer PATH or {ENV})"


def test_its_kernel_is_set_beside_glvoxs_fastest_variant_in_the_same_cell():
    from glvox.study.bench_report import best_surface_gpu, peer_stats_table

    def row(key, gpu, n=256, mesh="bunny.ply", method="ss-conservative"):
        return {"key": key, "method": method, "gpu_ms": gpu, "mesh": mesh, "n": n}

    rows = [row("ss-conservative", 3.0), row("ss-conservative[variant=simple]", 2.0),
            row("ss-conservative[variant=sorted]", None), row("ss-conservative", 0.5, n=128),
            row("ss-conservative", 0.1, mesh="other.ply"), row("ss-solid", 0.2, method="ss-solid")]
    assert best_surface_gpu(rows, "bunny.ply", 256) == (2.0, "ss-conservative[variant=simple]")
    assert best_surface_gpu(rows, "bunny.ply", 512) is None
    peer = {"mesh": "bunny.ply", "n": 256, "wall_ms": 900.0,
            "peer_stats": {"kernel_ms": 8.0, "device": "gpu", "count": 5, "glvox_count": 5, "iou": 1.0,
                           "missing": 0, "extra": 0}}
    assert "| bunny.ply | 256 | 900 | 8.0 | 2.0 (ss-conservative[variant=simple]) | 0.25 | gpu |" \
        in peer_stats_table([peer], rows)
    assert "| 8.0 | - | - | gpu |" in peer_stats_table([dict(peer, n=512)], rows)
