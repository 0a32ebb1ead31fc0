"""compare/gpu_report.py: the steps run in their own processes within the budget, and the
report says what each gave, also when one fails or is left without time.  compare/gpu_lease.py:
the one command that runs it on a lent GPU machine fits the device tool, and the wheels it
carries are the versions tested here."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import moderngl
from conftest import load_script

ROOT = Path(__file__).resolve().parents[1]
SCRIPT = ROOT / "compare" / "gpu_report.py"


def report(tmp_path, *args):
    out = tmp_path / "report"
    p = subprocess.run([sys.executable, str(SCRIPT), "-o", str(out), *args], capture_output=True, text=True,
                       timeout=300, cwd=ROOT)
    return p, out


def test_a_small_report(tmp_path):
    p, out = report(tmp_path, "--steps", "info", "readback", "bench", "--budget", "240", "--mesh", "gen:torus",
                    "--bench-sizes", "32", "--bench-methods", "ss-conservative", "--readback-sizes", "64")
    assert p.returncode == 0, p.stdout + p.stderr
    assert sorted(f.name for f in out.iterdir()) == ["bench.log", "bench.md", "info.json", "readback.log",
                                                      "report.md"]
    info = json.loads((out / "info.json").read_text())
    text = (out / "report.md").read_text()
    assert f"Renderer: {info['renderer']}" in text
    for step in ("info", "readback", "bench"):
        assert f"| {step} | ok |" in text
    assert "ss-conservative" in (out / "bench.md").read_text()


def test_a_failed_step_and_a_spent_budget_are_reported(tmp_path):
    p, out = report(tmp_path, "--steps", "bench", "tables", "--budget", "60", "--mesh", "/no/such/mesh.ply",
                    "--bench-sizes", "32", "--bench-methods", "ss-conservative")
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
        assert f"| ss-conservative | gen:torus | {n} |" in text and f"| ss-solid | gen:torus | {n} |" in text
