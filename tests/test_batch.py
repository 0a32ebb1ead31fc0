"""``glvox batch``: dataset-scale voxelization, checked against ``glvox voxelize`` file by file.

The dataset is generated (:func:`glvox.testing.datasets.synthetic_dataset`: 200 small
meshes of primitives and perturbed shapes in nested folders, four suffixes,
a few open boxes, plus deliberately broken files).  The expectation for each
mesh is the output of the single-file command (its entry point
``glvox.cli.main(["voxelize", ...])``, run in this process), and for each
broken file the reason written beside it in ``glvox.testing.datasets.BROKEN`` and the
message the single-file command prints.
"""

from __future__ import annotations

import contextlib
import csv
import io as _io
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from glvox import cli
from glvox.batch import (LOCK_NAME, MANIFEST_COLUMNS, BatchSettings, Progress, find_meshes, plan_jobs,
                         read_manifest, run_batch)
from glvox.errors import GlvoxError, GridError, MeshLoadError, MethodError
from glvox.methods import method_names
from glvox.testing.crash import CrashingTask
from glvox.testing.datasets import BROKEN, synthetic_dataset

#: Small grids and fast GPU methods keep the 200-mesh runs within seconds on llvmpipe.
R = 32
N_MESHES = 200


def glvox(*args, env=None, **kw):
    return subprocess.run([sys.executable, "-m", "glvox", *map(str, args)], capture_output=True,
                          text=True, timeout=600, env=env, **kw)


def voxelize_cli(mesh, out, method, *extra):
    """``glvox voxelize MESH -r R -m METHOD -o OUT -q``: exit status and the stderr text."""
    err = _io.StringIO()
    with contextlib.redirect_stderr(err):
        code = cli.main(["voxelize", str(mesh), "-r", str(R), "-m", method, "-o", str(out), "-q",
                         *map(str, extra)])
    return code, err.getvalue().strip()


def same_output(a: Path, b: Path) -> bool:
    """Equal binvox bytes, or equal npz arrays (occupancy, origin, voxel size, method, kind)."""
    if a.suffix == ".binvox":
        return a.read_bytes() == b.read_bytes()
    with np.load(a) as x, np.load(b) as y:
        return set(x.files) == set(y.files) and all(
            x[k].dtype == y[k].dtype and np.array_equal(x[k], y[k]) for k in x.files)


def manifest_rows(path) -> dict[str, dict[str, str]]:
    with open(path, newline="") as f:
        r = csv.DictReader(f)
        assert tuple(r.fieldnames) == MANIFEST_COLUMNS
        rows = list(r)
    by_input = {row["input"]: row for row in rows}
    assert len(by_input) == len(rows), "one row per mesh"
    return by_input


def output_name(rel: str, suffix: str) -> str:
    """Where a mesh's output goes: the mirrored path with the format's suffix; files of one
    folder that share a stem (broken/garbage.obj, broken/garbage.ply) keep their mesh suffix."""
    if Path(rel).stem == "garbage":
        return rel + suffix
    return str(Path(rel).with_suffix(suffix).as_posix())


@pytest.fixture(scope="module")
def dataset(tmp_path_factory):
    root = tmp_path_factory.mktemp("dataset")
    files = synthetic_dataset(root, N_MESHES)
    assert sum(1 for f in files.values() if f["broken"] is None) == N_MESHES
    return root, files


@pytest.fixture(scope="module")
def references(dataset, tmp_path_factory):
    """Single-file command outputs: (method, suffix) -> rel -> (exit code, stderr, path)."""
    root, files = dataset
    cache: dict = {}

    def get(method: str, suffix: str, rels=None):
        key = (method, suffix)
        out = tmp_path_factory.mktemp(f"ref-{method}-{suffix[1:]}") if key not in cache else None
        table = cache.setdefault(key, {"dir": out, "rows": {}})
        for rel in (rels if rels is not None else files):
            if rel not in table["rows"]:
                path = table["dir"] / rel.replace("/", "__")
                path = path.with_suffix(suffix)
                code, err = voxelize_cli(root / rel, path, method)
                table["rows"][rel] = (code, err, path)
        return {rel: table["rows"][rel] for rel in (rels if rels is not None else files)}

    return get


