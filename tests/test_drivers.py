"""Other GL implementations on any machine with Mesa: softpipe, zink and OSMesa, and the behaviour probes.

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

zink, Mesa's OpenGL over Vulkan, runs here on lavapipe (Mesa's Vulkan driver on
the CPU), unpacked by ``.ci/drivers`` with libOSMesa (the OSMesa backend's
selftest runs here too).  With its inlined uniforms on it dispatched
a compute program with another program's uniform values: ss-solid-tiled, solid,
binvox-solid and the mapped readback failed the selftest.  glvox turns the
inlining off (``glvox.gl.context.DRIVER_DEFAULTS``) and probes the behaviour for
every GL method (``uniform-update``).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys

import numpy as np
import pytest

from glvox.errors import CapabilityError
from glvox.gl.context import DRIVER_DEFAULTS
from glvox.gpu.behaviours import PROBES, UNIFORM_STEPS, broken, uniform_branch_word, uniform_update_errors
from glvox.mesh import load_mesh
from glvox.methods import method_infos, run_method
from glvox.grid import grid_for
from glvox.testing.drivers import SOFTPIPE, osmesa_library, unpacked_dir, zink_env
from glvox.testing.gl_limits import PUBLISHED, FakeContext

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


class _InlinedUniforms:
    """A model of zink's inlined uniforms (Mesa 22.3): the values a dispatch's branches
    see are the context's, updated only where a program's uniforms are set, not where
    a program is bound again with the values it holds."""

    def __init__(self, stale: bool):
        self.stale = stale
        self.held: list[tuple | None] = [None, None]
        self.inlined: tuple | None = None

    def dispatch(self, prog: int, values) -> int:
        if values is not None:
            self.held[prog] = self.inlined = values
        elif not self.stale:
            self.inlined = self.held[prog]
        return uniform_branch_word(prog, *self.inlined)


def test_the_uniform_probe_tells_a_stale_driver_from_a_right_one():
    """The probe's sequence passes the right model and finds the stale one where, worked
    by hand, it must: dispatches 7, 10 and 13 reuse their program's values right after
    the other program was given others (14 reuses them after its own program ran: the
    stale model gets that one right, as zink did)."""
    assert uniform_update_errors(_InlinedUniforms(stale=False).dispatch) == []
    errors = uniform_update_errors(_InlinedUniforms(stale=True).dispatch)
    assert [e.split(" (")[0] for e in errors] == ["dispatch 7", "dispatch 10", "dispatch 13"], errors
    assert all("unchanged since its last dispatch" in e for e in errors)
    assert sum(v is None for _, v in UNIFORM_STEPS) == 4


def test_the_uniform_probe_passes_here(gl_context):
    """The probe passes on this context: testing/uniform_branch.comp writes what
    uniform_branch_word says on each of its four branches (the sequence takes each)."""
    assert broken(gl_context, "uniform-update") is None


def test_every_gl_method_is_refused_where_uniforms_go_stale(gl_context, monkeypatch):
    """A context that fails uniform-update refuses every GL method in one line, naming
    the CPU reference that runs instead; CPU methods still run."""
    monkeypatch.setitem(gl_context.caches, "behaviours", {"uniform-update": "stale (test)"})
    mesh = load_mesh("gen:torus")
    spec = grid_for(mesh, 16)
    with pytest.raises(CapabilityError) as err:
        run_method("ss-conservative", mesh, spec)
    msg = str(err.value)
    assert msg.startswith("method 'ss-conservative' needs uniform-update: stale (test)"), msg
    assert msg.endswith("'reference-conservative' runs on this context instead"), msg
    for info in method_infos():
        if info.uses_gl:
            assert any(m.startswith("uniform-update") for m in info.requires.missing(gl_context)), info.name
    assert run_method("reference-conservative", mesh, spec).count > 0


def test_zink_inlined_uniforms_are_off_unless_the_user_says():
    """The context factory sets ZINK_INLINE_UNIFORMS=0 before the driver reads it, and
    leaves a value the environment gives alone; glvox info says which it was."""
    code = ("import json; from glvox.gl.context import create_context, driver_settings; create_context(); "
            "print(json.dumps(driver_settings()))")
    env = {k: v for k, v in os.environ.items() if k not in DRIVER_DEFAULTS}
    for given, want in ((None, {"value": "0", "set_by": "glvox"}), ("1", {"value": "1", "set_by": "environment"})):
        e = env if given is None else {**env, "ZINK_INLINE_UNIFORMS": given}
        proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=e, timeout=120)
        assert proc.returncode == 0, proc.stderr[-2000:]
        assert json.loads(proc.stdout.splitlines()[-1]) == {"ZINK_INLINE_UNIFORMS": want}


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


#: A box that one axis's view sees at another size than the next axis's view, all else alike
#: (grid 3 x 3 x 8 of unit voxels; the x and y views are 3 x 8 and 8 x 3 pixels).
VIEW_SIZES_CHECK = """
import json, trimesh
from glvox.grid import GridSpec
from glvox.mesh import load_mesh
from glvox.methods import run_method
box = trimesh.creation.box(bounds=[[0.2, 0.2, 0.3], [2.7, 2.7, 7.6]])
mesh = load_mesh((box.vertices, box.faces), name="box")
spec = GridSpec((3, 3, 8), (0, 0, 0), 1.0)
out = {}
for name, ref in (("karabassi", "reference-solid"), ("passalis-stencil", "reference-solid"),
                  ("passalis-peel", "reference-solid"), ("binvox-solid", "reference-binvox")):
    got, want = run_method(name, mesh, spec).dense(), run_method(ref, mesh, spec).dense()
    out[name] = [int(want.sum()), int((got ^ want).sum())]
