"""GLSL loading: recursive ``#include``, injected defines, per-context program cache.

Every GLSL source lives in the top-level ``shaders/`` folder of the checkout,
shipped in the wheel as the data package ``glvox._shaders`` (this loader is
``glvox.gl.shaders``).  Paths are relative to
that folder (``"common/bits.glsl"``); users can add their own folders.

Preprocessing
-------------
* ``#include "path"`` is resolved relative to the including file, then
  against the search folders.  Each file is included once per program (a
  second include of the same file is dropped), and nesting deeper than
  :data:`MAX_INCLUDE_DEPTH` is an error (it means an include cycle or a
  design problem).
* Defines are injected right after the top file's ``#version`` line,
  followed by a ``#line`` directive, so the rest keeps its own line numbers.
* ``#line`` directives encode the file: line L of the n-th file is written as
  ``n * LINE_BASE + L``.  Drivers disagree on whether they print the
  source-string number of ``#line L S`` (Mesa prints 0), but all print the
  line, so errors are mapped back to ``file:line`` from the line alone.
"""

from __future__ import annotations

import os
import re
import time
import weakref
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any, Iterable, Mapping, Sequence

from ..errors import ShaderError
from .compiler_log import map_log

MAX_INCLUDE_DEPTH = 16
LINE_BASE = 100000

_INCLUDE = re.compile(r'^\s*#\s*include\s+[<"]([^">]+)[">]\s*(//.*)?$')
_VERSION = re.compile(r"^\s*#\s*version\b")
_IDENT = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")
# a storage block's declaration: `... buffer Name {` (comments stripped first)
_STORAGE_BLOCK = re.compile(r"\bbuffer\s+([A-Za-z_][A-Za-z0-9_]*)\s*\{")
# the same with the qualifiers before it: `layout(...) readonly buffer Name {`
_QUALIFIED_BLOCK = re.compile(r"((?:\b(?:layout\s*\([^)]*\)|readonly|writeonly|coherent|volatile|restrict)\s*)*)"
                              r"\bbuffer\s+([A-Za-z_][A-Za-z0-9_]*)\s*\{")
_COMMENT = re.compile(r"//[^\n]*|/\*.*?\*/", re.S)



def builtin_shader_dir() -> Path:
    """The folder holding glvox's own shaders (checkout or installed wheel).

    A source checkout's own ``shaders/`` comes first: an editable install maps
    ``glvox._shaders`` to the checkout it was installed from, so another checkout
    (a git worktree run with PYTHONPATH) would otherwise run its own Python with
    that checkout's shaders.
    """
    here = Path(__file__).resolve().parents[2]
    if (here / "pyproject.toml").is_file() and (here / "shaders" / "common").is_dir():
        return here / "shaders"
    try:
        root = resources.files("glvox._shaders")
        path = Path(str(root))
        if (path / "common").is_dir():
            return path
    except (ModuleNotFoundError, TypeError):
        pass
    path = Path(__file__).resolve().parents[2] / "shaders"
    if (path / "common").is_dir():
        return path
    raise ShaderError(
        "glvox's shader folder was not found (neither the installed package glvox._shaders "
        f"nor {path}); reinstall glvox"
    )


def _search_dirs(extra: Iterable[os.PathLike | str] = ()) -> tuple[Path, ...]:
    dirs = [Path(p).resolve() for p in extra]
    env = os.environ.get("GLVOX_SHADER_PATH")
    if env:
        dirs += [Path(p).resolve() for p in env.split(os.pathsep) if p]
    dirs.append(builtin_shader_dir())
    return tuple(dirs)


def format_define(name: str, value: Any) -> str:
    """``#define name value`` for a bool, int, float or string value."""
    if not _IDENT.match(name):
        raise ShaderError(f"define name must be a GLSL identifier, got {name!r}")
    if isinstance(value, bool):
        text = "1" if value else "0"
    elif isinstance(value, int):
        text = str(value)
    elif isinstance(value, float):
        text = repr(value)
        if "e" not in text and "." not in text:
            text += ".0"
    elif value is None:
        text = ""
    else:
        text = str(value)
        if "\n" in text:
            raise ShaderError(f"define {name} must be one line, got {value!r}")
    return f"#define {name} {text}".rstrip()


