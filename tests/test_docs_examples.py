"""Every example in README.md and docs/**/*.md runs as written.

The convention, for whoever writes a page
-----------------------------------------
Every fenced block names its language, and the language says whether it runs:

- ```python   runs.  The page's python blocks run in order in one namespace, in a
              fresh temporary working directory (the one its shell blocks use too),
              so a later block may use an earlier one's names and files.
- ```sh       runs.  Each line (``#`` comments dropped, ``&&`` chains split) is one
              command: ``glvox ...`` and ``.venv/bin/glvox ...`` go through
              :func:`glvox.cli.main` and must exit 0; the set-up commands in
              :data:`NOT_RUN` (installing, running the suite) are recognised and
              left alone; anything else fails this test: put it in a ``text`` block.
- ```text     is shown, never run: output, diagrams, commands that need a GPU,
              minutes or a network (long benchmarks).  Use it rarely.
- ```glsl     is shown, never run (a shader; docs/testing.md runs its own).

Blocks after a ``<!-- file: PATH -->`` line are files of docs/testing.md's example
project: they are written out and that project's tests run in a child pytest
(the last test below), not executed here.

Meshes named in a page (``glvox data list``) are found or fetched first
(:func:`glvox.testing.plugin.mesh_or_skip`: skipped with one line when not
available, failed where meshes are required).  Keep examples small (grids up to
64, ``gen:`` meshes or small shared ones): this whole file runs in well under a
minute on 2 cores with llvmpipe.
"""

from __future__ import annotations

import contextlib
import io
import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest

from glvox.cli import main
from glvox.datasets import mesh_names
from glvox.methods import FAMILIES
from glvox.methods.base import PASS_FAMILIES
from glvox.testing.plugin import mesh_or_skip

TOP = Path(__file__).resolve().parents[1]
DOC = TOP / "docs" / "testing.md"
PAGES = [TOP / "README.md", *sorted((TOP / "docs").rglob("*.md"))]

#: Fences: the language, the body; ``file`` set where a ``<!-- file: PATH -->`` line precedes it.
FENCE = re.compile(r"(?:<!-- file: (?P<file>[^ ]+) -->\n)?^```(?P<lang>[a-z]*)\n(?P<body>.*?)^```", re.S | re.M)
RUN = {"python", "sh"}
SHOWN = {"text", "glsl"}

#: Set-up commands a page may show in a ``sh`` block without this test running them.
NOT_RUN = ("bash .ci/setup", "pip install ", ".venv/bin/pip install ", "python3 -m venv ",
           ".venv/bin/python -m pytest")

BLOCK = re.compile(r"<!-- file: (?P<path>[^ ]+) -->\n```[a-z]*\n(?P<body>.*?)```", re.S)


def _rel(page: Path) -> str:
    return page.relative_to(TOP).as_posix()


def blocks(page: Path) -> list[tuple[str, str, str | None]]:
    """(language, body, file) of every fenced block of ``page``, in order."""
    return [(m["lang"], m["body"], m["file"]) for m in FENCE.finditer(page.read_text())]


def commands(body: str) -> list[str]:
    """The commands of a ``sh`` block: one per line and per ``&&``, comments dropped."""
    out = []
    for line in body.splitlines():
        words = shlex.split(line, comments=True)
        if not words:
            continue
        part: list[str] = []
        for word in [*words, "&&"]:
            if word == "&&":
                out.append(shlex.join(part))
                part = []
            else:
                part.append(word)
    return out


def run_cli(command: str) -> None:
    args = shlex.split(command)
    if args[0] == ".venv/bin/glvox":
        args[0] = "glvox"
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            rc = main(args[1:])
        except SystemExit as exc:  # argparse: --help exits 0, wrong usage 2
            rc = exc.code
    assert rc in (0, None), f"`{command}` exited {rc}:\n{err.getvalue()[-2000:]}"


RUNNABLE = [p for p in PAGES if any(lang in RUN and not f for lang, _, f in blocks(p))]


def test_every_fence_says_whether_it_runs():
    bad = [f"{_rel(p)}: ```{lang or '(none)'}" for p in PAGES for lang, _, _ in blocks(p)
           if lang not in RUN | SHOWN]
    assert not bad, f"every fenced block names python, sh (both run), text or glsl (shown): {bad}"


