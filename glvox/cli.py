"""Command line: ``glvox info | methods | voxelize | sdf | convert | batch | ldi | volume | compare | bench | data | inspect
| render | selftest``.

Errors glvox raises on purpose print one line ``glvox: error: ...`` and exit
with status 1 (2 for wrong usage, as argparse does, in the same one-line
form); never a traceback.

Every command checks all its arguments before it loads or voxelizes
anything: its parser sets ``validate=`` (a function of the parsed
arguments that raises :class:`~glvox.errors.GlvoxError`, built from the
checks in :mod:`glvox.preflight`) beside ``func=``, and :func:`main` runs it
first.  A command added later does the same.
"""

from __future__ import annotations

import argparse
import sys
from typing import Sequence

from . import preflight
from ._version import __version__
from .commands import (cmd_batch, cmd_bench, cmd_compare, cmd_convert, cmd_data, cmd_info, cmd_inspect, cmd_ldi,
                       cmd_calibrate, cmd_methods, cmd_render, cmd_sdf, cmd_selftest, cmd_voxelize, cmd_volume)
from .errors import GlvoxError
from .grid import DEFAULT_RESOLUTION, host_threads
from .gpu.readback import readback_mode
from .methods import DEFAULT_METHOD, FAMILIES, PIPELINES
from .methods.attributes.passes import ATTRIBUTE_NAMES, FILL_MODES, NORMAL_MODES
from .study.options import add_bench_arguments, add_compare_arguments


class _Parser(argparse.ArgumentParser):
    """argparse with glvox's one-line errors (exit status 2 for wrong usage, as argparse's)."""

    def error(self, message: str):
        self.exit(2, f"glvox: error: {message} (see `{self.prog} --help`)\n")


def _axis(value: str) -> int:
    """``x``/``y``/``z`` or ``0``/``1``/``2``."""
    v = value.strip().lower()
    if v in ("x", "y", "z"):
        return "xyz".index(v)
    if v in ("0", "1", "2"):
        return int(v)
    raise argparse.ArgumentTypeError(f"axis must be x, y, z or 0, 1, 2, got {value!r}")


#: -r's help where a grid is needed (voxelize, batch, ldi).
_RESOLUTION_HELP = (f"voxels along the longest axis (cubic N^3 grid); default {DEFAULT_RESOLUTION} when "
                    "neither --dims nor --voxel-size is given")


def _add_output_arguments(p, json_help: str, quiet_help: str = "no progress messages") -> None:
    """--backend, --json and --quiet, shared by the commands that run a GL job."""
    p.add_argument("--backend", choices=["egl", "osmesa", "auto"], default=None)
    p.add_argument("--json", action="store_true", help=json_help)
    p.add_argument("-q", "--quiet", action="store_true", help=quiet_help)


def _add_grid_arguments(p: argparse.ArgumentParser, bounds: bool = False) -> None:
    """The grid options beside -r shared by voxelize, batch and ldi (see glvox.grid_for)."""
    p.add_argument("--dims", type=int, nargs=3, metavar=("NX", "NY", "NZ"), help="explicit dims")
    p.add_argument("--voxel-size", type=float, help="explicit voxel size (world units)")
    if bounds:
        p.add_argument("--bounds", type=float, nargs=6, metavar=("XMIN", "YMIN", "ZMIN", "XMAX", "YMAX", "ZMAX"),
                       help="region to cover instead of the mesh's bounding box")
    p.add_argument("--padding", type=int, default=0, help="empty voxels kept on every side")
    p.add_argument("--tight", action="store_true", help="non-cubic dims fitted to the bounding box")


def _add_attribute_arguments(p) -> None:
    """--attributes, --normals, --fill-attributes of voxelize and batch (README "Attributes")."""
    p.add_argument("--attributes", metavar="NAMES", default=None,
                   help=f"per-voxel data from the mesh, comma-separated: {','.join(ATTRIBUTE_NAMES)} (npz output)")
    p.add_argument("--normals", choices=NORMAL_MODES, default="face",
                   help="normal attribute: the source triangle's, or interpolated vertex normals (default face)")
    p.add_argument("--fill-attributes", choices=FILL_MODES, default="none",
                   help="solids: interior voxels carry none (default) or the nearest surface voxel's")