@dataclass
class Source:
    """A preprocessed GLSL source and the files it came from.

    Attributes
    ----------
    text : str
        The source handed to the compiler.
    files : list of Path
        Files by index, as encoded in ``#line`` (index 0 is the top file).
    """

    text: str
    files: list[Path] = field(default_factory=list)
    root: Path | None = None

    @property
    def name(self) -> str:
        """The top file, as messages name it."""
        return self._name(self.files[0])

    def location(self, encoded_line: int) -> str:
        """``file:line`` for a line number as the compiler printed it."""
        idx, line = divmod(int(encoded_line), LINE_BASE)
        if 0 <= idx < len(self.files):
            return f"{self._name(self.files[idx])}:{line}"
        return f"<generated>:{encoded_line}"

    def _name(self, path: Path) -> str:
        if self.root is not None:
            try:
                return "shaders/" + path.relative_to(self.root).as_posix()
            except ValueError:
                pass
        return str(path)

    @property
    def storage_blocks(self) -> frozenset[str]:
        """Names of the storage blocks (``buffer Name { ... }``) the source declares.

        Parsed from the preprocessed text (includes expanded, comments
        stripped).  Conditional compilation is not evaluated: a block inside
        an ``#if`` branch that is not taken counts as declared, which is the
        safe side (:func:`glvox.gpu.dispatch.bind` skips a declared block the
        program does not have).
        """
        return frozenset(_STORAGE_BLOCK.findall(_COMMENT.sub(" ", self.text)))

    @property
    def storage_access(self) -> dict[str, tuple[bool, bool, bool]]:
        """Storage block name -> (read, written, atomic) as the source allows: ``readonly``
        blocks are not written, ``writeonly`` ones not read, others both; ``atomic`` when
        every use of the block's members is the first argument of an ``atomic*()`` call
        (what :mod:`glvox.testing.hazards` checks barriers by).  Read from the branches of
        ``#if`` the defines select (:func:`active_text`)."""
        text = active_text(_COMMENT.sub(" ", self.text))
        out: dict[str, tuple[bool, bool, bool]] = {}
        for m in _QUALIFIED_BLOCK.finditer(text):
            quals, name = m.group(1), m.group(2)
            body = text[m.end():text.find("}", m.end())]
            members = re.findall(r"([A-Za-z_]\w*)\s*(?:\[[^\]]*\])?\s*;", body)
            rest = text[:m.start()] + text[m.end() + len(body):]
            uses = [u for mem in members for u in re.finditer(rf"\b{mem}\b", rest)]
            atomic = bool(uses) and all(re.search(r"\batomic\w*\s*\(\s*$", rest[:u.start()]) for u in uses)
            read = re.search(r"\bwriteonly\b", quals) is None
            written = re.search(r"\breadonly\b", quals) is None
            old = out.get(name)
            out[name] = (read, written, atomic) if old is None else (read or old[0], written or old[1],
                                                                     atomic and old[2])
        return out

    def map_log(self, log: str) -> str:
        """``log`` with each located line (Mesa, NVIDIA, AMD or glslang shape,
        :mod:`glvox.gl.compiler_log`) rewritten to ``file:line[:column]:
        severity: message``; lines without a location are kept as they are."""
        return map_log(log, self.location)


_DIRECTIVE = re.compile(r"^\s*#\s*(if|ifdef|ifndef|elif|else|endif|define|undef)\b(.*)$")
_DEFINED = re.compile(r"\bdefined\s*(?:\(\s*([A-Za-z_]\w*)\s*\)|([A-Za-z_]\w*))")
_WORD = re.compile(r"[A-Za-z_]\w*")


