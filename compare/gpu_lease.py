"""What a lent GPU machine without network needs to run compare/gpu_report.py, in one command.

    python compare/gpu_lease.py prepare       # here, with network: fetch it into folders git ignores
    python compare/gpu_lease.py command       # the one command to run there, and the folders to carry

The GPU machines this project is lent (an NVIDIA H200 image with CUDA, PyTorch
and pytest, no network; see the project's GPU notes) lack the GL loaders and
glvox's own Python packages, and a run there sends only the working tree.
``prepare`` puts beside the checkout, in folders it adds to ``.git/info/exclude``:

* ``.gl/``: Debian's vendor-neutral GL loaders (:data:`DEBS`, amd64), which the
  command unpacks over ``/`` (the NVIDIA driver's EGL library is there already);
* ``.whl/``: wheels of :data:`WHEELS` for CPython 3.12 on x86-64, at the versions
  installed here, which the command installs into ``/tmp/site``: moderngl and
  the packages the image lacks, and NVIDIA's cuda-core and cuda-bindings, so that
  ``device='cuda'`` runs with the versions tested here, not the image's own;
* ``.meshes/``: a copy of the shared meshes (``GLVOX_MESHES``), which do not
  travel with the tree;
* ``.peers/``: cuda_voxelizer, the CUDA voxelizer glvox is measured against
  (:data:`PEER_SOURCES`): the sources it and its mesh library trimesh2 need to
  build, and a binary built from them here where ``nvcc`` is at hand (machine
  code for sm_80 and sm_90, PTX for later GPUs, the CUDA runtime linked in).
  ``python compare/gpu_lease.py peer`` keeps that binary where it runs and
  otherwise builds it from the carried sources (a binary built on one image may
  not run on another's system libraries); the command runs it, and gives the
  binary to the report's ``peer`` step when it works.

``command`` prints the command (at most 2,000 characters, the device tool's
limit) and the folders to carry: it unpacks and installs the above, readies the
peer, points
``GLVOX_MESHES`` at ``.meshes``, loads glvox's pytest plugin by name (nothing is
pip-installed as a package there) and runs ``gpu_report.py`` into ``$OUT/r``
with ``--budget`` seconds (default 480, which leaves room in a 10-minute call
for the machine's own start-up work).  ``prepare --dry-run`` prints what it
would fetch without fetching.
"""

from __future__ import annotations

import argparse
import concurrent.futures
import importlib.metadata
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

#: The GL loaders the H100 and H200 images lacked (libEGL.so.1, libOpenGL.so.0, libGLdispatch.so.0 ...).
DEBS = ("libegl1", "libglvnd0", "libopengl0", "libgl1", "libglx0", "libgles2")

#: Python packages carried as wheels: glvox's needs the image lacks, and the cuda extra.
WHEELS = ("moderngl", "glcontext", "trimesh", "pooch", "platformdirs", "cuda-core", "cuda-bindings",
          "cuda-pathfinder")

#: pip's target for the device's Python (3.12, x86-64, manylinux).
PLATFORM = ["--only-binary=:all:", "--python-version", "3.12", "--implementation", "cp",
            "--platform", "manylinux_2_28_x86_64", "--platform", "manylinux_2_17_x86_64",
            "--platform", "manylinux2014_x86_64"]

#: The folders ``prepare`` fills and ``command`` carries.
CARRY = (".gl", ".whl", ".meshes", ".peers")

#: The peer the GPU-speed figures are measured against, and the mesh library it
#: reads with: repository and tag (cuda_voxelizer's v0.6 is the version glvox was
#: first compared with; trimesh2's tag is the one cuda_voxelizer's own CI builds).
PEER_SOURCES = {"cuda_voxelizer": ("https://github.com/Forceflow/cuda_voxelizer", "v0.6"),
                "trimesh2": ("https://github.com/Forceflow/trimesh2", "2022.03.04")}

#: What of each repository the build needs (about 2 MiB together).
PEER_KEEP = {"cuda_voxelizer": ("src", "LICENSE"), "trimesh2": ("include", "libsrc", "LICENSE", "COPYING")}

