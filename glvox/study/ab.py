"""``glvox bench --against REV``: this glvox against the one at a git revision, run by run.

The baseline file of ``glvox bench --check`` holds times taken earlier, on a
machine whose load has moved since; on this shared 2-core machine llvmpipe's
raster methods drifted by 20-40 % between two hours while a compute
calibration workload drifted the other way (best times of passalis-stencil:
95 ms in the baseline, 116-136 ms a day later with unchanged code), and no
machine factor corrects that.  This check removes the drift instead of
estimating it: two long-lived child processes, one importing glvox from a
``git archive`` of REV ("base"), one importing this checkout ("head"), take
turns run by run on the same cell (mesh, N, method), so a burst of load
lands on both alike.  Every timed run is one ``run_method`` call, after one
warm-up run per side (compilation); a cell regresses when head's best
*and* median times both exceed base's by more than the tolerance.

The children (:mod:`glvox.study.ab_child`, run with ``python -S`` and
``PYTHONPATH`` = their source tree + this interpreter's site-packages) use
only the library API every glvox revision has (``load_mesh``, ``grid_for``,
``run_method``), not the bench code of REV, and each checks that glvox and
its shaders came from its own tree before it serves.
"""

from __future__ import annotations

import io
import json
import os
import shutil
import site
import statistics
import subprocess
import sys
import tarfile
import tempfile
import time
from pathlib import Path
from typing import Any, Callable, Sequence

from glvox.errors import GlvoxError

from ..datasets import checkout_root, mesh_dir

def source_root() -> Path:
    """The checkout this glvox is imported from (``--against`` needs git)."""
    root = checkout_root()
    if root is None:
        raise GlvoxError(f"glvox bench --against compares git revisions, but glvox is imported from "
                         f"{Path(__file__).resolve().parents[2]}, which is not a git checkout of glvox")
    return root


def extract_revision(rev: str, dest: Path, root: Path | None = None) -> Path:
    """The files of glvox at ``rev`` (``git archive``) under ``dest``."""
    root = root or source_root()
    try:
        p = subprocess.run(["git", "-C", str(root), "archive", "--format=tar", rev],
                           capture_output=True, check=False)
    except FileNotFoundError:
        raise GlvoxError("glvox bench --against needs git on PATH") from None
    if p.returncode != 0:
        raise GlvoxError(f"git archive {rev!r} failed in {root}: {p.stderr.decode(errors='replace').strip()}")
    with tarfile.open(fileobj=io.BytesIO(p.stdout)) as tar:
        try:
            tar.extractall(dest, filter="data")
        except TypeError:  # Python without extraction filters
            tar.extractall(dest)
    if not (dest / "glvox" / "__init__.py").is_file():
        raise GlvoxError(f"revision {rev!r} has no glvox package")
    return dest


#: The child script (:mod:`glvox.study.ab_child`), copied beside the revision's tree.
CHILD = Path(__file__).with_name("ab_child.py")


def child_env(src: Path) -> dict[str, str]:
    """The environment of a child serving ``src``: ``PYTHONPATH`` = ``src``, then this
    interpreter's site-packages (numpy, moderngl, trimesh...), then the inherited
    ``PYTHONPATH``; no ``GLVOX_SHADER_PATH`` (the shaders come from ``src``)."""
    dirs = [str(src), *site.getsitepackages()]
    if site.ENABLE_USER_SITE and os.path.isdir(site.getusersitepackages()):
        dirs.append(site.getusersitepackages())
    dirs += [p for p in os.environ.get("PYTHONPATH", "").split(os.pathsep) if p]
    env = {k: v for k, v in os.environ.items() if k != "GLVOX_SHADER_PATH"}
    # the archive has no ../shared beside it: both find the meshes where this glvox does
    env.update(PYTHONPATH=os.pathsep.join(dirs), GLVOX_MESHES=str(mesh_dir()))
    return env


