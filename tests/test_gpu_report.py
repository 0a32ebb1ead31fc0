"""compare/gpu_report.py: the steps run in their own processes within the budget, and the
report says what each gave, also when one fails or is left without time.  compare/gpu_lease.py:
the one command that runs it on a lent GPU machine fits the device tool, and the wheels it
carries are the versions tested here."""

from __future__ import annotations

import argparse
import json
import os
import re
import shutil
import stat
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import moderngl
import pytest
from glvox import get_context, load_mesh
from conftest import load_script
from test_peer_cuda import FAKE

ROOT = Path(__file__).resolve().parents[1]
SCRIPT = ROOT / "compare" / "gpu_report.py"


def report(tmp_path, *args):
    out = tmp_path / "report"
    env = {k: v for k, v in os.environ.items() if k != "GLVOX_CUDA_VOXELIZER"}
    p = subprocess.run([sys.executable, str(SCRIPT), "-o", str(out), *args], capture_output=True, text=True,
                       timeout=300, cwd=ROOT, env=env)
    return p, out


def test_a_small_report(tmp_path):
    p, out = report(tmp_path, "--steps", "info", "readback", "bench", "--budget", "240", "--mesh", "gen:torus",
                    "--bench-sizes", "32", "--bench-methods", "ss-conservative", "--readback-sizes", "64")
    assert p.returncode == 0, p.stdout + p.stderr
    assert sorted(f.name for f in out.iterdir()) == ["bench.log", "info.json", "readback.log", "report.md"]
    info = json.loads((out / "info.json").read_text())
    text = (out / "report.md").read_text()
    assert f"Renderer: {info['renderer']}" in text
    for step in ("info", "readback", "bench"):
        assert f"| {step} | ok |" in text
    assert "| ss-conservative |" in (out / "bench.log").read_text()  # the bench's tables are in its log


def test_a_failed_step_and_a_spent_budget_are_reported(tmp_path):
    p, out = report(tmp_path, "--steps", "bench", "tables", "--budget", "60", "--mesh", "/no/such/mesh.ply",
                    "--bench-sizes", "32", "--zhang-sizes", "32", "--bench-methods", "ss-conservative")
    assert p.returncode == 1
    text = (out / "report.md").read_text()
    assert "| bench | failed (exit" in text and "/no/such/mesh.ply" in (out / "bench.log").read_text()
    p, out = report(tmp_path, "--steps", "info", "--budget", "1")
    assert p.returncode == 1
    assert "| info | skipped (no budget left) |" in (out / "report.md").read_text()


def test_the_lease_command_fits_the_device_tool_and_carries_what_it_uses():
    """One command within the device tool's 2,000 characters that unpacks the debs,
    installs the wheels, finds the carried meshes and runs gpu_report.py into $OUT;
    `command` prints it with the folders to carry (at most 8)."""
    lease = load_script("gpu_lease")
    cmd = lease.command(480)
    assert len(cmd) <= lease.COMMAND_MAX
    for folder in lease.CARRY:
        assert f"{folder}/" in cmd or f"$PWD/{folder}" in cmd, folder
    assert cmd.index("dpkg -x") < cmd.index("pip install") < cmd.index("compare/gpu_report.py -o $OUT/r --budget 480")
    assert "--steps" not in cmd and "--steps info tests" in lease.command(60, ["info", "tests"])
    p = subprocess.run([sys.executable, str(ROOT / "compare" / "gpu_lease.py"), "command"], capture_output=True,
                       text=True, timeout=60, cwd=ROOT)
    assert p.returncode == 0 and p.stdout.splitlines() == [cmd, "carry: " + " ".join(lease.CARRY)]
    assert len(lease.CARRY) <= 8
    p = subprocess.run([sys.executable, str(ROOT / "compare" / "gpu_lease.py"), "prepare", "--dry-run",
                        "--peer-repo", "cuda_voxelizer"], capture_output=True, text=True, timeout=60, cwd=ROOT)
    assert p.returncode == 2 and p.stderr.splitlines()[-1].endswith(
        "--peer-repo takes NAME=URL with NAME one of cuda_voxelizer, trimesh2, got 'cuda_voxelizer'")


