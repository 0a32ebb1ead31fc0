"""glvox.datasets and glvox data: meshes by name, found on disk or downloaded and checked.

The machine has no internet: downloads are tested against an HTTP server on
127.0.0.1 in a thread, which serves files from a dict and counts requests.
Synthetic sources (bytes made here, their SHA-256 computed here) test the
machinery; the real registry is checked against ../shared/meshes where it
is present.
"""

from __future__ import annotations

import gzip
import hashlib
import http.server
import os
import socket
import subprocess
import sys
import threading

import pytest

from glvox import datasets
from glvox.datasets import MeshSource
from glvox.errors import DatasetError


def glvox(*args, env=None, cwd=None):
    full = {**os.environ, **(env or {})}
    return subprocess.run([sys.executable, "-m", "glvox", *map(str, args)], capture_output=True, text=True,
                          timeout=600, env=full, cwd=cwd)


class _Server:
    """Files by URL path, the paths asked for, and the base URL."""

    def __init__(self):
        self.files: dict[str, bytes] = {}
        self.asked: list[str] = []
        files, asked = self.files, self.asked

        class Handler(http.server.BaseHTTPRequestHandler):
            def do_GET(self):
                asked.append(self.path)
                body = files.get(self.path)
                if body is None:
                    self.send_error(404)
                    return
                self.send_response(200)
                self.send_header("Content-Length", str(len(body)))
                self.end_headers()
                self.wfile.write(body)

            def log_message(self, *a):  # keep the test output clean
                pass

        self.httpd = http.server.ThreadingHTTPServer(("127.0.0.1", 0), Handler)
        self.url = f"http://127.0.0.1:{self.httpd.server_address[1]}"
        self.thread = threading.Thread(target=self.httpd.serve_forever, daemon=True)
        self.thread.start()

    def close(self):
        self.httpd.shutdown()
        self.httpd.server_close()


@pytest.fixture
def server():
    s = _Server()
    yield s
    s.close()