print(json.dumps(out))
"""


def test_softpipe_draws_views_of_different_sizes(softpipe):
    """On softpipe, a raster view drawn after a view of another size drew nothing where
    only the geometry stage's uniforms changed between them (its size among them): this
    box came out empty from the depth-buffer methods.  The old depth keys' per-view
    doubles had hidden it where the mesh's extents differ along the axes.  The fragment
    stage now clamps its pixel to the view's size, so that the size is its uniform too."""
    proc = subprocess.run([sys.executable, "-c", VIEW_SIZES_CHECK], capture_output=True, text=True,
                          env={**os.environ, **SOFTPIPE}, timeout=600)
    assert proc.returncode == 0, proc.stderr[-2000:]
    for name, (voxels, off) in json.loads(proc.stdout).items():
        assert voxels == 72 and off == 0, (name, voxels, off)


@pytest.fixture(scope="module")
def zink() -> dict[str, str]:
    """The zink environment (:func:`zink_env`); skips where it does not give zink."""
    env = zink_env()
    if env is None:
        pytest.skip(f"no lavapipe unpacked at {unpacked_dir()} (bash .ci/drivers unpacks it)")
    proc = subprocess.run([sys.executable, "-m", "glvox", "info", "--json"], capture_output=True, text=True,
                          env=env, timeout=120)
    info = json.loads(proc.stdout) if proc.returncode == 0 else {}
    if not info.get("renderer", "").startswith("zink"):
        pytest.skip(f"the lavapipe environment does not give zink here ({info.get('renderer')!r}: "
                    f"{proc.stderr.strip()[-300:]})")
    return env


def test_zink_passes_the_selftest(zink):
    """Every method equals its check on zink (GL over Vulkan, lavapipe) on every selftest
    case, the readback row included.  With zink's inlined uniforms on (Mesa 22.3's
    default before glvox turned them off) four rows failed: ss-solid-tiled returned empty
    solids once ss-conservative's sorted variant had set the shared dispatch-arguments
    program's branch uniform, binvox-solid and solid lost voxels, and the mapped readback
    differed from glGetBufferSubData's words."""
    proc = subprocess.run([sys.executable, "-m", "glvox", "selftest", "--json"], capture_output=True, text=True,
                          env=zink, timeout=600)
    report = json.loads(proc.stdout)
    assert report["renderer"].startswith("zink")
    bad = [(r["method"], r["status"], r["detail"][:3]) for r in report["methods"] if r["status"] != "ok"]
    assert proc.returncode == 0 and not bad, bad


def test_zink_with_inlined_uniforms_refuses_every_gl_method(zink, tmp_path):
    """Where the user turns zink's inlined uniforms back on, the probe finds the stale
    values: glvox info says so, and a voxelization is refused in one line naming the
    variable and the CPU reference that runs instead."""
    env = {**zink, "ZINK_INLINE_UNIFORMS": "1"}
    proc = subprocess.run([sys.executable, "-m", "glvox", "info", "--json"], capture_output=True, text=True,
                          env=env, timeout=120)
    why = json.loads(proc.stdout)["behaviours"]["uniform-update"]
    assert why.startswith("a compute program dispatched with other uniform values than it holds"), why
    assert "ZINK_INLINE_UNIFORMS=0" in why
    out = tmp_path / "torus.npz"
    proc = subprocess.run([sys.executable, "-m", "glvox", "voxelize", "gen:torus", "-r", "16", "-o", str(out), "-q"],
                          capture_output=True, text=True, env=env, timeout=120)
    errors = [line for line in proc.stderr.splitlines() if line.startswith("glvox: error:")]
    assert proc.returncode != 0 and not out.exists() and len(errors) == 1, proc.stderr[-2000:]
    assert "needs uniform-update" in errors[0] and "'reference-conservative' runs on this context instead" in errors[0]


def test_the_osmesa_backend_passes_the_selftest():
    """glvox's OSMesa backend (its fallback where EGL fails) gives a context on which
    every method equals its check on every selftest case."""
    lib = osmesa_library()
    if lib is None:
        pytest.skip(f"no libOSMesa installed or unpacked at {unpacked_dir()} (bash .ci/drivers unpacks it)")
    # GALLIUM_DRIVER left out: OSMesa runs llvmpipe only (a suite run on zink sets it)
    env = {**{k: v for k, v in os.environ.items() if k != "GALLIUM_DRIVER"}, "GLVOX_BACKEND": "osmesa",
           "GLVOX_OSMESA": lib}
    proc = subprocess.run([sys.executable, "-m", "glvox", "selftest", "--json"], capture_output=True, text=True,
                          env=env, timeout=600)
    assert proc.returncode == 0, proc.stderr[-2000:]
    report = json.loads(proc.stdout)
    info = json.loads(subprocess.run([sys.executable, "-m", "glvox", "info", "--json"], capture_output=True,
                                     text=True, env=env, timeout=120).stdout)
    assert info["backend"] == "osmesa" and report["ok"]