#: Machine code for the A100 (sm_80) and the H100 / H200 (sm_90), and sm_90 PTX that a
#: later GPU's driver compiles at start.  nvcc links the CUDA runtime statically by default.
CUDA_GENCODE = ("arch=compute_80,code=sm_80", "arch=compute_90,code=sm_90", "arch=compute_90,code=compute_90")

#: cuda_voxelizer's sources as its CMakeLists.txt lists them.
PEER_SRCS = ("src/main.cpp", "src/util_cuda.cpp", "src/util_io.cpp", "src/cpu_voxelizer.cpp",
             "src/libs/magicavoxel_file_writer/VoxWriter.cpp", "src/voxelize.cu", "src/voxelize_solid.cu")

#: The device tool's limits: a command's characters, the carried tree's bytes.
COMMAND_MAX = 2000
TREE_MAX = 64 << 20


def pinned() -> list[str]:
    """``name==version`` for each of :data:`WHEELS` as installed here (the versions the
    suite ran with); a package not installed here is fetched at its newest."""
    out = []
    for name in WHEELS:
        try:
            out.append(f"{name}=={importlib.metadata.version(name)}")
        except importlib.metadata.PackageNotFoundError:
            out.append(name)
    return out


def exclude(root: Path) -> None:
    """Add the carried folders to ``root``'s ``.git/info/exclude`` (once each)."""
    path = root / ".git" / "info" / "exclude"
    path.parent.mkdir(parents=True, exist_ok=True)
    have = path.read_text().splitlines() if path.exists() else []
    new = [f"/{d}/" for d in CARRY if f"/{d}/" not in have]
    if new:
        with open(path, "a") as f:
            f.write("".join(line + "\n" for line in new))


def fetch_commands(root: Path) -> list[list[str]]:
    """The commands ``prepare`` runs (apt-get for the debs, pip for the wheels)."""
    apt = ["apt-get", "-oAPT::Architecture=amd64", "-oAPT::Architectures=amd64", "download", *DEBS]
    pip = [sys.executable, "-m", "pip", "download", "--no-deps", *PLATFORM, "-d", str(root / ".whl"), *pinned()]
    return [apt, pip]


def tree_bytes(root: Path) -> int:
    """Bytes that travel: the tracked and untracked-not-ignored files, and the carried folders."""
    files = subprocess.run(["git", "ls-files", "-co", "--exclude-standard", "-z"], cwd=root, check=True,
                           capture_output=True).stdout.decode().split("\0")
    total = sum((root / f).stat().st_size for f in files if f and (root / f).is_file())
    for d in CARRY:
        total += sum(p.stat().st_size for p in (root / d).rglob("*") if p.is_file())
    return total


def fetch_peer_sources(dest: Path, repos: dict[str, str] | None = None) -> None:
    """Clone each of :data:`PEER_SOURCES` at its tag (from ``repos[name]`` where given) and
    keep what the build needs (:data:`PEER_KEEP`) in ``dest/<name>``."""
    repos = repos or {}
    with tempfile.TemporaryDirectory(prefix="glvox-peer-") as tmp:
        for name, (url, tag) in PEER_SOURCES.items():
            clone = Path(tmp) / name
            subprocess.run(["git", "-c", "advice.detachedHead=false", "clone", "-q", "--depth", "1", "--branch",
                            tag, repos.get(name, url), str(clone)], check=True)
            for part in PEER_KEEP[name]:
                src, dst = clone / part, dest / name / part
                dst.parent.mkdir(parents=True, exist_ok=True)
                if src.is_dir():
                    shutil.copytree(src, dst)
                else:
                    shutil.copy2(src, dst)


def peer_build_commands(src: Path, build: Path, binary: Path, nvcc: str = "nvcc") -> list[list[list[str]]]:
    """The build of cuda_voxelizer from ``src`` (:func:`fetch_peer_sources`), in stages whose
    commands may run side by side: trimesh2's library sources but its OpenGL viewer's
    (``GL*.cc``, which need GL headers), the archive, then cuda_voxelizer with nvcc."""
    tm, cv = src / "trimesh2", src / "cuda_voxelizer"
    objs = []
    compile_ = []
    for cc in sorted((tm / "libsrc").glob("*.cc")):
        if cc.name.startswith("GL"):
            continue
        obj = build / f"{cc.stem}.o"
        objs.append(obj)
        compile_.append(["g++", "-O3", "-fopenmp", "-std=c++17", "-I", str(tm / "include"), "-c", str(cc),
                         "-o", str(obj)])
    lib = build / "libtrimesh.a"
    archive = [["ar", "rcs", str(lib), *map(str, objs)]]
    gencode = [a for g in CUDA_GENCODE for a in ("-gencode", g)]
    link = [[nvcc, "-O3", "-DNDEBUG", "-std=c++17", "-Xcompiler", "-fopenmp,-O3", *gencode,
             "-I", str(tm / "include"), *(str(cv / f) for f in PEER_SRCS), "-L", str(build), "-ltrimesh",
             "-lgomp", "-o", str(binary)]]
    return [compile_, archive, link]