class Side:
    """A child process serving timed runs of one glvox source tree.

    ``python -S`` skips site, and with it the editable-install finder that
    would resolve ``glvox`` to this checkout; the script runs from ``workdir``
    (a folder of its own), so neither the working directory nor the script's
    folder can put another glvox first.
    """

    def __init__(self, name: str, src: Path, workdir: Path):
        self.name = name
        script = workdir / CHILD.name
        if not script.is_file():
            shutil.copyfile(CHILD, script)
        self.proc = subprocess.Popen([sys.executable, "-S", str(script), str(src)], stdin=subprocess.PIPE,
                                     stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                                     env=child_env(src), cwd=workdir)
        self._read()

    def _read(self) -> dict[str, Any]:
        line = self.proc.stdout.readline()
        if not line:
            err = self.proc.stderr.read().strip().splitlines()
            raise GlvoxError(f"the {self.name} glvox process ended: {' / '.join(err[-4:])}")
        return json.loads(line)

    def runs(self, mesh: str, n: int, method: str, options: dict, runs: int) -> dict[str, Any]:
        req = {"mesh": mesh, "n": n, "method": method, "options": options, "runs": runs}
        self.proc.stdin.write(json.dumps(req) + "\n")
        self.proc.stdin.flush()
        return self._read()

    def close(self) -> None:
        if self.proc.poll() is None:
            self.proc.stdin.close()
            try:
                self.proc.wait(timeout=30)
            except subprocess.TimeoutExpired:
                self.proc.kill()


def verdict(base_ms: Sequence[float], head_ms: Sequence[float], tolerance: float) -> dict[str, Any]:
    """Best and median of each side, their ratios, and whether head regressed
    (both ratios above 1 + tolerance: a real slowdown moves both)."""
    b, h = min(base_ms), min(head_ms)
    bm, hm = statistics.median(base_ms), statistics.median(head_ms)
    return {"base_ms": b, "head_ms": h, "base_median_ms": bm, "head_median_ms": hm,
            "ratio": h / b, "median_ratio": hm / bm, "runs": min(len(base_ms), len(head_ms)),
            "regressed": h / b > 1 + tolerance and hm / bm > 1 + tolerance}


#: Short cells keep alternating until this many seconds have passed (at most
#: MAX_RUNS runs per side): a 2 ms cell jitters by 0.3 ms from run to run
#: here, and ten runs per side flagged unchanged code as 17 % slower.
MIN_SECONDS, MAX_RUNS = 1.0, 200

#: A cell that looks regressed keeps alternating for this many more seconds,
#: and the verdict is taken again over all its runs: a real slowdown stays,
#: a burst of load on a shared machine is outvoted.  Measured: a quick
#: preset run flagged 3 of 60 cells of methods the change had not touched
#: (best and median 1.10-1.20); timed again, none had both above 1.10.
CONFIRM_SECONDS = 3.0


def _alternate(sides: Sequence[Side], mesh: str, n: int, method: str, options: dict, repeat: int,
               budget: float, min_seconds: float, times: dict[str, list[float]]) -> str | None:
    """Alternate single runs of the sides into ``times``; an error message or None."""
    t0 = time.perf_counter()
    i = 0
    while True:
        for s in (sides if i % 2 == 0 else list(reversed(sides))):
            got = s.runs(mesh, n, method, options, 1)
            if "error" in got:
                return f"{s.name}: {got['error']}"
            times[s.name] += got["ms"]
        i += 1
        elapsed = time.perf_counter() - t0
        if i >= MAX_RUNS or (i >= 3 and elapsed > budget) or (i >= repeat and elapsed >= min_seconds):
            return None


