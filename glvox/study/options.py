"""The command lines of ``glvox compare``, ``glvox bench`` and ``glvox calibrate``: presets, defaults, arguments.

``glvox.cli`` builds every subcommand's parser at start-up, so this module
imports nothing but argparse, pathlib and glvox's tolerances and errors: the runner, the peers,
the tables and the plots are imported only when ``compare`` or ``bench``
actually runs.
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path
from typing import Any

from glvox.errors import GlvoxError
from glvox.tolerances import REGRESSION_TOLERANCE

# -- glvox calibrate -------------------------------------------------------------

#: ``glvox calibrate``'s defaults: the mesh, the grid sizes, the timed rounds.
CALIBRATE_MESH = "stanford_bunny_bun_zipper.ply"
CALIBRATE_SIZES = (64, 128, 256, 512)
CALIBRATE_REPEAT = 5

# -- glvox compare ---------------------------------------------------------------

#: Largest grid on which ``glvox compare`` checks results against the CPU
#: references by default: the float64 references take seconds per mesh at
#: 256^3 and minutes at 1024^3 here, far longer than the methods they check.
CHECK_MAX = 256

#: ``glvox compare`` presets: methods (None = every registered one), meshes,
#: sizes, repeats; ``cpu_max``: the float64 CPU references are checks, not
#: contenders, past this size.
COMPARE_PRESETS: dict[str, dict[str, Any]] = {
    "quick": {"meshes": ["stanford_bunny_bun_zipper.ply", "cad_rocker_arm.obj"],
              "sizes": [32, 64, 128], "repeat": 3, "check_max": 128},
    "paper": {"meshes": ["stanford_bunny_bun_zipper.ply", "stanford_dragon_vrip_res2.ply",
                         "stanford_armadillo_libigl_86k.obj", "stanford_happy_buddha_113k.obj",
                         "cad_rocker_arm.obj", "cad_fandisk.off", "depth_reduced_diamond_lattice.stl",
                         "depth_gyroid_tpms_sheet.stl"],
              "sizes": [128, 256, 512, 1024], "repeat": 3, "check_max": 256, "cpu_max": 256},
    # the open-mesh study: every solid method on the shared meshes that are not watertight,
    # each checked against the winding-number solid, which any mesh has; and on generated
    # meshes broken as dataset meshes are (double-sided, inconsistently wound), checked
    # against the winding-number solid of their clean twin (glvox.mesh.DEFECTIVE)
    "open": {"meshes": ["stanford_bunny_bun_zipper.ply", "stanford_dragon_vrip_res2.ply",
                        "stanford_dragon_vrip_res3.ply", "stanford_happy_buddha_113k.obj",
                        "depth_cycloidal_drive.ply", "depth_gyroid_tpms_sheet.stl", "messy_teapot_newell.obj",
                        "messy_tower_holes.obj", "messy_soup_synthetic.stl", "messy_not_convex.obj",
                        "messy_wallhole.obj", "gen:double-sided-torus", "gen:double-sided-bunny-like",
                        "gen:flipped-half-sphere"],
             "kinds": ["solid", "sparse"], "reference": "reference-gwn", "open_solids": True,
             "sizes": [64, 128], "repeat": 3, "check_max": 128},
}


def add_compare_arguments(p: argparse.ArgumentParser) -> None:
    """The options of ``glvox compare``."""
    p.add_argument("--preset", choices=sorted(COMPARE_PRESETS), default=None,
                   help="quick: every method, two shared meshes, up to 128^3; paper: the papers' sizes "
                        "up to 1024^3 on eight shared meshes; open: every solid method on the open shared "
                        "meshes against reference-gwn at 64^3 and 128^3")
    p.add_argument("-m", "--methods", nargs="+", default=None, help="registered method names (default all)")
    p.add_argument("--meshes", nargs="+", default=None,
                   help="mesh files, names in GLVOX_MESHES, or gen:torus|sphere|box|bunny-like")
    p.add_argument("-r", "--sizes", nargs="+", type=int, default=None, help="grid resolutions N (N^3)")
    p.add_argument("--repeat", type=int, default=None, help="timed warm runs per cell (median reported)")
    p.add_argument("--check-max", type=int, default=None,
                   help=f"largest N checked against the CPU references (default {CHECK_MAX}; 0: none)")
    p.add_argument("-o", "--out", default="results", help="output folder (resumed if it has results)")
    p.add_argument("--force", action="store_true", help="recompute every cell, ignoring earlier results")
    p.add_argument("--no-pictures", action="store_true", help="skip the renders and slice images")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress bar")


# -- glvox bench -----------------------------------------------------------------

#: ``glvox bench`` presets.  ``fallback``: a generated mesh used in place of a
#: shared mesh that is not on this machine (a clean install has no shared
#: meshes), so the quick preset always runs.  ``budget``: seconds of warm runs
#: after which a contender stops repeating in a cell.
BENCH_PRESETS: dict[str, dict[str, Any]] = {
    "quick": {"meshes": ["stanford_bunny_bun_zipper.ply", "stanford_armadillo_libigl_86k.obj"],
              "fallback": {"stanford_bunny_bun_zipper.ply": "gen:bunny-like",
                           "stanford_armadillo_libigl_86k.obj": "gen:torus"},
              "sizes": [64, 128], "repeat": 5, "budget": 3.0},
    "full": {"meshes": ["stanford_bunny_bun_zipper.ply", "stanford_dragon_vrip_res2.ply"],
             "fallback": {},
             "sizes": [128, 256, 512, 1024], "repeat": 5, "budget": 10.0},
}

#: Warm rounds and seconds per cell of ``glvox bench`` without a preset value.
BENCH_REPEAT, BENCH_BUDGET = 5, 10.0

#: Timed runs per side and cell of ``--against`` (the sides take turns).
AB_REPEAT = 10

#: The peers' names, in table order (:data:`glvox.study.peers.PEERS` holds them;
#: named here so that building the parser does not import the peers).
PEER_NAMES = ("open3d", "trimesh-subdivide", "trimesh-fill", "pyvista", "igl-winding", "warp-winding",
              "cuda-voxelizer")

#: The environment variable naming the cuda_voxelizer binary when ``--cuda-voxelizer`` is not given.
CUDA_VOXELIZER_ENV = "GLVOX_CUDA_VOXELIZER"


def check_binary(path: str | os.PathLike) -> Path:
    """``path`` as an executable file (the cuda_voxelizer peer's binary), or a one-line GlvoxError."""
    p = Path(path).expanduser()
    if not p.is_file():
        raise GlvoxError(f"cuda_voxelizer binary {p} not found (--cuda-voxelizer PATH or {CUDA_VOXELIZER_ENV})")
    if not os.access(p, os.X_OK):
        raise GlvoxError(f"cuda_voxelizer binary {p} is not executable")
    return p.resolve()


#: ``--check`` given without a PATH: the checkout's ``compare/bench_baseline.json``
#: (:func:`glvox.study.regression.baseline_path`).  ``--save-baseline`` always
#: takes a PATH: a benchmark run never rewrites a tracked file unasked.
CHECKOUT_BASELINE = "<checkout>"


def add_bench_arguments(p: argparse.ArgumentParser) -> None:
    """The options of ``glvox bench``."""
    p.add_argument("--preset", choices=sorted(BENCH_PRESETS), default=None,
                   help="quick: every method and peer on two shared meshes at 64^3 and 128^3 (generated "
                        "meshes when the shared ones are absent); full: bunny and dragon, 128^3 to 1024^3")
    p.add_argument("-m", "--methods", nargs="+", default=None,
                   help="glvox methods (default: every GPU method of kind surface, solid or sparse)")
    p.add_argument("--no-variants", action="store_true",
                   help="only each method's default (not ss-conservative's simple and sorted variants too)")
    p.add_argument("--peers", nargs="*", default=None, choices=list(PEER_NAMES),
                   help=f"peers to run (default all installed: {', '.join(PEER_NAMES)})")
    p.add_argument("--meshes", nargs="+", default=None,
                   help="mesh files, names in GLVOX_MESHES, or gen:torus|sphere|box|bunny-like")
    p.add_argument("-r", "--sizes", nargs="+", type=int, default=None, help="grid resolutions N (N^3)")
    p.add_argument("--repeat", type=int, default=None, help="timed warm rounds per cell (median reported)")
    p.add_argument("--budget", type=float, default=None,
                   help="seconds of warm runs after which a contender stops repeating in a cell")
    p.add_argument("--check-max", type=int, default=None,
                   help="largest N compared with the CPU references (default: every size; 0: none)")
    p.add_argument("--peer-max", action="append", default=[], metavar="PEER=N",
                   help="run a peer up to N^3 instead of its default limit (PEER=none: no limit)")
    p.add_argument("--cuda-voxelizer", default=None, metavar="PATH",
                   help="the cuda_voxelizer binary to run as the peer cuda-voxelizer (default: "
                        "$GLVOX_CUDA_VOXELIZER); its grid is its own cube, checked against ss-conservative "
                        "on that cube (row peer_stats)")
    p.add_argument("-o", "--out", default=None, help="folder for bench.md and results.json")
    p.add_argument("--check", nargs="?", const=CHECKOUT_BASELINE, default=None, metavar="PATH",
                   help="exit status 3 when a method regressed by more than "
                        f"{REGRESSION_TOLERANCE * 100:.0f}%% against a baseline results file (default: "
                        "compare/bench_baseline.json of the checkout glvox runs from)")  # argparse formats help with %
    p.add_argument("--save-baseline", default=None, metavar="PATH",
                   help="write the results as a baseline file for --check (the checkout's own is "
                        "compare/bench_baseline.json: name it to refresh it)")
    p.add_argument("--against", default=None, metavar="REV",
                   help="A/B check: time the plan's glvox methods with glvox at git revision REV and with this "
                        "checkout, run by run in two processes (no peers; --repeat runs per side, default "
                        f"{AB_REPEAT}); exit status 3 when a method's best and median times grew by more than "
                        f"{REGRESSION_TOLERANCE * 100:.0f}%%. Immune to machine drift, unlike --check")
    p.add_argument("--cold-start", action="store_true",
                   help="also time each method's first call in a fresh process (Mesa's shader disk cache off) "
                        "on the first mesh at the smallest size")
    p.add_argument("--end-to-end", nargs="?", const="", default=None, metavar="FOLDER",
                   help="time whole jobs per file instead (read, fit the N^3 grid, voxelize, dense numpy "
                        "occupancy) over FOLDER (default: the shared meshes) at the first -r size (default "
                        "64): glvox's methods (-m, default ss-conservative) against Open3D (--peers "
                        "open3d trimesh-subdivide); meshes/s from best and median of --repeat rounds")
    p.add_argument("--sdf", action="store_true",
                   help="signed distance fields: glvox sdf against Open3D, libigl and mesh-to-sdf on the same "
                        "voxel centers (with --meshes and -r)")
    p.add_argument("--json", action="store_true", help="print the rows as JSON instead of the tables")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress messages")