def _add_info_parser(sub) -> None:
    pi = sub.add_parser("info", help="print the GL backend, renderer, version and limits")
    pi.add_argument("--backend", choices=["egl", "osmesa", "auto"], default=None)
    pi.add_argument("--json", action="store_true", help="machine-readable output")
    pi.set_defaults(func=cmd_info)


def _add_methods_parser(sub) -> None:
    pm = sub.add_parser("methods", help="list the registered methods")
    pm.add_argument("--kind", choices=["surface", "solid", "ldi", "sparse"])
    pm.add_argument("--family", choices=FAMILIES, help="a method family (its package, shaders and docs page)")
    pm.add_argument("--pipeline", choices=PIPELINES, help="how the methods run")
    pm.add_argument("--json", action="store_true")
    pm.set_defaults(func=cmd_methods)


def _add_voxelize_parser(sub) -> None:
    pv = sub.add_parser("voxelize", help="voxelize a mesh into .npz or .binvox",
                        description="Voxelize MESH (a file trimesh loads, or gen:torus / gen:sphere / "
                                    "gen:box / gen:bunny-like).")
    pv.add_argument("mesh")
    pv.add_argument("-r", "--resolution", type=int, help=_RESOLUTION_HELP)
    pv.add_argument("-m", "--method", default=None, help="registry name (see `glvox methods`)")
    pv.add_argument("-o", "--output", help="output file: .npz, .binvox, .nrrd, .nii(.gz), .vti, .vdb, .vox, "
                                           ".points.ply/.glb or .cubes.ply/.glb")
    pv.add_argument("-O", "--option", action="append", default=[], metavar="KEY=VALUE",
                    help="method option (repeatable); `--KEY VALUE` works too, e.g. --axis 2")
    _add_grid_arguments(pv, bounds=True)
    pv.add_argument("--fit", choices=("center", "binvox"), default="center",
                    help="grid placement with -r: centered on the bounding box (default), or binvox's (its "
                         "minimum corner at the box's, longest side = N voxels; .binvox written in binvox's "
                         "convention)")
    pv.add_argument("--allow-open", action="store_true",
                    help="let solid methods run on meshes that are not watertight")
    _add_output_arguments(pv, "print counts and timings as JSON")
    _add_attribute_arguments(pv)
    pv.set_defaults(func=cmd_voxelize, validate=preflight.validate_voxelize)


def _add_sdf_parser(sub) -> None:
    ps = sub.add_parser("sdf", help="signed distances from the voxel centers (or near-surface samples) to a mesh",
                        description="Signed distance field of MESH on the grid's voxel centers (world units, "
                                    "negative inside), or --samples N points near the surface with their distances.")
    ps.add_argument("mesh")
    ps.add_argument("-r", "--resolution", type=int, help=_RESOLUTION_HELP)
    ps.add_argument("-o", "--output", required=True, help="output file: .npz, .nrrd, .nii(.gz) or .vti (samples: .npz)")
    ps.add_argument("--band", default="3", help="voxels from the surface where distances are exact (beyond: "
                                                "clamped to +-band voxels), or 'all' (default 3)")
    ps.add_argument("--sign", default="solid", metavar="METHOD",
                    help="the solid method whose occupancy gives the sign (default solid: picked per mesh)")
    ps.add_argument("--truncation", default=None, metavar="T[vox|world]",
                    help="clamp to +-T (world units, or voxels with the suffix vox): a TSDF")
    ps.add_argument("--samples", type=int, default=None, metavar="N",
                    help="write N near-surface sample points with their signed distances instead of a grid")
    ps.add_argument("--seed", type=int, default=0, help="random seed of --samples (default 0)")
    _add_grid_arguments(ps)
    ps.add_argument("--allow-open", action="store_true",
                    help="let a --sign method that needs a closed mesh run on an open one")
    _add_output_arguments(ps, "print timings and counts as JSON")
    ps.set_defaults(func=cmd_sdf, validate=preflight.validate_sdf)