def measure_cell(sides: Sequence[Side], mesh: str, n: int, method: str, options: dict, repeat: int,
                 budget: float, tolerance: float) -> dict[str, Any]:
    """Warm both sides up, then alternate single runs: at least ``repeat`` each
    (fewer, but three, once ``budget`` seconds have passed), and more while
    the cell has taken less than :data:`MIN_SECONDS`.  A cell that looks
    regressed is measured :data:`CONFIRM_SECONDS` more and judged on all its
    runs (``rechecked`` then holds the first ratios)."""
    times: dict[str, list[float]] = {s.name: [] for s in sides}
    for s in sides:
        warm = s.runs(mesh, n, method, options, 1)
        if "error" in warm:
            return {"error": f"{s.name}: {warm['error']}"}
    err = _alternate(sides, mesh, n, method, options, repeat, budget, MIN_SECONDS, times)
    if err:
        return {"error": err}
    first = verdict(times["base"], times["head"], tolerance)
    if not first["regressed"]:
        return first
    err = _alternate(sides, mesh, n, method, options, repeat, max(budget, CONFIRM_SECONDS), CONFIRM_SECONDS,
                     times)
    if err:
        return {"error": err}
    return {**verdict(times["base"], times["head"], tolerance),
            "rechecked": (first["ratio"], first["median_ratio"])}


def table(rows: Sequence[dict[str, Any]], rev: str, tolerance: float) -> str:
    ok = [r for r in rows if "error" not in r]
    out = [f"## This glvox against {rev}, run by run",
           "",
           "Each timed run is one `run_method` call; the two sides take turns run by run in two processes "
           f"(after a warm-up each). A cell regresses when head's best and median both exceed base's by more "
           f"than {tolerance:.0%}; a cell that does is measured {CONFIRM_SECONDS:g} s more and judged again on "
           "all its runs.",
           "",
           "| method | mesh | N | runs | base best ms | head best ms | best ratio | median ratio | |",
           "|---|---|---|---|---|---|---|---|---|"]
    for r in ok:
        note = "**REGRESSED**" if r["regressed"] else ""
        if r.get("rechecked"):
            note = (note + " " if note else "") + "measured again (first: {:.2f} / {:.2f})".format(*r["rechecked"])
        out.append(f"| {r['key']} | {r['mesh']} | {r['n']} | {r['runs']} | {r['base_ms']:.1f} | "
                   f"{r['head_ms']:.1f} | {r['ratio']:.2f} | {r['median_ratio']:.2f} | {note} |")
    for r in rows:
        if "error" in r:
            out.append(f"\nnot compared: {r['key']} on {r['mesh']} {r['n']}^3 ({r['error']})")
    bad = [r for r in ok if r["regressed"]]
    out += ["", (f"- **NOT MET**: {len(bad)} of {len(ok)} cells regressed by more than {tolerance:.0%} "
                 f"against {rev}" if bad else
                 f"- **MET**: no method regresses by more than {tolerance:.0%} ({len(ok)} cells against {rev})")]
    return "\n".join(out)


def run_against(plan, rev: str, tolerance: float,
                progress: Callable[[str], None] = lambda s: None) -> tuple[list[dict[str, Any]], str]:
    """Time the glvox contenders of ``plan`` with glvox at ``rev`` and with this glvox."""
    root = source_root()
    contenders = [c for c in plan.contenders if not c.is_peer and not c.is_calibration]
    rows = []
    with tempfile.TemporaryDirectory(prefix="glvox-ab-") as tmp:
        base_src = extract_revision(rev, Path(tmp) / "base", root)
        workdir = Path(tmp) / "child"
        workdir.mkdir()
        sides = []
        try:
            sides = [Side("base", base_src, workdir), Side("head", root, workdir)]
            for mesh in plan.meshes:
                for n in plan.sizes:
                    for c in contenders:
                        progress(f"{c.label} on {Path(mesh).name} {n}^3")
                        r = measure_cell(sides, mesh, n, c.method, dict(c.options), plan.repeat, plan.budget,
                                         tolerance)
                        rows.append({"key": c.key, "mesh": Path(mesh).name, "n": n, **r})
        finally:
            for s in sides:
                s.close()
    if not any("error" not in r for r in rows):
        raise GlvoxError(f"no glvox cell ran in both {rev} and this glvox: nothing to compare")
    return rows, table(rows, rev, tolerance)
