"""What each ``glvox`` command does, once :mod:`glvox.cli` has parsed and
checked its arguments (:mod:`glvox.preflight`): one ``cmd_<command>(args)``
per command, returning the exit status.  Errors glvox raises on purpose
propagate as :class:`~glvox.errors.GlvoxError`; :func:`glvox.cli.main` prints
them as one line.
"""

from __future__ import annotations

import json
import signal
import sys
import threading
import warnings
from pathlib import Path


from . import datasets, io, preflight
from ._version import __version__
from .batch import BatchSettings, run_batch
from .errors import GlvoxError
from .gl.context import get_context
from .gpu.behaviours import PROBES, broken
from .grid import binvox_grid, grid_for
from .inspect import inspect_mesh
from .mesh import binvox_bounds, load_mesh
from .methods import Request, get_method, method_infos, run_method
from .methods.ldi.leung_wang import overlap_bounds, overlap_grid, run_intersection
from .methods.sdf.field import signed_distance_field
from .methods.sdf.samples import save_samples, sdf_samples
from .progress import Progress, Stages
from .visuals import load_visual_mesh
from .results import LDI, SDFGrid, SparseOctree


def cmd_info(args) -> int:
    ctx = get_context(args.backend)
    d = ctx.describe()
    # the behaviours the methods rely on, probed on this context (None: done right)
    d["behaviours"] = {name: broken(ctx, name) for name in PROBES}
    if args.json:
        print(json.dumps(d, indent=2))
        return 0
    print(f"glvox {__version__}")
    for key in ("backend", "device", "vendor", "renderer", "version"):
        print(f"{key + ':':<10} {d[key]}")
    print("limits:")
    for k, v in d["limits"].items():
        print(f"  {k:<40} {v}")
    print("behaviours:")
    for k, v in d["behaviours"].items():
        print(f"  {k:<40} {'ok' if v is None else 'BROKEN: ' + v}")
    print("driver settings:")
    for k, v in d["driver_settings"].items():
        print(f"  {k + '=' + v['value']:<40} (set by {v['set_by']})")
    return 0


def cmd_methods(args) -> int:
    infos = method_infos(args.kind, args.family, args.pipeline)
    if args.json:
        print(json.dumps([i.to_dict() for i in infos], indent=2))
        return 0
    w = max((len(i.name) for i in infos), default=4)
    print(f"{'name':<{w}}  {'kind':<8} {'family':<9} {'pipeline':<8} summary")
    pad = f"{'':<{w}}  {'':<8} {'':<9} {'':<8}"
    for i in infos:
        print(f"{i.name:<{w}}  {i.kind:<8} {i.family:<9} {i.pipeline:<8} {i.summary}")
        print(f"{pad} paper: {i.paper}")
        for name, o in i.options.items():
            choices = f" {list(o.choices)}" if o.choices else ""
            print(f"{pad} -O {name}={o.default}{choices}: {o.help}")
    return 0


def _spec(args, mesh):
    """The grid of ``mesh`` from the checked grid options."""
    return grid_for(mesh, args.resolution if args.dims is None and args.voxel_size is None else None,
                    dims=args.dims, voxel_size=args.voxel_size, padding=args.padding, tight=args.tight)


def _summary(result) -> str:
    """What a result holds, in a few words: voxels set, or an LDI's layers, samples and volume."""
    if isinstance(result, LDI):
        return f"n_max {result.n_max}, {result.samples} samples, volume {result.volume:.9g}"
    voxels = result.run.stats.get("voxels")
    return f"{voxels if voxels is not None else result.count} voxels set"


class SlabProgress:
    """A method's slabs as ``glvox voxelize`` shows them: a bar on a terminal, else a line
    every few seconds and one at the end (:class:`~glvox.progress.Progress`); a method
    that runs its slabs again (gwn-solid past its bit planes) starts a new one."""

    def __init__(self, enabled: bool):
        self.enabled = enabled
        self.bar: Progress | None = None

    def __call__(self, done: int, total: int) -> None:
        if not self.enabled:
            return
        if self.bar is None or done <= self.bar.done:
            self.close()
            self.bar = Progress(total, unit="slab")
        self.bar.update(done - self.bar.done)

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()
            self.bar = None


