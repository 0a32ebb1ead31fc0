"""``glvox bench --check``: no regression against a baseline results file.

The baseline (``glvox bench --save-baseline``) is one machine's timings: it
lives in the checkout's ``compare/bench_baseline.json``, not in the package.
A glvox cell regresses when its best warm time exceeds the baseline's by
more than :data:`glvox.tolerances.REGRESSION_TOLERANCE` after allowing for a
busier machine (:func:`machine_factor`).
"""

from __future__ import annotations

import json
import statistics
from pathlib import Path
from typing import Any, Sequence

from glvox.errors import GlvoxError
from glvox.tolerances import REGRESSION_TOLERANCE

from ..datasets import checkout_root
from .options import CHECKOUT_BASELINE
from .plan import CALIBRATION, row_key

#: The baseline's place in a checkout.
BASELINE = Path("compare") / "bench_baseline.json"


def baseline_path(arg: str) -> Path:
    """The PATH of ``--check`` / ``--save-baseline``; without one, the checkout's
    ``compare/bench_baseline.json`` (an installed glvox has no checkout: PATH is needed)."""
    if arg != CHECKOUT_BASELINE:
        return Path(arg)
    root = checkout_root()
    if root is None:
        raise GlvoxError("--check and --save-baseline need a PATH: glvox does not run from a checkout, "
                         "whose compare/bench_baseline.json is the default")
    return root / BASELINE


def load_baseline(path: Path) -> dict[str, Any]:
    if not Path(path).is_file():
        raise GlvoxError(f"no benchmark baseline at {path}: run `glvox bench --preset quick --save-baseline "
                         f"{path}` on the version to compare against, or pass --check PATH")
    data = json.loads(Path(path).read_text())
    if not isinstance(data, dict) or "rows" not in data:
        raise GlvoxError(f"{path} is not a glvox bench results file (expected an object with 'rows')")
    return data


def machine_factor(rows: Sequence[dict], baseline: Sequence[dict]) -> float | None:
    """How much slower the machine is now than when the baseline was taken.

    The median over cells present in both of (best time now / best time then)
    of the GL calibration workload (:mod:`glvox.study.calibration`), which
    feels the load on llvmpipe's threads as the glvox methods do; of the
    peers' cells when the baseline has no calibration; None when neither is
    common.
    """
    base = {row_key(r): r for r in baseline if r.get("status") == "ok"}

    def ratios(pick):
        return [r["min_ms"] / base[row_key(r)]["min_ms"] for r in rows
                if pick(r) and r["status"] == "ok" and row_key(r) in base]

    got = ratios(lambda r: r["group"] == CALIBRATION) or ratios(lambda r: r["peer"])
    return statistics.median(got) if got else None


def _is_glvox(r: dict[str, Any]) -> bool:
    return not r["peer"] and r["group"] != CALIBRATION


def check_regressions(rows: Sequence[dict], baseline: Sequence[dict], factor: float | None,
                      tolerance: float = REGRESSION_TOLERANCE) -> list[dict[str, Any]]:
    """glvox cells whose best warm time regressed against the baseline.

    A cell regresses when its best time (the least of its warm runs: noise on
    a shared machine only ever adds time) exceeds the baseline's by more than
    ``tolerance`` after dividing by the machine factor where that is above 1:
    a busier machine slows the fixed GL workload too, and a change in glvox
    slows glvox alone.  A factor below 1 (a quieter machine than the
    baseline's) is not applied: methods do not all speed up alike when cores
    free up (compute methods and the GL workload speed up, the raster
    methods much less; compare/README.md has the measurement), so it would
    accuse methods of what is only noise.  Rows missing from either side are
    ignored (new methods, peers not installed).

    Returns
    -------
    list of dict
        key, mesh, n, base_ms, now_ms, raw (now / base), normalized (raw / factor).
    """
    base = {row_key(r): r for r in baseline if r.get("status") == "ok" and not r.get("peer")}
    out = []
    for r in rows:
        b = base.get(row_key(r))
        if not _is_glvox(r) or r["status"] != "ok" or b is None:
            continue
        raw = r["min_ms"] / b["min_ms"]
        norm = raw / max(1.0, factor or 1.0)
        if norm > 1 + tolerance:
            out.append({"key": r["key"], "mesh": r["mesh"], "n": r["n"], "base_ms": b["min_ms"],
                        "now_ms": r["min_ms"], "raw": raw, "normalized": norm})
    return out


def check(rows: Sequence[dict], baseline: Sequence[dict]) -> dict[str, Any]:
    """The whole check: ``common`` (glvox cells measured in both), ``factor``
    (:func:`machine_factor`) and ``regressions`` (:func:`check_regressions`)."""
    base_keys = {row_key(r) for r in baseline if r.get("status") == "ok"}
    common = sum(1 for r in rows if _is_glvox(r) and r["status"] == "ok" and row_key(r) in base_keys)
    factor = machine_factor(rows, baseline)
    return {"common": common, "factor": factor, "regressions": check_regressions(rows, baseline, factor)}


def keep_best(rows: list[dict[str, Any]], again: Sequence[dict[str, Any]]) -> None:
    """Lower each row's best time (``min_ms``) to that of the same cell measured ``again``."""
    best = {row_key(r): r["min_ms"] for r in again if r["status"] == "ok"}
    for r in rows:
        k = row_key(r)
        if k in best:
            r["min_ms"] = min(r["min_ms"], best[k])
