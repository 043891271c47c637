"""The numbers behind a case's figure: rodnet's curves read from a run, the reference curve, and
the case's checks placed on them (see :mod:`rodnet.report.spec` for the ``[figure]`` table)."""

from __future__ import annotations

import tomllib
from collections.abc import Callable
from dataclasses import dataclass, field
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from rodnet.report.spec import Columns, FigureSpec, reference_function, reference_table
from rodnet.run import RunResult
from rodnet.scene import load_scene
from rodnet.topology import build_structure
from rodnet.validate import COMPONENTS, tolerance

DENSE = 400  # points of a reference curve given by a function


@dataclass(frozen=True)
class Mark:
    """A check drawn on a figure: its expected value [unit of the curve] with its tolerance at
    the abscissa ``x`` of its frame (history) or node (shape), and the reference there."""

    component: str
    x: float
    expected: float
    tolerance: float
    reference: float


@dataclass(frozen=True)
class Band:
    """A metric check drawn across a series figure: expected value and tolerance."""

    label: str
    expected: float
    tolerance: float


@dataclass(frozen=True)
class Curves:
    """Everything one figure shows.

    Attributes
    ----------
    x : (n,) float
        rodnet's abscissae: the saved frames' times or load factors, or the rod's arc length.
    y : dict of (n,) float
        rodnet's value per component.
    ref_x, ref_y : (m,) float and dict of (m,) float, or None
        The reference curve as drawn (a dense grid, or the rows of its CSV file).
    ref_at_x : dict of (n,) float or None
        The reference at rodnet's abscissae, for the differences.
    """

    spec: FigureSpec
    x: NDArray[np.float64]
    y: Columns
    ref_x: NDArray[np.float64] | None = None
    ref_y: Columns | None = None
    ref_at_x: Columns | None = None
    marks: list[Mark] = field(default_factory=list)
    bands: list[Band] = field(default_factory=list)


def _component(vectors: NDArray[np.float64], component: str) -> NDArray[np.float64]:
    """One component of ``vectors`` (..., 3): x, y, z or the norm."""
    if component == "norm":
        return np.linalg.norm(vectors, axis=-1)
    return vectors[..., COMPONENTS[component]]


def _rod_nodes(result: RunResult, rod: str) -> NDArray[np.int64]:
    nodes = result.summary["nodes"]
    found = []
    while f"{rod}:{len(found)}" in nodes:
        found.append(nodes[f"{rod}:{len(found)}"])
    if not found:
        raise ValueError(f"the result has no rod named {rod!r} (figure.rod)")
    return np.asarray(found, dtype=np.int64)


def _frame(spec: FigureSpec, n_frames: int) -> int:
    if not -n_frames <= spec.frame < n_frames:
        raise ValueError(f"figure.frame = {spec.frame}, but the run saved {n_frames} frames")
    return spec.frame % n_frames


def rodnet_curves(spec: FigureSpec, result: RunResult, scene_file: Path
                  ) -> tuple[NDArray[np.float64], Columns, NDArray[np.int64]]:
    """rodnet's abscissae (n,), values per component (n,) and the node of each abscissa (for a
    shape; empty for a history)."""
    arrays = result.arrays
    if spec.quantity == "series":
        name = spec.components[0]
        if name not in arrays or arrays[name].shape != arrays["time"].shape:
            raise ValueError(f"the result has no series {name!r} with one value per frame "
                             "(figure.name)")
        return arrays["time"], {name: arrays[name]}, np.zeros(0, np.int64)
    positions = arrays["positions"]
    if spec.shape:
        nodes = _rod_nodes(result, spec.rod or "")
        rest = build_structure(load_scene(scene_file)).rest_positions[nodes]
        x = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(rest, axis=0), axis=1))])
        vectors = positions[_frame(spec, len(positions)), nodes]
        origin = positions[0, nodes]
    else:
        node = result.summary["nodes"].get(spec.node)
        if node is None:
            raise ValueError(f"the result has no node {spec.node!r} (figure.node)")
        nodes, x = np.zeros(0, np.int64), arrays["time"]
        vectors, origin = positions[:, node], positions[0, node]
    if spec.quantity == "displacement":
        vectors = vectors - origin
    return x, {c: _component(vectors, c) for c in spec.components}, nodes