def test_the_lease_pins_the_wheels_tested_here_and_keeps_its_folders_out_of_git(tmp_path):
    """prepare fetches the versions installed here, and adds each carried folder to
    .git/info/exclude once however often it runs."""
    lease = load_script("gpu_lease")
    pins = dict(p.split("==") for p in lease.pinned() if "==" in p)
    assert pins["moderngl"] == moderngl.__version__
    assert set(lease.WHEELS) >= {"moderngl", "glcontext", "trimesh", "pooch"}
    apt, pip = lease.fetch_commands(tmp_path)
    assert apt[-len(lease.DEBS):] == list(lease.DEBS) and "--no-deps" in pip and "3.12" in pip
    (tmp_path / ".git" / "info").mkdir(parents=True)
    (tmp_path / ".git" / "info" / "exclude").write_text("# git's own comment\n")
    lease.exclude(tmp_path)
    lease.exclude(tmp_path)
    lines = (tmp_path / ".git" / "info" / "exclude").read_text().splitlines()
    assert lines == ["# git's own comment"] + [f"/{d}/" for d in lease.CARRY]


def test_the_sync_step_puts_its_table_in_the_report(tmp_path):
    """The per-stage waits' cost (compare/bench_sync.py) needs no file of its own: its
    table, with and without the waits side by side, is in report.md."""
    p, out = report(tmp_path, "--steps", "sync", "--budget", "200", "--mesh", "gen:torus")
    assert p.returncode == 0, p.stdout + p.stderr
    assert sorted(f.name for f in out.iterdir()) == ["report.md"]
    text = (out / "report.md").read_text()
    assert "| sync | ok |" in text and "`below`" in text
    for n in (64, 128, 256):
        for method in ("ss-conservative", "ss-solid", "gwn-solid"):
            assert f"| {method} | gen:torus | {n} |" in text


def test_the_peer_step_runs_cuda_voxelizer_beside_ss_conservative(tmp_path):
    """With a cuda_voxelizer binary (here a fake that behaves as it does), the peer step
    benches it beside ss-conservative and checks its voxels on its own cube, in a log of
    its own; the bench step does not wait on it.  Without one the step is skipped, and
    that is no failure."""
    fake = tmp_path / "cuda_voxelizer"
    fake.write_text(FAKE.format(python=sys.executable))
    fake.chmod(fake.stat().st_mode | stat.S_IXUSR)
    p, out = report(tmp_path, "--steps", "bench", "peer", "--budget", "240", "--mesh", "gen:torus",
                    "--bench-sizes", "16", "--peer-sizes", "16", "--bench-methods", "ss-conservative",
                    "--cuda-voxelizer", str(fake))
    assert p.returncode == 0, p.stdout + p.stderr
    assert sorted(f.name for f in out.iterdir()) == ["bench.log", "peer.log", "report.md"]
    peer = (out / "peer.log").read_text()
    assert "| peer cuda-voxelizer |" in peer and "## cuda_voxelizer on its own cube" in peer
    # its wall time, its printed kernel time beside glvox's GPU time and their ratio, and its
    # voxels equal to glvox's on its cube
    assert re.search(r"\| gen:torus \| 16 \| [0-9.]+ \| 1\.5 \| [0-9.]+ \(ss-conservative[^)]*\) \| [0-9.]+ \| "
                     r"gpu \| (\d+) \| \1 \| 1\.000000 \| 0 \| 0 \|", peer)
    assert "cuda-voxelizer" not in (out / "bench.log").read_text()
    p, out = report(tmp_path, "--steps", "info", "peer", "--budget", "60")
    assert p.returncode == 0, p.stdout + p.stderr
    assert "| peer | skipped (no cuda_voxelizer binary" in (out / "report.md").read_text()


def test_every_step_together_fits_the_eight_files_the_device_brings_back(tmp_path):
    """The device tool brings back at most 8 files: report.md and the steps' own files,
    and the lease command writes nothing else under $OUT."""
    gr = load_script("gpu_report")
    args = argparse.Namespace(readback_sizes=["64"], mesh="gen:torus", bench_methods=["ss-conservative"],
                              bench_sizes=["32"], peer_sizes=["32"], zhang_sizes=["32"], cuda_voxelizer="cv")
    out = tmp_path / "out"
    def files(steps):
        return {"report.md"} | {gr.commands(step, out, tmp_path / "work", args)[1].name for step in steps
                                if gr.commands(step, out, tmp_path / "work", args)[1].parent == out}

    assert len(files(gr.STEPS)) <= 8, sorted(files(gr.STEPS))
    assert len(files(gr.EXTRA_STEPS)) <= 8
    assert abs(sum(gr.STEPS.values()) - 1.0) < 1e-9
    assert load_script("gpu_lease").command(480).count("$OUT") == 1


