"""The package's layers: every import inside glvox points down the README's Layout list.

A module may import glvox modules of its own layer or of the layers listed
before it, never one listed after it, and nothing inside glvox imports the
package face (glvox/__init__.py).  Function-local imports count too: a lazy
import does not make an upward dependency acceptable.
"""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import pytest

from glvox.methods import FAMILIES, method_infos
from glvox.methods.base import PASS_FAMILIES, SHARED_SHADERS

ROOT = Path(__file__).resolve().parents[1] / "glvox"

#: The README's Layout order, lowest first.
LAYERS = ["_version", "errors", "tolerances", "progress", "grid", "meshfiles", "mesh", "traits", "visuals", "datasets",
          "results", "formats", "io", "gl", "gpu", "reference", "methods", "inspect", "metrics", "batch", "testing", "study",
          "preflight", "commands", "cli", "__main__"]


def _layer(module: str) -> str:
    """'glvox.gpu.sort' -> 'gpu'."""
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else "__init__"


def _is_submodule(name: str) -> bool:
    return (ROOT / name).is_dir() or (ROOT / f"{name}.py").is_file()


def _imports(path: Path) -> list[tuple[int, str]]:
    """(line, absolute module) of every glvox import in ``path``, relative ones resolved."""
    rel = path.relative_to(ROOT.parent).with_suffix("")
    package = list(rel.parts[:-1]) if rel.name != "__init__" else list(rel.parts[:-1])
    out = []
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom):
            if node.level:
                base = package[: len(package) - node.level + 1]
                mod = ".".join(base + ([node.module] if node.module else []))
            else:
                mod = node.module or ""
            if mod == "glvox" or mod.startswith("glvox."):
                names = [a.name for a in node.names]
                if mod == "glvox":  # `from glvox import x` / `from .. import x`: x is a submodule or the face
                    out += [(node.lineno, f"glvox.{n}" if _is_submodule(n) else "glvox") for n in names]
                else:
                    out.append((node.lineno, mod))
        elif isinstance(node, ast.Import):
            out += [(node.lineno, a.name) for a in node.names if a.name.startswith("glvox")]
    return out


#: Scripts run in a child process that use glvox as a user does, through the face.
THROUGH_THE_FACE = {
    "glvox/study/ab_child.py": "serves timed runs of any revision's glvox, old layouts included",
    "glvox/study/coldstart.py": "times a user's cold start, of which `import glvox` is part",
}

MODULES = sorted(p for p in ROOT.rglob("*.py") if p.name != "__init__.py" or p.parent != ROOT)


def test_every_module_is_in_a_layer():
    unknown = sorted({_layer(".".join(p.relative_to(ROOT.parent).with_suffix("").parts)) for p in MODULES}
                     - set(LAYERS))
    assert not unknown, f"add these to LAYERS in the README's order: {unknown}"


@pytest.mark.parametrize("path", MODULES, ids=lambda p: str(p.relative_to(ROOT.parent)))
def test_imports_point_down(path):
    own = _layer(".".join(path.relative_to(ROOT.parent).with_suffix("").parts))
    face_ok = path.relative_to(ROOT.parent).as_posix() in THROUGH_THE_FACE
    bad = []
    for line, mod in _imports(path):
        target = _layer(mod)
        if (target == "__init__" and not face_ok) or (target in LAYERS and LAYERS.index(target) > LAYERS.index(own)):
            bad.append(f"line {line}: {mod}")
    assert not bad, f"{path.name} ({own}) imports upward: {bad}"


def test_compare_scripts_import():
    """The by-hand scripts in compare/ are outside the package and no test runs them: their
    imports are checked here (each script's top level, not its main), so a module that moves
    in glvox/ cannot leave one broken."""
    scripts = sorted((ROOT.parent / "compare").glob("*.py"))
    assert scripts
    code = ("import runpy, sys\n"
            "for p in sys.argv[1:]:\n"
            "    runpy.run_path(p, run_name='glvox_import_check')\n")
    p = subprocess.run([sys.executable, "-c", code, *map(str, scripts)], capture_output=True, text=True,
                       timeout=300, cwd=ROOT.parent)
    assert p.returncode == 0, p.stderr[-2000:]


def test_every_mutant_still_applies():
    """compare/mutants.py patches source text: a mutant whose text moved or changed can no
    longer run, and nothing else would notice (the box-test mutants went stale when the
    shaders took `precise`, the depth-peel one when its module moved). Each patch must
    match its file exactly once and change it."""
    code = ("import runpy, sys\n"
            "m = runpy.run_path('compare/mutants.py', run_name='glvox_import_check')\n"
            "bad = []\n"
            "for mu in m['MUTANTS']:\n"
            "    text = open(mu.file).read()\n"
            "    for old, new in mu.patches:\n"
            "        if text.count(old) != 1 or old == new:\n"
            "            bad.append(f'{mu.id}: {old[:60]!r} x{text.count(old)}')\n"
            "print(len(m['MUTANTS']))\n"
            "sys.exit('\\n'.join(bad) or None)\n")
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120, cwd=ROOT.parent)
    assert p.returncode == 0, p.stderr[-2000:]
    assert int(p.stdout.split()[-1]) >= 30


