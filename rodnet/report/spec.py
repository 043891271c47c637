"""The ``[figure]`` and ``[refinement]`` tables of a validation case's ``expected.toml``.

``[figure]`` says what the report plots of rodnet's result and against which reference::

    [figure]
    x = "load_factor"        # "time" | "load_factor": a history, one point per saved frame
                             # "arc_length": a shape, the nodes of `rod` at `frame`
    quantity = "position"    # "position" | "displacement" (from frame 0) of `node` or `rod`,
                             # or "series": an array of result.npz with one value per frame
    node = "beam:end"        # history of position or displacement: the node
    rod = "beam"             # shape: the rod, its nodes in order
    frame = -1               # shape: the saved frame (default: the last)
    components = ["x", "z"]  # one curve each: x | y | z | norm (quantity = "series": omitted)
    name = "mouth_area"      # quantity = "series": the array
    reference = "tip"        # a function of the case's reference.py, or a CSV file of the case
    ylabel = "tip position [m]"

A reference function ``f(x, scene)`` gets the abscissae ``x`` (n,) and the scene as parsed TOML
(a dict) and returns a dict mapping each component (the series' name for ``"series"``) to an
array (n,). A CSV file has a header line naming its columns: the abscissa (the value of ``x``)
and the components; it is drawn as given and interpolated linearly for the differences.
Without ``reference`` the checks alone stand for it: every check on the plotted node (or rod)
and component is drawn at its frame as the expected value with its tolerance, and on a
``"series"`` figure every ``metric`` check is drawn as a line with its tolerance band.

``[refinement]`` runs the case's scene again at several values of one scene key and measures
the error of one check against its expected value at each::

    [refinement]
    key = "rods.0.elements"  # a scene key, set as with `rodnet run --set`
    values = [5, 10, 20, 40]
    scale = "count"          # the resolution h goes as 1 / value ("count") or as value ("size")
    check = 2                # which [[checks]] entry, counted from 1
    expected_order = 2.0     # optional: the order the method should show

The observed order between two values is ``log(e_k / e_k+1) / log(h_k / h_k+1)``.
"""

from __future__ import annotations

import csv
import types
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from rodnet.errors import SceneError

HISTORY_X = {"time": "time [s]", "load_factor": "load factor"}
SHAPE_X = {"arc_length": "arc length [m]"}
QUANTITIES = ("position", "displacement", "series")
COMPONENT_NAMES = ("x", "y", "z", "norm")
SCALES = ("count", "size")

Columns = dict[str, NDArray[np.float64]]


@dataclass(frozen=True)
class FigureSpec:
    """A case's ``[figure]`` table, checked."""

    x: str
    quantity: str
    components: tuple[str, ...]
    node: str | None
    rod: str | None
    frame: int
    reference: str | None
    ylabel: str

    @property
    def shape(self) -> bool:
        """True for a shape along a rod, False for a history over the frames."""
        return self.x in SHAPE_X


@dataclass(frozen=True)
class RefinementSpec:
    """A case's ``[refinement]`` table, checked; ``check`` counts from 0."""

    key: str
    values: tuple[float, ...]
    scale: str
    check: int
    expected_order: float | None

    def resolution(self) -> NDArray[np.float64]:
        """The relative resolution h of each value (n,): 1 / value for counts, value for sizes."""
        v = np.asarray(self.values, float)
        return 1.0 / v if self.scale == "count" else v


def _pick(table: dict[str, Any], key: str, where: str, allowed: tuple[str, ...] | dict[str, str],
          default: str | None = None) -> str:
    value = table.get(key, default)
    if value not in allowed:
        raise SceneError(f"{where}.{key}", value, f"must be one of {list(allowed)}")
    return str(value)


def _text(table: dict[str, Any], key: str, where: str) -> str:
    value = table.get(key)
    if not isinstance(value, str) or not value:
        raise SceneError(f"{where}.{key}", value, "must be a non-empty string")
    return value


def _known(table: dict[str, Any], known: set[str], where: str) -> None:
    if unknown := sorted(set(table) - known):
        raise SceneError(f"{where}.{unknown[0]}", table[unknown[0]],
                         f"unknown key; allowed: {sorted(known)}")


def _number(value: Any) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool)


