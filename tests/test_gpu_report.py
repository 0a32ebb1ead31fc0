"""compare/gpu_report.py: the steps run in their own processes within the budget, and the
report says what each gave, also when one fails or is left without time."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

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