def error_message(stderr: str) -> str:
    assert stderr.startswith("glvox: error: "), stderr
    return stderr[len("glvox: error: "):]


def check_outputs(out: Path, files, refs, suffix: str, manifest: dict, method: str):
    """Every good mesh's output equals the single-file command's; every failure is in the
    manifest with its reason and the single-file command's message."""
    for rel, info in files.items():
        code, err, ref = refs[rel]
        row = manifest[rel]
        assert row["method"] == method and row["glvox_version"]
        target = out / output_name(rel, suffix)
        assert row["output"] == output_name(rel, suffix)
        if code == 0:
            assert info["broken"] is None
            assert target.is_file(), f"{rel}: no output"
            assert same_output(target, ref), f"{rel}: batch output differs from glvox voxelize"
            assert row["status"] in ("done", "skipped"), row
        else:
            assert not target.exists()
            assert row["status"] == "failed", row
            assert row["error"] == error_message(err), rel
            expected = info["broken"] or "NotWatertightError"
            assert row["reason"] == expected, f"{rel}: reason {row['reason']}, expected {expected}"
        if row["status"] == "done":
            assert row["watertight"] == ("true" if info["watertight"] else "false")
            assert int(row["triangles"]) > 0 and int(row["voxels"]) > 0
            assert row["dims"] == f"{R}x{R}x{R}"
            assert float(row["total_s"]) >= float(row["voxelize_s"]) > 0


# ---------------------------------------------------------------------------
# inputs and output paths
# ---------------------------------------------------------------------------


def test_find_meshes_recursive_by_suffix_and_list_file(dataset, tmp_path):
    root, files = dataset
    found_root, meshes = find_meshes(root)
    assert found_root == root
    # README.txt and .hidden.obj are not picked up; every other file is, sorted
    assert [p.relative_to(root).as_posix() for p in meshes] == sorted(files, key=lambda r: Path(r).parts)
    _, stl = find_meshes(root, suffixes=["STL"])
    assert {p.suffix for p in stl} == {".stl"} and len(stl) == sum(r.endswith(".stl") for r in files)

    listed = ["group1/sub1/sphere_0001.obj", "group2/sub2/torus_0002.ply", "group1/sub1/sphere_0001.obj"]
    lst = root / "list.txt"
    lst.write_text("# comment\n\n" + "\n".join(listed) + "\n" + str(root / "broken/nan.obj") + "\n")
    list_root, listed_meshes = find_meshes(lst)
    assert list_root == root       # the deepest folder holding every listed mesh
    assert [p.relative_to(root).as_posix() for p in listed_meshes] == [listed[0], listed[1], "broken/nan.obj"]
    lst.unlink()


def test_plan_mirrors_the_tree_and_keeps_suffixes_that_clash(tmp_path):
    src = tmp_path / "in"
    for rel in ("a/chair.obj", "a/chair.stl", "a/b/table.ply", "lamp.off", ".git/x.obj", "a/notes.txt"):
        (src / rel).parent.mkdir(parents=True, exist_ok=True)
        (src / rel).write_text("x")
    out = src / "voxels"           # inside the input: never searched
    (out / "old").mkdir(parents=True)
    (out / "old" / "stale.obj").write_text("x")
    jobs = plan_jobs(src, out, "binvox")
    assert [(j.rel, j.out_rel) for j in jobs] == [
        ("lamp.off", "lamp.binvox"),
        ("a/chair.obj", "a/chair.obj.binvox"), ("a/chair.stl", "a/chair.stl.binvox"),
        ("a/b/table.ply", "a/b/table.binvox"),
    ]
    assert all(Path(j.output) == out / j.out_rel and Path(j.input) == src / j.rel for j in jobs)