def _interpolated(ref_x: NDArray[np.float64], table: Columns, components: tuple[str, ...],
                  points: NDArray[np.float64]) -> Columns:
    return {c: np.interp(points, ref_x, table[c]) for c in components}


def _evaluated(function: Any, scene: dict[str, Any], components: tuple[str, ...],
               points: NDArray[np.float64]) -> Columns:
    values = function(np.asarray(points, float), scene)
    missing = [c for c in components if c not in values]
    if missing:
        raise ValueError(f"the reference function returned no {missing[0]!r} (it returned "
                         f"{sorted(values)})")
    return {c: np.broadcast_to(np.asarray(values[c], float), np.shape(points)) for c in components}


def _reference(spec: FigureSpec, folder: Path, x: NDArray[np.float64], lower: float
               ) -> tuple[NDArray[np.float64], Columns, Callable[[NDArray[np.float64]], Columns]]:
    """The reference curve as drawn and a function giving it at any abscissae."""
    assert spec.reference is not None
    if spec.reference.endswith(".csv"):
        table = reference_table(folder / spec.reference, (spec.x, *spec.components))
        ref_x = table[spec.x]
        return ref_x, {c: table[c] for c in spec.components}, partial(
            _interpolated, ref_x, table, spec.components)
    scene = tomllib.loads((folder / "scene.toml").read_text())
    at = partial(_evaluated, reference_function(folder, spec.reference), scene, spec.components)
    grid = np.linspace(lower, float(np.max(x)), DENSE)
    return grid, at(grid), at


def case_curves(spec: FigureSpec, folder: Path, checks: list[dict[str, Any]], result: RunResult
                ) -> Curves:
    """The figure of a case that ran: rodnet's curves, the reference, the checks on them."""
    x, y, nodes = rodnet_curves(spec, result, folder / "scene.toml")
    ref_x = ref_y = ref_at_x = None
    at = None
    if spec.reference is not None:
        lower = float(x[0]) if spec.x == "time" else 0.0
        ref_x, ref_y, at = _reference(spec, folder, x, lower)
        ref_at_x = at(x)
    marks = []
    for check in checks:
        where = _mark_abscissa(spec, check, result, x, nodes)
        if where is not None:
            component = check.get("component", "norm")
            reference = float(at(np.array([where]))[component][0]) if at else np.nan
            marks.append(Mark(component, where, float(check["expected"]), tolerance(check),
                              reference))
    bands = [Band(f"metric {c['name']}", float(c["expected"]), tolerance(c))
             for c in checks if spec.quantity == "series" and c["quantity"] == "metric"]
    return Curves(spec, x, y, ref_x, ref_y, ref_at_x, marks, bands)


def _mark_abscissa(spec: FigureSpec, check: dict[str, Any], result: RunResult,
                   x: NDArray[np.float64], nodes: NDArray[np.int64]) -> float | None:
    """Where ``check`` lies on the figure, or ``None`` when it reads something else."""
    if (spec.quantity == "series" or check["quantity"] != spec.quantity
            or check.get("component", "norm") not in spec.components):
        return None
    frame = int(check.get("frame", -1))
    n_frames = len(result.arrays["time"])
    if not -n_frames <= frame < n_frames:
        return None
    if not spec.shape:
        return float(x[frame]) if check["node"] == spec.node else None
    node = result.summary["nodes"].get(check["node"])
    if frame % n_frames != _frame(spec, n_frames) or node not in nodes:
        return None
    return float(x[int(np.flatnonzero(nodes == node)[0])])
