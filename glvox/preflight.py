"""Checks of a command's arguments before any work: every command runs them first.

A command line that cannot succeed should fail in a second with one line,
not after minutes of loading and voxelizing (or with a traceback when the
result is written).  Each check raises a :class:`~glvox.errors.GlvoxError`
whose message the CLI prints as ``glvox: error: ...``; none loads a mesh,
makes a GL context or writes anything that stays.

The checks: output files (:func:`output_file`: the folder exists and takes
a file, the suffix is known), output folders (:func:`output_folder`), grid
options (:func:`grid_args`), the method and its options
(:func:`method_args`), mesh arguments (:func:`mesh_arg`), whether a format
holds the grid (:func:`format_fits`).  Below them, each command's
``validate_<command>(args)``, which ``glvox.cli`` runs before the command
(its parser's ``validate=``); a new command adds its own from these checks.
"""

from __future__ import annotations

import importlib.util
import math
import os
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Iterable, Sequence

import numpy as np

from . import datasets, io
from .errors import FormatError, GlvoxError, GridError
from .grid import DEFAULT_RESOLUTION, MAX_VOXELS, GridSpec, fit_grid
from .batch import BatchSettings
from .methods import Request, get_method
from .methods.attributes.passes import parse_attributes
from .methods.base import MethodInfo
from .methods.sdf.field import parse_band, parse_truncation, sign_request
from .methods.sdf.samples import check_samples
from .methods.ss.variant_store import store_path
from .study.options import (BENCH_PRESETS, CALIBRATE_MESH, CALIBRATE_REPEAT, CALIBRATE_SIZES, CHECKOUT_BASELINE,
                            COMPARE_PRESETS, check_binary)


def _writable_folder(folder: Path, what: str) -> None:
    """Create and delete a file in ``folder``: the only test of writability that
    holds for read-only mounts, /proc and permissions alike (root passes ``os.access``)."""
    try:
        with tempfile.TemporaryFile(dir=folder, prefix=".glvox-probe-"):
            pass
    except OSError as exc:
        raise GlvoxError(f"cannot write the {what} in {folder}: creating a file there fails "
                         f"({exc.strerror or exc})") from None


def output_file(path: str | os.PathLike, suffixes: Sequence[str], what: str = "output") -> Path:
    """Check an output file: a known suffix, an existing folder that takes a new file, not a folder.

    Parameters
    ----------
    path : path
    suffixes : sequence of str
        Accepted suffixes, lower case with the dot (``('.npz', '.binvox')``).
    what : str
        The argument's name in messages (``'output'``, ``'manifest'``).

    Returns
    -------
    Path
    """
    p = Path(path).expanduser()
    if p.suffix.lower() not in suffixes:
        raise FormatError(f"unknown {what} file suffix {p.suffix!r} for {p}: use {' or '.join(suffixes)}")
    if p.is_dir():
        raise GlvoxError(f"the {what} {p} is a folder; give a file name ending in {' or '.join(suffixes)}")
    folder = p.parent if str(p.parent) else Path(".")
    if not folder.is_dir():
        raise GlvoxError(f"the {what}'s folder {folder} does not exist")
    _writable_folder(folder, what)
    return p


def output_folder(path: str | os.PathLike, what: str = "output folder") -> Path:
    """Check an output folder: a folder (or not yet there) whose nearest existing folder takes files."""
    p = Path(path).expanduser()
    if p.exists() and not p.is_dir():
        raise GlvoxError(f"the {what} {p} is a file, not a folder")
    existing = p.absolute()
    while not existing.exists():
        existing = existing.parent
    if not existing.is_dir():
        raise GlvoxError(f"cannot make the {what} {p}: {existing} is a file")
    _writable_folder(existing, what)
    return p


def result_file(path: str | os.PathLike, kind: str | None = None, dims: Sequence[int] | None = None,
                what: str = "output") -> Path:
    """Check a voxel file to write: what :func:`glvox.io.check_writable` checks (a known
    suffix, the format's library, a result kind and dims the format holds, an existing
    folder), then that the folder really takes a new file.

    Parameters
    ----------
    path : path
    kind : {'surface', 'solid', 'sparse', 'ldi'}, optional
        The result's kind, when known.
    dims : (3,) int, optional
        The grid's dims, when known.
    what : str
        The argument's name in messages.
    """
    p = Path(path).expanduser()
    io.check_writable(p, kind=kind, dims=dims)
    _writable_folder(p.parent if str(p.parent) else Path("."), what)
    return p