# ---------------------------------------------------------------------------
# one vocabulary: a family's package, shaders, tests and page share its name
# ---------------------------------------------------------------------------

TOP = ROOT.parent
PACKAGES = sorted(p.name for p in (ROOT / "methods").iterdir() if (p / "__init__.py").is_file())


def test_every_method_package_is_a_family():
    assert PACKAGES == sorted(FAMILIES + PASS_FAMILIES), \
        "a package under glvox/methods/ is a method family (FAMILIES) or a pass family (PASS_FAMILIES)"
    loose = sorted(p.name for p in (ROOT / "methods").glob("*.py")
                   if p.stem not in ("__init__", "base", "envelope", "request"))
    assert not loose, f"modules of a family belong in its package glvox/methods/<family>/: {loose}"


@pytest.mark.parametrize("family", sorted(FAMILIES + PASS_FAMILIES))
def test_family_names_match(family):
    """The family's tests, and its shader folder where it has shaders, carry the package's name."""
    assert (TOP / "tests" / f"test_{family}.py").is_file(), f"tests of {family} belong in tests/test_{family}.py"
    uses = {line.split('"')[1].split("/")[0]
            for path in (ROOT / "methods" / family).glob("*.py")
            for line in path.read_text().splitlines() if '_program(' in line and '"' in line
            and "/" in line.split('"')[1]}
    own = uses - set(SHARED_SHADERS)
    assert own <= {family} | set(FAMILIES + PASS_FAMILIES), own
    if (TOP / "shaders" / family).is_dir():
        assert family in uses, f"glvox/methods/{family}/ loads no shader of shaders/{family}/"


def test_every_shader_folder_has_a_family():
    folders = sorted(p.name for p in (TOP / "shaders").iterdir() if p.is_dir() and p.name != "__pycache__")
    stray = [f for f in folders if f not in FAMILIES + PASS_FAMILIES + SHARED_SHADERS]
    assert not stray, f"shader folders named like no family: {stray}"


def test_every_family_registers_its_methods():
    """Every method family registers at least one method, and each method's family is its package."""
    by_family = {i.family for i in method_infos()}
    assert by_family == set(FAMILIES)


@pytest.mark.parametrize("family", sorted(FAMILIES + PASS_FAMILIES))
def test_every_family_has_a_docs_page(family):
    """docs/methods/<family>.md documents the family (its methods, papers, options, figures);
    tests/test_docs_examples.py checks that the page names each method and that its examples run."""
    assert (TOP / "docs" / "methods" / f"{family}.md").is_file(), f"document {family} in docs/methods/{family}.md"
    pages = sorted(p.stem for p in (TOP / "docs" / "methods").glob("*.md"))
    assert set(pages) <= set(FAMILIES + PASS_FAMILIES), f"pages named like no family: {pages}"


# ---------------------------------------------------------------------------
# one vocabulary for GPU bindings: the shader's block names, never numbers by hand
# ---------------------------------------------------------------------------

#: The only modules that may call ``bind_to_storage_buffer`` themselves: the helper that binds by
#: block name, and the test harness whose public ``buffers=`` may still be keyed by binding number.
BINDS_BY_NUMBER = {"glvox/gpu/dispatch.py", "glvox/testing/harness.py"}


def test_storage_buffers_are_bound_by_block_name():
    """A pass binds its buffers with ``glvox.gpu.dispatch.bind(prog, Block=buf)``, which reads
    each binding from the program: a number written by hand next to the GLSL's can drift from it."""
    bad = []
    for path in MODULES:
        rel = path.relative_to(TOP).as_posix()
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if not (isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute)
                    and node.func.attr == "bind_to_storage_buffer"):
                continue
            literal = any(isinstance(n, ast.Constant) for a in node.args for n in ast.walk(a))
            if rel not in BINDS_BY_NUMBER or literal:
                bad.append(f"{rel}:{node.lineno}")
    assert not bad, f"bind storage buffers by block name (glvox.gpu.dispatch.bind): {bad}"


#: The only module that may call a moderngl buffer's ``clear``: the helper that falls back to it.
CLEARS_ON_THE_HOST = {"glvox/gpu/buffers.py"}


def test_buffers_are_cleared_on_the_gpu():
    """moderngl's ``Buffer.clear(size=...)`` maps the buffer and fills it on the host (on a GPU
    with its own memory: a wait and a trip over the bus); passes clear with
    ``glvox.gpu.buffers.clear_buffer`` (glClearNamedBufferSubData).  A call with ``size=`` or
    ``chunk=`` is a buffer's clear (a dict's or a framebuffer's takes neither)."""
    bad = []
    for path in MODULES:
        rel = path.relative_to(TOP).as_posix()
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if (isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute) and node.func.attr == "clear"
                    and any(k.arg in ("size", "chunk", "offset") for k in node.keywords)
                    and rel not in CLEARS_ON_THE_HOST):
                bad.append(f"{rel}:{node.lineno}")
    assert not bad, f"clear buffers with glvox.gpu.buffers.clear_buffer: {bad}"
