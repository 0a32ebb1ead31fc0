"""How many voxels the tie rule excuses, per method and shared mesh.

For every shared mesh and every registered dense method whose reference has a
tie set (surfaces and solids; solids skip open meshes): the reference's tie
set size and the mismatches against the reference that it excuses (inside the
tie set), beside the mismatches it does not (0 for an exact method).  Uses the
library API every glvox revision has (``load_mesh``, ``grid_for``,
``run_method``, ``glvox.metrics.tie_set``), so the same script measures an
older revision too:

    python compare/ties_excused.py -r 128 --json after.json
    mkdir /tmp/rev && git archive REV | tar -x -C /tmp/rev
    R=$PWD SP=$(python -c 'import site; print(site.getsitepackages()[0])')
    (cd /tmp && GLVOX_MESHES=$R/../shared/meshes PYTHONPATH=/tmp/rev:$SP \\
        python -S $R/compare/ties_excused.py -r 128 --json $R/before.json)
    python compare/ties_excused.py --table before.json after.json

(``python -S`` and a working directory without a ``glvox`` folder, so that the
revision's glvox and shaders are the ones imported.)
"""

from __future__ import annotations

import argparse
import json
import sys
import warnings
from pathlib import Path

import numpy as np

import glvox
from glvox.methods import get_method, method_names, run_method
from glvox.metrics import tie_set
try:
    from glvox.datasets import SHARED_MESHES, mesh_dir
except ImportError:  # revisions before glvox.datasets: the script measures older revisions too
    from glvox.study.meshes import SHARED_MESHES, mesh_dir


def _dense(result) -> np.ndarray:
    return (result.to_grid() if hasattr(result, "to_grid") else result).dense()


def measure(resolution: int, meshes, methods=None) -> list[dict]:
    """One row per (mesh, method): ties, excused and unexplained mismatches."""
    rows = []
    names = [n for n in method_names() if methods is None or n in methods]
    for name in meshes:
        path = mesh_dir() / name
        if not path.is_file():
            print(f"skip {name}: not in {mesh_dir()}", file=sys.stderr)
            continue
        mesh = glvox.load_mesh(str(path))
        spec = glvox.grid_for(mesh, resolution)
        refs: dict[str, tuple[np.ndarray, np.ndarray]] = {}
        for method in names:
            info = get_method(method).info
            ref = info.reference
            if info.kind not in ("surface", "solid", "sparse") or not ref or not get_method(ref).has_ties:
                continue
            if get_method(ref).info.kind == "solid" and not mesh.watertight:
                continue
            if ref not in refs:
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore")
                    refs[ref] = (_dense(run_method(ref, mesh, spec, allow_open=True)), tie_set(ref, mesh, spec))
            ref_grid, ties = refs[ref]
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                got = _dense(run_method(method, mesh, spec))
            diff = got ^ ref_grid
            rows.append({"mesh": name, "method": method, "reference": ref, "ties": int(ties.sum()),
                         "excused": int((diff & ties).sum()), "not_ties": int((diff & ~ties).sum())})
            print(json.dumps(rows[-1]), file=sys.stderr, flush=True)
    return rows


def table(before: list[dict], after: list[dict]) -> str:
    """Markdown: per mesh and method, excused mismatches before -> after, and the tie sets."""
    key = lambda r: (r["mesh"], r["method"])  # noqa: E731
    b = {key(r): r for r in before}
    lines = ["| mesh | method | tie set before | after | excused before | after | not ties before | after |",
             "|---|---|---|---|---|---|---|---|"]
    for r in after:
        o = b.get(key(r), {})
        lines.append(f"| {r['mesh']} | `{r['method']}` | {o.get('ties', '-')} | {r['ties']} | "
                     f"{o.get('excused', '-')} | {r['excused']} | {o.get('not_ties', '-')} | {r['not_ties']} |")
    return "\n".join(lines)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("-r", "--resolution", type=int, default=128)
    ap.add_argument("--meshes", nargs="*", default=list(SHARED_MESHES))
    ap.add_argument("-m", "--methods", nargs="*", default=None)
    ap.add_argument("--json", type=Path, help="write the rows here")
    ap.add_argument("--table", nargs=2, type=Path, metavar=("BEFORE", "AFTER"),
                    help="print the before/after table of two --json files and exit")
    args = ap.parse_args(argv)
    if args.table:
        print(table(json.loads(args.table[0].read_text()), json.loads(args.table[1].read_text())))
        return 0
    rows = measure(args.resolution, args.meshes, args.methods)
    if args.json:
        args.json.write_text(json.dumps(rows, indent=1))
    print(table([], rows))
    return 0


if __name__ == "__main__":
    sys.exit(main())