def _add_convert_parser(sub) -> None:
    pcv = sub.add_parser(
        "convert", help="convert a voxel file to another format (placement kept)",
        description="Read INPUT and write OUTPUT in the format of its suffix: .npz, .binvox, .nrrd, .nii, "
                    ".nii.gz, .vti, .vdb, .vox, .points.ply/.glb, .cubes.ply/.glb (the last three in the "
                    "voxels' colours).  Placement (origin, voxel size, dims) is kept; extra masks where "
                    "the output format holds them (.npz, .vti, .vdb; a warning names what is dropped).  "
                    "NRRD and NIfTI need `pip install 'glvox[formats]'`, .vdb OpenVDB's Python module.")
    pcv.add_argument("input", help="voxel file to read")
    pcv.add_argument("output", help="file to write (format by suffix)")
    pcv.add_argument("--convention", choices=["trimesh", "binvox"], default="trimesh",
                     help="binvox placement of a binvox input or output (default trimesh's)")
    pcv.add_argument("--no-coverage", action="store_true",
                     help="write an octree to .vdb without its coverage FloatGrid")
    pcv.add_argument("-q", "--quiet", action="store_true", help="no progress messages")
    pcv.set_defaults(func=cmd_convert, validate=preflight.validate_convert)


def _add_render_parser(sub) -> None:
    pr = sub.add_parser(
        "render", help="draw a voxel file as lit cubes in the voxels' own colours (PNG)",
        description="Read RESULT (any voxel file glvox reads; an octree is decoded) and draw its exposed "
                    "voxels as lit cubes, headless, in the voxels' own colours where it has them (the "
                    "'color' attribute), else in one blue-grey; large grids are pooled by 2 until at most "
                    "1.5 million cubes remain.  Needs matplotlib: pip install 'glvox[compare]'.")
    pr.add_argument("input", metavar="RESULT", help="voxel file to draw")
    pr.add_argument("-o", "--output", required=True, help="picture to write (.png)")
    pr.add_argument("--size", type=int, nargs=2, default=[960, 720], metavar=("W", "H"),
                    help="picture size in pixels (default 960 720)")
    pr.add_argument("--direction", type=float, nargs=3, default=[0.9, 0.65, 1.25], metavar=("X", "Y", "Z"),
                    help="where the camera looks from, relative to the voxels' center (world axes)")
    pr.add_argument("--up", type=float, nargs=3, default=[0.0, 1.0, 0.0], metavar=("X", "Y", "Z"),
                    help="the picture's up direction (default +y)")
    pr.add_argument("--flat", action="store_true", help="unlit: every face in its voxel's colour exactly")
    pr.add_argument("--single-color", action="store_true", help="ignore the voxels' colours")
    pr.add_argument("--backend", choices=["egl", "osmesa", "auto"], default=None)
    pr.add_argument("-q", "--quiet", action="store_true", help="no progress messages")
    pr.set_defaults(func=cmd_render, validate=preflight.validate_render)


