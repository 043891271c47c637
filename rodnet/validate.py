"""Validation cases: a scene, the values it must reproduce and where those values come from.

A case is a folder ``validation/cases/<name>/`` with ``scene.toml``, ``README.md`` and
``expected.toml``::

    description = "Cantilever rolled into a circle by an end moment 2 pi EI / L"
    source = "Analytic: the curvature M / EI is uniform (Euler elastica)"
    slow = false                 # true: run by `rodnet validate`, not by the default tests

    [[checks]]
    quantity = "position"        # position | displacement | metric
    node = "beam:end"            # a node selector (position, displacement)
    component = "norm"           # x | y | z | norm
    frame = -1                   # which saved frame (default: the last)
    expected = 0.0
    abs_tol = 1.0e-6             # and/or rel_tol

``metric`` checks read ``summary.json`` metrics by ``name``. Everything runs through the same
scene loader and :func:`rodnet.run.run` as a user's run.

Two optional tables serve the report of ``rodnet validate --report`` (see
:mod:`rodnet.report.spec`): ``[figure]``, what to plot of the result against which reference
curve, and ``[refinement]``, a scene key to vary for an observed order of convergence.
"""

from __future__ import annotations

import math
import time
import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from rodnet.errors import SceneError
from rodnet.run import RunResult, run
from rodnet.scene import load_scene

COMPONENTS = {"x": 0, "y": 1, "z": 2}


@dataclass(frozen=True)
class CheckResult:
    case: str
    label: str
    value: float
    expected: float
    tolerance: float
    passed: bool


def case_folders(root: Path) -> list[Path]:
    """Every folder under ``root`` holding both ``scene.toml`` and ``expected.toml``."""
    return sorted(p.parent for p in root.glob("*/expected.toml") if (p.parent / "scene.toml").exists())


QUANTITIES = ("position", "displacement", "metric")
CHECK_KEYS = {"quantity", "node", "component", "frame", "name", "expected", "abs_tol", "rel_tol"}


def read_expected(folder: Path) -> dict[str, Any]:
    """The case's ``expected.toml``, its ``[[checks]]`` checked (:class:`SceneError` naming the
    file, the entry and the key: a bad check is bad input, not a failed run)."""
    path = folder / "expected.toml"
    try:
        data = tomllib.loads(path.read_text())
    except tomllib.TOMLDecodeError as exc:
        raise SceneError(str(path), "...", f"is not valid TOML: {exc}") from None
    checks = data.get("checks", [])
    if not isinstance(checks, list) or not all(isinstance(c, dict) for c in checks):
        raise SceneError(f"{path}: checks", checks, "must be an array of tables [[checks]]")
    for i, check in enumerate(checks):
        _check_entry(check, f"{path}: checks[{i}]")
    return data


def _check_entry(check: dict[str, Any], where: str) -> None:
    """One ``[[checks]]`` table: its keys, the quantity and what that quantity needs."""
    unknown = sorted(set(check) - CHECK_KEYS)
    if unknown:
        raise SceneError(f"{where}.{unknown[0]}", check[unknown[0]],
                         f"is not a key of a check: {sorted(CHECK_KEYS)}")
    quantity = check.get("quantity")
    if quantity not in QUANTITIES:
        raise SceneError(f"{where}.quantity", quantity, f"must be one of {list(QUANTITIES)}")
    needed = "name" if quantity == "metric" else "node"
    if not isinstance(check.get(needed), str) or not check[needed]:
        raise SceneError(f"{where}.{needed}", check.get(needed),
                         f"a {quantity} check needs it: a "
                         + ("metric of summary.json" if needed == "name" else "node selector"))
    if check.get("component", "norm") not in (*COMPONENTS, "norm"):
        raise SceneError(f"{where}.component", check["component"], "must be x, y, z or norm")
    if not isinstance(check.get("frame", -1), int):
        raise SceneError(f"{where}.frame", check["frame"], "must be an integer (a saved frame)")
    for key in ("expected", "abs_tol", "rel_tol"):
        value = check.get(key, 0.0)
        if isinstance(value, bool) or not isinstance(value, (int, float)) or \
                (key != "expected" and not value >= 0.0):
            raise SceneError(f"{where}.{key}", value, "must be a number"
                             + (" >= 0" if key != "expected" else ""))
    if "expected" not in check:
        raise SceneError(f"{where}.expected", None, "is required: the value the check expects")