def test_bad_inputs_are_refused_before_any_work(tmp_path):
    with pytest.raises(MeshLoadError, match="batch input not found"):
        find_meshes(tmp_path / "nope")
    (tmp_path / "empty").mkdir()
    with pytest.raises(MeshLoadError, match=r"no mesh files \(suffixes .*\.obj.*\) under"):
        find_meshes(tmp_path / "empty")
    (tmp_path / "m.obj").write_text("v 0 0 0\n")
    with pytest.raises(MeshLoadError, match="is a mesh file; glvox batch takes a folder"):
        find_meshes(tmp_path / "m.obj")
    (tmp_path / "empty" / "x.stl").write_text("x")
    with pytest.raises(MethodError, match="unknown method 'nope'"):
        run_batch(tmp_path / "empty", tmp_path / "o", BatchSettings("nope", resolution=8), workers=0)
    with pytest.raises(MethodError, match="has no option"):
        run_batch(tmp_path / "empty", tmp_path / "o",
                  BatchSettings("ss-conservative", resolution=8, options=(("bogus", "1"),)), workers=0)
    with pytest.raises(GridError, match="give -r/--resolution"):
        run_batch(tmp_path / "empty", tmp_path / "o", BatchSettings("ss-conservative"), workers=0)
    assert not (tmp_path / "o").exists()
    p = glvox("batch", tmp_path / "empty", "-o", tmp_path / "o", "-r", 8, "--workers", 2,
              "--scheduler", "tcp://127.0.0.1:1")
    assert p.returncode == 1 and "give one or the other" in p.stderr and "Traceback" not in p.stderr


def test_atomic_save_never_leaves_a_partial_output(tmp_path, monkeypatch):
    import glvox
    from glvox import io as gio
    from glvox.batch import atomic_save

    grid = glvox.voxelize("gen:box", 8, method="reference-solid")
    out = tmp_path / "a" / "box.npz"
    real_save = gio.save

    def dies_half_way(g, path, **kw):
        Path(path).write_bytes(b"PK\x03\x04 half an archive")
        raise OSError("disk full")

    monkeypatch.setattr(gio, "save", dies_half_way)
    with pytest.raises(OSError, match="disk full"):
        atomic_save(grid, out)
    assert list(out.parent.iterdir()) == []
    monkeypatch.setattr(gio, "save", real_save)
    assert atomic_save(grid, out) == out
    assert [p.name for p in out.parent.iterdir()] == ["box.npz"] and gio.load(out).equal(grid)


@pytest.mark.parametrize("method", method_names(kind="ldi"))
def test_methods_without_a_file_format_are_refused(tmp_path, method):
    (tmp_path / "in").mkdir()
    (tmp_path / "in" / "x.stl").write_text("x")
    with pytest.raises(MethodError, match=f"{method!r} returns a result of kind 'ldi', which glvox cannot save"):
        run_batch(tmp_path / "in", tmp_path / "o", BatchSettings(method, resolution=8), workers=0)
    assert not (tmp_path / "o").exists()


# ---------------------------------------------------------------------------
# the whole dataset through the default path (a local Dask cluster), killed and resumed
# ---------------------------------------------------------------------------


