"""What a batch does: its settings, the meshes it finds and the job of each mesh."""

from __future__ import annotations

import os
from collections import Counter
from dataclasses import dataclass
from pathlib import Path
from typing import Sequence

from ..errors import GlvoxError, GridError, MeshLoadError, MethodError
from ..methods import Request, get_method

#: Kinds of result that :func:`glvox.io.save` writes.
SAVED_KINDS = ("surface", "solid", "sparse")

#: Suffixes of point clouds and other non-mesh formats trimesh reads; never batch inputs.
_NOT_MESH_FORMATS = {"xyz", "stl_ascii"}


def mesh_suffixes() -> tuple[str, ...]:
    """File suffixes (with the dot, lower case) of the mesh formats trimesh can load here."""
    # trimesh, dask and distributed are imported lazily in glvox.batch: they
    # take longer to import than the rest of glvox, and commands such as
    # `glvox batch --help` or a refused setting need none of them
    from trimesh.exchange.load import mesh_formats

    return tuple(sorted(f".{f}" for f in mesh_formats() if f not in _NOT_MESH_FORMATS))


@dataclass(frozen=True)
class BatchSettings:
    """What every mesh of a batch is voxelized with (the arguments of ``glvox voxelize``).

    Attributes
    ----------
    method : str
        Registry name.
    resolution : int, optional
        N: voxels along the longest axis (cubic N^3 grid), unless ``dims`` or
        ``voxel_size`` is given.
    dims : (3,) int, optional
    voxel_size : float, optional
        World units.
    padding : int
    tight : bool
    options : tuple of (str, str)
        Method options, as ``-O KEY=VALUE`` gives them.
    allow_open : bool
        Let solid methods run on meshes that are not watertight.
    backend : str, optional
        ``'egl'``, ``'osmesa'`` or ``'auto'``.
    fmt : {'npz', 'binvox'}
        Output format.
    inspect : bool
        Also inspect every mesh (:func:`glvox.inspect.inspect_mesh`, with the
        uncertain share on the batch's grid) into the manifest's extra
        columns; off by default: it takes longer than loading the mesh
        (0.5-1.6 s for 17k-200k triangles here).
    attributes : tuple of str
        Per-voxel attributes (``--attributes``; npz only).
    normals : {'face', 'vertex'}
    fill_attributes : {'none', 'nearest'}
    """

    method: str
    resolution: int | None = None
    dims: tuple[int, int, int] | None = None
    voxel_size: float | None = None
    padding: int = 0
    tight: bool = False
    options: tuple[tuple[str, str], ...] = ()
    allow_open: bool = False
    backend: str | None = None
    fmt: str = "npz"
    inspect: bool = False
    attributes: tuple[str, ...] = ()
    normals: str = "face"
    fill_attributes: str = "none"

    def validate(self) -> None:
        """Refuse unknown methods, options, formats and grid arguments before any work."""
        if self.fmt not in ("npz", "binvox"):
            raise GlvoxError(f"output format must be 'npz' or 'binvox', got {self.fmt!r}")
        if self.resolution is None and self.dims is None and self.voxel_size is None:
            raise GridError("give -r/--resolution N, --dims NX NY NZ or --voxel-size H")
        info = get_method(self.method).info
        if info.kind not in SAVED_KINDS:
            raise MethodError(f"glvox batch writes voxel grids (npz, binvox), and {self.method!r} returns "
                              f"a result of kind {info.kind!r}, which glvox cannot save; use a method of "
                              f"kind {', '.join(SAVED_KINDS)}")
        self.request()
        if self.attributes and self.fmt != "npz":
            raise GlvoxError(f"{self.fmt} files would drop the attributes; use --format npz")

    def request(self) -> Request:
        """The method request these settings run (options coerced, attributes checked)."""
        return Request.make(self.method, dict(self.options), self.attributes, self.normals, self.fill_attributes)

    def params(self) -> str:
        """The settings as ``glvox voxelize`` arguments; equal strings mean equal outputs."""
        parts = [f"-m {self.method}"]
        if self.dims is not None:
            parts.append("--dims " + " ".join(str(d) for d in self.dims))
        elif self.voxel_size is not None:
            parts.append(f"--voxel-size {self.voxel_size!r}")
        else:
            parts.append(f"-r {self.resolution}")
        if self.padding:
            parts.append(f"--padding {self.padding}")
        if self.tight:
            parts.append("--tight")
        parts += [f"-O {k}={v}" for k, v in sorted(self.options)]
        if self.allow_open:
            parts.append("--allow-open")
        if self.attributes:
            parts.append(f"--attributes {','.join(self.attributes)} --normals {self.normals} "
                         f"--fill-attributes {self.fill_attributes}")
        parts.append(f"--format {self.fmt}")
        return " ".join(parts)


@dataclass(frozen=True)
class Job:
    """One mesh of a batch.

    Attributes
    ----------
    input : str
        Absolute path of the mesh file.
    rel : str
        Its path relative to the input root, POSIX separators (the manifest key).
    output : str
        Absolute path of the output file.
    out_rel : str
        Its path relative to the output folder.
    """

    input: str
    rel: str
    output: str
    out_rel: str


