"""What the study runs: contenders x meshes x grid sizes, and how.

One plan type serves ``glvox compare`` and ``glvox bench``
(:mod:`glvox.study.harness` runs it).  A *contender* is a registered glvox
method with options, a peer voxelizer (:mod:`glvox.study.peers`), or the
calibration workload (:mod:`glvox.study.calibration`); a *cell* is one
contender on one mesh at one grid size, and gives one row.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Mapping, Sequence

from glvox.methods import get_method

from .peers import get_peer

#: Group a glvox method's rows are put in, by kind: ss-octree's sparse solid
#: decodes to the same voxels as a dense solid, so it races the solid peers.
GROUP = {"surface": "surface", "solid": "solid", "sparse": "solid", "ldi": "ldi"}

#: Group and key of the calibration pseudo-contender.
CALIBRATION = "calibration"
CALIBRATION_KEY = "calibration:gl-busy"


@dataclass(frozen=True)
class Contender:
    """A glvox method (with options), a peer, or the calibration workload: one row per cell.

    Build them with :meth:`of_method`, :meth:`of_peer` or :data:`CALIBRATION_CONTENDER`.
    """

    key: str
    group: str
    method: str | None = None
    options: tuple[tuple[str, Any], ...] = ()
    peer: str | None = None

    @classmethod
    def of_method(cls, name: str, options: Mapping[str, Any] | None = None) -> "Contender":
        """The registered method ``name`` (an unknown name raises, listing the known ones).

        Its key is the name, followed by ``[k=v,...]`` when ``options`` are given.
        """
        info = get_method(name).info
        items = tuple(sorted((options or {}).items()))
        key = name + (f"[{','.join(f'{k}={v}' for k, v in items)}]" if items else "")
        return cls(key, GROUP.get(info.kind, info.kind), method=name, options=items)

    @classmethod
    def of_peer(cls, name: str) -> "Contender":
        """The peer voxelizer ``name`` (key ``peer:NAME``)."""
        p = get_peer(name)
        return cls(f"peer:{p.name}", p.kind, peer=p.name)

    @property
    def label(self) -> str:
        """The contender as a person reads it in progress messages (not the row key)."""
        if self.is_calibration:
            return "the calibration workload"
        if self.is_peer:
            return f"peer {self.peer}"
        return self.method + (f" ({', '.join(f'{k} {v}' for k, v in self.options)})" if self.options else "")

    @property
    def is_peer(self) -> bool:
        return self.peer is not None

    @property
    def is_calibration(self) -> bool:
        return self.group == CALIBRATION

    @property
    def runs_on_cpu(self) -> bool:
        """A glvox method without GL (the float64 references)."""
        return self.method is not None and not get_method(self.method).info.uses_gl


#: The fixed GL workload timed beside the contenders (``glvox bench``'s machine factor).
CALIBRATION_CONTENDER = Contender(CALIBRATION_KEY, CALIBRATION)


def mesh_label(mesh: str) -> str:
    """A mesh's name in rows and tables: the file name, or ``gen:...`` as given."""
    return mesh if mesh.startswith("gen:") else Path(mesh).name


@dataclass(frozen=True)
class Cell:
    """One contender on one mesh (a path or ``gen:...``) at grid size N = ``n``."""

    mesh: str
    n: int
    contender: Contender

    @property
    def method(self) -> str | None:
        return self.contender.method

    @property
    def key(self) -> str:
        """The identity of the cell's row (see :func:`row_key`)."""
        return f"{self.contender.key}|{mesh_label(self.mesh)}|{self.n}"


def row_key(row: Mapping[str, Any]) -> str:
    """The identity of a row: contender key, mesh and N (resumption, baselines)."""
    return f"{row['key']}|{row['mesh']}|{row['n']}"


@dataclass
class Plan:
    """Contenders x meshes x sizes, and how to time and check them.

    Attributes
    ----------
    meshes : sequence of str
        Resolved mesh paths or ``gen:...`` names (:func:`glvox.datasets.resolve_mesh`).
    sizes : sequence of int
        Grid resolutions N (cubic N^3 grids fitted by :func:`glvox.grid_for`).
    contenders : sequence of Contender
    repeat : int
        Timed warm rounds per cell after the cold run.
    budget : float or None
        Seconds of warm runs after which a contender stops repeating in a
        cell (at least one run); None: always ``repeat``.
    check_max : int or None
        Largest N compared with the exact references; None: every size.
    cpu_max : int or None
        glvox methods without GL (the float64 references) are left out of the
        cells above this N.
    peer_max : dict
        Per peer name, the largest N it runs at (None: no limit) instead of
        its own default; a peer above its limit gives a skipped row.
    open_solids : bool
        Run solid, sparse and LDI methods on open meshes too (parity of
        crossings, ``allow_open``); False gives them a skipped row there.
    reference : str or None
        Check every contender against this reference instead of its own
        (the open-mesh study: ``reference-gwn``, the one solid defined for
        any mesh); None: each contender's registered reference.
    """

    meshes: Sequence[str]
    sizes: Sequence[int]
    contenders: Sequence[Contender]
    repeat: int = 5
    budget: float | None = None
    check_max: int | None = None
    cpu_max: int | None = None
    peer_max: dict[str, int | None] = field(default_factory=dict)
    open_solids: bool = True
    reference: str | None = None

    def peer_limit(self, name: str) -> int | None:
        return self.peer_max.get(name, get_peer(name).max_n)

    def checks(self, n: int) -> bool:
        """Whether results at N = ``n`` are compared with the references."""
        return self.check_max is None or n <= self.check_max

    def cells(self) -> list[Cell]:
        """Every cell, by mesh, then size, then contender."""
        return [Cell(mesh, n, c) for mesh in self.meshes for n in self.sizes for c in self.contenders
                if self.cpu_max is None or n <= self.cpu_max or not c.runs_on_cpu]