def test_killed_batch_resumes_without_redoing_or_corrupting(dataset, references, tmp_path):
    root, files = dataset
    refs = references("ss-conservative", ".binvox")
    out = tmp_path / "out"
    args = ["batch", root, "-o", out, "-r", R, "-m", "ss-conservative", "--format", "binvox",
            "--workers", 2]
    first = subprocess.Popen([sys.executable, "-m", "glvox", *map(str, args), "-q"],
                             stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, start_new_session=True)

    def finished():
        return [p for p in out.rglob("*.binvox") if ".part-" not in p.name] if out.is_dir() else []

    deadline = time.monotonic() + 300
    try:
        while len(finished()) < 40:
            assert first.poll() is None, f"batch ended before the kill: {first.stderr.read().decode()}"
            assert time.monotonic() < deadline, "no outputs appeared"
            time.sleep(0.02)
    finally:
        # the batch and its worker processes, at once, with no chance to clean up (a batch
        # that already ended has no group left: the assertion above says why it ended)
        with contextlib.suppress(ProcessLookupError):
            os.killpg(first.pid, signal.SIGKILL)
        first.wait()
        first.stderr.close()
    before = {p: (p.stat().st_ino, p.stat().st_mtime_ns, p.read_bytes()) for p in finished()}
    assert 40 <= len(before) < N_MESHES
    # a temporary file of a write cut short never counts as an output, and goes on rerun
    victim = next(out / output_name(r, ".binvox") for r, i in files.items()
                  if i["broken"] is None and out / output_name(r, ".binvox") not in before)
    victim.parent.mkdir(parents=True, exist_ok=True)
    planted = victim.with_name(f".{victim.name}.part-1-deadbeef.binvox")
    planted.write_bytes(b"#binvox 1\ndim 32 32 32\n")

    p = glvox(*args, "--json")
    assert p.returncode == 3, p.stderr          # 3: finished, some meshes failed
    summary = json.loads(p.stdout)
    n_broken = len(BROKEN)
    assert summary["total"] == N_MESHES + n_broken and summary["pending"] == 0
    assert summary["skipped"] == len(before)
    assert summary["done"] == N_MESHES - len(before)
    assert summary["failed"] == n_broken
    assert summary["mode"] == "local cluster (2 workers)"
    assert not [q for q in out.rglob("*") if ".part-" in q.name]
    assert victim.is_file() and not planted.exists()
    for path, (ino, mtime, data) in before.items():
        st = path.stat()
        assert (st.st_ino, st.st_mtime_ns) == (ino, mtime), f"{path} was rewritten"
        assert path.read_bytes() == data
    rows = manifest_rows(out / "manifest.csv")
    assert set(rows) == set(files)
    assert {r for r, row in rows.items() if row["status"] == "skipped"} == {
        r for r in files if out / output_name(r, ".binvox") in before}
    check_outputs(out, files, refs, ".binvox", rows, "ss-conservative")
    # the in-process reference is the command itself: one file through a real `glvox voxelize`
    rel = "group0/sub0/box_0000.stl"
    q = glvox("voxelize", root / rel, "-r", R, "-m", "ss-conservative", "-o", tmp_path / "one.binvox", "-q")
    assert q.returncode == 0, q.stderr
    assert (tmp_path / "one.binvox").read_bytes() == (out / output_name(rel, ".binvox")).read_bytes()
    # a third run, in this process, finds everything done: only the broken files are tried again
    s = run_batch(root, out, BatchSettings("ss-conservative", resolution=R, fmt="binvox"), workers=0,
                  quiet=True)
    assert (s.skipped, s.done, s.failed) == (N_MESHES, 0, n_broken)
    for path, (ino, mtime, _) in before.items():
        assert (path.stat().st_ino, path.stat().st_mtime_ns) == (ino, mtime)


# ---------------------------------------------------------------------------
# an existing Dask cluster (started here), a solid method
# ---------------------------------------------------------------------------


def test_dask_scheduler_address_solid_method(dataset, references, tmp_path):
    distributed = pytest.importorskip("distributed", reason="the Dask path needs dask[distributed]")
    root, files = dataset
    sub = {r: i for r, i in files.items() if r.startswith("group0/")}
    assert any(not i["watertight"] for i in sub.values())
    refs = references("ss-solid", ".npz", list(sub))
    out = tmp_path / "out"
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address=None) as cluster, distributed.Client(cluster) as client:
        pids = set(client.run(os.getpid).values())
        p = glvox("batch", root / "group0", "-o", out, "-r", R, "-m", "ss-solid",
                  "--scheduler", cluster.scheduler_address)
    assert p.returncode == 3, p.stderr
    assert f"scheduler {cluster.scheduler_address}" in p.stdout
    assert "failed by reason: NotWatertightError" in p.stdout
    rows = manifest_rows(out / "manifest.csv")       # paths relative to the input folder, group0
    assert set(rows) == {r[len("group0/"):] for r in sub}
    for rel, info in sub.items():
        code, err, ref = refs[rel]
        row = rows[rel[len("group0/"):]]
        target = out / Path(rel[len("group0/"):]).with_suffix(".npz")
        assert row["output"] == Path(rel[len("group0/"):]).with_suffix(".npz").as_posix()
        if info["watertight"]:
            assert code == 0 and row["status"] == "done", row
            assert same_output(target, ref), f"{rel}: batch output differs from glvox voxelize"
        else:
            assert row["status"] == "failed" and row["reason"] == "NotWatertightError"
            assert row["error"] == error_message(err)
            assert not target.exists()
    # the work ran on the cluster's worker processes, both of them
    assert {int(r["worker"].rsplit(":", 1)[1]) for r in rows.values() if r["worker"]} == pids


# ---------------------------------------------------------------------------
# a worker crash: retried once on a fresh worker, then recorded
# ---------------------------------------------------------------------------


