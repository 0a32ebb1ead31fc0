"""docs/testing.md runs: its files are written into a project folder and pytest runs them.

Every fenced block after a ``<!-- file: PATH -->`` line is one file of the
example project.  pytest runs in a child process from another working
directory than the project's, with the plugin as installed, so the example
also proves that ``search=`` folders are taken from the test file.
"""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

DOC = Path(__file__).resolve().parents[1] / "docs" / "testing.md"

BLOCK = re.compile(r"<!-- file: (?P<path>[^ ]+) -->\n```[a-z]*\n(?P<body>.*?)```", re.S)


def doc_files() -> dict[str, str]:
    return {m["path"]: m["body"] for m in BLOCK.finditer(DOC.read_text())}


def test_the_doc_holds_a_compute_and_a_fragment_shader_test():
    files = doc_files()
    assert set(files) == {"tests/shaders/double.comp", "tests/shaders/stripes.frag", "tests/shaders/broken.comp",
                          "tests/test_my_shaders.py"}
    assert "run_compute" in files["tests/test_my_shaders.py"] and "run_fragment" in files["tests/test_my_shaders.py"]


def test_the_doc_examples_pass_from_another_working_directory(tmp_path):
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