def positive(name: str, value: Any, *, integer: bool = True) -> None:
    """``value`` is None or a positive (integer) number."""
    if value is None:
        return
    ok = value > 0 and (int(value) == value if integer else math.isfinite(value))
    if not ok:
        raise GlvoxError(f"{name} must be a positive {'integer' if integer else 'number'}, got {value!r}")


def grid_args(resolution: int | None = None, dims: Sequence[int] | None = None, voxel_size: float | None = None,
              bounds: Sequence[float] | None = None, padding: int = 0, tight: bool = False) -> GridSpec | None:
    """Check the grid options as :func:`glvox.grid.grid_for` will see them, before the mesh is loaded.

    Precedence as on the command line: ``dims``, else ``voxel_size``, else
    ``resolution``.

    Returns
    -------
    GridSpec or None
        The grid when it does not depend on the mesh (explicit ``bounds``;
        or ``dims``; or ``resolution`` without ``tight``: its dims are right,
        its placement is a unit box's), else None.
    """
    if resolution is None and dims is None and voxel_size is None:
        raise GridError("give -r/--resolution N, --dims NX NY NZ or --voxel-size H")
    if dims is not None or voxel_size is not None:
        resolution = None
    if voxel_size is not None and not (math.isfinite(voxel_size) and voxel_size > 0):
        raise GridError(f"voxel_size must be a finite positive number, got {voxel_size!r}")
    if bounds is not None:
        box = np.asarray(bounds, dtype=np.float64).reshape(2, 3)
        return fit_grid(box, resolution, dims=dims, voxel_size=voxel_size, padding=padding, tight=tight)
    unit = np.array([[0.0, 0.0, 0.0], [1.0, 1.0, 1.0]])
    # a stand-in voxel size: its dims depend on the mesh, but padding and exclusivity are checked
    spec = fit_grid(unit, resolution, dims=dims, voxel_size=None if voxel_size is None else 1.0,
                    padding=padding, tight=tight)
    return None if voxel_size is not None or (resolution is not None and tight) else spec


def method_args(name: str, options: dict[str, Any], kinds: Iterable[str] | None = None,
                command: str = "glvox voxelize", attributes=None, normals: str = "face",
                fill_attributes: str = "none") -> Request:
    """A registered method, of one of ``kinds`` when given, its options coerced and the
    attributes asked of it checked: the :class:`~glvox.methods.Request` the command runs."""
    return Request.make(name, options, attributes, normals, fill_attributes,
                        kinds=tuple(kinds) if kinds is not None else None, command=command)


def format_fits(path: Path, info: MethodInfo, spec: GridSpec) -> None:
    """Whether ``path``'s format (checked writable before) holds ``info``'s result on ``spec``,
    e.g. binvox holds cubic voxel grids only (the format registry decides)."""
    io.check_dims(path, info.kind, spec.dims)


# ---------------------------------------------------------------------------
# the commands' arguments (parsed by glvox.cli)
# ---------------------------------------------------------------------------


def parse_options(pairs: Sequence[str], extra: Sequence[str] = ()) -> dict[str, str]:
    """Method options from ``-O KEY=VALUE`` and from ``--KEY VALUE`` / ``--KEY=VALUE``."""
    out = {}
    for p in pairs:
        if "=" not in p:
            raise GlvoxError(f"method options are KEY=VALUE, got {p!r}")
        k, v = p.split("=", 1)
        out[k.strip().replace("-", "_")] = v.strip()
    rest = list(extra)
    while rest:
        tok = rest.pop(0)
        if not tok.startswith("--") or len(tok) < 3:
            raise GlvoxError(f"unexpected argument {tok!r}")
        if "=" in tok:
            k, v = tok[2:].split("=", 1)
        elif rest and not rest[0].startswith("--"):
            k, v = tok[2:], rest.pop(0)
        else:
            raise GlvoxError(f"method option {tok} needs a value")
        out[k.replace("-", "_")] = v
    return out


def mesh_arg(name: str) -> None:
    """A mesh argument names a file, a generated mesh or a mesh glvox can fetch (checked, not loaded)."""
    datasets.check_mesh_name(name)


#: The line a command prints (stderr, unless --quiet or --json) when it uses
#: the default grid.
DEFAULT_GRID_NOTE = f"glvox: grid: -r {DEFAULT_RESOLUTION} (default; give -r N, --dims or --voxel-size)"


def default_grid(args) -> bool:
    """Set ``args.resolution`` to :data:`~glvox.grid.DEFAULT_RESOLUTION` when no grid option
    (-r, --dims, --voxel-size) is given; whether it did (see :func:`note_default_grid`)."""
    if args.resolution is None and args.dims is None and args.voxel_size is None:
        args.resolution = DEFAULT_RESOLUTION
        return True
    return False


