"""``glvox selftest``: passes on this machine, and names a method broken on purpose.

Kept to two or three methods per run (the whole registry takes about 11 s on
llvmpipe; that figure is measured with ``glvox selftest``, not here).
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from glvox import cli
from glvox.methods import get_method, method_infos
from glvox.results.voxels import VoxelGrid
from glvox.study.selftest import BOUNDS, _describe


def _run(capsys, *argv):
    rc = cli.main(["selftest", *argv])
    return rc, capsys.readouterr()


def test_selftest_passes_here(gl_context, capsys):
    rc, out = _run(capsys, "--methods", "ss-conservative", "peel-ldi", "karabassi", "--json")
    report = json.loads(out.out)
    assert rc == 0, out.out
    assert report["ok"] and report["renderer"] == gl_context.renderer
    rows = {r["method"]: r for r in report["methods"]}
    assert set(rows) == {"ss-conservative", "peel-ldi", "karabassi"}
    assert all(r["status"] == "ok" and r["mismatches"] == 0 and r["cases"] == len(report["cases"]) >= 4
               for r in rows.values())
    assert rows["peel-ldi"]["check"] == "exact vs reference-ldi"
    assert rows["karabassi"]["check"] == "bounded: contains reference-solid"


def test_the_table_starts_with_the_renderer(gl_context, capsys):
    rc, out = _run(capsys, "--methods", "ss-solid", "-q")
    lines = out.out.splitlines()
    assert rc == 0
    assert lines[0] == f"renderer:  {gl_context.renderer}" and lines[1].startswith("vendor:")
    assert any(l.split()[:1] == ["ss-solid"] and l.rstrip().endswith("ok") for l in lines)
    assert lines[-1].startswith("all methods agree with their checks")


def _broken(monkeypatch, name, change):
    """Make method ``name`` return ``change(dense)`` instead of its grid."""
    cls = type(get_method(name))
    run = cls.run

    def broken(self, mesh, spec, **kw):
        grid = run(self, mesh, spec, **kw)
        return VoxelGrid(change(grid.dense().copy()), spec)

    monkeypatch.setattr(cls, "run", broken)


def _flip_corner(dense):
    dense[0, 0, 0] = ~dense[0, 0, 0]
    return dense


def test_a_flipped_voxel_fails_and_names_the_method(gl_context, capsys, monkeypatch):
    _broken(monkeypatch, "ss-conservative", _flip_corner)
    rc, out = _run(capsys, "--methods", "ss-conservative", "ss-6sep", "-q")
    assert rc == 1
    assert "FAILED: ss-conservative" in out.out and "ss-6sep" not in out.out.splitlines()[-1]
    row = next(l for l in out.out.splitlines() if l.startswith("ss-conservative "))
    assert row.split()[-1] == "mismatch" and int(row.split()[-3]) >= 4  # one voxel on each case


def test_an_approximate_method_outside_its_bound_fails(gl_context, capsys, monkeypatch):
    """karabassi may add voxels to the exact solid, never lose them: an emptied grid fails."""
    _broken(monkeypatch, "karabassi", np.zeros_like)
    rc, out = _run(capsys, "--methods", "karabassi", "--json")
    report = json.loads(out.out)
    assert rc == 1 and not report["ok"]
    (row,) = report["methods"]
    assert row["method"] == "karabassi" and row["status"] == "mismatch" and row["mismatches"] > 0


@pytest.mark.parametrize("change, bad", [(lambda d: d, False), (_flip_corner, True), (np.zeros_like, True)])
def test_binvox_solid_may_differ_from_its_twin_on_ties_only(gl_context, capsys, monkeypatch, change, bad):
    """binvox-solid against reference-binvox up to its tie set: unchanged it passes; one
    voxel off in a corner no column of the mesh reaches fails, and so does an emptied grid."""
    _broken(monkeypatch, "binvox-solid", change)
    rc, out = _run(capsys, "--methods", "binvox-solid", "--json")
    (row,) = json.loads(out.out)["methods"]
    assert (rc, row["status"], row["mismatches"] > 0) == ((1, "mismatch", True) if bad else (0, "ok", False)), row


def test_every_approximate_method_has_a_bound():
    approximate = {i.name for i in method_infos() if not i.exact and i.family != "reference"}
    assert approximate == set(BOUNDS)
    for name in approximate:
        assert _describe(name).startswith("bounded")


def test_an_unknown_method_is_refused_before_any_work(capsys):
    rc, out = _run(capsys, "--methods", "nope")
    assert rc == 1 and out.err.startswith("glvox: error: unknown method 'nope'") and out.out == ""