def _add_batch_parser(sub) -> None:
    pb = sub.add_parser(
        "batch", help="voxelize every mesh of a folder or list (parallel, resumable)",
        description="Voxelize every mesh file under INPUT (a folder, searched recursively by suffix, or a "
                    "text file with one mesh path per line) with the same options, into OUTPUT mirroring "
                    "the input tree.  Workers are local processes (an existing Dask cluster with --scheduler), "
                    "one GL context each.  Outputs are written "
                    "atomically and skipped on rerun, so a killed batch resumes; OUTPUT/manifest.csv has "
                    "one row per mesh.  Exit status 0 when every mesh is done or skipped, 3 when some "
                    "failed (see the manifest).")
    pb.add_argument("input", help="folder of meshes, or text file listing mesh paths")
    pb.add_argument("-o", "--output", required=True, help="output folder")
    pb.add_argument("-r", "--resolution", type=int, help=_RESOLUTION_HELP)
    pb.add_argument("-m", "--method", default=None, help="registry name (see `glvox methods`)")
    pb.add_argument("--format", choices=["npz", "binvox"], default="npz", help="output format (default npz)")
    pb.add_argument("-O", "--option", action="append", default=[], metavar="KEY=VALUE",
                    help="method option (repeatable)")
    _add_grid_arguments(pb)
    pb.add_argument("--allow-open", action="store_true",
                    help="let solid methods run on meshes that are not watertight")
    pb.add_argument("--workers", type=int, default=None,
                    help="local worker processes (default 1); 0 runs in this process (no crash isolation)")
    pb.add_argument("--scheduler", metavar="ADDRESS",
                    help="run on an existing Dask cluster (e.g. tcp://host:8786) instead of a local one")
    pb.add_argument("--overwrite", action="store_true", help="redo meshes whose output exists")
    pb.add_argument("--manifest", help="manifest CSV path (default OUTPUT/manifest.csv)")
    pb.add_argument("--inspect", action="store_true",
                    help="also report each mesh's defects (glvox inspect) in the manifest's extra columns")
    pb.add_argument("--suffix", action="append", metavar="SUFFIX",
                    help="mesh suffix to search for (repeatable; default: every format trimesh loads)")
    _add_attribute_arguments(pb)
    _add_output_arguments(pb, "print the summary as JSON", "no progress bar, messages or summary")
    pb.set_defaults(func=cmd_batch, validate=preflight.validate_batch)


def _add_ldi_parser(sub) -> None:
    pl = sub.add_parser(
        "ldi", help="sample a mesh into a layered depth image (.npz)",
        description="Layered depth image of MESH along --axis: rays through the centers of the grid's "
                    "voxel columns, sorted samples per ray (pairs bound the solid).  Default method "
                    "leung-wang-ldi (conservative, Leung & Wang 2013); peel-ldi and reference-ldi are exact.  "
                    "npz keys: depths (float32, (n_p, n_q, n_max), voxel units along the axis, NaN past "
                    "each ray's count), counts, origin, voxel_size, axis, dims, lod_c.")
    pl.add_argument("mesh")
    pl.add_argument("-r", "--resolution", type=int, help=_RESOLUTION_HELP)
    pl.add_argument("--lod-c", type=int, default=None,
                    help="cells along the rays (Leung & Wang's LOD-C; default 1024)")
    pl.add_argument("--axis", type=_axis, default=2, help="ray direction: x, y or z (default z)")
    pl.add_argument("-m", "--method", default="leung-wang-ldi",
                    help="an ldi method (see `glvox methods --kind ldi`)")
    pl.add_argument("-o", "--output", help="output file (.npz)")
    pl.add_argument("-O", "--option", action="append", default=[], metavar="KEY=VALUE",
                    help="method option (repeatable), e.g. -O targets=4")
    _add_grid_arguments(pl)
    pl.add_argument("--allow-open", action="store_true", help="sample meshes that are not watertight (parity)")
    _add_output_arguments(pl, "print counts and timings as JSON")
    pl.set_defaults(func=cmd_ldi, validate=preflight.validate_ldi)