def note_default_grid(args, defaulted: bool) -> None:
    """Print :data:`DEFAULT_GRID_NOTE` on stderr when the default grid was taken, unless
    --quiet or --json; the validators call it last, so a failing check prints its error alone."""
    if defaulted and not (getattr(args, "quiet", False) or getattr(args, "json", False)):
        print(DEFAULT_GRID_NOTE, file=sys.stderr)


def _grid_args(args, bounds: bool = False) -> GridSpec | None:
    """:func:`grid_args` of a command's parsed grid options."""
    return grid_args(args.resolution, args.dims, args.voxel_size, args.bounds if bounds else None,
                     getattr(args, "padding", 0), getattr(args, "tight", False))


def attribute_output(request: Request, out: Path | None) -> None:
    """An output that keeps the attributes asked for (npz and .vti all; .vox, points and cubes the colour)."""
    names = request.attributes
    dropped = io.format_for(out).drops(names) if names and out is not None else []
    if dropped:
        raise GlvoxError(f"{out.name} would drop the attributes {dropped}: .npz and .vti keep every attribute, "
                         ".vox, .points.* and .cubes.* the colour only")


@dataclass(frozen=True)
class VoxelizeCall:
    """``glvox voxelize`` checked: what the command runs, nothing of it checked again.

    Attributes
    ----------
    request : Request
        The method, its coerced options and the attributes asked of it.
    output : Path or None
        The file to write, its suffix, folder and format checked.
    grid : GridSpec or None
        The grid when it does not depend on the mesh (``--bounds``), else None.
    output_fits : bool
        True when the output's format was checked against the grid's dims
        (known before the mesh is loaded).
    """

    request: Request
    output: Path | None
    grid: GridSpec | None
    output_fits: bool


def validate_voxelize(args) -> VoxelizeCall:
    request = method_args(args.method, parse_options(args.option, args.extra), attributes=args.attributes,
                          normals=args.normals, fill_attributes=args.fill_attributes)
    out = result_file(args.output, kind=request.info.kind) if args.output else None
    attribute_output(request, out)
    mesh_arg(args.mesh)
    defaulted = default_grid(args)
    if getattr(args, "fit", "center") == "binvox":
        given = [flag for flag, on in (("--dims", args.dims is not None), ("--voxel-size", args.voxel_size is not None),
                                       ("--bounds", args.bounds is not None), ("--padding", args.padding != 0),
                                       ("--tight", args.tight)) if on]
        if given:
            raise GlvoxError(f"--fit binvox places an N^3 grid by -r N alone (binvox -d N); drop {', '.join(given)}")
    spec = _grid_args(args, bounds=True)
    if out is not None and spec is not None:
        format_fits(out, request.info, spec)
    note_default_grid(args, defaulted)
    return VoxelizeCall(request, out, spec if args.bounds is not None else None, spec is not None)


#: Bytes per voxel ``glvox sdf`` holds at its peak: the float32 field and its GPU
#: readback, the solid's occupancy and winding numbers, the masks, the signed copy.
SDF_BYTES_PER_VOXEL = 22


def sdf_memory(dims: Sequence[int]) -> None:
    """GlvoxError, in one line, when a dense float grid of ``dims`` would not fit: over
    glvox's dense limit, or over the memory available now (Linux's MemAvailable)."""
    n = int(np.prod([int(d) for d in dims], dtype=np.int64))
    need = n * SDF_BYTES_PER_VOXEL
    have = _available_memory()
    if n > MAX_VOXELS or (have is not None and need > have):
        where = f"{have / 2**30:.1f} GiB are available" if have is not None else "over glvox's dense limit"
        raise GlvoxError(f"an SDF on {'x'.join(map(str, dims))} voxels needs about {need / 2**30:.1f} GiB "
                         f"({SDF_BYTES_PER_VOXEL} bytes per voxel) and {where}: use a smaller -r")


def _available_memory() -> int | None:
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    return None


@dataclass(frozen=True)
class SdfCall:
    """``glvox sdf`` checked: the output and the band in voxels (``inf`` for 'all')."""

    output: Path
    band: float


def validate_sdf(args) -> SdfCall:
    band = parse_band(args.band)
    parse_truncation(args.truncation)
    if args.samples is not None:
        check_samples(args.samples)
        out = output_file(args.output, (".npz",), "samples output")
    else:
        sign_request(args.sign)
        out = result_file(args.output, kind="sdf")
    mesh_arg(args.mesh)
    defaulted = default_grid(args)
    spec = _grid_args(args)
    if spec is not None and args.samples is None:
        sdf_memory(spec.dims)
    note_default_grid(args, defaulted and args.samples is None)
    return SdfCall(out, band)


