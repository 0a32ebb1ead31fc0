"""ss-conservative's ``auto`` variant from a calibration measured on the GPU in use
(``glvox calibrate``, :mod:`glvox.methods.ss.variant_store`), else the llvmpipe rule."""

from __future__ import annotations

import json
import warnings

import pytest

import glvox
from glvox.cli import main
from glvox.errors import CalibrationWarning
from glvox.methods import run_method
from glvox.methods.ss import variant_store
from glvox.methods.ss.surface import LLVMPIPE_RULE, auto_variant, default_variant

#: A renderer string no driver reports: "another GPU" must never be the one the suite runs on
#: (it was an H100's string, and on that H100 this test saw its own calibration as another's).
OTHER = "glvox test renderer (not a GPU)"


@pytest.fixture
def store(tmp_path, monkeypatch):
    path = tmp_path / "cache" / "glvox" / "ss_variants.json"
    monkeypatch.setenv("GLVOX_CALIBRATION", str(path))
    return path


def entry(n, triangles, variant):
    return {"n": n, "dims": [n, n, n], "triangles": triangles, "density": triangles / n**2, "variant": variant,
            "best_ms": {}, "mesh": "test"}


def write(path, renderers):
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps({"version": 1, "renderers": renderers}))


def test_store_path_follows_xdg_cache_home(tmp_path, monkeypatch):
    monkeypatch.delenv("GLVOX_CALIBRATION")
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    assert variant_store.store_path() == tmp_path / "glvox" / "ss_variants.json"
    monkeypatch.delenv("XDG_CACHE_HOME")
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    assert variant_store.store_path() == tmp_path / "home" / ".cache" / "glvox" / "ss_variants.json"


def test_lookup_takes_the_nearest_density_band_of_this_renderer_only(store):
    # bands at F/N^2 = 9216 / 64^2 = 2.25 and 9216 / 512^2 = 0.035; their geometric middle is 0.28
    write(store, {"r": [entry(64, 9216, "specialized"), entry(512, 9216, "sorted")],
                  OTHER: [entry(64, 9216, "simple")]})
    assert variant_store.lookup("r", 9216, (64, 64, 64)).variant == "specialized"
    assert variant_store.lookup("r", 9216, (160, 160, 160)).variant == "specialized"  # 0.36: nearer 2.25
    assert variant_store.lookup("r", 9216, (200, 200, 200)).variant == "sorted"       # 0.23: nearer 0.035
    assert variant_store.lookup("r", 9216, (4096,) * 3).variant == "sorted"            # past the bands
    assert variant_store.lookup("r2", 9216, (64, 64, 64)) is None
    assert variant_store.lookup(OTHER, 10, (512,) * 3).variant == "simple"


def test_a_stored_calibration_of_this_renderer_changes_auto(gl_context, store):
    mesh = glvox.load_mesh("gen:torus")             # 9216 triangles: at 64^3 F/N^2 = 2.25, the rule says simple
    spec = glvox.grid_for(mesh, 64)
    assert default_variant(mesh.n_triangles, spec.dims) == "simple"
    plain = run_method("ss-conservative", mesh, spec, ctx=gl_context)
    assert plain.run.stats["variant"] == "simple" and plain.run.stats["variant_rule"] == LLVMPIPE_RULE

    write(store, {OTHER: [entry(64, 9216, "sorted")]})  # another GPU's choice: not this one's
    other = run_method("ss-conservative", mesh, spec, ctx=gl_context)
    assert other.run.stats["variant"] == "simple" and other.run.stats["variant_rule"] == LLVMPIPE_RULE

    variant_store.save(gl_context.renderer, [entry(64, 9216, "sorted")])
    assert set(variant_store.load()) == {OTHER, gl_context.renderer}  # the other renderer's entry kept
    mine = run_method("ss-conservative", mesh, spec, ctx=gl_context)
    assert mine.run.stats["variant"] == "sorted"
    assert mine.run.stats["variant_rule"].startswith(f"calibrated on this renderer ({store})")
    assert mine.equal(plain)
    # sorted cannot take more triangles than one indirect dispatch: the fallback still holds
    variant, rule = auto_variant(mesh.n_triangles, spec.dims, 1, gl_context.renderer)
    assert variant == "specialized" and rule.startswith("calibrated") and "too many triangles for sorted" in rule


@pytest.mark.parametrize("text, why", [
    ("{not json", "Expecting property name"),
    ('{"version": 2, "renderers": {}}', "not a version 1 calibration file"),
    ('{"version": 1, "renderers": {"R": [{"n": 64, "density": 2.0, "variant": "fastest"}]}}', "is not {n, density > 0, variant}"),
    ('{"version": 1, "renderers": {"R": [{"n": 64, "density": -1, "variant": "simple"}]}}', "is not {n, density > 0, variant}"),
    ('[]', "not a version 1"),
])
def test_a_corrupt_store_is_ignored_with_a_warning(gl_context, store, text, why):
    store.parent.mkdir(parents=True)
    store.write_text(text.replace('"R"', json.dumps(gl_context.renderer)))
    mesh = glvox.load_mesh("gen:torus")
    spec = glvox.grid_for(mesh, 64)
    with pytest.warns(CalibrationWarning, match=rf"ignoring the variant calibration {store} \(.*{why}"):
        g = run_method("ss-conservative", mesh, spec, ctx=gl_context)
    assert g.run.stats["variant"] == "simple" and g.run.stats["variant_rule"] == LLVMPIPE_RULE


def test_calibrate_measures_stores_and_auto_follows(gl_context, store, capsys):
    assert main(["calibrate", "--mesh", "gen:torus", "--sizes", "8", "24", "--repeat", "1"]) == 0
    out = capsys.readouterr().out
    entries = variant_store.load()[gl_context.renderer]
    assert [e["n"] for e in entries] == [8, 24] and all(e["mesh"] == "gen:torus" for e in entries)
    for e in entries:  # the stored winner is the fastest of the times stored beside it
        assert set(e["best_ms"]) == {"simple", "specialized", "sorted"}
        assert e["variant"] == min(e["best_ms"], key=e["best_ms"].get)
        assert e["density"] == pytest.approx(9216 / 8**2 if e["n"] == 8 else 9216 / 24**2)
    assert f"stored in {store}" in out and gl_context.renderer in out
    mesh = glvox.load_mesh("gen:torus")
    g = run_method("ss-conservative", mesh, glvox.grid_for(mesh, 24), ctx=gl_context)
    assert g.run.stats["variant"] == entries[1]["variant"] and g.run.stats["variant_rule"].startswith("calibrated")
    assert main(["calibrate", "--show"]) == 0
    shown = capsys.readouterr().out
    assert f"(gen:torus at 24^3): {entries[1]['variant']}" in shown


@pytest.mark.parametrize("args, message", [
    (["--sizes", "1"], "--sizes must be at least 2, got 1"),
    (["--repeat", "0"], "--repeat must be a positive integer, got 0"),
    (["--show", "--sizes", "8"], "--show prints what is stored; it takes no --mesh, --sizes or --repeat"),
    (["--mesh", "/nonexistent/x.obj"], "x.obj"),
])
def test_calibrate_refuses_bad_arguments_before_work(store, capsys, args, message):
    assert main(["calibrate", *args]) == 1
    err = capsys.readouterr().err
    assert err.startswith("glvox: error:") and message in err and len(err.strip().splitlines()) == 1
    assert not store.exists()


def test_the_tests_do_not_read_the_users_calibration():
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert variant_store.load() == {}  # conftest points GLVOX_CALIBRATION at no file