#: The peer's build, on a synthetic source tree laid out as cuda_voxelizer's and
#: trimesh2's: a library function, a viewer file that must not be built, the CUDA
#: sources (a kernel that is never launched: no GPU here) and OpenMP.
SYNTHETIC = {
    "trimesh2/include/answer.h": "int trimesh_answer();\n",
    "trimesh2/libsrc/answer.cc": '#include "answer.h"\nint trimesh_answer() { return 42; }\n',
    "trimesh2/libsrc/GLviewer.cc": "#error the OpenGL viewer needs GL headers and is not built\n",
    "trimesh2/LICENSE": "", "trimesh2/COPYING": "", "cuda_voxelizer/LICENSE": "",
    "cuda_voxelizer/src/main.cpp": textwrap.dedent("""\
        #include <cstdio>
        #include <omp.h>
        #include "answer.h"
        int cu_answer();
        int main() {
            std::printf("## CUDA VOXELIZER (synthetic) %d %d %d\\n", trimesh_answer(), cu_answer(),
                        omp_get_max_threads() > 0);
            return 0;
        }
        """),
    "cuda_voxelizer/src/voxelize.cu": "__global__ void k(int* p) { *p = 7; }\nint cu_answer() { return 7; }\n",
    "cuda_voxelizer/src/voxelize_solid.cu": "__global__ void k2(int* p) { *p = 1; }\n",
    "cuda_voxelizer/src/util_cuda.cpp": "", "cuda_voxelizer/src/util_io.cpp": "",
    "cuda_voxelizer/src/cpu_voxelizer.cpp": "", "cuda_voxelizer/src/libs/magicavoxel_file_writer/VoxWriter.cpp": "",
}


def synthetic_sources(root: Path) -> Path:
    for name, text in SYNTHETIC.items():
        (root / name).parent.mkdir(parents=True, exist_ok=True)
        (root / name).write_text(text)
    return root


def test_the_peer_build_recipe(tmp_path):
    """trimesh2's library sources but its viewer's (GL*.cc), archived; cuda_voxelizer's
    sources as its CMakeLists.txt lists them, linked with nvcc for sm_80 and sm_90 with
    sm_90 PTX, OpenMP, the CUDA runtime static (nvcc's default: no -cudart shared)."""
    lease = load_script("gpu_lease")
    src = synthetic_sources(tmp_path / "src")
    (src / "trimesh2/libsrc/TriMesh_io.cc").write_text("")
    compile_, archive, link = lease.peer_build_commands(src, tmp_path / "b", tmp_path / "cv", "NVCC")
    assert [c[c.index("-c") + 1] for c in compile_] == [str(src / "trimesh2/libsrc/TriMesh_io.cc"),
                                                       str(src / "trimesh2/libsrc/answer.cc")]
    assert archive == [["ar", "rcs", str(tmp_path / "b/libtrimesh.a"), str(tmp_path / "b/TriMesh_io.o"),
                        str(tmp_path / "b/answer.o")]]
    (cmd,) = link
    assert cmd[0] == "NVCC" and cmd[-2:] == ["-o", str(tmp_path / "cv")] and "-cudart" not in cmd
    pairs = [cmd[i + 1] for i, a in enumerate(cmd) if a == "-gencode"]
    assert pairs == ["arch=compute_80,code=sm_80", "arch=compute_90,code=sm_90", "arch=compute_90,code=compute_90"]
    assert [a for a in cmd if a.startswith(str(src / "cuda_voxelizer"))] == [
        str(src / "cuda_voxelizer" / f) for f in ("src/main.cpp", "src/util_cuda.cpp", "src/util_io.cpp",
                                                   "src/cpu_voxelizer.cpp",
                                                   "src/libs/magicavoxel_file_writer/VoxWriter.cpp",
                                                   "src/voxelize.cu", "src/voxelize_solid.cu")]
    assert "-ltrimesh" in cmd and "-fopenmp,-O3" in cmd