def validate_batch(args) -> BatchSettings:
    """The batch's settings, checked once (:meth:`BatchSettings.validate`), which the command runs."""
    output_folder(args.output)
    if args.manifest:
        output_file(args.manifest, (".csv",), "manifest")
    if not os.path.exists(args.input):
        raise GlvoxError(f"batch input not found: {args.input} (a folder of meshes or a text file of paths)")
    if args.scheduler and args.workers is not None:
        raise GlvoxError("--workers sizes the local cluster; with --scheduler the cluster's own "
                         "workers run the batch, so give one or the other")
    if args.workers is not None and args.workers < 0:
        raise GlvoxError(f"--workers must be 0 (in this process) or more, got {args.workers}")
    options = parse_options(args.option)
    defaulted = default_grid(args)
    settings = BatchSettings(
        method=args.method, resolution=args.resolution,
        dims=tuple(args.dims) if args.dims is not None else None, voxel_size=args.voxel_size,
        padding=args.padding, tight=args.tight, options=tuple(sorted(options.items())),
        allow_open=args.allow_open, backend=args.backend, fmt=args.format, inspect=args.inspect,
        attributes=parse_attributes(args.attributes), normals=args.normals, fill_attributes=args.fill_attributes)
    settings.validate()
    spec = _grid_args(args)
    if args.format == "binvox" and (spec is None or len(set(spec.dims)) != 1):
        raise GlvoxError("binvox stores cubic grids only: use -r N without --tight or --voxel-size, or cubic "
                         "--dims, or --format npz")
    note_default_grid(args, defaulted)
    return settings


def ldi_options(args, info) -> dict:
    """The LDI method's options from -O, --axis and --lod-c."""
    options = parse_options(args.option)
    options["axis"] = args.axis
    if "lod_c" in info.options:
        options["lod_c"] = args.lod_c
    elif args.lod_c is not None:
        raise GlvoxError(f"--lod-c is an option of leung-wang-ldi, not of {args.method!r}")
    return {k: v for k, v in options.items() if v is not None}


def validate_ldi(args) -> Request:
    if args.output:
        result_file(args.output, kind="ldi")
    mesh_arg(args.mesh)
    info = get_method(args.method).info
    if info.kind != "ldi":
        raise GlvoxError(f"glvox ldi needs a method of kind 'ldi' (leung-wang-ldi, peel-ldi, reference-ldi), "
                         f"got {args.method!r} (kind {info.kind!r}); use glvox voxelize for voxel grids")
    positive("--lod-c", args.lod_c)
    request = method_args(args.method, ldi_options(args, info), kinds=("ldi",), command="glvox ldi")
    defaulted = default_grid(args)
    _grid_args(args)
    note_default_grid(args, defaulted)
    return request


def validate_volume(args) -> None:
    if args.output:
        result_file(args.output, kind="ldi")
    mesh_arg(args.mesh_a)
    mesh_arg(args.mesh_b)
    positive("--lod-c", args.lod_c)
    defaulted = default_grid(args)
    grid_args(args.resolution, args.dims, args.voxel_size)
    note_default_grid(args, defaulted)


def validate_inspect(args) -> None:
    mesh_arg(args.mesh)
    positive("-r/--resolution", args.resolution)


def validate_convert(args) -> None:
    """``glvox convert IN OUT``: both suffixes known, each format's library importable, the
    input a file, the output writable and not the input."""
    src = Path(args.input)
    io.check_readable(src)
    fmt = io.check_writable(args.output)
    dst = result_file(args.output)
    if args.no_coverage and "coverage" not in fmt.options:
        raise GlvoxError(f"--no-coverage is an option of .vdb output, not of {fmt.name}: {dst}")
    if dst.exists() and src.resolve() == dst.resolve():
        raise GlvoxError(f"input and output are the same file: {src}")


#: Largest picture side ``glvox render`` draws: the GL_MAX_RENDERBUFFER_SIZE every
#: OpenGL 4.5 driver must reach (llvmpipe reports exactly this), so no context is
#: needed to check it.
MAX_PICTURE = 16384