def test_worker_crash_is_retried_once_then_recorded(dataset, references, tmp_path):
    root, files = dataset
    rels = ["group1/sub1/sphere_0001.obj", "group2/sub2/torus_0002.ply", "group3/sub0/cylinder_0003.off"]
    refs = references("ss-conservative", ".binvox", rels)
    lst = tmp_path / "meshes.txt"
    lst.write_text("\n".join(str(root / r) for r in rels) + "\n")
    log = tmp_path / "crashes.log"
    out = tmp_path / "out"
    # the task kills its worker process (SIGKILL, as the OOM killer would) on the torus
    s = run_batch(lst, out, BatchSettings("ss-conservative", resolution=R, fmt="binvox"), workers=1,
                  quiet=True, task=CrashingTask("torus_0002", str(log)))
    assert (s.done, s.failed, s.failed_by_reason) == (2, 1, {"WorkerCrashed": 1})
    attempts = log.read_text().split("\n")[:-1]
    assert len(attempts) == 2, attempts                  # the first try and one retry
    assert len({a.split()[1] for a in attempts}) == 2     # each in its own worker process
    rows = manifest_rows(out / "manifest.csv")           # paths relative to the listed files' root
    crashed = rows["group2/sub2/torus_0002.ply"]
    assert crashed["status"] == "failed" and crashed["reason"] == "WorkerCrashed"
    assert crashed["error"].startswith("worker crashed: the worker process died while voxelizing "
                                       "group2/sub2/torus_0002.ply, and again on the retry")
    for rel in rels[0], rels[2]:
        assert rows[rel]["status"] == "done"
        assert same_output(out / Path(rel).with_suffix(".binvox"), refs[rel][2])


# ---------------------------------------------------------------------------
# in this process (workers=0): list files, overwrite, settings, open meshes, lock
# ---------------------------------------------------------------------------


def test_in_process_overwrite_settings_and_allow_open(dataset, tmp_path):
    root, files = dataset
    rels = [next(r for r, i in files.items() if i["kind"] == k) for k in ("box", "open_box", "capsule")]
    lst = tmp_path / "list.txt"
    lst.write_text("\n".join(str(root / r) for r in rels) + "\nmissing/gone.obj\n")
    # outputs mirror the paths below the deepest folder that holds every listed file
    base = Path(os.path.commonpath([root, tmp_path]))
    key = {r: (root / r).relative_to(base).as_posix() for r in rels}
    gone_key = (tmp_path / "missing/gone.obj").relative_to(base).as_posix()
    out = tmp_path / "out"
    settings = BatchSettings("ss-solid", resolution=R, allow_open=True)
    s = run_batch(lst, out, settings, workers=0, quiet=True)
    assert (s.total, s.done, s.failed, s.mode) == (4, 3, 1, "in-process")
    rows = manifest_rows(out / "manifest.csv")
    assert set(rows) == set(key.values()) | {gone_key}
    gone = rows[gone_key]
    assert gone["reason"] == "MeshLoadError" and gone["error"].startswith("mesh file not found")
    for rel in rels:
        ref = tmp_path / "ref" / Path(rel).with_suffix(".npz").name
        ref.parent.mkdir(exist_ok=True)
        code, err = voxelize_cli(root / rel, ref, "ss-solid", "--allow-open")
        assert code == 0, err
        row = rows[key[rel]]
        assert row["output"] == Path(key[rel]).with_suffix(".npz").as_posix()
        assert same_output(out / row["output"], ref), rel
        assert ("not watertight" in row["warnings"]) == (not files[rel]["watertight"])
        assert row["params"] == "-m ss-solid -r 32 --allow-open --format npz"
    target = out / rows[key[rels[0]]]["output"]
    st = target.stat()
    # other settings into the same folder: refused, nothing touched
    with pytest.raises(GlvoxError, match=r"holds 3 outputs made with other settings .*-r 16"):
        run_batch(lst, out, BatchSettings("ss-solid", resolution=16, allow_open=True), workers=0, quiet=True)
    assert target.stat().st_mtime_ns == st.st_mtime_ns
    # --overwrite redoes them (a new file renamed over the old one)
    s = run_batch(lst, out, settings, workers=0, quiet=True, overwrite=True)
    assert (s.done, s.skipped, s.failed) == (3, 0, 1)
    assert target.stat().st_ino != st.st_ino
    previous = manifest_rows(out / "manifest.csv")
    # a rerun carries the finished rows over, marked skipped
    s = run_batch(lst, out, settings, workers=0, quiet=True)
    assert (s.done, s.skipped, s.failed) == (0, 3, 1)
    again = manifest_rows(out / "manifest.csv")
    for k in key.values():
        assert again[k]["status"] == "skipped" and previous[k]["status"] == "done"
        assert {c: v for c, v in again[k].items() if c != "status"} == \
               {c: v for c, v in previous[k].items() if c != "status"}
    assert again[gone_key]["status"] == "failed" and again[gone_key]["finished"]
    # redone without --allow-open, the open mesh fails, and its earlier output goes with it
    opened = out / again[key[rels[1]]]["output"]
    assert opened.is_file()
    s = run_batch(lst, out, BatchSettings("ss-solid", resolution=R), workers=0, quiet=True, overwrite=True)
    assert (s.done, s.failed, s.failed_by_reason) == (2, 2, {"MeshLoadError": 1, "NotWatertightError": 1})
    assert not opened.exists()