@pytest.mark.skipif(shutil.which("nvcc") is None, reason="needs CUDA's nvcc")
def test_the_recipe_builds_a_program_that_runs(tmp_path):
    lease = load_script("gpu_lease")
    src = synthetic_sources(tmp_path / "src")
    lease.build_peer(src, tmp_path / "peer" / "cuda_voxelizer")
    assert lease.peer_runs(tmp_path / "peer" / "cuda_voxelizer") is None
    p = subprocess.run([str(tmp_path / "peer" / "cuda_voxelizer")], capture_output=True, text=True, timeout=60)
    assert p.stdout.split()[-3:] == ["42", "7", "1"]
    (src / "trimesh2/libsrc/broken.cc").write_text("this is not C++\n")
    with pytest.raises(subprocess.CalledProcessError):
        lease.build_peer(src, tmp_path / "peer2" / "cuda_voxelizer")


def test_the_device_keeps_a_peer_that_runs_and_builds_one_that_does_not(tmp_path, monkeypatch, capsys):
    """A binary built here may not run on the device's image: `gpu_lease.py peer` keeps one
    that starts and prints its banner, builds from the carried sources otherwise, and says
    in one line why there is none."""
    lease = load_script("gpu_lease")
    folder = tmp_path / ".peers"
    folder.mkdir()
    binary = folder / "cuda_voxelizer"

    def script(text):
        binary.write_text(f"#!/bin/sh\n{text}\n")
        binary.chmod(binary.stat().st_mode | stat.S_IXUSR)

    built = []

    def build(src, out):
        built.append((src, out))
        script("echo '## CUDA VOXELIZER'")

    monkeypatch.setattr(lease, "build_peer", build)
    script("echo '## CUDA VOXELIZER'; echo 'Not enough program parameters.'")
    assert lease.ensure_peer(folder) == 0 and built == []
    script("echo 'error while loading shared libraries: libcudart.so.13' >&2; exit 127")
    assert lease.ensure_peer(folder) == 0 and built == [(folder / "src", binary)]
    assert "exited with status 127: error while loading shared libraries" in capsys.readouterr().out

    def failing(src, out):
        raise subprocess.CalledProcessError(1, ["g++", "-c"], "", "x.cc:1: error: expected ';'")

    binary.unlink()
    monkeypatch.setattr(lease, "build_peer", failing)
    assert lease.ensure_peer(folder) == 1
    assert capsys.readouterr().out.splitlines()[-1] == (
        "peer: not built: g++ exited with status 1: x.cc:1: error: expected ';'")
    monkeypatch.undo()
    assert lease.ensure_peer(folder) == 1  # the real build: no sources carried
    assert "no peer sources in" in capsys.readouterr().out


def test_the_tables_step_prints_every_papers_table_and_fails_if_one_fails(tmp_path):
    """Schwarz & Seidel's Tables 1-3 and Zhang et al.'s timings, their own figures beside
    glvox's, one after the other in one log; a table that fails fails the step, and the
    tables after it still run."""
    p, out = report(tmp_path, "--steps", "tables", "--budget", "240", "--bench-sizes", "32", "--zhang-sizes", "32")
    assert p.returncode == 0, p.stdout + p.stderr
    log = (out / "tables.log").read_text()
    for paper in ("Schwarz & Seidel 2010 Table 1", "Schwarz & Seidel 2010 Table 2", "Schwarz & Seidel 2010 Table 3",
                  "Zhang et al. 2018 Table 2"):
        assert paper in log, paper
    zhang = log[log.index("Zhang et al. 2018 Table 2"):]
    assert "stanford_dragon_vrip_res2.ply" in zhang and "cad_fandisk.off" not in zhang  # the S&S tables' meshes
    p, out = report(tmp_path, "--steps", "tables", "--budget", "240", "--bench-sizes", "none",
                    "--zhang-sizes", "32")
    assert p.returncode == 1 and "| tables | failed (exit 1) |" in (out / "report.md").read_text()
    assert "Zhang et al. 2018 Table 2" in (out / "tables.log").read_text()