def cmd_voxelize(args) -> int:
    call: preflight.VoxelizeCall = args.checked
    info = call.request.info
    say = Stages(args.quiet or args.json)
    out = call.output
    mesh_path = datasets.resolve_mesh(args.mesh, quiet=args.quiet or args.json)
    say(f"loading {args.mesh}")
    mesh = load_visual_mesh(mesh_path) if call.request.attributes else load_mesh(mesh_path)
    say(f"{mesh.n_triangles} triangles ({mesh.n_degenerate} zero-area dropped), "
        f"{'watertight' if mesh.watertight else 'NOT watertight'}")
    binvox_fit = getattr(args, "fit", "center") == "binvox"
    if binvox_fit:
        spec = binvox_grid(binvox_bounds(mesh_path, mesh), args.resolution)
    else:
        spec = call.grid if call.grid is not None else _spec(args, mesh)
    if out is not None and not call.output_fits:
        preflight.format_fits(out, info, spec)  # the dims of --tight / --voxel-size are known now
    say(f"grid {spec}")
    picked = call.request.method.resolve(mesh)
    if picked != info.name:  # an alias (-m solid): say what it picked and why
        why = call.request.method.why(mesh)
        info = get_method(picked).info
        say(f"voxelizing with {info.name} ({info.family} family, {info.pipeline}, {info.kind}; "
            f"picked by {call.request.name}: {why})")
    else:
        say(f"voxelizing with {info.name} ({info.family} family, {info.pipeline}, {info.kind})")
    slabs = SlabProgress(not (args.quiet or args.json))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            result = run_method(call.request, mesh, spec, backend=args.backend, allow_open=args.allow_open,
                                progress=slabs)
        finally:
            slabs.close()
    for w in caught:
        print(f"glvox: warning: {w.message}", file=sys.stderr)
    run = result.run
    say(f"{_summary(result)}; {run.timings.summary()}")
    if out is not None:
        # binvox's placement is written in binvox's header convention (translate = origin, scale = n h)
        _save(result, out, **({"convention": "binvox"} if binvox_fit else {}))
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


def cmd_sdf(args) -> int:
    """``glvox sdf MESH -o out.npz``: the signed distance field on the grid, or --samples N points."""
    call: preflight.SdfCall = args.checked
    say = Stages(args.quiet or args.json)
    mesh = load_mesh(datasets.resolve_mesh(args.mesh, quiet=args.quiet or args.json))
    say(f"loaded {mesh.name}: {mesh.n_triangles} triangles")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        if args.samples is not None:
            save_samples(sdf_samples(mesh, args.samples, seed=args.seed), call.output)
            summary = {"samples": args.samples, "seed": args.seed}
        else:
            spec = _spec(args, mesh)
            preflight.sdf_memory(spec.dims)
            say(f"grid {spec}")
            result = signed_distance_field(mesh, spec, band=args.band, sign=args.sign, truncation=args.truncation,
                                           backend=args.backend, allow_open=args.allow_open)
            say(f"{result!r}; {result.run.timings.summary()}")
            _save(result, call.output)
            summary = result.run.to_dict()
    for w in caught:
        print(f"glvox: warning: {w.message}", file=sys.stderr)
    say(f"wrote {call.output}")
    if args.json:
        print(json.dumps({**summary, "output": str(call.output)}, indent=2, default=str))
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
    from .study.render import render_voxels, save_png, save_sdf_slice_png

    say = Stages(args.quiet)
    result = io.load(args.input)
    if isinstance(result, SDFGrid):  # a slice with the zero level marked
        save_sdf_slice_png(result, Path(args.output))
        say(f"wrote {args.output} (the middle z slice of {result!r})")
        return 0
    if isinstance(result, LDI):
        raise GlvoxError(f"glvox render draws voxel grids; {args.input} holds an LDI (depths per ray)")
    grid = result.to_grid() if isinstance(result, SparseOctree) else result
    say(f"read {args.input}: {grid!r}")
    if grid.count == 0:  # a blank picture would pass for a drawing of nothing in particular
        dims = "x".join(map(str, grid.spec.dims))
        raise GlvoxError(f"{args.input} holds no voxels (its {dims} grid is empty): nothing to draw; an empty solid "
                         f"usually means its method cannot read the mesh (`glvox inspect MESH` says which can)")
    img = render_voxels(get_context(args.backend), grid, size=tuple(args.size), direction=tuple(args.direction),
                        up=tuple(args.up), own_colors=not args.single_color, flat=args.flat)
    save_png(img, Path(args.output))
    say(f"wrote {args.output} ({args.size[0]} x {args.size[1]})")
    return 0


def cmd_batch(args) -> int:
    """``glvox batch``: exit 0 when every mesh is done or skipped, 3 when some failed."""
    settings: BatchSettings = args.checked

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


def cmd_ldi(args) -> int:
    """``glvox ldi``: a layered depth image (default leung-wang-ldi) into an npz."""
    request: Request = args.checked
    info = request.info
    say = Stages(args.quiet or args.json)
    out = Path(args.output) if args.output else None
    mesh_path = datasets.resolve_mesh(args.mesh, quiet=args.quiet or args.json)
    say(f"loading {args.mesh}")
    mesh = load_mesh(mesh_path)
    say(f"{mesh.n_triangles} triangles, {'watertight' if mesh.watertight else 'NOT watertight'}")
    spec = _spec(args, mesh)
    say(f"grid {spec}; sampling with {info.name}")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        result = run_method(request, mesh, spec, backend=args.backend, allow_open=args.allow_open)
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


def cmd_selftest(args) -> int:
    """``glvox selftest``: exit 0, or 1 when a method mismatches its check or fails."""
    from .study.selftest import main as selftest_main  # for start-up time, as in cmd_compare

    return selftest_main(args)


def cmd_calibrate(args) -> int:
    """``glvox calibrate``: ss-conservative's variants timed on this GPU, the fastest stored."""
    from .study.calibrate import main as calibrate_main  # for start-up time, as in cmd_compare

    return calibrate_main(args)


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