def find_nvcc() -> str | None:
    """nvcc on the PATH, or in the usual toolkit folder."""
    found = shutil.which("nvcc")
    if found:
        return found
    usual = Path("/usr/local/cuda/bin/nvcc")
    return str(usual) if usual.is_file() else None


def build_peer(src: Path, binary: Path) -> None:
    """Build cuda_voxelizer from ``src`` into ``binary`` (:func:`peer_build_commands`);
    CalledProcessError with the failing command's output, RuntimeError without nvcc."""
    missing = [f"{name}/{part}" for name, parts in PEER_KEEP.items() for part in parts
               if not (src / name / part).exists()]
    if missing:
        raise RuntimeError(f"no peer sources in {src} ({missing[0]} is missing)")
    nvcc = find_nvcc()
    if nvcc is None:
        raise RuntimeError("no nvcc on this machine")
    with tempfile.TemporaryDirectory(prefix="glvox-peer-build-") as build:
        binary.parent.mkdir(parents=True, exist_ok=True)
        for stage in peer_build_commands(src, Path(build), binary, nvcc):
            with concurrent.futures.ThreadPoolExecutor(max_workers=os.cpu_count() or 2) as pool:
                for proc in pool.map(lambda cmd: subprocess.run(cmd, capture_output=True, text=True), stage):
                    if proc.returncode != 0:
                        raise subprocess.CalledProcessError(proc.returncode, proc.args, proc.stdout, proc.stderr)


def peer_runs(binary: Path) -> str | None:
    """None when ``binary`` starts and prints cuda_voxelizer's banner (with no arguments it
    prints its help and exits 0); else why not, in one line."""
    if not binary.is_file():
        return f"no {binary}"
    try:
        p = subprocess.run([str(binary)], capture_output=True, text=True, timeout=60)
    except OSError as exc:
        return f"{binary} does not start: {exc}"
    except subprocess.TimeoutExpired:
        return f"{binary} did not return within 60 s"
    if p.returncode != 0 or "cuda voxelizer" not in p.stdout.lower():
        tail = " | ".join((p.stdout + p.stderr).strip().splitlines()[-2:])
        return f"{binary} exited with status {p.returncode}: {tail}"
    return None


def ensure_peer(folder: Path) -> int:
    """Keep ``folder``'s cuda_voxelizer where it runs, else build it from ``folder/src``;
    0 when a working binary is there at the end."""
    binary = folder / "cuda_voxelizer"
    why = peer_runs(binary)
    if why is None:
        print(f"peer: {binary} runs")
        return 0
    print(f"peer: {why}; building it from {folder / 'src'}", flush=True)
    try:
        build_peer(folder / "src", binary)
    except (RuntimeError, OSError) as exc:
        print(f"peer: not built: {exc}")
        return 1
    except subprocess.CalledProcessError as exc:
        tail = " | ".join((exc.stdout + exc.stderr).strip().splitlines()[-3:])
        print(f"peer: not built: {exc.cmd[0]} exited with status {exc.returncode}: {tail}")
        return 1
    why = peer_runs(binary)
    print(f"peer: built {binary}" + (f", but {why}" if why else ""))
    return 0 if why is None else 1