def _add_volume_parser(sub) -> None:
    pvol = sub.add_parser(
        "volume", help="intersecting volume of two closed meshes (Leung & Wang Sec. V-A)",
        description="Print the volume of the overlap of MESH_A and MESH_B (world units cubed), from the "
                    "conservative LDI of the overlap on a grid fitted to the intersection of their bounding "
                    "boxes: an upper bound of the overlap sampled on the rays.")
    pvol.add_argument("mesh_a")
    pvol.add_argument("mesh_b")
    pvol.add_argument("-r", "--resolution", type=int,
                      help=f"voxels along the overlap region's longest axis (default {DEFAULT_RESOLUTION})")
    pvol.add_argument("--lod-c", type=int, default=1024, help="cells along the rays (default 1024)")
    pvol.add_argument("--axis", type=_axis, default=2, help="ray direction: x, y or z (default z)")
    pvol.add_argument("--dims", type=int, nargs=3, metavar=("NX", "NY", "NZ"), help="explicit dims")
    pvol.add_argument("--voxel-size", type=float, help="explicit voxel size (world units)")
    pvol.add_argument("-o", "--output", help="also write the overlap's LDI (.npz)")
    pvol.add_argument("--allow-open", action="store_true", help="meshes that are not watertight (parity)")
    _add_output_arguments(pvol, "print the volume, counts and timings as JSON")
    pvol.set_defaults(func=cmd_volume, validate=preflight.validate_volume)


def _add_inspect_parser(sub) -> None:
    pin = sub.add_parser(
        "inspect", help="report a mesh's defects: components, holes, non-manifold edges, orientation, ...",
        description="Triangles, connected components, boundary and non-manifold edges, duplicate and "
                    "degenerate faces, winding consistency, orientation (signed volume) and an estimate of "
                    "self-intersections of MESH; with -r N also the share of the solid whose generalized "
                    "winding number lies within 0.1 of the threshold on the N^3 grid (how ambiguous a "
                    "solid of it is).")
    pin.add_argument("mesh")
    pin.add_argument("-r", "--resolution", type=int, default=None,
                     help="also measure the uncertain share on the N^3 grid (GPU winding numbers)")
    pin.add_argument("--backend", choices=["egl", "osmesa", "auto"], default=None)
    pin.add_argument("--json", action="store_true", help="print the report as JSON")
    pin.set_defaults(func=cmd_inspect, validate=preflight.validate_inspect)


def _add_compare_parser(sub) -> None:
    pc = sub.add_parser(
        "compare", help="run methods x meshes x grid sizes: tables, plots and pictures",
        description="Every chosen method on every mesh and grid size: timed warm runs, voxel counts, "
                    "agreement with the exact references, separability; writes results.csv/.json, "
                    "tables.md, plots/ and pictures/ into -o (rerunning resumes).")
    add_compare_arguments(pc)
    pc.set_defaults(func=cmd_compare, validate=preflight.validate_compare)


def _add_bench_parser(sub) -> None:
    pbe = sub.add_parser(
        "bench", help="glvox against Open3D, trimesh, PyVista and libigl on the same grids: ratio table",
        description="Every glvox GPU method and every installed peer voxelizer (pip install 'glvox[peers]') "
                    "on the same mesh and grid, timed in one process (medians of interleaved warm runs), "
                    "with each one's agreement with glvox's exact references; prints the ratio of each "
                    "method to the fastest peer of its kind.")
    add_bench_arguments(pbe)
    pbe.set_defaults(func=cmd_bench, validate=preflight.validate_bench)


def _add_data_parser(sub) -> None:
    pd = sub.add_parser(
        "data", help="the meshes glvox knows by name: list (licences, credits), fetch, path",
        description="The meshes of glvox's tests, comparison and README, by name.  `list` shows each with "
                    "its size, where it is, its licence and credit; `fetch NAME...` (or --all) downloads the "
                    "missing ones (checked against their SHA-256) into GLVOX_MESHES or the user cache; `path "
                    "NAME` prints where one is (no NAME: the download folder).  GLVOX_DATA_MIRROR=URL downloads "
                    "from a mirror that serves the files under their glvox names.")
    pd.add_argument("action", choices=["list", "fetch", "path"])
    pd.add_argument("names", nargs="*", metavar="NAME", help="mesh names (see `glvox data list`)")
    pd.add_argument("--all", action="store_true", help="fetch every mesh")
    pd.add_argument("-q", "--quiet", action="store_true", help="no download messages or progress bar")
    pd.set_defaults(func=cmd_data, validate=preflight.validate_data)


