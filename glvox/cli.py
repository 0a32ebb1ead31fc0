"""Command line: ``glvox info | methods | voxelize | convert | batch | ldi | volume | compare | bench | data | inspect
| render``.

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
import json
import signal
import sys
import threading
import warnings
from pathlib import Path
from typing import Sequence

import numpy as np

from . import datasets, io, preflight
from ._version import __version__
from .batch import BatchSettings, run_batch
from .errors import GlvoxError
from .gl.context import get_context
from .grid import grid_for
from .inspect import inspect_mesh
from .mesh import load_mesh
from .methods import DEFAULT_METHOD, get_method, method_infos, run_method
from .methods.attribute_pass import ATTRIBUTE_NAMES, FILL_MODES, NORMAL_MODES, parse_attributes
from .methods.leung_wang import overlap_bounds, overlap_grid, run_intersection
from .progress import Stages
from .visuals import load_visual_mesh
from .results import LDI, SparseOctree
from .study.options import add_bench_arguments, add_compare_arguments


class _Parser(argparse.ArgumentParser):
    """argparse with glvox's one-line errors (exit status 2 for wrong usage, as argparse's)."""

    def error(self, message: str):
        self.exit(2, f"glvox: error: {message} (see `{self.prog} --help`)\n")


def cmd_info(args) -> int:
    d = get_context(args.backend).describe()
    if args.json:
        print(json.dumps(d, indent=2))
        return 0
    print(f"glvox {__version__}")
    for key in ("backend", "device", "vendor", "renderer", "version"):
        print(f"{key + ':':<10} {d[key]}")
    print("limits:")
    for k, v in d["limits"].items():
        print(f"  {k:<40} {v}")
    return 0


def cmd_methods(args) -> int:
    infos = method_infos(args.kind, args.family)
    if args.json:
        print(json.dumps([i.to_dict() for i in infos], indent=2))
        return 0
    w = max((len(i.name) for i in infos), default=4)
    print(f"{'name':<{w}}  {'kind':<8} {'family':<8} summary")
    for i in infos:
        print(f"{i.name:<{w}}  {i.kind:<8} {i.family:<8} {i.summary}")
        print(f"{'':<{w}}  {'':<8} {'':<8} paper: {i.paper}")
        for name, o in i.options.items():
            choices = f" {list(o.choices)}" if o.choices else ""
            print(f"{'':<{w}}  {'':<8} {'':<8} -O {name}={o.default}{choices}: {o.help}")
    return 0


def _spec(args, mesh, bounds=None):
    """The grid of ``mesh`` from the checked grid options."""
    return grid_for(mesh, args.resolution if args.dims is None and args.voxel_size is None else None,
                    dims=args.dims, voxel_size=args.voxel_size, bounds=bounds, padding=args.padding,
                    tight=args.tight)


def _summary(result) -> str:
    """What a result holds, in a few words: voxels set, or an LDI's layers, samples and volume."""
    if isinstance(result, LDI):
        return f"n_max {result.n_max}, {result.samples} samples, volume {result.volume:.9g}"
    voxels = result.run.stats.get("voxels")
    return f"{voxels if voxels is not None else result.count} voxels set"


def cmd_voxelize(args) -> int:
    say = Stages(args.quiet or args.json)
    out = Path(args.output) if args.output else None
    method = get_method(args.method)
    options = preflight.parse_options(args.option, args.extra)
    mesh_path = datasets.resolve_mesh(args.mesh, quiet=args.quiet or args.json)
    say(f"loading {args.mesh}")
    names = parse_attributes(args.attributes)
    mesh = load_visual_mesh(mesh_path) if names else load_mesh(mesh_path)
    say(f"{mesh.n_triangles} triangles ({mesh.n_degenerate} zero-area dropped), "
        f"{'watertight' if mesh.watertight else 'NOT watertight'}")
    bounds = np.array(args.bounds, dtype=np.float64).reshape(2, 3) if args.bounds is not None else None
    spec = _spec(args, mesh, bounds)
    if out is not None:
        preflight.format_fits(out, method.info, spec)  # the dims of --tight / --voxel-size are known now
    say(f"grid {spec}")
    say(f"voxelizing with {method.info.name} ({method.info.family}, {method.info.kind})")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        result = run_method(args.method, mesh, spec, backend=args.backend, allow_open=args.allow_open,
                            attributes=names, normals=args.normals, fill_attributes=args.fill_attributes,
                            **options)
    for w in caught:
        print(f"glvox: warning: {w.message}", file=sys.stderr)
    run = result.run
    say(f"{_summary(result)}; {run.timings.summary()}")
    if out is not None:
        _save(result, out)
        say(f"wrote {out}")
    if args.json:
        d = run.to_dict()
        d["mesh"] = {"name": mesh.name, "triangles": mesh.n_triangles,
                     "degenerate_dropped": mesh.n_degenerate, "watertight": mesh.watertight}
        d["output"] = str(out) if out else None
        print(json.dumps(d, indent=2))
    elif args.quiet is False and out is None:
        print(_summary(result))
    return 0