def _closed_port() -> int:
    """A port on 127.0.0.1 where nothing listens (bound, then released)."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _sha(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


@pytest.fixture
def fake(monkeypatch, tmp_path):
    """Register synthetic sources; GLVOX_MESHES = an empty folder; no memory of failed hosts."""
    monkeypatch.setattr(datasets, "_UNREACHABLE", {})
    data = tmp_path / "data"
    monkeypatch.setenv("GLVOX_MESHES", str(data))
    monkeypatch.delenv("GLVOX_DATA_MIRROR", raising=False)

    def add(name: str, body: bytes, **kw) -> MeshSource:
        src = MeshSource(name, "someone/repo", "c0ffee", kw.pop("path", f"models/{name}"), _sha(body), len(body),
                         "MIT", "someone", **kw)
        monkeypatch.setitem(datasets.SOURCES, name, src)
        return src

    add.data = data
    return add


def test_mirror_download_is_checked_kept_and_not_repeated(fake, server, monkeypatch):
    body = b"solid t\nendsolid t\n" * 10
    fake("tiny.stl", body)
    server.files["/mirror/tiny.stl"] = body
    monkeypatch.setenv("GLVOX_DATA_MIRROR", server.url + "/mirror/")
    path = datasets.fetch("tiny.stl", quiet=True)
    assert path == fake.data / "tiny.stl" and path.read_bytes() == body
    assert datasets.fetch("tiny.stl", quiet=True) == path and datasets.find("tiny.stl") == path
    assert server.asked == ["/mirror/tiny.stl"]          # the second fetch found it on disk
    assert sorted(p.name for p in fake.data.iterdir()) == ["tiny.stl"]


def test_companions_come_along(fake, server, monkeypatch):
    obj, mtl, jpg = b"mtllib a b.mtl\nv 0 0 0\n", b"map_Kd a uv.jpg\n", b"\xff\xd8jpeg"
    fake("a b.mtl", mtl)
    fake("a uv.jpg", jpg)
    fake("a.obj", obj, companions=("a b.mtl", "a uv.jpg"))
    server.files.update({"/m/a.obj": obj, "/m/a%20b.mtl": mtl, "/m/a%20uv.jpg": jpg})
    monkeypatch.setenv("GLVOX_DATA_MIRROR", server.url + "/m")
    assert datasets.fetch("a.obj", quiet=True).read_bytes() == obj
    assert (fake.data / "a b.mtl").read_bytes() == mtl and (fake.data / "a uv.jpg").read_bytes() == jpg
    (fake.data / "a uv.jpg").unlink()                  # a mesh without its texture is not found...
    assert datasets.find("a.obj") is None
    datasets.fetch("a.obj", quiet=True)                # ...and fetching brings back only what is missing
    assert server.asked == ["/m/a.obj", "/m/a%20b.mtl", "/m/a%20uv.jpg", "/m/a%20uv.jpg"]


def test_upstream_gzip_is_unpacked_and_checked(fake, server, monkeypatch):
    body = b"ply\nformat ascii 1.0\nend_header\n" * 50
    packed = gzip.compress(body)
    fake("dragon.ply", body, path="models/dragon.ply.gz", gz_sha256=_sha(packed))
    server.files["/raw/someone/repo/c0ffee/models/dragon.ply.gz"] = packed
    monkeypatch.setattr(datasets, "RAW_BASE", server.url + "/raw")
    assert datasets.fetch("dragon.ply", quiet=True).read_bytes() == body
    assert sorted(p.name for p in fake.data.iterdir()) == ["dragon.ply"]   # no .gz, no .part left


def test_upstream_gzip_that_unpacks_to_another_file(fake, server, monkeypatch):
    packed = gzip.compress(b"not the dragon")
    fake("dragon.ply", b"the dragon", path="models/dragon.ply.gz", gz_sha256=_sha(packed))
    server.files["/raw/someone/repo/c0ffee/models/dragon.ply.gz"] = packed
    monkeypatch.setattr(datasets, "RAW_BASE", server.url + "/raw")
    with pytest.raises(DatasetError, match=r"unpacked to a file that does not match dragon.ply's SHA-256; "
                                           r"nothing was kept"):
        datasets.fetch("dragon.ply", quiet=True)
    assert not [p for p in fake.data.iterdir() if p.name.startswith("dragon.ply") and p.suffix != ".gz"]


def test_hash_mismatch_is_one_line_and_keeps_nothing(fake, server, monkeypatch):
    fake("tiny.stl", b"the right bytes")
    server.files["/tiny.stl"] = b"the wrong bytes"
    monkeypatch.setenv("GLVOX_DATA_MIRROR", server.url)
    with pytest.raises(DatasetError) as e:
        datasets.fetch("tiny.stl", quiet=True)
    msg = str(e.value)
    assert "\n" not in msg and msg.startswith(f"the download of tiny.stl from {server.url}/tiny.stl does not "
                                              f"match its SHA-256 (expected {_sha(b'the right bytes')[:16]}")
    assert not any(fake.data.iterdir())


def test_missing_file_is_one_line(fake, server, monkeypatch):
    fake("tiny.stl", b"x")
    monkeypatch.setenv("GLVOX_DATA_MIRROR", server.url)
    with pytest.raises(DatasetError) as e:
        datasets.fetch("tiny.stl", quiet=True)
    assert str(e.value).startswith(f"cannot download mesh tiny.stl: {server.url}/tiny.stl answered HTTP 404; ")
    assert "\n" not in str(e.value)


def test_offline_is_one_line_and_remembered(fake, monkeypatch):
    fake("one.stl", b"1")
    fake("two.stl", b"2")
    base = f"http://127.0.0.1:{_closed_port()}"
    monkeypatch.setenv("GLVOX_DATA_MIRROR", base)
    with pytest.raises(DatasetError) as e:
        datasets.fetch("one.stl", quiet=True)
    assert str(e.value).startswith(f"mesh one.stl is not on this machine and cannot be downloaded: no "
                                   f"connection to {base} (Connection refused); get it where there is network "
                                   f"with `glvox data fetch one.stl`, set GLVOX_MESHES")
    with pytest.raises(DatasetError, match=r"could not be reached earlier \(Connection refused\)"):
        datasets.fetch("two.stl", quiet=True)       # no second wait for the same host


def test_lookup_order(fake, server, monkeypatch, tmp_path):
    """GLVOX_MESHES alone when set; else ../shared/meshes, then the user cache, where downloads go."""
    fake("tiny.stl", b"mirror")
    server.files["/tiny.stl"] = b"mirror"
    monkeypatch.setenv("GLVOX_DATA_MIRROR", server.url)
    shared, cache = tmp_path / "shared", tmp_path / "xdg"
    shared.mkdir()
    (shared / "tiny.stl").write_bytes(b"shared")
    monkeypatch.setattr(datasets, "shared_dir", lambda: shared)
    monkeypatch.setenv("XDG_CACHE_HOME", str(cache))
    fake.data.mkdir()
    (fake.data / "tiny.stl").write_bytes(b"env")
    assert datasets.fetch("tiny.stl").read_bytes() == b"env"           # GLVOX_MESHES wins
    monkeypatch.delenv("GLVOX_MESHES")
    assert datasets.fetch("tiny.stl").read_bytes() == b"shared"
    (shared / "tiny.stl").unlink()
    got = datasets.fetch("tiny.stl", quiet=True)                          # downloaded into the cache
    assert got.read_bytes() == b"mirror" and got.parent == cache / "glvox" == datasets.data_dir()
    assert datasets.search_dirs() == [shared, cache / "glvox"] and server.asked == ["/tiny.stl"]


def test_resolve_mesh(fake, tmp_path):
    assert datasets.resolve_mesh("gen:torus") == "gen:torus"
    f = tmp_path / "m.obj"
    f.write_text("v 0 0 0\n")
    assert datasets.resolve_mesh(f) == str(f)
    with pytest.raises(DatasetError, match=r"^mesh file not found: nope.obj \(nor is it a mesh name glvox knows"):
        datasets.resolve_mesh("nope.obj")
    with pytest.raises(DatasetError, match=r"^unknown mesh name 'nope.obj'; `glvox data list` shows the known"):
        datasets.fetch("nope.obj")


# ---------------------------------------------------------------------------
# the real registry
# ---------------------------------------------------------------------------


def _sources_md() -> dict[str, tuple[str, str, str, str]]:
    """file -> (repo, path, commit, licence) from the shared folder's SOURCES.md table."""
    md = datasets.shared_dir() / "SOURCES.md"
    if not md.is_file():
        pytest.skip(f"{md} not found: the registry is checked against the shared folder's SOURCES.md")
    rows = {}
    for line in md.read_text().splitlines():
        cells = [c.strip() for c in line.split("|")[1:-1]]
        if len(cells) < 5 or not cells[0].startswith("`"):
            continue
        files = [f.strip("` ") for f in cells[0].replace("(+", ",").rstrip(")").split(",")]
        paths = [p.strip("` ") for p in cells[2].replace(" (gunzipped)", "").split(",")]
        commit = cells[3].split()[0].strip("`")
        for name, path in zip(files, paths):
            rows[name] = (cells[1], path, commit, cells[4])
    return rows