def run_case(folder: Path, output: Path) -> tuple[RunResult, list[CheckResult]]:
    """Run the case's scene into ``output`` and evaluate its checks."""
    expected = read_expected(folder)
    result = run(load_scene(folder / "scene.toml"), output, progress=False)
    checks = [evaluate(folder.name, c, result) for c in expected.get("checks", [])]
    return result, checks


@dataclass(frozen=True)
class CaseOutcome:
    """A case that was run: its result (``None`` when the run raised), its checks, the error
    that stopped it (empty when none) and the wall time [s] of the run and the checks."""

    folder: Path
    result: RunResult | None
    checks: list[CheckResult]
    error: str
    wall_time_s: float

    @property
    def passed(self) -> bool:
        return (not self.error and self.result is not None and self.result.status == "ok"
                and all(c.passed for c in self.checks))

    @property
    def failure(self) -> str:
        """Why the run did not end well: the error it raised or its message; empty when it did."""
        if self.error:
            return self.error
        return "" if self.result is None or self.result.status == "ok" else self.result.message


def validate_case(folder: Path, output: Path) -> CaseOutcome:
    """:func:`run_case`, with a run that raises (a scene it cannot run, an error inside the run)
    kept as a failed case whose every check fails, so that the other cases still run."""
    start = time.perf_counter()
    try:
        result, checks = run_case(folder, output)
        error = ""
    except Exception as exc:  # noqa: BLE001 -- reported as the case's failure
        result, error = None, f"{type(exc).__name__}: {exc}"
        checks = [CheckResult(folder.name, check_label(c), math.nan,
                              float(c.get("expected", math.nan)), tolerance(c), False)
                  for c in read_expected(folder).get("checks", [])]
    return CaseOutcome(folder, result, checks, error, time.perf_counter() - start)


def check_label(check: dict[str, Any]) -> str:
    """How a check is named in the reports, e.g. ``position beam:end z (frame -1)``."""
    if check["quantity"] == "metric":
        return f"metric {check['name']}"
    frame = int(check.get("frame", -1))
    return f"{check['quantity']} {check['node']} {check.get('component', 'norm')} (frame {frame})"


def tolerance(check: dict[str, Any]) -> float:
    """``abs_tol + rel_tol |expected|`` of a check."""
    return (float(check.get("abs_tol", 0.0))
            + float(check.get("rel_tol", 0.0)) * abs(float(check.get("expected", 0.0))))


def check_value(check: dict[str, Any], result: RunResult) -> float:
    """The value a check reads from ``result``; NaN when the run stopped before its frame."""
    if check["quantity"] == "metric":
        return float(result.summary["metrics"].get(check["name"], math.nan))
    positions = result.arrays["positions"]
    frame = int(check.get("frame", -1))
    if not -len(positions) <= frame < len(positions):
        return math.nan
    nodes = result.summary["nodes"]
    if check["node"] not in nodes:
        raise SceneError("checks.node", check["node"], "names no node of the scene (such as "
                         f"{', '.join(sorted(nodes)[:4])})")
    node = nodes[check["node"]]
    vec = positions[frame, node]
    if check["quantity"] == "displacement":
        vec = vec - positions[0, node]
    comp = check.get("component", "norm")
    return float(np.linalg.norm(vec)) if comp == "norm" else float(vec[COMPONENTS[comp]])


def evaluate(case: str, check: dict[str, Any], result: RunResult) -> CheckResult:
    """One ``[[checks]]`` entry of ``case`` against ``result``; it passes when the run ended
    well and ``|value - expected| <= abs_tol + rel_tol |expected|``."""
    value, target, tol = check_value(check, result), float(check["expected"]), tolerance(check)
    passed = result.status == "ok" and abs(value - target) <= tol
    return CheckResult(case, check_label(check), value, target, tol, passed)


def report(results: list[CheckResult]) -> str:
    """A Markdown table of check results."""
    lines = ["| case | check | value | expected | tolerance | pass |", "|---|---|---|---|---|---|"]
    lines += [f"| {r.case} | {r.label} | {r.value:.6g} | {r.expected:.6g} | {r.tolerance:.2g} | "
              f"{'yes' if r.passed else 'NO'} |" for r in results]
    return "\n".join(lines)