def _condition(expr: str, macros: Mapping[str, str], depth: int = 0) -> bool:
    """A ``#if`` expression's value: integers, macros, ``defined``, C's operators."""
    expr = _DEFINED.sub(lambda m: "1" if (m.group(1) or m.group(2)) in macros else "0", expr)

    def word(m: re.Match) -> str:
        value = macros.get(m.group(0))
        if value is None or depth > 8:
            return "0"
        return f"({_expand(value, macros, depth + 1)})"

    if re.search(r"[A-Za-z_]\w*\s*\(", _DEFINED.sub("", expr)):
        raise ValueError(f"a function-like macro in #if {expr}")
    expr = _WORD.sub(word, expr)
    expr = re.sub(r"(\d+)[uU]\b", r"\1", expr).replace("&&", " and ").replace("||", " or ")
    expr = re.sub(r"!(?!=)", " not ", expr)
    return bool(eval(expr, {"__builtins__": {}}, {}))  # digits and operators only by now


def _expand(value: str, macros: Mapping[str, str], depth: int) -> str:
    return _WORD.sub(lambda m: f"({_expand(macros[m.group(0)], macros, depth + 1)})"
                     if m.group(0) in macros and depth <= 8 else m.group(0), value)


def active_text(text: str) -> str:
    """``text`` with the lines of ``#if`` branches its own ``#define``s do not select blanked
    (line numbers kept).  An expression this cannot evaluate keeps every branch: the
    text stays a superset of what the compiler sees."""
    macros: dict[str, str] = {}
    out: list[str] = []
    stack: list[tuple[bool, bool, bool]] = []  # (enclosing active, this branch active, a branch taken)
    active = True
    for line in text.split("\n"):
        m = _DIRECTIVE.match(line)
        if m is None:
            out.append(line if active else "")
            continue
        kind, rest = m.group(1), m.group(2).strip()
        out.append("")
        if kind in ("if", "ifdef", "ifndef"):
            try:
                value = (_condition(rest, macros) if kind == "if" else
                         (rest.split()[0] in macros) == (kind == "ifdef"))
            except Exception:  # noqa: BLE001 - not evaluable here: keep the branch
                value = None
            stack.append((active, value is not False, value is True))
            active = active and value is not False
        elif kind == "elif" and stack:
            outer, _, taken = stack[-1]
            try:
                value = False if taken else _condition(rest, macros)
            except Exception:  # noqa: BLE001
                value = None
            stack[-1] = (outer, value is not False, taken or value is True)
            active = outer and value is not False
        elif kind == "else" and stack:
            outer, _, taken = stack[-1]
            stack[-1] = (outer, not taken, True)
            active = outer and not taken
        elif kind == "endif" and stack:
            active = stack.pop()[0]
        elif active and kind == "define":
            parts = rest.split(None, 1)
            if parts and "(" not in parts[0]:
                macros[parts[0]] = parts[1] if len(parts) > 1 else ""
        elif active and kind == "undef" and rest:
            macros.pop(rest.split()[0], None)
    return "\n".join(out)


def resolve(path: str | os.PathLike, dirs: Sequence[Path], relative_to: Path | None = None) -> Path:
    p = Path(path)
    if p.is_absolute():
        if p.is_file():
            return p
    else:
        cands = ([relative_to / p] if relative_to is not None else []) + [d / p for d in dirs]
        for c in cands:
            if c.is_file():
                return c.resolve()
    where = ", ".join(str(d) for d in ([relative_to] if relative_to else []) + list(dirs))
    raise ShaderError(f"shader file {str(path)!r} not found (searched {where})")


