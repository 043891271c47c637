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
"""

from __future__ import annotations

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
    checks = [_evaluate(folder.name, c, result) for c in expected.get("checks", [])]
    return result, checks


def _evaluate(case: str, check: dict[str, Any], result: RunResult) -> CheckResult:
    quantity = check["quantity"]
    frame = int(check.get("frame", -1))
    if quantity == "metric":
        value, label = float(result.summary["metrics"][check["name"]]), f"metric {check['name']}"
    else:
        node = result.summary["nodes"][check["node"]]
        vec = result.arrays["positions"][frame, node]
        if quantity == "displacement":
            vec = vec - result.arrays["positions"][0, node]
        comp = check.get("component", "norm")
        value = float(np.linalg.norm(vec)) if comp == "norm" else float(vec[COMPONENTS[comp]])
        label = f"{quantity} {check['node']} {comp} (frame {frame})"
    target = float(check["expected"])
    tol = float(check.get("abs_tol", 0.0)) + float(check.get("rel_tol", 0.0)) * abs(target)
    passed = result.status == "ok" and abs(value - target) <= tol
    return CheckResult(case, label, value, target, tol, passed)


def report(results: list[CheckResult]) -> str:
    """A Markdown table of check results."""
    lines = ["| case | check | value | expected | tolerance | pass |", "|---|---|---|---|---|---|"]
    lines += [f"| {r.case} | {r.label} | {r.value:.6g} | {r.expected:.6g} | {r.tolerance:.2g} | "
              f"{'yes' if r.passed else 'NO'} |" for r in results]
    return "\n".join(lines)