def test_the_registry_is_sources_md():
    rows = _sources_md()
    assert set(rows) == set(datasets.SOURCES)
    for name, (repo, path, commit, licence) in rows.items():
        src = datasets.SOURCES[name]
        assert (src.repo, src.path, src.commit) == (repo, path, commit), name
    assert set(datasets.SHARED_MESHES) <= set(datasets.mesh_names())
    assert "CC BY-NC 3.0" in rows["messy_tower_holes.obj"][3] and datasets.SOURCES["messy_tower_holes.obj"] \
        .licence == "CC BY-NC 3.0"


def test_hashes_and_sizes_are_the_shared_copies():
    shared = datasets.shared_dir()
    present = [s for s in datasets.SOURCES.values() if (shared / s.name).is_file()]
    if not present:
        pytest.skip(f"no shared meshes in {shared}")
    for src in present:
        assert datasets.file_sha256(shared / src.name) == src.sha256, src.name
        assert (shared / src.name).stat().st_size == src.size, src.name


def test_a_real_mesh_through_a_mirror(server, monkeypatch, tmp_path):
    """The mirror layout is the shared folder's: a file served under its glvox name passes its real check."""
    shared = datasets.shared_dir() / "messy_soup_synthetic.stl"
    if not shared.is_file():
        pytest.skip(f"{shared} not found")
    monkeypatch.setattr(datasets, "_UNREACHABLE", {})
    server.files["/messy_soup_synthetic.stl"] = shared.read_bytes()
    env = {"GLVOX_MESHES": str(tmp_path / "d"), "GLVOX_DATA_MIRROR": server.url}
    p = glvox("data", "fetch", "messy_soup_synthetic.stl", env=env)
    assert p.returncode == 0, p.stderr
    assert p.stdout.strip() == str(tmp_path / "d" / "messy_soup_synthetic.stl")
    assert p.stderr.startswith(f"glvox: downloaded messy_soup_synthetic.stl (5 kB) from {server.url}/")
    p = glvox("data", "path", "messy_soup_synthetic.stl", env=env)
    assert p.returncode == 0 and p.stdout.strip() == str(tmp_path / "d" / "messy_soup_synthetic.stl")