def _add_selftest_parser(sub) -> None:
    ps = sub.add_parser(
        "selftest", help="every method on this GPU against the CPU references (under a minute)",
        description="Every registered method (or --methods) on small generated meshes (and a shared mesh when "
                    "it is on this machine) at 16^3-32^3, checked against its exact CPU reference up to proven "
                    "ties, or against its paper's bound for approximate methods; prints the GL renderer, then "
                    "a table.  Exit status 1 when any method mismatches or fails.")
    ps.add_argument("--methods", nargs="+", metavar="METHOD", help="only these registered methods")
    _add_output_arguments(ps, "print the report as JSON", "no per-case progress lines")
    ps.set_defaults(func=cmd_selftest, validate=preflight.validate_selftest)


def _add_calibrate_parser(sub) -> None:
    pk = sub.add_parser(
        "calibrate", help="time ss-conservative's variants on this GPU; auto then uses the fastest",
        description="Times ss-conservative's variants (simple, specialized, sorted) on MESH at each size on "
                    "this GL device and stores the fastest per density band (triangles / N^2) under the GL "
                    "renderer string in ~/.cache/glvox/ss_variants.json (XDG_CACHE_HOME; GLVOX_CALIBRATION "
                    "names another file); variant=auto then uses it on this renderer.  --show prints what "
                    "is stored.")
    pk.add_argument("--mesh", default=None, help="mesh file, generated mesh or shared mesh name "
                                                 "(default: stanford_bunny_bun_zipper.ply)")
    pk.add_argument("--sizes", nargs="+", type=int, default=None, metavar="N",
                    help="grid sizes along the longest side (default: 64 128 256 512)")
    pk.add_argument("--repeat", type=int, default=None, help="interleaved timed rounds (default: 5)")
    pk.add_argument("--show", action="store_true", help="print the stored choices for this renderer; no timing")
    _add_output_arguments(pk, "print the measurements and the store as JSON", "no table")
    pk.set_defaults(func=cmd_calibrate, validate=preflight.validate_calibrate)


#: One function per command, each adding its subparser.
_COMMANDS = (_add_info_parser, _add_methods_parser, _add_voxelize_parser, _add_sdf_parser, _add_convert_parser, _add_batch_parser,
             _add_ldi_parser, _add_volume_parser, _add_compare_parser, _add_bench_parser, _add_data_parser,
             _add_inspect_parser, _add_render_parser, _add_selftest_parser, _add_calibrate_parser)


def build_parser() -> argparse.ArgumentParser:
    p = _Parser(prog="glvox", description="Headless GPU voxelization of triangle meshes.")
    p.add_argument("--version", action="version", version=f"glvox {__version__}")
    sub = p.add_subparsers(dest="command", required=True)
    for add in _COMMANDS:
        add(sub)
    return p


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args, extra = parser.parse_known_args(argv)
    if extra and args.command != "voxelize":
        parser.error(f"unrecognized arguments: {' '.join(extra)}")
    args.extra = extra
    if getattr(args, "method", "x") is None:
        args.method = DEFAULT_METHOD
    try:
        # glvox's environment settings, read where they are used, checked here first
        readback_mode()
        host_threads()
        validate = getattr(args, "validate", None)
        # every argument, before any work; what the check returns (a validated, frozen
        # request) is what the command runs, so nothing is checked twice
        args.checked = validate(args) if validate is not None else None
        return args.func(args)
    except GlvoxError as exc:
        print(f"glvox: error: {exc}", file=sys.stderr)
        return 1
    except OSError as exc:  # the checks passed, yet the system refused (a full disk, a vanished folder)
        where = f" ({exc.filename})" if exc.filename else ""
        print(f"glvox: error: {exc.strerror or exc}{where}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print("glvox: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