def _save(result, out: Path, **options) -> None:
    """``io.save``, its FormatWarnings (what a format drops) printed as ``glvox: warning:`` lines."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        io.save(result, out, **options)
    for w in caught:
        print(f"glvox: warning: {w.message}", file=sys.stderr)


def cmd_convert(args) -> int:
    """``glvox convert IN OUT``: read a voxel file and write it in the format of OUT's suffix."""
    src, dst = Path(args.input), Path(args.output)
    say = Stages(args.quiet)
    result = io.load(src, convention=args.convention)
    kind = "ldi" if isinstance(result, LDI) else "sparse" if isinstance(result, SparseOctree) else None
    io.check_writable(dst, kind=kind, dims=result.dims)
    say(f"read {src}: {result!r}")
    options = {"coverage": False} if args.no_coverage else {}
    _save(result, dst, convention=args.convention, **options)
    say(f"wrote {dst} ({dst.stat().st_size} bytes)")
    return 0


def cmd_render(args) -> int:
    """``glvox render RESULT -o PICTURE.png``: the voxels as lit cubes in their own colours."""
    # imported here for start-up time, as in cmd_compare: the renderer needs moderngl and matplotlib
    from .study.render import render_voxels, save_png

    say = Stages(args.quiet)
    result = io.load(args.input)
    if isinstance(result, LDI):
        raise GlvoxError(f"glvox render draws voxel grids; {args.input} holds an LDI (depths per ray)")
    grid = result.to_grid() if isinstance(result, SparseOctree) else result
    say(f"read {args.input}: {grid!r}")
    img = render_voxels(get_context(args.backend), grid, size=tuple(args.size), direction=tuple(args.direction),
                        up=tuple(args.up), own_colors=not args.single_color, flat=args.flat)
    save_png(img, Path(args.output))
    say(f"wrote {args.output} ({args.size[0]} x {args.size[1]})")
    return 0


def cmd_batch(args) -> int:
    """``glvox batch``: exit 0 when every mesh is done or skipped, 3 when some failed."""
    options = preflight.parse_options(args.option)
    settings = BatchSettings(
        method=args.method, resolution=args.resolution,
        dims=tuple(args.dims) if args.dims is not None else None, voxel_size=args.voxel_size,
        padding=args.padding, tight=args.tight, options=tuple(sorted(options.items())),
        allow_open=args.allow_open, backend=args.backend, fmt=args.format, inspect=args.inspect,
        attributes=parse_attributes(args.attributes), normals=args.normals, fill_attributes=args.fill_attributes)

    def on_term(signum, frame):  # batch schedulers stop jobs with SIGTERM: keep the manifest
        raise KeyboardInterrupt

    main_thread = threading.current_thread() is threading.main_thread()
    previous = signal.signal(signal.SIGTERM, on_term) if main_thread else None
    try:
        summary = run_batch(args.input, args.output, settings,
                            workers=1 if args.workers is None else args.workers,
                            scheduler=args.scheduler, overwrite=args.overwrite, manifest=args.manifest,
                            suffixes=args.suffix or None, quiet=args.quiet or args.json)
    finally:
        if main_thread:
            signal.signal(signal.SIGTERM, previous)
    if args.json:
        print(json.dumps(summary.to_dict(), indent=2))
    elif not args.quiet:
        print(summary.format())
    return 3 if summary.failed else 0