def test_the_pages_have_examples_that_run():
    """The README and the method pages are among the pages checked (a parser that found no
    block would make every other test here pass vacuously)."""
    names = {_rel(p) for p in RUNNABLE}
    assert "README.md" in names and "docs/methods/ss.md" in names and len(names) >= 10, names


@pytest.mark.parametrize("page", RUNNABLE, ids=_rel)
def test_page_examples_run(page, tmp_path, monkeypatch):
    runnable = [(lang, body) for lang, body, f in blocks(page) if lang in RUN and not f]
    text = "\n".join(body for _, body in runnable)
    for name in mesh_names():
        if name in text:
            mesh_or_skip(name)
    monkeypatch.chdir(tmp_path)
    namespace: dict = {"__name__": "__docs__"}
    for i, (lang, body) in enumerate(runnable):
        if lang == "python":
            exec(compile(body, f"{_rel(page)} block {i}", "exec"), namespace)
            continue
        for command in commands(body):
            if command.startswith(("glvox ", ".venv/bin/glvox ")):
                run_cli(command)
            else:
                assert command.startswith(NOT_RUN), \
                    f"{_rel(page)}: `{command}` is not a glvox command: put it in a ```text block"


#: The README's test command, which .ci/run runs as its last step.
TEST_COMMAND = ".venv/bin/python -m pytest -q -n 2"


def test_the_readme_test_command_is_what_ci_runs():
    readme = [c for lang, body, _ in blocks(TOP / "README.md") if lang == "sh" for c in commands(body)]
    ci = [line.strip() for line in (TOP / ".ci" / "run").read_text().splitlines()
          if line.strip() and not line.startswith("#")]
    assert TEST_COMMAND in readme and ci[-1] == TEST_COMMAND, ci
    assert any(c.startswith(".venv/bin/glvox voxelize") for c in readme), "the README's first command"


@pytest.mark.parametrize("family", sorted(FAMILIES + PASS_FAMILIES))
def test_every_family_page_names_its_methods(family):
    from glvox.methods import method_infos

    page = (TOP / "docs" / "methods" / f"{family}.md").read_text()
    missing = [i.name for i in method_infos() if i.family == family and f"`{i.name}`" not in page]
    assert not missing, f"docs/methods/{family}.md does not name {missing}"


def test_doc_links_resolve():
    bad = []
    for page in PAGES:
        for target in re.findall(r"\]\(([^)#\s]+)(?:#[^)]*)?\)", page.read_text()):
            if "://" not in target and not (page.parent / target).exists():
                bad.append(f"{_rel(page)} -> {target}")
    assert not bad, bad


# ---------------------------------------------------------------------------
# docs/testing.md: its files are written into a project folder and pytest runs them
# ---------------------------------------------------------------------------

def doc_files() -> dict[str, str]:
    return {m["path"]: m["body"] for m in BLOCK.finditer(DOC.read_text())}


def test_the_doc_holds_a_compute_and_a_fragment_shader_test():
    files = doc_files()
    assert set(files) == {"tests/shaders/double.comp", "tests/shaders/stripes.frag", "tests/shaders/broken.comp",
                          "tests/test_my_shaders.py"}
    assert "run_compute" in files["tests/test_my_shaders.py"] and "run_fragment" in files["tests/test_my_shaders.py"]


def test_the_doc_examples_pass_from_another_working_directory(tmp_path):
    """pytest runs in a child process from another working directory than the project's, with
    the plugin as installed, so the example also proves that ``search=`` folders are taken
    from the test file."""
    project = tmp_path / "my_project"
    for rel, body in doc_files().items():
        (project / rel).parent.mkdir(parents=True, exist_ok=True)
        (project / rel).write_text(body)
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    # -p no:dash: Dash (pulled in by Open3D, a peer of the test extras) installs a pytest
    # plugin that warns about its own hooks, which -W error would turn into a failure
    p = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "-p", "no:dash", "-W", "error",
                        str(project / "tests")], capture_output=True, text=True, cwd=elsewhere, timeout=300)
    assert p.returncode == 0 and "3 passed" in p.stdout, p.stdout + p.stderr
