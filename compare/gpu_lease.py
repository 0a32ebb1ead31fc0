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
  travel with the tree.

``command`` prints the command (at most 2,000 characters, the device tool's
limit) and the folders to carry: it unpacks and installs the above, points
``GLVOX_MESHES`` at ``.meshes``, loads glvox's pytest plugin by name (nothing is
pip-installed as a package there) and runs ``gpu_report.py`` into ``$OUT/r``
with ``--budget`` seconds (default 480, which leaves room in a 10-minute call
for the machine's own start-up work).  ``prepare --dry-run`` prints what it
would fetch without fetching.
"""

from __future__ import annotations

import argparse
import importlib.metadata
import os
import shutil
import subprocess
import sys
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
CARRY = (".gl", ".whl", ".meshes")

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


def prepare(root: Path, meshes: Path, dry_run: bool = False) -> int:
    apt, pip = fetch_commands(root)
    if dry_run:
        print(" ".join(apt), "   # in .gl")
        print(" ".join(pip))
        print(f"copy {meshes}/* -> .meshes/")
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
    size = tree_bytes(root)
    print(f"travels: {size / 2**20:.1f} MiB of {TREE_MAX / 2**20:.0f} MiB")
    if size > TREE_MAX:
        print("over the device tool's limit: leave meshes out of .meshes", file=sys.stderr)
        return 1
    return 0


def command(budget: int = 480, steps: list[str] | None = None) -> str:
    """The device command: unpack, install, run gpu_report.py into $OUT/r (all its
    steps, or ``steps``)."""
    return ("set -o pipefail; for f in .gl/*.deb; do dpkg -x \"$f\" /; done; ldconfig; "
            "python3 -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade "
            "--target /tmp/site .whl/*.whl || exit 1; "
            "export PYTHONPATH=/tmp/site:$PWD GLVOX_MESHES=$PWD/.meshes PYTHONUNBUFFERED=1 "
            "PYTEST_ADDOPTS='-p glvox.testing.plugin'; "
            "[ -d .git ] || git init -q; nvidia-smi -L; "
            f"python3 compare/gpu_report.py -o $OUT/r --budget {int(budget)}"
            + (f" --steps {' '.join(steps)}" if steps else "") + " 2>&1 | tee $OUT/lease.log")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = ap.add_subparsers(dest="what", required=True)
    p = sub.add_parser("prepare", help="fetch the loaders, wheels and meshes into folders git ignores")
    p.add_argument("--meshes", type=Path, default=None, help="the shared meshes (default: GLVOX_MESHES)")
    p.add_argument("--dry-run", action="store_true", help="print what would be fetched")
    c = sub.add_parser("command", help="print the device command and the folders to carry")
    c.add_argument("--budget", type=int, default=480, help="gpu_report.py's budget in seconds")
    c.add_argument("--steps", nargs="+", help="gpu_report.py's steps (default: all)")
    args = ap.parse_args(argv)
    if args.what == "prepare":
        meshes = args.meshes or Path(os.environ.get("GLVOX_MESHES", ROOT.parent / "shared" / "meshes"))
        return prepare(ROOT, meshes, args.dry_run)
    print(command(args.budget, args.steps))
    print("carry:", " ".join(CARRY))
    return 0


if __name__ == "__main__":
    sys.exit(main())