def validate_render(args) -> None:
    """``glvox render RESULT -o PICTURE.png``: the picture writable, the input readable,
    size, direction and up sensible, matplotlib (which writes the PNG) importable."""
    output_file(args.output, (".png",), "picture")
    io.check_readable(args.input)
    w, h = args.size
    if not (0 < w <= MAX_PICTURE and 0 < h <= MAX_PICTURE):
        raise GlvoxError(f"--size must be two integers in 1..{MAX_PICTURE} (pixels), got {w} {h}")
    d, u = np.asarray(args.direction, float), np.asarray(args.up, float)
    if not (np.all(np.isfinite(d)) and np.all(np.isfinite(u))) or np.linalg.norm(d) == 0:
        raise GlvoxError(f"--direction must be a finite non-zero vector, got {args.direction}")
    if np.linalg.norm(np.cross(d / np.linalg.norm(d), u)) < 1e-6:
        raise GlvoxError(f"--up {args.up} must not be parallel to --direction {args.direction}")
    if importlib.util.find_spec("matplotlib") is None:
        raise GlvoxError("glvox render writes PNG with matplotlib, which is not installed: "
                         "pip install 'glvox[compare]'")


def validate_study(args, presets: dict, name: str, *, meshes_needed: bool = True) -> None:
    """What ``glvox compare`` and ``glvox bench`` share: output folder, methods, meshes, sizes
    (``meshes_needed`` False: ``bench --end-to-end``, which takes a folder, or the shared meshes,
    and its first size, or 64)."""
    if args.out:
        output_folder(args.out)
    preset = presets.get(args.preset or "", {})
    if meshes_needed and (not (args.meshes or preset.get("meshes")) or not (args.sizes or preset.get("sizes"))):
        raise GlvoxError(f"give --preset {'|'.join(presets)}, or --meshes and -r/--sizes")
    for m in args.methods or []:
        get_method(m)
    for m in args.meshes or []:
        mesh_arg(m)
    for n in args.sizes or []:
        positive(f"{name} grid sizes", n)
    positive("--repeat", args.repeat)
    if args.check_max is not None and args.check_max < 0:
        raise GlvoxError(f"--check-max must be 0 (no reference checks) or a positive integer, got {args.check_max}")


def validate_compare(args) -> None:
    validate_study(args, COMPARE_PRESETS, "compare")


def validate_bench(args) -> None:
    if args.save_baseline:  # outputs first, as every command does
        output_file(args.save_baseline, (".json",), "baseline")
    if getattr(args, "sdf", False) and not (args.meshes and args.sizes):
        raise GlvoxError("glvox bench --sdf takes --meshes and -r/--sizes (no preset)")
    validate_study(args, BENCH_PRESETS, "bench", meshes_needed=args.end_to_end is None)
    if args.end_to_end and not Path(args.end_to_end).is_dir():
        raise GlvoxError(f"--end-to-end takes a folder of meshes, got {args.end_to_end}")
    if args.check and args.check != CHECKOUT_BASELINE and not Path(args.check).is_file():
        raise GlvoxError(f"no benchmark baseline at {args.check}: run `glvox bench --preset quick "
                         f"--save-baseline {args.check}` on the version to compare against")
    if args.budget is not None:
        positive("--budget", args.budget, integer=False)
    if getattr(args, "cuda_voxelizer", None) is not None:
        check_binary(args.cuda_voxelizer)


def validate_selftest(args) -> None:
    for m in args.methods or []:
        get_method(m)  # an unknown name: one line listing the known ones


def validate_calibrate(args) -> None:
    if args.show:
        if args.mesh is not None or args.sizes is not None or args.repeat is not None:
            raise GlvoxError("--show prints what is stored; it takes no --mesh, --sizes or --repeat")
        return
    args.mesh = args.mesh or CALIBRATE_MESH
    args.sizes = args.sizes or list(CALIBRATE_SIZES)
    args.repeat = CALIBRATE_REPEAT if args.repeat is None else args.repeat
    for n in args.sizes:
        positive("--sizes", n)
        if n < 2:
            raise GlvoxError(f"--sizes must be at least 2, got {n}")
    positive("--repeat", args.repeat)
    mesh_arg(args.mesh)
    folder = store_path().parent
    existing = next((p for p in (folder, *folder.parents) if p.exists()), Path("/"))
    _writable_folder(existing, "calibration")


def validate_data(args) -> None:
    for n in args.names:
        datasets.source(n)  # an unknown name: one line pointing at `glvox data list`
    if args.action == "fetch":
        if not args.names and not args.all:
            raise GlvoxError("give the names of the meshes to fetch (`glvox data list`), or --all")
        if any(datasets.find(n) is None for n in (args.names or datasets.mesh_names())):
            output_folder(datasets.data_dir(), "download folder")
    elif args.all:
        raise GlvoxError("--all goes with `glvox data fetch`")
    elif args.action == "path" and len(args.names) > 1:
        raise GlvoxError("glvox data path takes one mesh name (or none: the download folder)")
    elif args.action == "list" and args.names:
        raise GlvoxError("glvox data list takes no names")
