"""Everything worth knowing about glvox on a GPU, in one command and one folder.

    python compare/gpu_report.py -o results/gpu              # about 8 minutes on an H100
    python compare/gpu_report.py -o results/gpu --budget 300 --steps info selftest tests

For whoever has a GPU glvox has not met (a new vendor, a new driver): it runs, each
in its own process with its share of ``--budget`` seconds,

* ``info``: ``glvox info --json`` (renderer, vendor, limits);
* ``selftest``: ``glvox selftest --json`` (every method against its CPU reference,
  the compiler's arithmetic, the tie decisions, the read-back);
* ``tests``: the tests that depend on the GPU's compiler, rasterizer, memory model
  and limits (:data:`GPU_TESTS`: ties, exactness, barriers, bounds, geometry
  shaders, big buffers, results kept on the GPU), with pytest-xdist's workers where
  it is installed;
* ``readback``: ``compare/bench_readback.py`` at 512^3 and 1024^3 (``--cuda`` too
  where cuda-core sees a GPU);
* ``sync``: ``compare/bench_sync.py`` at 64^3-256^3: whole calls with and without
  the per-stage waits for the GPU, side by side (its table is in ``report.md``),
  of ``ss-conservative``, ``ss-solid`` and ``gwn-solid``;
* ``bench``: ``glvox bench`` of the main methods on the bunny at 128^3-1024^3;
* ``outside``: ``compare/outside_stages.py``: where ``ss-conservative``'s whole call
  at the bench's largest size spends the time outside its timed stages, by
  function, and then ``gwn-solid``'s at its smallest, each stage's wall time beside
  its GPU time (its tables are in ``report.md``): on an H100 ``gwn-solid`` took
  12.5 ms at 128^3 against 1.4 ms for ``ss-solid``, and whether that floor is the
  GPU's work, the waits or the CPU's is what these tables tell;
* ``peer``: with ``--cuda-voxelizer PATH``, ``glvox bench`` of ``ss-conservative``
  (its variants too) beside that cuda_voxelizer binary on the bunny at
  256^3-1024^3: the two tools' whole calls and kernel times side by side, its
  voxels checked against glvox's on its own cube (``compare/gpu_lease.py`` builds
  the binary for a lent machine).  A step of its own, so that the bench's figures
  do not wait on it, and skipped without a binary;
* ``tables``: the papers' timing tables with their own figures beside this GPU's,
  one script after the other into one log: Schwarz & Seidel's Tables 1-3
  (``compare/table1_ss_surface.py``, ``table2_ss_solid.py``, ``table3_ss_octree.py``;
  GTX 285) at the bench's sizes and Zhang et al.'s timings
  (``compare/zhang_table1.py --timing``; GTX 970) at 256^3 and 512^3 on the same
  meshes (:data:`ZHANG_MESHES`; about 10 s a script on a 2-core machine with
  llvmpipe, most of it start-up).

Two more steps run only when ``--steps`` names them (they do not fit one 10-minute
call beside the others; a second call can run them): ``suite``, the whole default
test suite with pytest-xdist's workers, and ``quick``, ``glvox bench --preset
quick`` (every method and installed peer on two shared meshes at 64^3 and 128^3).

It writes at most eight files to the output folder (the device tool brings back
eight): ``report.md`` (each step's status, seconds and last lines), ``info.json``,
``selftest.json``, and a ``.log`` per other step but ``sync`` and ``outside``, whose
tables are in ``report.md`` (the bench's logs hold its tables).  A step that fails, times out or is left without budget is reported
as such and the next one runs; the exit status is 1 when any step did not finish
with status 0 (a ``peer`` step skipped for want of a binary does not count).
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import os
import shlex
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

try:  # glvox[cuda], optional: the readback step adds device='cuda' where it works
    import cuda.core  # noqa: F401
    from cuda.bindings import driver as _cuda_driver
except ImportError:
    _cuda_driver = None

ROOT = Path(__file__).resolve().parents[1]

#: The test files whose outcome depends on the GPU and its driver.
GPU_TESTS = [
    "tests/test_ties.py", "tests/test_exact.py", "tests/test_hazards.py", "tests/test_bounds.py",
    "tests/test_shaders.py", "tests/test_arithmetic.py", "tests/test_precise.py", "tests/test_tie_probe.py",
    "tests/test_context.py", "tests/test_device_results.py", "tests/test_readback.py",
    "tests/test_mapped_readback.py", "tests/test_capabilities.py",
    "tests/test_ss.py::test_a_grid_in_one_buffer_past_two_billion_voxels",
]

#: Steps in order, with their share of the budget.
STEPS = {"info": 0.02, "selftest": 0.12, "tests": 0.27, "readback": 0.08, "sync": 0.04, "bench": 0.24,
         "outside": 0.03, "peer": 0.10, "tables": 0.10}

#: Steps run only when named, with their shares (relative, as above).
EXTRA_STEPS = {"suite": 0.6, "quick": 0.4}
SHARES = {**STEPS, **EXTRA_STEPS}

#: Zhang et al.'s timings on the meshes of Schwarz & Seidel's tables (the paper's own
#: meshes are not shared ones): all seventeen would take most of the step's share.
ZHANG_MESHES = ("stanford_bunny_bun_zipper.ply", "stanford_dragon_vrip_res2.ply", "stanford_armadillo_libigl_86k.obj")

#: The peer step's sizes: cuda_voxelizer's process writes a binvox file of the whole
#: grid (about 5 s at 1024^3 on a 2-core machine), so it stops there.
PEER_SIZES = ("256", "512", "1024")

BUNNY = "stanford_bunny_bun_zipper.ply"

#: The sync step's methods: the flagship, the solid it is measured against, and
#: gwn-solid, whose call has the most stages (and the most waits) of them.
SYNC_METHODS = ("ss-conservative", "ss-solid", "gwn-solid")


def _cuda_seen() -> bool:
    """cuda-core is installed and the CUDA driver answers (device='cuda' can be timed)."""
    if _cuda_driver is None:
        return False
    try:
        err, = _cuda_driver.cuInit(0)
    except Exception:  # noqa: BLE001 - no driver library
        return False
    return err == _cuda_driver.CUresult.CUDA_SUCCESS


def commands(step: str, out: Path, work: Path, args) -> tuple[list[str], Path]:
    """The command of ``step`` and the file its standard output goes to."""
    py, glvox = sys.executable, [sys.executable, "-m", "glvox"]
    if step == "info":
        return [*glvox, "info", "--json"], out / "info.json"
    if step == "selftest":
        return [*glvox, "selftest", "--json"], out / "selftest.json"
    workers = ["-n", str(max(1, min(8, (os.cpu_count() or 2) // 2)))] \
        if importlib.util.find_spec("xdist") is not None else []
    if step == "tests":
        return [py, "-m", "pytest", "-q", "-rfE", *workers, *GPU_TESTS], out / "tests.log"
    if step == "suite":
        return [py, "-m", "pytest", "-q", "-rfE", *workers], out / "suite.log"
    if step == "quick":
        return [*glvox, "bench", "--preset", "quick", "-q"], out / "quick.log"
    if step == "readback":
        return [py, str(ROOT / "compare" / "bench_readback.py"), "-r", *args.readback_sizes, "--repeat", "3",
                *(["--cuda"] if _cuda_seen() else [])], out / "readback.log"
    if step == "sync":  # its table is in report.md (the output folder holds eight files at most)
        return [py, str(ROOT / "compare" / "bench_sync.py"), "-m", *SYNC_METHODS, "--meshes", args.mesh,
                "-r", "64", "128", "256"], work / "sync.log"
    if step == "bench":
        return [*glvox, "bench", "-m", *args.bench_methods, "--meshes", args.mesh, "-r", *args.bench_sizes,
                "--repeat", "5", "--check-max", "128", "--peers", "-q"], out / "bench.log"
    if step == "outside":  # its tables are in report.md (the output folder holds eight files at most)
        script = [py, str(ROOT / "compare" / "outside_stages.py"), "--mesh", args.mesh, "--top", "8"]
        runs = [[*script, "-r", args.bench_sizes[-1]], [*script, "-m", "gwn-solid", "-r", args.bench_sizes[0]]]
        return ["sh", "-c", "s=0; " + " ".join(f"{shlex.join(c)} || s=1;" for c in runs) + " exit $s"], \
            work / "outside.log"
    if step == "peer":
        return [*glvox, "bench", "-m", "ss-conservative", "--meshes", args.mesh, "-r", *args.peer_sizes,
                "--repeat", "3", "--check-max", "0", "--peers", "cuda-voxelizer", "--cuda-voxelizer",
                str(args.cuda_voxelizer), "-q"], out / "peer.log"
    if step == "tables":  # every script runs, the step fails if one does
        scripts = [[py, str(ROOT / "compare" / f"{name}.py"), "--sizes", *args.bench_sizes, "--repeat", "3"]
                   for name in ("table1_ss_surface", "table2_ss_solid", "table3_ss_octree")]
        scripts.append([py, str(ROOT / "compare" / "zhang_table1.py"), "--timing", "-r", ",".join(args.zhang_sizes),
                        "--repeats", "3", "--meshes", ",".join(ZHANG_MESHES)])
        return ["sh", "-c", "s=0; " + " ".join(f"{shlex.join(c)} || s=1;" for c in scripts) + " exit $s"], \
            out / "tables.log"
    raise ValueError(step)


def run_step(cmd: list[str], log: Path, timeout: float) -> tuple[str, float]:
    """Run ``cmd`` into ``log`` within ``timeout`` seconds.  In a process group of its own,
    killed whole at the timeout: a step's children (pytest's workers, the tables' scripts)
    must not run on into the next step."""
    t0 = time.perf_counter()
    with open(log, "w") as f:
        proc = subprocess.Popen(cmd, stdout=f, stderr=subprocess.STDOUT, cwd=ROOT, start_new_session=True,
                                env={**os.environ, "PYTHONUNBUFFERED": "1"})
        try:
            code = proc.wait(timeout=timeout)
            status = "ok" if code == 0 else f"failed (exit {code})"
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
            status = f"timed out after {timeout:.0f} s"
    return status, time.perf_counter() - t0


def _tail(path: Path, lines: int) -> str:
    try:
        text = path.read_text(errors="replace").rstrip().splitlines()
    except OSError:
        return ""
    return "\n".join(text[-lines:])


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("-o", "--out", required=True, help="folder for report.md and the steps' files")
    ap.add_argument("--budget", type=float, default=540.0, help="seconds for all steps together")
    ap.add_argument("--steps", nargs="+", choices=list(SHARES), default=list(STEPS),
                    help=f"default: {' '.join(STEPS)}; also {' '.join(EXTRA_STEPS)}")
    ap.add_argument("--mesh", default=BUNNY, help="the bench's mesh (a path or a shared mesh's name)")
    ap.add_argument("--bench-sizes", nargs="+", default=["128", "256", "512", "1024"])
    ap.add_argument("--bench-methods", nargs="+",
                    default=["ss-conservative", "ss-solid", "eisemann-solid", "gwn-solid", "ss-octree",
                             "scanline-rlv", "scanline-ilv"])
    ap.add_argument("--readback-sizes", nargs="+", default=["512", "1024"])
    ap.add_argument("--peer-sizes", nargs="+", default=list(PEER_SIZES))
    ap.add_argument("--zhang-sizes", nargs="+", default=["256", "512"])
    ap.add_argument("--cuda-voxelizer", default=os.environ.get("GLVOX_CUDA_VOXELIZER"),
                    help="a cuda_voxelizer binary for the peer step (default: $GLVOX_CUDA_VOXELIZER)")
    args = ap.parse_args(argv)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    start = time.perf_counter()
    shares = {**SHARES, "peer": SHARES["peer"] if args.cuda_voxelizer else 0.0}  # a skipped step takes none
    rows = []
    failed = False
    with tempfile.TemporaryDirectory(prefix="glvox-gpu-report-") as tmp:
        work = Path(tmp)
        for n, step in enumerate(args.steps):
            left = args.budget - (time.perf_counter() - start)
            later = sum(shares[s] for s in args.steps[n:])
            share = left * shares[step] / later if later else left
            cmd, log = commands(step, out, work, args)
            if step == "peer" and not args.cuda_voxelizer:
                rows.append((step, "skipped (no cuda_voxelizer binary: --cuda-voxelizer PATH)", 0.0, log, cmd, ""))
                continue
            if share < 5:
                rows.append((step, "skipped (no budget left)", 0.0, log, cmd, ""))
                failed = True  # the report lacks it
                continue
            print(f"gpu_report: {step} ({share:.0f} s at most): {' '.join(cmd)}", flush=True)
            status, seconds = run_step(cmd, log, share)
            failed |= status != "ok"
            # before work/ goes; a step whose output is only in report.md keeps all of its tables
            rows.append((step, status, seconds, log, cmd, _tail(log, 25 if log.parent == out else 60)))
    lines = ["# glvox on this GPU", ""]
    info = out / "info.json"
    if info.is_file():
        try:
            d = json.loads(info.read_text())
            lines += [f"Renderer: {d.get('renderer')} ({d.get('vendor')}, {d.get('version')}), "
                      f"backend {d.get('backend')}.", ""]
        except ValueError:
            pass
    lines += [f"`python compare/gpu_report.py {' '.join(argv if argv is not None else sys.argv[1:])}`, "
              f"budget {args.budget:.0f} s, {time.perf_counter() - start:.0f} s used.", "",
              "| step | status | seconds | output |", "|---|---|---|---|"]
    lines += [f"| {s} | {st} | {sec:.1f} | `{log.name if log.parent == out else 'below'}` |"
              for s, st, sec, log, _, _ in rows]
    for s, st, sec, log, cmd, tail in rows:
        lines += ["", f"## {s}: {st}", "", f"`{' '.join(cmd)}`", "", "```text", tail, "```"]
    (out / "report.md").write_text("\n".join(lines) + "\n")
    print(f"gpu_report: {out / 'report.md'}" + (" (some steps failed)" if failed else ""))
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
