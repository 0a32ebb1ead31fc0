"""Compiler info logs of every GL vendor, read line by line.

Each driver writes its own shape of location (verbatim examples in
``tests/test_compiler_log.py``, with their sources):

* Mesa (llvmpipe, radeonsi, iris, ...): ``0:6(12): error: `valuez' undeclared``
  -- string:line(column);
* NVIDIA: ``0(6) : error C1503: undefined variable "valuez"`` -- string(line),
  where the string may be a name (``file.frag(130) : warning C7011: ...``) or
  missing (``(0) : error C0000: ...``, no location);
* AMD legacy and glslang-style front ends (AMD on Windows, Intel on Windows,
  ANGLE, Apple): ``ERROR: 0:6: 'valuez' : undeclared identifier`` and
  ``ERROR: 0:74: error(#143) Undeclared identifier: x``.

:func:`parse_line` reads one line into a :class:`Diagnostic` (or None for a
line without a location: summaries such as ``ERROR: 1 compilation errors.``,
link errors, moderngl's headers), anchored so that numbers inside a message
(``vec3(2)``, ``0:6:``) are never taken for a location: NVIDIA's ``S(L)`` must
start the line or follow a space and be followed by `` : error|warning``;
glslang's ``S:L:`` must follow ``ERROR:``/``WARNING:``; Mesa's ``S:L(C):`` must
start the line.  Locations are decoded from the line number alone (the
string number is printed differently by each vendor, Mesa prints 0).
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Callable

# an application's prefix before the location, e.g. "file.fsh: " (kept)
_PREFIX = r"(?P<prefix>(?:[^\s:]+:\s+)*)"
_MESA = re.compile(r"^\s*" + r"(?P<s>\d+):(?P<l>\d+)\((?P<c>\d+)\):\s*"
                   r"(?P<sev>error|warning|preprocessor error|preprocessor warning|info)\s*:\s?(?P<msg>.*)$",
                   re.I)
_NVIDIA = re.compile(r"^\s*" + _PREFIX + r"(?P<s>[^\s()]*)\((?P<l>\d+)\)\s+:\s+(?P<sev>error|warning|info)\b"
                     r"\s*(?P<msg>.*)$", re.I)
_GLSLANG = re.compile(r"^\s*" + _PREFIX + r"(?P<sev>ERROR|WARNING):\s*(?P<s>\d+):(?P<l>\d+):\s*(?P<msg>.*)$")


@dataclass(frozen=True)
class Diagnostic:
    """One located compiler message.

    Attributes
    ----------
    source : str
        The source-string identity as printed (a number, a name, or '').
    line : int
        The line as printed (glvox encodes file and line in it, LINE_BASE).
    column : int or None
        Mesa's column; None where the vendor gives none.
    severity : str
        ``'error'`` or ``'warning'`` (``'info'`` as printed), lower case.
    message : str
        The driver's text after the location (NVIDIA's code kept: ``C1503: ...``).
    prefix : str
        Any application prefix before the location, kept as is.
    """

    source: str
    line: int
    column: int | None
    severity: str
    message: str
    prefix: str = ""


def parse_line(line: str) -> Diagnostic | None:
    """The located message of ``line``, or None when it has no location."""
    m = _MESA.match(line)
    if m:
        sev = m["sev"].lower().replace("preprocessor ", "")
        return Diagnostic(m["s"], int(m["l"]), int(m["c"]), sev, m["msg"].strip())
    m = _NVIDIA.match(line)
    if m and int(m["l"]) > 0:  # "(0) : error C0000: ..." is NVIDIA's location-less form
        msg = m["msg"].strip()
        msg = msg[1:].strip() if msg.startswith(":") else msg
        return Diagnostic(m["s"], int(m["l"]), None, m["sev"].lower(), msg, m["prefix"])
    m = _GLSLANG.match(line)
    if m:
        return Diagnostic(m["s"], int(m["l"]), None, m["sev"].lower(), m["msg"].strip(), m["prefix"])
    return None


def map_log(log: str, location: Callable[[int], str]) -> str:
    """``log`` with every located line rewritten to one vendor-neutral form,
    ``<location(line)>[:column]: <severity>: <message>`` (``location`` turns
    the printed line into ``file:line``); other lines are kept unchanged."""
    out = []
    for raw in log.splitlines():
        d = parse_line(raw)
        if d is None:
            out.append(raw)
            continue
        col = f":{d.column}" if d.column is not None else ""
        out.append(f"{d.prefix}{location(d.line)}{col}: {d.severity}: {d.message}")
    return "\n".join(out)