def prepare(root: Path, meshes: Path, dry_run: bool = False, peer: bool = True,
            repos: dict[str, str] | None = None) -> int:
    apt, pip = fetch_commands(root)
    if dry_run:
        print(" ".join(apt), "   # in .gl")
        print(" ".join(pip))
        print(f"copy {meshes}/* -> .meshes/")
        if peer:
            for name, (url, tag) in PEER_SOURCES.items():
                print(f"git clone --branch {tag} {(repos or {}).get(name, url)} -> .peers/src/{name}")
            print("build .peers/cuda_voxelizer with " + (find_nvcc() or "nvcc (absent here: on the device)"))
        return 0
    if not meshes.is_dir():
        sys.exit(f"no shared meshes at {meshes}: set GLVOX_MESHES")
    exclude(root)
    for d in CARRY:
        shutil.rmtree(root / d, ignore_errors=True)
        (root / d).mkdir()
    subprocess.run(apt, cwd=root / ".gl", check=True)
    subprocess.run(pip, check=True)
    for f in meshes.iterdir():
        if f.is_file():
            shutil.copy2(f, root / ".meshes" / f.name)
    if peer:
        fetch_peer_sources(root / ".peers" / "src", repos)
        if find_nvcc() is None:
            print("no nvcc here: the device command builds cuda_voxelizer from .peers/src")
        else:
            ensure_peer(root / ".peers")
    size = tree_bytes(root)
    print(f"travels: {size / 2**20:.1f} MiB of {TREE_MAX / 2**20:.0f} MiB")
    if size > TREE_MAX:
        print("over the device tool's limit: leave meshes out of .meshes", file=sys.stderr)
        return 1
    return 0


def command(budget: int = 480, steps: list[str] | None = None) -> str:
    """The device command: unpack, install, run gpu_report.py into $OUT/r (all its
    steps, or ``steps``)."""
    return ("for f in .gl/*.deb; do dpkg -x \"$f\" /; done; ldconfig; "
            "python3 -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade "
            "--target /tmp/site .whl/*.whl || exit 1; "
            "export PYTHONPATH=/tmp/site:$PWD GLVOX_MESHES=$PWD/.meshes PYTHONUNBUFFERED=1 "
            "PYTEST_ADDOPTS='-p glvox.testing.plugin'; "
            "[ -d .git ] || git init -q; nvidia-smi -L; cv=; "
            "python3 compare/gpu_lease.py peer && cv=\"--cuda-voxelizer $PWD/.peers/cuda_voxelizer\"; "
            f"python3 compare/gpu_report.py -o $OUT/r --budget {int(budget)}"
            + (f" --steps {' '.join(steps)}" if steps else "") + " $cv")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = ap.add_subparsers(dest="what", required=True)
    p = sub.add_parser("prepare", help="fetch the loaders, wheels and meshes into folders git ignores")
    p.add_argument("--meshes", type=Path, default=None, help="the shared meshes (default: GLVOX_MESHES)")
    p.add_argument("--dry-run", action="store_true", help="print what would be fetched")
    p.add_argument("--no-peer", action="store_true", help="leave cuda_voxelizer out")
    p.add_argument("--peer-repo", action="append", default=[], metavar="NAME=URL",
                   help=f"clone peer source NAME ({', '.join(PEER_SOURCES)}) from URL (a mirror)")
    sub.add_parser("peer", help="keep .peers/cuda_voxelizer where it runs, else build it from .peers/src")
    c = sub.add_parser("command", help="print the device command and the folders to carry")
    c.add_argument("--budget", type=int, default=480, help="gpu_report.py's budget in seconds")
    c.add_argument("--steps", nargs="+", help="gpu_report.py's steps (default: all)")
    args = ap.parse_args(argv)
    if args.what == "prepare":
        meshes = args.meshes or Path(os.environ.get("GLVOX_MESHES", ROOT.parent / "shared" / "meshes"))
        bad = [r for r in args.peer_repo if r.partition("=")[0] not in PEER_SOURCES or not r.partition("=")[2]]
        if bad:
            ap.error(f"--peer-repo takes NAME=URL with NAME one of {', '.join(PEER_SOURCES)}, got {bad[0]!r}")
        repos = dict(r.split("=", 1) for r in args.peer_repo)
        return prepare(ROOT, meshes, args.dry_run, not args.no_peer, repos)
    if args.what == "peer":
        return ensure_peer(ROOT / ".peers")
    print(command(args.budget, args.steps))
    print("carry:", " ".join(CARRY))
    return 0


if __name__ == "__main__":
    sys.exit(main())
