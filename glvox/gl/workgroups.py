"""What a compute shader asks of the context, read from its source.

A method's capability check must match what its shaders declare, per
dimension: GL guarantees only ``1024 x 1024 x 64`` work group sizes and 1024
invocations (GL 4.6 core, Table 23.62) and NVIDIA reports exactly that, so a
``local_size_x = 256`` shader runs everywhere while a ``local_size_z = 256`` one
would not.  :func:`compute_needs` preprocesses a shader with the defines the
method passes (``#include``, ``#ifdef``/``#if``, object-like ``#define`` and
``const`` integers) and evaluates

* ``layout(local_size_x = X, local_size_y = Y, local_size_z = Z) in;``
  (a missing size is 1), and
* the bytes of its ``shared`` arrays (scalars and vectors of 4-byte
  components; an unknown type is an error, not a guess),
* its shader storage blocks: how many (GL_MAX_COMPUTE_SHADER_STORAGE_BLOCKS,
  8 guaranteed, 16 on NVIDIA, iris and llvmpipe) and the highest ``binding``
  (GL_MAX_SHADER_STORAGE_BUFFER_BINDINGS),

so the numbers in :class:`~glvox.methods.base.Requirements` come from the
shaders rather than from hand-written constants.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from functools import lru_cache
from typing import Any, Iterable, Mapping

from ..errors import ShaderError
from .shaders import builtin_shader_dir, preprocess

_SIZES = {"x": 0, "y": 1, "z": 2}
#: Bytes per element of the types a ``shared`` declaration may use.  Vectors
#: of three are counted as four components: the std430-like padding some
#: drivers apply to shared storage, so the estimate does not undercount.
_TYPE_BYTES = {"uint": 4, "int": 4, "float": 4, "bool": 4,
               "uvec2": 8, "ivec2": 8, "vec2": 8, "bvec2": 8,
               "uvec3": 16, "ivec3": 16, "vec3": 16, "uvec4": 16, "ivec4": 16, "vec4": 16,
               "double": 8, "dvec2": 16, "dvec3": 32, "dvec4": 32, "mat4": 64}

_LAYOUT_IN = re.compile(r"layout\s*\(([^)]*local_size[^)]*)\)\s*in\s*;")
_LOCAL = re.compile(r"local_size_([xyz])\s*=\s*([^,]+)")
_SHARED = re.compile(r"^\s*shared\s+(\w+)\s+(\w+)\s*((?:\[[^\]]*\]\s*)*);", re.M)
_CONST = re.compile(r"^\s*const\s+(?:uint|int)\s+(\w+)\s*=\s*([^;]+);", re.M)
_BUFFER = re.compile(r"layout\s*\(([^)]*)\)\s*(?:\w+\s+)*buffer\s+\w+\s*\{")
_BINDING = re.compile(r"binding\s*=\s*([^,)]+)")
_DIRECTIVE = re.compile(r"^\s*#\s*(\w+)\s*(.*)$")
_TOKEN = re.compile(r"\s*(?:(\d+)[uU]?|(\w+)|(<<|>>|<=|>=|==|!=|&&|\|\||[-+*/%()?:<>!~&|^]))")


@dataclass(frozen=True)
class ComputeNeeds:
    """What compute shaders need: the largest work group size per dimension,
    the largest invocation count of one group, the largest shared memory of
    one program in bytes, the most storage blocks of one program and the
    storage buffer bindings used (highest ``binding`` + 1); the maximum over
    the shaders joined with ``|``."""

    local_size: tuple[int, int, int] = (0, 0, 0)
    invocations: int = 0
    shared_bytes: int = 0
    storage_blocks: int = 0
    storage_bindings: int = 0

    def __or__(self, other: "ComputeNeeds") -> "ComputeNeeds":
        return ComputeNeeds(tuple(max(a, b) for a, b in zip(self.local_size, other.local_size)),
                            max(self.invocations, other.invocations), max(self.shared_bytes, other.shared_bytes),
                            max(self.storage_blocks, other.storage_blocks),
                            max(self.storage_bindings, other.storage_bindings))


class _Expr:
    """Integer GLSL/preprocessor expressions: literals, names (macros, consts),
    ``uint(..)``/``int(..)`` casts, the C operators and ``?:``."""

    _BINARY = [("||",), ("&&",), ("|",), ("^",), ("&",), ("==", "!="), ("<", "<=", ">", ">="),
               ("<<", ">>"), ("+", "-"), ("*", "/", "%")]

    def __init__(self, text: str, names: Mapping[str, Any], undefined_zero: bool):
        self.toks, pos = [], 0
        text = text.strip()
        while pos < len(text):
            m = _TOKEN.match(text, pos)
            if not m or m.end() == pos:
                raise ValueError(f"cannot read {text[pos:]!r}")
            self.toks.append(int(m.group(1)) if m.group(1) else (m.group(2) or m.group(3)))
            pos = m.end()
        self.i, self.names, self.undefined_zero = 0, names, undefined_zero

    def value(self) -> int:
        v = self._ternary()
        if self.i != len(self.toks):
            raise ValueError(f"trailing {self.toks[self.i:]}")
        return int(v)

    def _peek(self):
        return self.toks[self.i] if self.i < len(self.toks) else None

    def _take(self, want=None):
        tok = self._peek()
        if want is not None and tok != want:
            raise ValueError(f"expected {want!r}, got {tok!r}")
        self.i += 1
        return tok

    def _ternary(self) -> int:
        cond = self._binary(0)
        if self._peek() != "?":
            return cond
        self._take("?")
        a = self._ternary()
        self._take(":")
        b = self._ternary()
        return a if cond else b

    def _binary(self, level: int) -> int:
        if level == len(self._BINARY):
            return self._unary()
        left = self._binary(level + 1)
        while self._peek() in self._BINARY[level]:
            op = self._take()
            right = self._binary(level + 1)
            left = {"||": lambda a, b: int(bool(a) or bool(b)), "&&": lambda a, b: int(bool(a) and bool(b)),
                    "|": int.__or__, "^": int.__xor__, "&": int.__and__,
                    "==": lambda a, b: int(a == b), "!=": lambda a, b: int(a != b),
                    "<": lambda a, b: int(a < b), "<=": lambda a, b: int(a <= b),
                    ">": lambda a, b: int(a > b), ">=": lambda a, b: int(a >= b),
                    "<<": int.__lshift__, ">>": int.__rshift__, "+": int.__add__, "-": int.__sub__,
                    "*": int.__mul__, "/": int.__floordiv__, "%": int.__mod__}[op](int(left), int(right))
        return left

    def _unary(self) -> int:
        tok = self._take()
        if tok == "-":
            return -self._unary()
        if tok == "!":
            return int(not self._unary())
        if tok == "~":
            return ~self._unary()
        if tok == "(":
            v = self._ternary()
            self._take(")")
            return v
        if isinstance(tok, int):
            return tok
        if tok in ("uint", "int") and self._peek() == "(":
            self._take("(")
            v = self._ternary()
            self._take(")")
            return v
        if isinstance(tok, str) and tok in self.names:
            return int(self.names[tok])
        if tok in ("true", "false"):
            return int(tok == "true")
        if self.undefined_zero and isinstance(tok, str) and re.match(r"\w+$", tok):
            return 0  # C preprocessor: an undefined name in #if is 0
        raise ValueError(f"unknown name {tok!r}")


def _evaluate(text: str, names: Mapping[str, Any], undefined_zero: bool = False) -> int:
    return _Expr(text, names, undefined_zero).value()


def _active_lines(text: str) -> tuple[list[str], dict[str, Any]]:
    """The lines the preprocessor keeps and the object-like macros' values
    (those that are integer expressions) at the end."""
    raw: dict[str, str] = {}
    kept: list[str] = []
    stack: list[tuple[bool, bool]] = []  # (this branch active, some branch of this #if taken)

    def active() -> bool:
        return all(s[0] for s in stack)

    def value(expr: str) -> int:
        expr = re.sub(r"\bdefined\s*\(?\s*(\w+)\s*\)?", lambda m: "1" if m.group(1) in raw else "0", expr)
        return _evaluate(expr, _macro_values(raw), undefined_zero=True)

    for line in text.splitlines():
        line = line.split("//")[0]
        m = _DIRECTIVE.match(line)
        if not m:
            if active():
                kept.append(line)
            continue
        word, rest = m.group(1), m.group(2).strip()
        if word in ("ifdef", "ifndef"):
            cond = (rest.split()[0] in raw) == (word == "ifdef") if active() else False
            stack.append((cond, cond))
        elif word == "if":
            cond = bool(value(rest)) if active() else False
            stack.append((cond, cond))
        elif word == "elif":
            _, taken = stack.pop()
            cond = (not taken) and all(s[0] for s in stack) and bool(value(rest))
            stack.append((cond, taken or cond))
        elif word == "else":
            _, taken = stack.pop()
            stack.append((not taken, True))
        elif word == "endif":
            stack.pop()
        elif word == "define" and active():
            dm = re.match(r"(\w+)(\(?)\s*(.*)$", rest)
            if dm and not dm.group(2):  # object-like only
                raw[dm.group(1)] = dm.group(3).strip()
        elif word == "undef" and active():
            raw.pop(rest.split()[0], None)
    return kept, _macro_values(raw)


def _macro_values(raw: Mapping[str, str]) -> dict[str, Any]:
    """Integer values of the macros whose bodies evaluate (others are left out)."""
    out: dict[str, Any] = {}
    for _ in range(len(raw) + 1):  # bodies may name later macros: iterate to a fixed point
        changed = False
        for name, body in raw.items():
            if name in out:
                continue
            try:
                out[name] = _evaluate(body or "1", out)
                changed = True
            except (ValueError, ZeroDivisionError):
                pass
        if not changed:
            break
    return out


def needs_of_source(text: str, where: str = "<source>") -> ComputeNeeds:
    """:class:`ComputeNeeds` of one preprocessed compute shader ``text``."""
    lines, names = _active_lines(text)
    body = "\n".join(lines)
    for m in _CONST.finditer(body):  # const uint NAME = expr; in order, each may use the earlier ones
        try:
            names[m.group(1)] = _evaluate(m.group(2), names)
        except (ValueError, ZeroDivisionError):
            pass
    layouts = _LAYOUT_IN.findall(body)
    if not layouts:
        raise ShaderError(f"{where}: no layout(local_size_x = ...) in; declaration")
    size = [1, 1, 1]
    try:
        for m in _LOCAL.finditer(layouts[-1]):
            size[_SIZES[m.group(1)]] = _evaluate(m.group(2), names)
        shared = 0
        for m in _SHARED.finditer(body):
            if m.group(1) not in _TYPE_BYTES:
                raise ValueError(f"shared type {m.group(1)!r} has no known size")
            count = 1
            for dim in re.findall(r"\[([^\]]*)\]", m.group(3)):
                count *= _evaluate(dim, names)
            shared += _TYPE_BYTES[m.group(1)] * count
        blocks = _BUFFER.findall(body)
        bindings = [_evaluate(b.group(1), names) for lay in blocks for b in [_BINDING.search(lay)] if b]
    except ValueError as exc:
        raise ShaderError(f"{where}: cannot size the work group or shared memory: {exc}") from None
    return ComputeNeeds(tuple(size), size[0] * size[1] * size[2], shared, len(blocks),
                        max(bindings, default=-1) + 1)


@lru_cache(maxsize=None)
def _needs_cached(path: str, defines: tuple) -> ComputeNeeds:
    src = preprocess(path, dict(defines))
    return needs_of_source(src.text, path)


def compute_needs(path: str, defines: Mapping[str, Any] | None = None) -> ComputeNeeds:
    """:class:`ComputeNeeds` of the compute shader ``path`` (relative to the
    shader folders, as :func:`~glvox.gl.shaders.compute_program` takes it)
    compiled with ``defines``."""
    return _needs_cached(str(path), tuple(sorted((defines or {}).items())))


def needs_of(uses: Iterable[tuple[str, Mapping[str, Any]]]) -> ComputeNeeds:
    """The joined needs of ``(path, defines)`` pairs; a path may be a glob
    (``"ss/*.comp"``) over the built-in shader folder."""
    out = ComputeNeeds()
    root = builtin_shader_dir()
    for path, defines in uses:
        paths = sorted(p.relative_to(root).as_posix() for p in root.glob(path)) if "*" in path else [path]
        if not paths:
            raise ShaderError(f"no compute shader matches {path!r}")
        for p in paths:
            out |= compute_needs(p, defines)
    return out