def figure_spec(table: dict[str, Any], folder: Path) -> FigureSpec:
    """Check a ``[figure]`` table; errors name ``<folder>/expected.toml: figure.<key>``."""
    where = f"{folder / 'expected.toml'}: figure"
    _known(table, {"x", "quantity", "node", "rod", "frame", "components", "name", "reference",
                   "ylabel"}, where)
    x = _pick(table, "x", where, {**HISTORY_X, **SHAPE_X})
    quantity = _pick(table, "quantity", where, QUANTITIES)
    node = rod = None
    if quantity == "series":
        if x in SHAPE_X:
            raise SceneError(f"{where}.x", x, "a series has one value per frame: use "
                             f"{list(HISTORY_X)}")
        components: tuple[str, ...] = (_text(table, "name", where),)
    else:
        comps = table.get("components", ["norm"])
        if not isinstance(comps, list) or not comps or any(c not in COMPONENT_NAMES for c in comps):
            raise SceneError(f"{where}.components", comps,
                             f"must be a non-empty list of {list(COMPONENT_NAMES)}")
        components = tuple(comps)
        if x in SHAPE_X:
            rod = _text(table, "rod", where)
        else:
            node = _text(table, "node", where)
    frame = table.get("frame", -1)
    if not isinstance(frame, int) or isinstance(frame, bool):
        raise SceneError(f"{where}.frame", frame,
                         "must be an integer (negative counts from the end)")
    reference = table.get("reference")
    if reference is not None:
        path = _reference_source(folder, _text(table, "reference", where), where)
        if path.suffix == ".csv":
            reference_table(path, (x, *components))
        else:
            reference_function(folder, reference)
    ylabel = table.get("ylabel", f"{quantity} [m]" if quantity != "series" else components[0])
    return FigureSpec(x, quantity, components, node, rod, frame, reference, str(ylabel))


def refinement_spec(table: dict[str, Any], checks: list[dict[str, Any]], folder: Path
                    ) -> RefinementSpec:
    """Check a ``[refinement]`` table against the case's ``checks``."""
    where = f"{folder / 'expected.toml'}: refinement"
    _known(table, {"key", "values", "scale", "check", "expected_order"}, where)
    key = _text(table, "key", where)
    values = table.get("values")
    if (not isinstance(values, list) or len(values) < 2 or len(set(values)) != len(values)
            or not all(_number(v) and v > 0 for v in values)):
        raise SceneError(f"{where}.values", values,
                         "must list at least two distinct positive numbers")
    scale = _pick(table, "scale", where, SCALES, default="count")
    check = table.get("check")
    if not isinstance(check, int) or isinstance(check, bool) or not 1 <= check <= len(checks):
        raise SceneError(f"{where}.check", check,
                         f"must number one of the case's {len(checks)} [[checks]] (from 1)")
    order = table.get("expected_order")
    if order is not None and not _number(order):
        raise SceneError(f"{where}.expected_order", order, "must be a number")
    return RefinementSpec(key, tuple(values), scale, check - 1,
                          None if order is None else float(order))


def case_specs(folder: Path, expected: dict[str, Any]
               ) -> tuple[FigureSpec | None, RefinementSpec | None]:
    """The checked ``[figure]`` and ``[refinement]`` of a case (``None`` where absent)."""
    figure = expected.get("figure")
    refinement = expected.get("refinement")
    for name, table in (("figure", figure), ("refinement", refinement)):
        if table is not None and not isinstance(table, dict):
            raise SceneError(f"{folder / 'expected.toml'}: {name}", table,
                             f"must be a table [{name}]")
    checks = expected.get("checks", [])
    return (None if figure is None else figure_spec(figure, folder),
            None if refinement is None else refinement_spec(refinement, checks, folder))


def _reference_source(folder: Path, reference: str, where: str) -> Path:
    """The file a ``reference`` names: the CSV file, or the case's reference.py."""
    path = folder / (reference if reference.endswith(".csv") else "reference.py")
    if not path.is_file():
        raise SceneError(f"{where}.reference", reference,
                         f"names no file: expected {path} (a CSV file of the case, or a function "
                         "of its reference.py)")
    return path


ReferenceFunction = Callable[[NDArray[np.float64], dict[str, Any]], Columns]


def reference_function(folder: Path, name: str) -> ReferenceFunction:
    """The function ``name`` of ``folder/reference.py``, read without writing a bytecode cache."""
    path = folder / "reference.py"
    module = types.ModuleType(f"reference_{folder.name}")
    module.__file__ = str(path)
    try:  # the case's own code, as tests load an oracle of elements/ by file path
        exec(compile(path.read_text(), str(path), "exec"), module.__dict__)  # noqa: S102
    except Exception as exc:  # noqa: BLE001 -- any error of that file is bad input
        raise SceneError(str(path), "...", f"cannot be read: {type(exc).__name__}: {exc}") from None
    function = getattr(module, name, None)
    if not callable(function):
        raise SceneError(f"{folder / 'expected.toml'}: figure.reference", name,
                         f"names no function of {path}")
    return function  # type: ignore[no-any-return]


def reference_table(path: Path, columns: tuple[str, ...]) -> Columns:
    """The named ``columns`` of a CSV file with a header line, each (n,)."""
    with path.open(newline="") as handle:
        rows = list(csv.reader(line for line in handle if not line.lstrip().startswith("#")))
    header, body = [h.strip() for h in rows[0]], rows[1:]
    if missing := [c for c in columns if c not in header]:
        raise SceneError(f"{path}", header,
                         f"has no column {missing[0]!r}; it needs {list(columns)}")
    try:
        data = np.array([[float(v) for v in row] for row in body if row], dtype=float)
    except ValueError:
        raise SceneError(f"{path}", "...", "must hold one number per column in every row after "
                         "the header") from None
    return {c: data[:, header.index(c)] for c in columns}
