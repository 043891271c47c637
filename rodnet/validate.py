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


def read_expected(folder: Path) -> dict[str, Any]:
    return tomllib.loads((folder / "expected.toml").read_text())


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
    node = result.summary["nodes"][check["node"]]
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