def preprocess(path: str | os.PathLike, defines: Mapping[str, Any] | None = None,
               search: Iterable[os.PathLike | str] = ()) -> Source:
    """Load ``path`` with its includes and ``defines`` into one :class:`Source`."""
    dirs = _search_dirs(search)
    top = resolve(path, dirs)
    files: list[Path] = []
    seen: set[Path] = set()

    def read(p: Path) -> list[str]:
        try:
            return p.read_text(encoding="utf-8").splitlines()
        except OSError as exc:
            raise ShaderError(f"cannot read shader file {p}: {exc}") from None

    def expand(p: Path, depth: int, chain: tuple[str, ...]) -> list[str]:
        if depth > MAX_INCLUDE_DEPTH:
            raise ShaderError(
                f"#include nested deeper than {MAX_INCLUDE_DEPTH} levels: {' -> '.join(chain)}"
            )
        idx = len(files)
        files.append(p)
        seen.add(p)
        out = [f"#line {idx * LINE_BASE + 1}"]
        for n, line in enumerate(read(p), start=1):
            m = _INCLUDE.match(line)
            if m:
                child = resolve(m.group(1), dirs, relative_to=p.parent)
                # include-once also makes cycles harmless: a file already in is skipped
                if child not in seen:
                    out.append(f"// begin include {m.group(1)}")
                    out += expand(child, depth + 1, chain + (str(child),))
                    out.append(f"// end include {m.group(1)}")
                out.append(f"#line {idx * LINE_BASE + n + 1}")
                continue
            if _VERSION.match(line):
                raise ShaderError(f"#version may only appear in the top file, found in {p}:{n}")
            out.append(line)
        return out

    lines = read(top)
    vline = next((i for i, l in enumerate(lines) if _VERSION.match(l)), None)
    if vline is None:
        raise ShaderError(f"{top}: the top shader file must start with a #version line")
    if any(l.strip() and not l.strip().startswith("//") for l in lines[:vline]):
        raise ShaderError(f"{top}:{vline + 1}: only comments may precede #version")
    files.append(top)
    seen.add(top)
    out = [lines[vline]]
    out += [format_define(k, v) for k, v in (defines or {}).items()]
    out.append(f"#line {vline + 2}")
    for n, line in enumerate(lines[vline + 1:], start=vline + 2):
        m = _INCLUDE.match(line)
        if m:
            child = resolve(m.group(1), dirs, relative_to=top.parent)
            if child not in seen:
                out.append(f"// begin include {m.group(1)}")
                out += expand(child, 1, (str(top), str(child)))
                out.append(f"// end include {m.group(1)}")
            out.append(f"#line {n + 1}")
            continue
        if _VERSION.match(line):
            raise ShaderError(f"#version appears twice in {top} (line {n})")
        out.append(line)
    return Source(text="\n".join(out) + "\n", files=files, root=dirs[-1])


# ---------------------------------------------------------------------------
# programs
# ---------------------------------------------------------------------------


@dataclass(frozen=True)
class ProgramSource:
    """What the loader knows of a program it built: its files and declared storage blocks.

    Attributes
    ----------
    files : tuple of str
        The top file of each stage, as messages name them (``shaders/ss/fill.comp``).
    storage_blocks : frozenset of str
        Storage block names the stages' sources declare, active or not.
    storage_access : mapping
        Block name -> (read, written, atomic) over the stages (:attr:`Source.storage_access`).
    """

    files: tuple[str, ...]
    storage_blocks: frozenset[str]
    storage_access: Mapping[str, tuple[bool, bool, bool]] = field(default_factory=dict, compare=False, hash=False)

    @property
    def name(self) -> str:
        """The files, as one message names them."""
        return " + ".join(self.files)


# program -> ProgramSource, for the programs compute_program / render_program built.  A side
# table rather than an attribute on the moderngl object: moderngl's objects are not ours, and
# the entry goes away with the program.
_SOURCES: "weakref.WeakKeyDictionary[Any, ProgramSource]" = weakref.WeakKeyDictionary()


def program_source(prog) -> ProgramSource | None:
    """The :class:`ProgramSource` of a program built by this module, else None."""
    try:
        return _SOURCES.get(prog)
    except TypeError:  # not weak-referenceable: not one of ours
        return None


