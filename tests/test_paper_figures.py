"""The papers' figures the compare/ tables print (glvox.study.paper_figures) are the papers':
every number checked against the papers' text (the .txt files in the folder
named by GLVOX_PAPERS, default ../shared/papers beside the checkout), and the rows the scripts
print carry them."""

from __future__ import annotations

import os
import re
from pathlib import Path

import pytest
from conftest import load_script

from glvox.study import paper_figures as pf

ROOT = Path(__file__).resolve().parent.parent
PAPERS = Path(os.environ.get("GLVOX_PAPERS") or ROOT.parent / "shared" / "papers")
SS_TXT = "schwarz-seidel-2010-fast-parallel-surface-and-solid-voxelization.txt"
ZHANG_TXT = "zhang-2018-projected-optimal-scanline.txt"


def paper_lines(name: str) -> list[str]:
    path = PAPERS / name
    if not path.is_file():
        pytest.skip(f"{path} is not on this machine (GLVOX_PAPERS names the folder of the papers' text)")
    return path.read_text(encoding="utf-8").splitlines()


def block(lines, start: str, end: str) -> list[list[str]]:
    """Tab-separated fields of the lines after the first starting with ``start`` up to one starting with ``end``."""
    i = next(k for k, line in enumerate(lines) if line.startswith(start))
    out = []
    for line in lines[i + 1:]:
        if line.startswith(end):
            return out
        out.append(line.split("\t"))
    raise AssertionError(f"no line starting with {end!r}")


def grid(field: str) -> int:
    """'128 ³', '256^{3}' or the OCR's '10243' -> the grid size."""
    digits = re.match(r"\s*(\d+)", field).group(1)
    return next(n for n in (4096, 2048, 1024, 512, 256, 128) if digits.startswith(str(n)))


def num(field: str):
    """'10.39' -> 10.39, '54k' -> 54, '3.2 MB' -> 3.2, '5.30%' -> 5.30, '2,483' -> 2483, '_'/'-' -> None."""
    f = field.strip().replace(",", "")
    if f in ("_", "-", "—"):
        return None
    m = re.fullmatch(r"(-?\d+(?:\.\d+)?)\s*(k|MB|%)?", f)
    assert m, f"not a number: {field!r}"
    return float(m.group(1)) if "." in m.group(1) else int(m.group(1))


def test_schwarz_seidel_table1_is_the_papers():
    rows = [r for r in block(paper_lines(SS_TXT), "Model\tGrid\tPipeline-based", "Table 1:")
            if len(r) > 10 and re.match(r"\d", r[1])]
    assert len(rows) == 16
    models = ["Stanford bunny", "Shrub", "Stanford dragon", "XYZ RGB Asian dragon"]
    for k, r in enumerate(rows):
        p = pf.SS_TABLE1[models[k // 4]][grid(r[1])]
        cases = tuple(int(c) for c in re.findall(r"(\d+)%", r[7]))
        assert [num(r[2]), num(r[3]), num(r[4]), num(r[5]), num(r[6]), cases,
                num(r[8]), num(r[9]), num(r[10]), num(r[11])] == [
            p["pipeline"], p["simple"], p["specialized"], p["sorted"], p["voxels_k"], p["cases"],
            p["sep6_simple"], p["sep6_specialized"], p["sep6_sorted"], p["sep6_voxels_k"]], r
    assert rows[0][0].startswith("Stanford bunny (69,666 tris)") and pf.SS_MODELS[
        "stanford_bunny_bun_zipper.ply"] == ("Stanford bunny", 69_666)


def test_schwarz_seidel_table2_is_the_papers():
    rows = [r for r in block(paper_lines(SS_TXT), "Model\tsize\tline", "Table 2:") if len(r) > 9]
    assert len(rows) == 12
    models = ["Stanford bunny", "Stanford dragon", "XYZ RGB Asian dragon"]
    for k, r in enumerate(rows):
        p = pf.SS_TABLE2[models[k // 4]][grid(r[1])]
        assert [num(f) for f in r[2:10]] == [p[c] for c in ("pipeline", "tri_parallel", "t_total", "t_pairs",
                                                             "t_sort", "t_tiles", "pairs_k", "tris")], r


def test_schwarz_seidel_table3_is_the_papers():
    lines = paper_lines(SS_TXT)
    i = next(k for k, line in enumerate(lines) if line.startswith("Binary grid size"))
    assert [grid(f) for f in lines[i].split("\t")[1:5]] == list(pf.SS_TABLE3_SIZES)
    rows = {r[0]: [num(f) for f in r[1:13]] for r in (line.split("\t") for line in lines[i + 2:i + 10])}
    labels = {"Total": "Total (the five stages)"}
    assert len(rows) == 8 and set(labels.get(k, k) for k in rows) == set(pf.SS_TABLE3)
    for label, values in rows.items():
        mine = pf.SS_TABLE3[labels.get(label, label)]
        assert values == [*mine["Stanford bunny"], *mine["Stanford dragon"], *mine["XYZ RGB Asian dragon"]], label


def test_zhang_table1_is_the_papers():
    rows = [r for r in block(paper_lines(ZHANG_TXT), "\t# C", "Table 1:") if r[0].endswith("°")]
    assert len(rows) == 14
    for k, r in enumerate(rows):
        axis, deg = "yz"[k // 7], int(r[0].rstrip("°"))
        ss, pan, ours = pf.ZHANG_TABLE1[axis][deg]
        assert [num(f) for f in r[1:7]] == [ss[0], pan[0], ours[0], ss[1], pan[1], ours[1]], r


def test_zhang_table2_gpu_column_is_the_papers():
    rows = [r for r in block(paper_lines(ZHANG_TXT), "Model\tResolution\t\\mathbf{CPU}", "Table 2:")
            if len(r) > 10 and re.match(r"\d", r[1])]
    assert len(rows) == 25
    models = list(pf.ZHANG_TABLE2_GPU)
    for k, r in enumerate(rows):
        n = grid(r[1])
        expect = pf.ZHANG_TABLE2_GPU[models[k // 5]].get(n)
        got = (num(r[8]), num(r[9]))
        assert got == (expect if expect else (None, None)), (models[k // 5], n, r)


def test_the_scripts_print_the_papers_rows():
    t1 = load_script("table1_ss_surface").paper_row("stanford_bunny_bun_zipper.ply", 1024)
    assert t1 == ("| paper: Stanford bunny (69,666 tris) | 1024^3 | Schwarz & Seidel 2010, NVIDIA GeForce GTX 285 | "
                  "72.64 | 60.96 | 20.69 | 26.75 | 3627k | 0%/3%/97% | 17.09 | 2147k |")
    t2 = load_script("table2_ss_solid").paper_row("stanford_dragon_vrip_res2.ply", 512)
    assert "| 3.16 | 7.57 | 7.19 | 1.41 | 1.96 | 2.91 | 476k | 67.3 |" in t2 and "GTX 285" in t2
    t3 = load_script("table3_ss_octree").paper_column("stanford_bunny_bun_zipper.ply", 4096)
    assert t3["Octree size"] == "216 MB" and t3["Total (the five stages)"] == "93.27"
    assert t3["Stored level-0 nodes"] == "0.69%" and t3["Scalar-valued grid size"] == "1024^3"
    assert load_script("table1_ss_surface").paper_row("cad_fandisk.off", 128) is None  # not a paper model
    z = load_script("zhang_table1").paper_table2([1024, 4096])
    assert "GTX 970" in z[0] and any(line.startswith("Elephant (10,150 tris)") and "15.4 / 4.6" in line
                                     for line in z)