def _is_hidden(name: str) -> bool:
    # dot files include our own temporary outputs and macOS "._x.obj" resource forks
    return name.startswith(".")


def _search_folder(src: Path, wanted: tuple[str, ...], exclude: str | os.PathLike | None) -> list[Path]:
    """Files under ``src`` ending with one of ``wanted``, sorted, hidden ones and ``exclude`` skipped."""
    skip = Path(exclude).absolute() if exclude is not None else None
    found: list[Path] = []
    for dirpath, dirnames, filenames in os.walk(src):
        here = Path(dirpath)
        dirnames[:] = sorted(d for d in dirnames
                             if not _is_hidden(d) and (skip is None or here / d != skip))
        found += [here / f for f in sorted(filenames)
                  if not _is_hidden(f) and f.lower().endswith(wanted)]
    if not found:
        raise MeshLoadError(f"no mesh files (suffixes {' '.join(wanted)}) under {src}")
    return found


def _read_list(src: Path) -> list[Path]:
    """The mesh paths a list file names, in order, without duplicates."""
    if not src.exists():
        raise MeshLoadError(f"batch input not found: {src} (expected a folder or a text file of mesh paths)")
    if src.name.lower().endswith(mesh_suffixes()):
        raise MeshLoadError(f"{src} is a mesh file; glvox batch takes a folder or a text file listing "
                            "mesh paths (use glvox voxelize for one mesh)")
    try:
        lines = src.read_text().splitlines()
    except (OSError, UnicodeDecodeError) as exc:
        raise MeshLoadError(f"cannot read the mesh list {src}: {exc}") from None
    meshes, seen = [], set()
    for ln in lines:
        ln = ln.strip()
        if not ln or ln.startswith("#"):
            continue
        p = Path(ln).expanduser()
        p = Path(os.path.normpath(p if p.is_absolute() else src.parent / p))
        if p not in seen:
            seen.add(p)
            meshes.append(p)
    if not meshes:
        raise MeshLoadError(f"the mesh list {src} names no file")
    return meshes


def find_meshes(source: str | os.PathLike, *, suffixes: Sequence[str] | None = None,
                exclude: str | os.PathLike | None = None) -> tuple[Path, list[Path]]:
    """The mesh files of a batch input and the root their outputs mirror.

    Parameters
    ----------
    source : path
        A folder, searched recursively (hidden files and folders skipped) for
        files whose suffix is in ``suffixes``; or a text file with one mesh
        path per line (blank lines and lines starting with ``#`` ignored,
        relative paths relative to the list's folder), taken as listed.
    suffixes : sequence of str, optional
        Suffixes with or without the dot, case-insensitive; default
        :func:`mesh_suffixes`.  Ignored for a list file.
    exclude : path, optional
        A folder not to search (the output folder when it lies inside the input).

    Returns
    -------
    root : Path
        The input folder, or the deepest folder holding every listed mesh.
    meshes : list of Path
        Absolute paths, sorted (folder) or in list order, without duplicates.

    Raises
    ------
    MeshLoadError
        When ``source`` does not exist, is itself a mesh file, or holds no mesh.
    """
    src = Path(source).expanduser().absolute()
    wanted = tuple(s.lower() if s.startswith(".") else "." + s.lower()
                   for s in (suffixes or mesh_suffixes()))
    if src.is_dir():
        return src, _search_folder(src, wanted, exclude)
    meshes = _read_list(src)
    root = Path(os.path.commonpath([str(p.parent) for p in meshes]))
    return root, meshes


def plan_jobs(source: str | os.PathLike, out_dir: str | os.PathLike, fmt: str = "npz", *,
              suffixes: Sequence[str] | None = None) -> list[Job]:
    """The jobs of a batch: each mesh and its output path, mirroring the input tree.

    ``chairs/a/model.obj`` under the input root goes to ``OUT/chairs/a/model.npz``.
    Meshes of one folder that differ only by suffix (``a.obj``, ``a.stl``) keep
    it: ``a.obj.npz``, ``a.stl.npz``.
    """
    out = Path(out_dir).expanduser().absolute()
    root, meshes = find_meshes(source, suffixes=suffixes, exclude=out)
    suffix = "." + fmt
    rels = [p.relative_to(root) for p in meshes]
    plain = [r.with_suffix(suffix) for r in rels]
    counts = Counter(plain)
    outs = [q if counts[q] == 1 else r.with_name(r.name + suffix) for r, q in zip(rels, plain)]
    clash = [str(o) for o, n in Counter(outs).items() if n > 1]
    if clash:
        raise GlvoxError(f"several meshes would be written to the same output: {', '.join(sorted(clash)[:5])}")
    return [Job(input=str(p), rel=r.as_posix(), output=str(out / o), out_rel=o.as_posix())
            for p, r, o in zip(meshes, rels, outs)]