def test_the_whole_suite_and_the_quick_bench_are_steps_named_on_demand(tmp_path):
    """Issue-sized GPU runs also want the whole suite and `glvox bench --preset quick`;
    they do not fit one call beside the default steps, so they run only when named."""
    gr = load_script("gpu_report")
    assert not set(gr.EXTRA_STEPS) & set(gr.STEPS)
    args = argparse.Namespace()
    cmd, log = gr.commands("suite", tmp_path, tmp_path, args)
    assert cmd[1:4] == ["-m", "pytest", "-q"] and not any(a.startswith("tests/") for a in cmd) \
        and log.name == "suite.log"
    cmd, log = gr.commands("quick", tmp_path, tmp_path, args)
    assert cmd[1:] == ["-m", "glvox", "bench", "--preset", "quick", "-q"] and log.name == "quick.log"
    p, out = report(tmp_path, "--steps", "suite", "--budget", "1")
    assert "| suite | skipped (no budget left) |" in (out / "report.md").read_text()


def test_a_step_that_times_out_is_killed_with_its_children(tmp_path):
    """A timed-out step's children (pytest's workers, the tables' scripts) must not run on
    into the next step: the step's whole process group goes."""
    gr = load_script("gpu_report")
    mark = tmp_path / "child"
    cmd = ["sh", "-c", f"(sleep 3; touch {mark}) & sleep 30"]
    status, seconds = gr.run_step(cmd, tmp_path / "step.log", 1.0)
    assert status == "timed out after 1 s" and seconds < 3
    time.sleep(3)
    assert not mark.exists()


def test_the_outside_step_names_where_a_call_spends_the_time_outside_its_stages(tmp_path):
    """compare/outside_stages.py profiles whole calls with the profiler paused in every stage:
    its total per call is the time outside them (up to cProfile's own cost), and its table,
    in report.md, names the functions that hold it."""
    p, out = report(tmp_path, "--steps", "outside", "--budget", "120", "--mesh", "gen:torus",
                    "--bench-sizes", "32", "128")
    assert p.returncode == 0, p.stdout + p.stderr
    assert sorted(f.name for f in out.iterdir()) == ["report.md"]
    text = (out / "report.md").read_text()
    assert "| outside | ok |" in text
    # ss-conservative at the bench's largest size, then gwn-solid at its smallest
    assert text.index("ss-conservative on gen:torus at 128^3") < text.index("gwn-solid on gen:torus at 32^3")
    heads = re.findall(r"stages ([0-9.]+) ms \(.*\), outside them ([0-9.]+) ms", text)
    totals = re.findall(r"profiled outside the stages: ([0-9.]+) ms per call", text)
    assert len(heads) == len(totals) == 2
    assert text.count("| ms per call (own) | calls per call | function |") == 2
    for (stages, outside), total in zip(heads, totals):
        # the profile holds the time outside the stages, not the stages' (a profiler left
        # running inside them would hold about the whole call)
        assert float(total) < 0.5 * (float(stages) + float(outside))


def test_outside_stages_gives_each_stage_per_call(shared_mesh):
    """A stage that runs several times in a call (gwn-solid's crossings: the mesh's, then
    the caps') is given once, summed over the call, so the stages add up to the call's
    stage total; its GPU time comes from the timer queries beside it."""
    mod = load_script("outside_stages")
    mesh = load_mesh(shared_mesh("stanford_bunny_bun_zipper.ply"))
    med, _ = mod.profile_calls("gwn-solid", mesh, 96, 1)
    assert sum(med["stages"].values()) == pytest.approx(med["stages_ms"], rel=1e-9)
    assert {"crossings", "bricks", "far", "refine"} <= set(med["gpu"]) <= set(med["stages"])
    assert "tree" not in med["gpu"]  # a CPU stage has no GPU time
    assert med["gpu"]["crossings"] <= med["stages"]["crossings"] * 1.05 + 0.05
    # the host's share: the calling thread's CPU time, within the call's wall time, and
    # on a software renderer (whose shaders run on threads of their own, which the
    # calling thread's time leaves out) well below it at this size
    host = mod.host_cpu("gwn-solid", mesh, 96, 3)
    assert 0 < host["cpu_ms"] <= host["wall_ms"] * 1.01 + 0.01
    if get_context().is_software:
        assert host["cpu_ms"] < 0.6 * host["wall_ms"]
