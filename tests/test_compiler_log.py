"""Compiler logs of every vendor map to file:line (glvox.gl.compiler_log).

The lines below are verbatim driver output, with their sources: Mesa from this
machine's llvmpipe (Mesa 22.3.6) and public reports of radeonsi; NVIDIA,
AMD's legacy front end and glslang-style front ends from public bug reports.
glvox encodes file n, line L as ``#line n * LINE_BASE + L``, so every
location is decoded from the printed line alone.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from glvox.errors import ShaderError
from glvox.gl.compiler_log import Diagnostic, map_log, parse_line
from glvox.gl.shaders import LINE_BASE, Source, compute_program

LOCATED = [
    # Mesa (llvmpipe, LOCAL; radeonsi: overte-org/overte#1616, Tinob/Ishiiruka#101)
    ("0:6(10): error: `valuez' undeclared", Diagnostic("0", 6, 10, "error", "`valuez' undeclared")),
    ("0:5(10): warning: `u' used uninitialized", Diagnostic("0", 5, 10, "warning", "`u' used uninitialized")),
    ("0:7(2): error: initializer of type vec3 cannot be assigned to variable of type vec2",
     Diagnostic("0", 7, 2, "error", "initializer of type vec3 cannot be assigned to variable of type vec2")),
    ("0:3(89): preprocessor error: syntax error, unexpected OTHER",
     Diagnostic("0", 3, 89, "error", "syntax error, unexpected OTHER")),
    ("0:144(13): warning: some implementations may not support implicit int -> uint conversions",
     Diagnostic("0", 144, 13, "warning", "some implementations may not support implicit int -> uint conversions")),
    # NVIDIA (xemu-project/xemu#315, bradleybauer/music_visualizer#6, DaemonEngine/Daemon#1241,
    # emezeske/digbuild#23, 3Dickulus/FragM#52, Septonious/Solas-Shader#104)
    ('0(274) : error C1503: undefined variable "c107"',
     Diagnostic("0", 274, None, "error", 'C1503: undefined variable "c107"')),
    ('broken.comp:6 : error C1503: undefined variable "valuez"', None),  # the paraphrase, no (L): no location
    ("0(139) : error C0000: syntax error, unexpected '(', expecting \"::\" at token \"(\"",
     Diagnostic("0", 139, None, "error", "C0000: syntax error, unexpected '(', expecting \"::\" at token \"(\"")),
    ("0(46) : warning C7533: global variable gl_MultiTexCoord0 is deprecated after version 120",
     Diagnostic("0", 46, None, "warning", "C7533: global variable gl_MultiTexCoord0 is deprecated after version 120")),
    ('/home/Fragmentarium/test.frag(130) : warning C7011: implicit cast from "int" to "float"',
     Diagnostic("/home/Fragmentarium/test.frag", 130, None, "warning", 'C7011: implicit cast from "int" to "float"')),
    ('composite3.fsh: composite3.fsh: 0(154) : error C1503: undefined variable "sunVisibility"',
     Diagnostic("0", 154, None, "error", 'C1503: undefined variable "sunVisibility"',
                "composite3.fsh: composite3.fsh: ")),
    # a message quoting a constructor: the location is 0(7), never vec3(2)
    ("0(7) : error C1035: assignment of incompatible types vec3(2) and vec2",
     Diagnostic("0", 7, None, "error", "C1035: assignment of incompatible types vec3(2) and vec2")),
    # AMD legacy (RPCS3/rpcs3#6613, PixarAnimationStudios/OpenSubdiv#189)
    ("ERROR: 0:74: error(#143) Undeclared identifier: diff_color1",
     Diagnostic("0", 74, None, "error", "error(#143) Undeclared identifier: diff_color1")),
    ("ERROR: 2:218: error(#143) Undeclared identifier: gl_PrimitiveID",
     Diagnostic("2", 218, None, "error", "error(#143) Undeclared identifier: gl_PrimitiveID")),
    # glslang-style: AMD RDNA, Intel on Windows (Luna5ama/Alpha-Piscium#1, RPCS3/rpcs3#6273,
    # sp614x/optifine#268, defold/editor2-issues#515), and the AMD form of the error
    ("ERROR: 0:6: 'valuez' : undeclared identifier", Diagnostic("0", 6, None, "error", "'valuez' : undeclared identifier")),
    ("ERROR: 2:6: '=' :  cannot convert from 'const int' to '3-component vector of float'",
     Diagnostic("2", 6, None, "error", "'=' :  cannot convert from 'const int' to '3-component vector of float'")),
    ("WARNING: 0:9: '' :  #version directive missing", Diagnostic("0", 9, None, "warning", "'' :  #version directive missing")),
]

UNLOCATED = [
    "error: Too much shared memory used (80000/32768)",                      # Mesa link error
    '(0) : error C0000: syntax error, unexpected $end, expecting "::" at token "<EOF>"',  # NVIDIA, no location
    "(0) : error C2003: incompatible options for link",
    "ERROR: error(#273) 4 compilation errors.  No code generated",             # AMD legacy summary
    "ERROR: 1 compilation errors.  No code generated.",                        # glslang summary
    "WARNING: Vertex shader was successfully compiled to run on hardware.",    # AMD success
    "INTERNAL ERROR: no main() function!",
    "GLSL Compiler failed", "compute_shader", "==============", "",
    "Vertex shader failed to compile with the following errors:",
    "the ratio 3:4: and vec3(2) : inside a message",
    # location-less NVIDIA line quoting a constructor followed by " : error": not vec3, line 2
    "(0) : error C1035: assignment of incompatible types vec3(2) : error in initializer",
]


@pytest.mark.parametrize("line,expected", LOCATED, ids=[l for l, _ in LOCATED])
def test_every_vendors_location_is_read(line, expected):
    assert parse_line(line) == expected


@pytest.mark.parametrize("line", UNLOCATED)
def test_lines_without_a_location_pass_through(line, tmp_path):
    assert parse_line(line) is None
    assert map_log(line, lambda n: "X") == line
    assert Source(text="", files=[tmp_path / f"f{i}.comp" for i in range(4)]).map_log(line) == line


def _source(tmp_path) -> Source:
    files = [tmp_path / "top.comp", tmp_path / "inc.glsl"]
    return Source(text="", files=files)


@pytest.mark.parametrize("log,mapped", [
    ("0:6(41): error: `valuez' undeclared", "top.comp:6:41: error: `valuez' undeclared"),
    ('0(6) : error C1503: undefined variable "valuez"', 'top.comp:6: error: C1503: undefined variable "valuez"'),
    ("ERROR: 0:6: 'valuez' : undeclared identifier", "top.comp:6: error: 'valuez' : undeclared identifier"),
    # file 1 at line 8, whatever string number the vendor prints
    (f"0:{LINE_BASE + 8}(2): warning: unused", "inc.glsl:8:2: warning: unused"),
    (f"3({LINE_BASE + 8}) : error C0000: syntax error", "inc.glsl:8: error: C0000: syntax error"),
    (f"ERROR: 1:{LINE_BASE + 8}: 'x' : undeclared identifier", "inc.glsl:8: error: 'x' : undeclared identifier"),
])
def test_logs_map_to_one_vendor_neutral_form(tmp_path, log, mapped):
    src = _source(tmp_path)
    header = "GLSL Compiler failed\n\ncompute_shader\n==============\n"
    out = src.map_log(header + log + "\nERROR: 1 compilation errors.  No code generated.")
    assert out == header + str(tmp_path / mapped) + "\nERROR: 1 compilation errors.  No code generated."


def test_the_docs_compile_error_check_holds_for_every_vendor(tmp_path):
    """docs/testing.md's example test matches the mapped error of Mesa, NVIDIA and AMD alike."""
    doc = (Path(__file__).resolve().parents[1] / "docs" / "testing.md").read_text()
    pattern = re.search(r'pytest\.raises\(ShaderError, match=r"([^"]+)"\)', doc).group(1)
    src = Source(text="", files=[tmp_path / "broken.comp"])
    for log in ("0:6(41): error: `valuez' undeclared", '0(6) : error C1503: undefined variable "valuez"',
                "ERROR: 0:6: 'valuez' : undeclared identifier"):
        assert re.search(pattern, src.map_log(log)), (pattern, src.map_log(log))


def test_a_real_compile_error_names_file_and_line(gl_context, tmp_path):
    """This machine's driver, end to end: an error in an included file names it."""
    (tmp_path / "inc.glsl").write_text("uint twice(uint v) {\n    return 2u * valuez;\n}\n")
    (tmp_path / "top.comp").write_text('#version 450\nlayout(local_size_x = 1) in;\n#include "inc.glsl"\n'
                                       "void main() { twice(1u); }\n")
    with pytest.raises(ShaderError, match=r"inc\.glsl:2(:\d+)?: error: "):
        compute_program(gl_context, str(tmp_path / "top.comp"), {"UNUSED": 1})