def _axis(value: str) -> int:
    """``x``/``y``/``z`` or ``0``/``1``/``2``."""
    v = value.strip().lower()
    if v in ("x", "y", "z"):
        return "xyz".index(v)
    if v in ("0", "1", "2"):
        return int(v)
    raise argparse.ArgumentTypeError(f"axis must be x, y, z or 0, 1, 2, got {value!r}")


def cmd_ldi(args) -> int:
    """``glvox ldi``: a layered depth image (default leung-wang-ldi) into an npz."""
    say = Stages(args.quiet or args.json)
    out = Path(args.output) if args.output else None
    info = get_method(args.method).info
    options = preflight.ldi_options(args, info)
    mesh_path = datasets.resolve_mesh(args.mesh, quiet=args.quiet or args.json)
    say(f"loading {args.mesh}")
    mesh = load_mesh(mesh_path)
    say(f"{mesh.n_triangles} triangles, {'watertight' if mesh.watertight else 'NOT watertight'}")
    spec = _spec(args, mesh)
    say(f"grid {spec}; sampling with {info.name}")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        result = run_method(args.method, mesh, spec, backend=args.backend, allow_open=args.allow_open,
                            **options)
    for w in caught:
        print(f"glvox: warning: {w.message}", file=sys.stderr)
    run = result.run
    say(f"{_summary(result)}; {run.timings.summary()}")
    if out is not None:
        result.save(out)
        say(f"wrote {out}")
    if args.json:
        d = run.to_dict()
        d.update({"n_max": result.n_max, "samples": result.samples, "volume": result.volume,
                  "output": str(out) if out else None})
        print(json.dumps(d, indent=2))
    elif out is None:
        print(_summary(result))
    return 0


def cmd_volume(args) -> int:
    """``glvox volume A B``: the intersecting volume of two closed meshes (Leung & Wang Sec. V-A)."""
    say = Stages(args.quiet or args.json)
    quiet = args.quiet or args.json
    a = load_mesh(datasets.resolve_mesh(args.mesh_a, quiet=quiet))
    b = load_mesh(datasets.resolve_mesh(args.mesh_b, quiet=quiet))
    say(f"{a.name}: {a.n_triangles} triangles; {b.name}: {b.n_triangles} triangles")
    if overlap_bounds(a, b) is None:
        volume, d = 0.0, {"volume": 0.0, "note": "the bounding boxes do not overlap"}
    else:
        spec = overlap_grid(a, b, args.resolution if args.dims is None and args.voxel_size is None else None,
                            dims=args.dims, voxel_size=args.voxel_size)
        res = run_intersection(a, b, spec, lod_c=args.lod_c, axis=args.axis, allow_open=args.allow_open,
                               backend=args.backend)
        volume = res.volume
        say(f"grid {res.spec}; n_max {res.n_max}; {res.run.timings.summary()}")
        d = res.run.to_dict()
        d.update({"volume": volume, "n_max": res.n_max, "samples": res.samples})
        if args.output:
            res.save(args.output)
            say(f"wrote {args.output}")
    if args.json:
        print(json.dumps(d, indent=2))
    else:
        print(f"{volume:.9g}")
    return 0


def cmd_inspect(args) -> int:
    """``glvox inspect``: the defects of a mesh (glvox.inspect.MeshReport)."""
    report = inspect_mesh(args.mesh, args.resolution, backend=args.backend)
    print(json.dumps(report.to_dict(), indent=2) if args.json else report.format())
    return 0


def cmd_compare(args) -> int:
    # imported here for start-up time: the study's runner, tables and plots are
    # needed by this command alone (its options come from the light study.options)
    from .study.compare import main as compare_main

    return compare_main(args)


def cmd_bench(args) -> int:
    """``glvox bench``: exit 0, or 3 when ``--check`` finds a regression."""
    from .study.bench import main as bench_main  # for start-up time, as in cmd_compare

    return bench_main(args)


