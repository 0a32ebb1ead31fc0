"""A second GL implementation on any machine with Mesa: softpipe, and the behaviour probes.

Mesa ships two software rasterizers in the same driver package: llvmpipe (what
the suite runs on) and softpipe, a separate implementation (its own rasterizer,
tile cache and shader interpreter, no LLVM).  softpipe advertises GL 3.3;
``MESA_GL_VERSION_OVERRIDE=4.5`` lifts that, and every compute method then runs
on it.  It found three things llvmpipe never shows (and one more, about the GL
error moderngl leaves: below):

* rendered pixels stay in softpipe's tile cache when a compute dispatch fetches
  the texture: the depth-buffer, LDI and binvox methods read empty layers and
  returned empty or wrong solids.  GL orders framebuffer writes before later reads by
  itself; glvox now puts a barrier after every draw whose targets are read
  (``glvox.gpu.dispatch.rendered``), which such a driver needs and a
  conforming one ignores.
* ``glLogicOp(GL_XOR)`` onto its RGBA32UI targets writes zeros: eisemann-* and
  leung-wang-ldi returned empty results with no GL error.  That is the driver's
  bug; glvox probes the behaviour once per context (``glvox.gpu.behaviours``)
  and refuses those methods in one line, naming what runs instead.
* its shader interpreter got a loop over a word's 32 bits wrong where neighbouring
  invocations left it by ``break`` at different bits (the last word of a row
  whose length is not a multiple of 32): passalis-stencil marked voxels
  unclassifiable that were not, and binvox-solid's parity vote came out empty.
  The loops now run to their bound (``depth/combine.comp``,
  ``binvox/combine.comp``), and the selftest has a case that reaches them.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys

import numpy as np
import pytest

from glvox.errors import CapabilityError
from glvox.gpu.behaviours import PROBES, broken
from glvox.mesh import load_mesh
from glvox.methods import method_infos, run_method
from glvox.grid import grid_for
from glvox.testing.gl_limits import PUBLISHED, FakeContext

SOFTPIPE = {"GALLIUM_DRIVER": "softpipe", "MESA_GL_VERSION_OVERRIDE": "4.5", "MESA_GLSL_VERSION_OVERRIDE": "450"}
#: The methods needing the logic op on integer targets (Requirements.behaviours).
LOGIC_OP = {"eisemann-solid", "eisemann-surface", "leung-wang-ldi"}


def test_the_logic_op_behaviour_holds_here(gl_context):
    assert broken(gl_context, "integer-logic-op") is None


def test_the_methods_that_need_the_logic_op_declare_it():
    assert {i.name for i in method_infos() if "integer-logic-op" in i.requires.behaviours} == LOGIC_OP


def test_published_contexts_hold_the_probes_answers():
    """A fake context (published limits, no GL behind it) answers every probe without
    running it, so the capability tables stay checkable on any machine."""
    for p in PUBLISHED:
        ctx = FakeContext(p)
        assert all(broken(ctx, name) is None for name in PROBES)


def test_a_broken_logic_op_is_found_and_refuses_before_any_work(gl_context, monkeypatch):
    """A context whose glLogicOp does nothing (each draw overwrites the target) fails the
    probe; the methods that need it are refused in one line that names the behaviour, what
    the context did, and what runs instead, and the others still run."""
    monkeypatch.setitem(gl_context.caches, "behaviours", {})  # a fresh context's: the probe runs
    monkeypatch.setattr(type(gl_context.raw), "set_logic_op", lambda self, op: None)
    why = broken(gl_context, "integer-logic-op")
    assert why is not None and why.startswith("glLogicOp(XOR) onto an RGBA32UI render target gives other words")
    mesh = load_mesh("gen:torus")
    spec = grid_for(mesh, 16)
    for name, instead in (("eisemann-solid", "passalis-peel"), ("eisemann-surface", "ss-conservative")):
        with pytest.raises(CapabilityError) as err:
            run_method(name, mesh, spec)
        msg = str(err.value)
        assert msg.startswith(f"method {name!r} needs integer-logic-op: glLogicOp(XOR)"), msg
        assert msg.endswith(f"'{instead}' runs on this context instead") and "\n" not in msg
    with pytest.raises(CapabilityError):
        run_method("leung-wang-ldi", mesh, spec)
    assert run_method("ss-solid", mesh, spec).count > 0


@pytest.fixture(scope="module")
def softpipe() -> dict:
    """``glvox info --json`` with softpipe asked for; skips where that is not softpipe."""
    proc = subprocess.run([sys.executable, "-m", "glvox", "info", "--json"], capture_output=True, text=True,
                          env={**os.environ, **SOFTPIPE}, timeout=120)
    info = json.loads(proc.stdout) if proc.returncode == 0 else {}
    if info.get("renderer") != "softpipe":
        pytest.skip(f"Mesa's softpipe is not what GALLIUM_DRIVER=softpipe gives here ({info.get('renderer')!r})")
    return info


def test_a_new_softpipe_context_has_no_gl_error_pending(softpipe):
    """moderngl's info leaves GL_INVALID_ENUM on softpipe (a limit it does not know); the
    context factory takes it, so glvox's own error checks see only glvox's calls."""
    code = "from glvox.gl.context import get_context; c = get_context(); c.limits(); print(c.mgl.error)"
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          env={**os.environ, **SOFTPIPE}, timeout=120)
    assert proc.stdout.split() == ["GL_NO_ERROR"], proc.stderr[-2000:]


def test_softpipe_runs_the_raster_methods_and_refuses_the_logic_op_ones(softpipe):
    """On softpipe, the depth-buffer methods and peel-ldi equal their references (they
    returned empty solids before the barrier after their draws), and the logic-op methods
    are refused, not empty: the selftest says so, method by method."""
    assert softpipe["behaviours"]["integer-logic-op"].startswith("glLogicOp(XOR) onto an RGBA32UI render target")
    methods = ["karabassi", "passalis-peel", "passalis-stencil", "peel-ldi", "ss-solid", *sorted(LOGIC_OP)]
    proc = subprocess.run([sys.executable, "-m", "glvox", "selftest", "--json", "--methods", *methods],
                          capture_output=True, text=True, env={**os.environ, **SOFTPIPE}, timeout=600)
    assert proc.returncode == 1, proc.stderr[-2000:]
    report = json.loads(proc.stdout)
    assert report["renderer"] == "softpipe"
    rows = {r["method"]: r for r in report["methods"]}
    for name in methods:
        row = rows[name]
        if name in LOGIC_OP:
            assert row["status"] == "refused" and len(row["detail"]) == 1, row
            assert "needs integer-logic-op: glLogicOp(XOR)" in row["detail"][0], row
        else:
            assert row["status"] == "ok" and row["mismatches"] == 0 and row["cases"] == len(report["cases"]), row
    assert rows["ties"]["status"] == "ok" and rows["arithmetic"]["status"] == "ok"


def test_binvox_parity_vote_on_softpipe(softpipe, tmp_path):
    """binvox-solid's parity vote (binvox -v) on softpipe equals reference-binvox on a grid
    whose rows end inside a word (40 voxels): it came out empty there before."""
    mesh = load_mesh("gen:torus")
    spec = grid_for(mesh, dims=(40, 36, 32))
    want = run_method("reference-binvox", mesh, spec, mode="vote").dense()
    out = tmp_path / "vote.npz"
    proc = subprocess.run([sys.executable, "-m", "glvox", "voxelize", "gen:torus", "--dims", "40", "36", "32",
                           "-m", "binvox-solid", "-O", "mode=vote", "-o", str(out), "-q"],
                          capture_output=True, text=True, env={**os.environ, **SOFTPIPE}, timeout=600)
    assert proc.returncode == 0, proc.stderr[-2000:]
    got = np.load(out)["occupancy"]
    assert want.sum() > 0 and np.array_equal(got, want), int((got ^ want).sum())