def _remember(prog, sources: Iterable[Source]) -> None:
    sources = list(sources)
    access: dict[str, tuple[bool, bool, bool]] = {}
    for src in sources:
        for name, (read, written, atomic) in src.storage_access.items():
            old = access.get(name, (False, False, True))
            access[name] = (read or old[0], written or old[1], atomic and old[2])
    _SOURCES[prog] = ProgramSource(
        files=tuple(s.name for s in sources),
        storage_blocks=frozenset().union(*(s.storage_blocks for s in sources)),
        storage_access=access,
    )


def _cache_key(kind: str, paths: Sequence[str], defines: Mapping[str, Any] | None,
               extra: Any = ()) -> tuple:
    d = tuple(sorted((k, repr(v)) for k, v in (defines or {}).items()))
    return (kind, tuple(str(p) for p in paths), d, extra)


def _compile_error(exc: Exception, sources: Mapping[str, Source]) -> ShaderError:
    log = str(exc)
    if "Linker failed" in log:
        names = ", ".join(s.name for s in sources.values())
        return ShaderError(f"linking {names} failed:\n{log.strip()}")
    # which stage failed: moderngl prints "<stage>_shader" then the log
    for stage, src in sources.items():
        if f"{stage}_shader" in log:
            return ShaderError(f"compiling {src.name} ({stage} shader) failed:\n{src.map_log(log).strip()}")
    src = next(iter(sources.values()))
    return ShaderError(f"shader compilation failed:\n{src.map_log(log).strip()}")


def compute_program(ctx, path: str, defines: Mapping[str, Any] | None = None,
                    search: Iterable[os.PathLike | str] = ()):
    """A compiled ``moderngl.ComputeShader`` for ``path``, cached on ``ctx``.

    Parameters
    ----------
    ctx : glvox.gl.context.GLContext
    path : str
        Shader path relative to a search folder, e.g. ``"testing/bits.comp"``.
    defines : mapping, optional
        Injected after ``#version``; part of the cache key.
    """
    search = tuple(search)
    key = _cache_key("compute", [path], defines, tuple(str(s) for s in search))
    prog = ctx.programs.get(key)
    if prog is not None:
        return prog
    src = preprocess(path, defines, search)
    t0 = time.perf_counter()
    try:
        prog = ctx.mgl.compute_shader(src.text)
    except Exception as exc:  # moderngl.Error
        raise _compile_error(exc, {"compute": src}) from None
    ctx.compile_seconds += time.perf_counter() - t0
    _remember(prog, [src])
    ctx.programs[key] = prog
    return prog


def render_program(ctx, vertex: str, fragment: str | None = None, geometry: str | None = None,
                   defines: Mapping[str, Any] | None = None, varyings: Sequence[str] = (),
                   search: Iterable[os.PathLike | str] = ()):
    """A linked ``moderngl.Program`` from stage files, cached on ``ctx``."""
    search = tuple(search)
    paths = [p for p in (vertex, fragment, geometry) if p is not None]
    key = _cache_key("render", paths, defines, (tuple(varyings), tuple(str(s) for s in search)))
    prog = ctx.programs.get(key)
    if prog is not None:
        return prog
    srcs = {"vertex": preprocess(vertex, defines, search)}
    if fragment is not None:
        srcs["fragment"] = preprocess(fragment, defines, search)
    if geometry is not None:
        srcs["geometry"] = preprocess(geometry, defines, search)
    t0 = time.perf_counter()
    try:
        prog = ctx.mgl.program(
            vertex_shader=srcs["vertex"].text,
            fragment_shader=srcs["fragment"].text if "fragment" in srcs else None,
            geometry_shader=srcs["geometry"].text if "geometry" in srcs else None,
            varyings=tuple(varyings),
        )
    except Exception as exc:
        raise _compile_error(exc, srcs) from None
    ctx.compile_seconds += time.perf_counter() - t0
    _remember(prog, srcs.values())
    ctx.programs[key] = prog
    return prog