def cmd_data(args) -> int:
    """``glvox data list | fetch NAME... | path [NAME]``: the meshes glvox knows by name."""
    if args.action == "list":
        for name in datasets.mesh_names():
            src, where = datasets.source(name), datasets.find(name)
            print(f"{name:<36} {src.size / 1e6:6.2f} MB  {where.parent if where else 'not on this machine'}")
            print(f"    licence: {src.licence}")
            print(f"    credit:  {src.credit}")
            print(f"    source:  {src.repo} {src.path} @ {src.commit[:10]}"
                  + (f" (with {', '.join(src.companions)})" if src.companions else ""))
        print(f"searched: {', '.join(str(d) for d in datasets.search_dirs())}; downloads go to "
              f"{datasets.data_dir()} (GLVOX_MESHES; GLVOX_DATA_MIRROR replaces the download site)")
    elif args.action == "fetch":
        for name in args.names or datasets.mesh_names():
            print(datasets.fetch(name, quiet=args.quiet))
    elif not args.names:
        print(datasets.data_dir())
    else:
        where = datasets.find(args.names[0])
        if where is None:
            raise GlvoxError(f"{args.names[0]} is not on this machine: `glvox data fetch {args.names[0]}` "
                             f"downloads it into {datasets.data_dir()}")
        print(where)
    return 0


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
    pm.add_argument("--family", choices=["raster", "compute", "cpu"])
    pm.add_argument("--json", action="store_true")
    pm.set_defaults(func=cmd_methods)


def _add_voxelize_parser(sub) -> None:
    pv = sub.add_parser("voxelize", help="voxelize a mesh into .npz or .binvox",
                        description="Voxelize MESH (a file trimesh loads, or gen:torus / gen:sphere / "
                                    "gen:box / gen:bunny-like).")
    pv.add_argument("mesh")
    pv.add_argument("-r", "--resolution", type=int, help="voxels along the longest axis (cubic N^3 grid)")
    pv.add_argument("-m", "--method", default=None, help="registry name (see `glvox methods`)")
    pv.add_argument("-o", "--output", help="output file: .npz, .binvox, .nrrd, .nii(.gz), .vti, .vdb, .vox, "
                                           ".points.ply/.glb or .cubes.ply/.glb")
    pv.add_argument("-O", "--option", action="append", default=[], metavar="KEY=VALUE",
                    help="method option (repeatable); `--KEY VALUE` works too, e.g. --axis 2")
    _add_grid_arguments(pv, bounds=True)
    pv.add_argument("--allow-open", action="store_true",
                    help="let solid methods run on meshes that are not watertight")
    _add_output_arguments(pv, "print counts and timings as JSON")
    _add_attribute_arguments(pv)
    pv.set_defaults(func=cmd_voxelize, validate=preflight.validate_voxelize)


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
                    "the input tree.  Workers are Dask processes, one GL context each.  Outputs are written "
                    "atomically and skipped on rerun, so a killed batch resumes; OUTPUT/manifest.csv has "
                    "one row per mesh.  Exit status 0 when every mesh is done or skipped, 3 when some "
                    "failed (see the manifest).")
    pb.add_argument("input", help="folder of meshes, or text file listing mesh paths")
    pb.add_argument("-o", "--output", required=True, help="output folder")
    pb.add_argument("-r", "--resolution", type=int, help="voxels along the longest axis (cubic N^3 grid)")
    pb.add_argument("-m", "--method", default=None, help="registry name (see `glvox methods`)")
    pb.add_argument("--format", choices=["npz", "binvox"], default="npz", help="output format (default npz)")
    pb.add_argument("-O", "--option", action="append", default=[], metavar="KEY=VALUE",
                    help="method option (repeatable)")
    _add_grid_arguments(pb)
    pb.add_argument("--allow-open", action="store_true",
                    help="let solid methods run on meshes that are not watertight")
    pb.add_argument("--workers", type=int, default=None,
                    help="worker processes of the local Dask cluster (default 1); 0 runs in this "
                         "process without Dask (no crash isolation)")
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
    pl.add_argument("-r", "--resolution", type=int, help="voxels along the longest axis (cubic N^3 grid)")
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
    pvol.add_argument("-r", "--resolution", type=int, help="voxels along the overlap region's longest axis")
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


#: One function per command, each adding its subparser.
_COMMANDS = (_add_info_parser, _add_methods_parser, _add_voxelize_parser, _add_convert_parser, _add_batch_parser,
             _add_ldi_parser, _add_volume_parser, _add_compare_parser, _add_bench_parser, _add_data_parser,
             _add_inspect_parser, _add_render_parser)


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
        validate = getattr(args, "validate", None)
        if validate is not None:
            validate(args)  # every argument, before any work
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