# ---------------------------------------------------------------------------
# the command line and the test plugin
# ---------------------------------------------------------------------------


def test_data_list_shows_licences_and_credits(tmp_path):
    p = glvox("data", "list", env={"GLVOX_MESHES": str(tmp_path)})
    assert p.returncode == 0, p.stderr
    for name in datasets.mesh_names():
        src = datasets.SOURCES[name]
        block = p.stdout.split(name, 1)[1].split("\n    source:", 1)[0]
        assert "not on this machine" in block and f"licence: {src.licence}" in block and f"credit:  {src.credit}" \
            in block, name
    assert "fuze uv.jpg" not in p.stdout.split("source:")[0]   # companions are not meshes of their own


def test_no_network_and_no_meshes_is_one_line_before_work(tmp_path):
    env = {"GLVOX_MESHES": str(tmp_path / "empty"), "GLVOX_DATA_MIRROR": f"http://127.0.0.1:{_closed_port()}"}
    p = glvox("compare", "--preset", "quick", "-o", tmp_path / "out", env=env, cwd=tmp_path)
    lines = p.stderr.strip().splitlines()
    assert p.returncode == 1 and len(lines) == 1, p.stderr
    assert lines[0].startswith("glvox: error: mesh stanford_bunny_bun_zipper.ply is not on this machine and "
                               "cannot be downloaded: no connection to")
    assert "glvox data fetch stanford_bunny_bun_zipper.ply" in lines[0] and not (tmp_path / "out").exists()
    p = glvox("data", "path", "cad_wingnut.obj", env=env)
    assert p.returncode == 1 and p.stderr.strip() == (
        f"glvox: error: cad_wingnut.obj is not on this machine: `glvox data fetch cad_wingnut.obj` downloads it "
        f"into {tmp_path / 'empty'}")


TEST_FILE = '''
def test_needs_the_bunny(glvox_mesh):
    assert glvox_mesh("stanford_bunny_bun_zipper.ply").is_file()
'''


@pytest.mark.parametrize("require, ci", [("", ""), ("1", ""), ("", "true"), ("0", "true")])
def test_plugin_skips_with_one_line_or_fails_when_required(tmp_path, require, ci):
    """Locally a missing mesh skips with one line naming it and where it was looked for; with
    GLVOX_REQUIRE_MESHES=1 or CI=true (issue 20: CI must not pass by skipping) it fails with it."""
    (tmp_path / "test_x.py").write_text(TEST_FILE)
    env = {**os.environ, "GLVOX_MESHES": str(tmp_path / "empty"),
           "GLVOX_DATA_MIRROR": f"http://127.0.0.1:{_closed_port()}", "GLVOX_REQUIRE_MESHES": require, "CI": ci}
    p = subprocess.run([sys.executable, "-m", "pytest", "-q", "-rs", "-p", "no:cacheprovider", "test_x.py"],
                       capture_output=True, text=True, cwd=tmp_path, env=env, timeout=300)
    why = "mesh stanford_bunny_bun_zipper.ply is not on this machine and cannot be downloaded"
    where = f"(looked in {tmp_path / 'empty'})"
    lines = [ln for ln in p.stdout.splitlines() if why in ln]
    assert len(lines) == 1 and where in lines[0], p.stdout
    if require == "1":
        assert p.returncode == 1 and "1 failed" in p.stdout and f"GLVOX_REQUIRE_MESHES is set and {why}" in lines[0]
    elif ci and require == "":
        assert p.returncode == 1 and "1 failed" in p.stdout and f"CI is set (GLVOX_REQUIRE_MESHES=0 skips instead) " \
            f"and {why}" in lines[0]
    else:
        assert p.returncode == 0 and "1 skipped" in p.stdout, p.stdout


def test_a_folder_that_takes_no_files_is_one_line(fake, server, monkeypatch):
    fake("tiny.stl", b"x")
    server.files["/tiny.stl"] = b"x"
    monkeypatch.setenv("GLVOX_DATA_MIRROR", server.url)
    monkeypatch.setenv("GLVOX_MESHES", "/proc/glvox_meshes")   # /proc takes no new entries, even for root
    with pytest.raises(DatasetError, match=r"^cannot make the download folder /proc/glvox_meshes: "):
        datasets.fetch("tiny.stl", quiet=True)
    assert server.asked == []