def test_a_second_batch_on_the_same_output_is_refused(dataset, tmp_path):
    fcntl = pytest.importorskip("fcntl", reason="the output lock uses POSIX flock")
    root, _ = dataset
    out = tmp_path / "out"
    out.mkdir()
    with open(out / LOCK_NAME, "a+") as f:
        fcntl.flock(f.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
        with pytest.raises(GlvoxError, match="another glvox batch is writing into"):
            run_batch(root / "broken", out, BatchSettings("ss-conservative", resolution=R), workers=0,
                      quiet=True)
    s = run_batch(root / "broken", out, BatchSettings("ss-conservative", resolution=R), workers=0,
                  quiet=True)
    assert s.failed == len(BROKEN)
    assert {r["input"]: r["reason"] for r in read_manifest(out / "manifest.csv")} == {
        k[len("broken/"):]: v for k, v in BROKEN.items()}


# ---------------------------------------------------------------------------
# progress and summary
# ---------------------------------------------------------------------------


class FakeClock:
    def __init__(self):
        self.t = 100.0

    def __call__(self):
        return self.t


def test_progress_bar_rate_eta_and_plain_lines():
    clock, tty = FakeClock(), _io.StringIO()
    p = Progress(200, unit="mesh", stream=tty, tty=True, clock=clock)
    assert "ETA ?" in p.line() and "nan" not in p.line()   # no rate yet: the ETA is unknown
    for i in range(50):
        clock.t += 0.2                           # 5 meshes per second
        if i < 2:
            p.status(f"{i + 1} failed")
        p.update()
    # 150 left at 5 meshes/s: 30 s
    assert p.line() == "50/200  25% |######                  |  5.00 mesh/s  ETA 00:30, 2 failed"
    assert tty.getvalue().count("\r") >= 2 and "\n" not in tty.getvalue()   # redrawn in place
    assert tty.getvalue().rsplit("\r", 1)[-1].startswith("50/200")
    p.close()
    assert tty.getvalue().endswith("\n")

    clock, log = FakeClock(), _io.StringIO()
    p = Progress(100, unit="mesh", stream=log, tty=False, clock=clock, log_interval=10)
    for _ in range(100):
        clock.t += 0.5
        p.update()
    lines = log.getvalue().splitlines()
    # one line every 10 s of the 50 s run, the last at the end
    assert len(lines) == 5 and lines[-1].startswith("[    50.0 s] 100/100 100%")
    assert "2.00 mesh/s" in lines[0] and "ETA 00:40" in lines[0]

    quiet = _io.StringIO()
    p = Progress(10, stream=quiet, enabled=False, tty=True, clock=FakeClock())
    p.update()
    p.close()
    assert quiet.getvalue() == ""


def test_rerun_that_skips_everything_reports_no_rate(dataset, tmp_path):
    root, _ = dataset
    args = ("batch", root / "group0", "-o", tmp_path / "o", "-r", R, "--workers", 0)
    assert glvox(*args).returncode == 0
    p = glvox(*args)
    assert p.returncode == 0, p.stderr
    assert "none processed: every output exists (--overwrite redoes them)" in p.stdout
    assert "meshes/s" not in p.stdout


def test_cli_summary_and_quiet(dataset, tmp_path):
    root, _ = dataset
    p = glvox("batch", root / "broken", "-o", tmp_path / "o", "-r", R, "--workers", 0)
    assert p.returncode == 3
    assert f"{len(BROKEN)} meshes in" in p.stdout and "(in-process" in p.stdout
    assert "done 0, skipped 0, failed 7" in p.stdout
    assert "failed by reason: EmptyMeshError 3, MeshLoadError 3, NonFiniteVertexError 1" in p.stdout
    assert "meshes/s" in p.stdout
    q = glvox("batch", root / "broken", "-o", tmp_path / "o", "-r", R, "--workers", 0, "-q")
    assert q.returncode == 3 and q.stdout == "" and q.stderr == ""


# ---------------------------------------------------------------------------
# local worker processes: messages of several meshes, llvmpipe threads and EGL devices per worker
# ---------------------------------------------------------------------------


def test_small_meshes_travel_several_per_message_large_ones_alone(tmp_path):
    from glvox.batch.jobs import Job
    from glvox.batch.pool import CHUNK_BYTES, CHUNK_MESHES, chunks

    def job(name, size):
        p = tmp_path / name
        p.write_bytes(b"x" * size)
        return Job(str(p), name, str(p) + ".npz", name + ".npz")

    small = [job(f"s{i}.obj", 100) for i in range(CHUNK_MESHES + 3)]
    big = [job("big1.obj", CHUNK_BYTES + 1), job("big2.obj", CHUNK_BYTES // 2 + 1),
           job("big3.obj", CHUNK_BYTES // 2)]
    out = [[j.rel for j in c] for c in chunks(small + big)]
    assert out[0] == [j.rel for j in small[:CHUNK_MESHES]]
    assert out[1:] == [[j.rel for j in small[CHUNK_MESHES:]], ["big1.obj"], ["big2.obj"], ["big3.obj"]]
    assert sum(out, []) == [j.rel for j in small + big]  # every job once, in order
    lpt = [[j.rel for j in c] for c in chunks(small + big, largest_first=True)]
    assert lpt[:2] == [["big1.obj"], ["big2.obj"]] and lpt[2][0] == "big3.obj"  # then small ones fill up
    assert sorted(sum(lpt, [])) == sorted(sum(out, []))


def test_workers_divide_llvmpipe_threads_and_take_egl_devices_in_turn(dataset, tmp_path, monkeypatch):
    from glvox.batch.pool import CHUNK_MESHES, lp_threads, worker_envs
    from glvox.testing.worker_env import WorkerEnvTask

    monkeypatch.delenv("LP_NUM_THREADS", raising=False)
    monkeypatch.delenv("GLVOX_THREADS", raising=False)
    root, files = dataset
    rels = [r for r, i in files.items() if i["broken"] is None][:CHUNK_MESHES + 4]  # two messages
    assert len(rels) == CHUNK_MESHES + 4
    lst = tmp_path / "meshes.txt"
    lst.write_text("\n".join(str(root / r) for r in rels) + "\n")
    # one EGL device listed: every worker gets it (this machine has one; several GPUs would be 0, 1, ...)
    s = run_batch(lst, tmp_path / "out", BatchSettings("ss-conservative", resolution=R), workers=2, quiet=True,
                  task=WorkerEnvTask(), egl_devices=[0])
    assert s.done == len(rels) and s.mode == "local cluster (2 workers)"
    rows = manifest_rows(tmp_path / "out" / "manifest.csv")
    want = f"LP_NUM_THREADS={lp_threads(2)} GLVOX_THREADS={lp_threads(2)} GLVOX_EGL_DEVICE=0"
    assert {rows[r]["warnings"] for r in rels} == {want}
    assert lp_threads(2) == str(max(1, (os.cpu_count() or 1) // 2)) and lp_threads(10**6) == "1"
    assert len({rows[r]["worker"] for r in rels}) == 2  # both worker processes took meshes
    # several GPUs: one device per worker, in turn
    envs = worker_envs(3, egl_devices=[0, 1])
    assert [e["GLVOX_EGL_DEVICE"] for e in envs] == ["0", "1", "0"] and "GLVOX_EGL_DEVICE" not in worker_envs(2)[0]


def test_inspect_columns_and_robust_solids_on_open_meshes(dataset, tmp_path, gl_context):
    """--inspect fills the report's columns (the same numbers as glvox inspect); a robust
    solid (carve-solid) voxelizes open meshes without --allow-open."""
    from glvox.batch.manifest import INSPECT_COLUMNS
    from glvox.grid import grid_for
    from glvox.inspect import inspect_mesh, uncertain_share
    from glvox.mesh import load_mesh
    from glvox.methods import run_method

    root, files = dataset
    rels = [next(r for r, i in files.items() if i["kind"] == k) for k in ("box", "open_box")]
    lst = tmp_path / "list.txt"
    lst.write_text("\n".join(str(root / r) for r in rels) + "\n")
    out = tmp_path / "out"
    s = run_batch(lst, out, BatchSettings("carve-solid", resolution=R, inspect=True), workers=0, quiet=True)
    assert (s.done, s.failed) == (2, 0)
    rows = {Path(r["input"]).name: r for r in manifest_rows(out / "manifest.csv").values()}
    for rel in rels:
        row = rows[Path(rel).name]
        report = inspect_mesh(root / rel).to_dict()
        # the uncertain share on the batch's grid, as the exact winding numbers give it
        mesh = load_mesh(root / rel)
        exact = run_method("reference-gwn", mesh, grid_for(mesh, R)).fields["winding"]
        report["uncertain_share"] = uncertain_share(exact)[1]
        for c in INSPECT_COLUMNS:
            if report[c] is None:
                assert row[c] == ""
            elif isinstance(report[c], bool):
                assert row[c] == ("true" if report[c] else "false"), c
            elif isinstance(report[c], str):
                assert row[c] == report[c], c
            else:
                assert float(row[c]) == pytest.approx(report[c], rel=1e-5, abs=1e-9), c
        assert float(row["inspect_s"]) > 0 and row["method"] == "carve-solid" and not row["warnings"]
    assert int(rows[Path(rels[1]).name]["boundary_edges"]) > 0 == int(rows[Path(rels[0]).name]["boundary_edges"])
    assert float(rows[Path(rels[1]).name]["uncertain_share"]) > 0 == float(rows[Path(rels[0]).name]["uncertain_share"])
    # without --inspect the columns stay empty
    s = run_batch(lst, tmp_path / "plain", BatchSettings("carve-solid", resolution=R), workers=0, quiet=True)
    assert all(r["components"] == r["inspect_s"] == "" for r in manifest_rows(tmp_path / "plain/manifest.csv").values())


def test_suspicious_solids_are_in_the_manifest_and_counted(tmp_path):
    """A double-sided cube's parity solid is empty: the manifest's warnings column names
    the cause and the method to use, and the summary counts the mesh as warned and empty."""
    from glvox.testing.defects import cube, double_sided_cube, write_obj

    src = tmp_path / "in"
    src.mkdir()
    write_obj(src / "plain.obj", cube())
    write_obj(src / "two_faced.obj", double_sided_cube())
    out = tmp_path / "o"
    p = glvox("batch", src, "-o", out, "-r", 8, "-m", "reference-solid", "--allow-open", "--workers", 0)
    assert p.returncode == 0, p.stderr
    rows = manifest_rows(out / "manifest.csv")
    assert rows["two_faced.obj"]["status"] == "done" and rows["two_faced.obj"]["voxels"] == "0"
    assert "0 voxels (empty) from reference-solid: double-sided faces cancel" in rows["two_faced.obj"]["warnings"]
    assert "use -m binvox-solid or -m carve-solid" in rows["two_faced.obj"]["warnings"]
    assert rows["plain.obj"]["warnings"] == "" and int(rows["plain.obj"]["voxels"]) > 0
    assert "with warnings 1, empty results 1: see the manifest's warnings column" in p.stdout
    j = glvox("batch", src, "-o", out, "-r", 8, "-m", "reference-solid", "--allow-open", "--workers", 0,
              "--overwrite", "--json")
    assert j.returncode == 0, j.stderr
    assert {k: json.loads(j.stdout)[k] for k in ("warned", "empty")} == {"warned": 1, "empty": 1}
