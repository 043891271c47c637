"""The validation report of ``rodnet validate --report DIR``: ``DIR/index.html`` (one page, its
figures embedded), ``DIR/report.json`` (the same numbers) and ``DIR/figures/*.png``."""

from __future__ import annotations

import json
import math
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from rodnet.io.results import output_directory
from rodnet.report.curves import case_curves
from rodnet.report.figures import checks_figure, curves_figure, refinement_figure
from rodnet.report.machine import environment
from rodnet.report.page import render
from rodnet.report.refinement import Refinement, refine
from rodnet.report.spec import FigureSpec, RefinementSpec, case_specs
from rodnet.validate import CaseOutcome, CheckResult, read_expected

NOT_RUN = "not run (slow)"


@dataclass
class CaseReport:
    """One case of the report: its outcome (``None``: not run), figures (file name -> PNG),
    notes on what could not be drawn, its refinement, and the wall time of all of it [s]."""

    folder: Path
    expected: dict[str, Any]
    outcome: CaseOutcome | None
    figures: dict[str, bytes] = field(default_factory=dict)
    captions: dict[str, str] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)
    refinement: Refinement | None = None
    wall_time_s: float = 0.0

    def add_figure(self, name: str, png: bytes, caption: str) -> None:
        self.figures[name], self.captions[name] = png, caption

    @property
    def status(self) -> str:
        if self.outcome is None:
            return NOT_RUN
        return "passed" if self.outcome.passed else "FAILED"


def figure_caption(spec: FigureSpec) -> str:
    """What a case's figure shows, in words."""
    parts = ", ".join(spec.components)
    if spec.quantity == "series":
        what = f"The series {spec.components[0]} at every saved frame"
    elif spec.shape:
        frame = "the last frame" if spec.frame == -1 else f"frame {spec.frame}"
        what = f"The {spec.quantity} ({parts}) of the nodes of rod {spec.rod} at {frame}"
    else:
        what = f"The {spec.quantity} ({parts}) of node {spec.node} at every saved frame"
    if spec.quantity == "series" and spec.reference is None:
        return (what + "; dashed line and grey band: the expected value of each metric check and "
                "its tolerance. Lower panel: the same, zoomed on the band.")
    if spec.reference is None:
        return what + "; squares with bars: the checks' expected values with their tolerances."
    source = (f"the table {spec.reference}" if spec.reference.endswith(".csv")
              else f"{spec.reference}() of reference.py")
    return (what + f", against the reference, {source} (dashed); squares with bars: the checks' "
            "expected values with their tolerances. Lower panel: rodnet less the reference.")


def _finite(value: float) -> float | None:
    """JSON has no NaN: a value that is not finite is written as null."""
    return value if math.isfinite(value) else None


def _check_json(c: CheckResult) -> dict[str, Any]:
    return {"label": c.label, "value": _finite(c.value), "expected": c.expected,
            "tolerance": c.tolerance, "passed": c.passed}


def _refinement_json(r: Refinement) -> dict[str, Any]:
    return {"key": r.spec.key, "values": list(r.spec.values), "scale": r.spec.scale,
            "check": r.label, "expected": r.expected,
            "values_found": [_finite(v) for v in r.values_found],
            "errors": [_finite(e) for e in r.errors], "orders": [_finite(p) for p in r.orders],
            "expected_order": r.spec.expected_order, "failures": list(r.failures)}


def _case_json(case: CaseReport) -> dict[str, Any]:
    out = case.outcome
    checks = out.checks if out is not None else []
    result = out.result if out is not None else None
    return {
        "name": case.folder.name,
        "description": case.expected.get("description", ""),
        "source": case.expected.get("source", ""),
        "slow": bool(case.expected.get("slow", False)),
        "status": case.status,
        "run_status": None if out is None else ("error" if result is None else result.status),
        "message": "" if out is None else out.failure,
        "wall_time_s": None if out is None else round(case.wall_time_s, 3),
        "checks": [_check_json(c) for c in checks],
        "figures": [{"file": f"figures/{name}", "caption": case.captions[name]}
                    for name in case.figures],
        "notes": case.notes,
        "refinement": None if case.refinement is None else _refinement_json(case.refinement),
    }


class ReportBuilder:
    """Collects the cases of one ``rodnet validate --report`` and writes the report.

    The constructor checks every case's ``[figure]`` and ``[refinement]`` table and the report
    folder, raising :class:`rodnet.errors.SceneError` before anything is run.
    """

    def __init__(self, directory: Path, folders: list[Path]) -> None:
        self.specs: dict[Path, tuple[FigureSpec | None, RefinementSpec | None]] = {
            f: case_specs(f, read_expected(f)) for f in folders}
        self.directory = output_directory(directory, "--report")
        self.cases: list[CaseReport] = []
        self.start = time.perf_counter()

    def not_run(self, folder: Path) -> None:
        """List a slow case that was left out."""
        self.cases.append(CaseReport(folder, read_expected(folder), None))

    def add(self, outcome: CaseOutcome, scratch: Path) -> CaseReport:
        """Draw the figures of a case that ran and run its refinement (into ``scratch``)."""
        start = time.perf_counter()
        folder = outcome.folder
        case = CaseReport(folder, read_expected(folder), outcome)
        figure, refinement = self.specs[folder]
        checks = case.expected.get("checks", [])
        if outcome.result is None:
            case.notes.append("No figure: the run raised an error (above).")
        elif figure is None:
            case.add_figure(f"{folder.name}_checks.png", checks_figure(outcome.checks, folder.name),
                            "This case declares no [figure] table: each check's (value - expected) "
                            "/ tolerance; a check passes inside the grey band.")
        else:
            try:
                curves = case_curves(figure, folder, checks, outcome.result)
            except (ValueError, KeyError, IndexError) as exc:
                case.notes.append(f"No figure: {exc}.")
            else:
                case.add_figure(f"{folder.name}.png", curves_figure(curves, folder.name),
                                figure_caption(figure))
        if refinement is not None and outcome.result is not None:
            case.refinement = refine(folder, refinement, checks, scratch / "refinement")
            order = refinement.expected_order
            case.add_figure(f"{folder.name}_refinement.png", refinement_figure(
                case.refinement, f"{folder.name}: refinement of {refinement.key}"),
                f"|value - expected| of {case.refinement.label} at {refinement.key} = "
                f"{', '.join(map(str, refinement.values))}"
                + ("" if order is None else f"; dashed: the slope of order {order:g}") + ".")
        case.wall_time_s = outcome.wall_time_s + time.perf_counter() - start
        self.cases.append(case)
        return case

    def verdict(self, slow_tests: str) -> dict[str, Any]:
        """Checks passed of all, cases run, failed and not run, the slow tests' outcome."""
        ran = [c for c in self.cases if c.outcome is not None]
        checks = [k for c in ran for k in c.outcome.checks]  # type: ignore[union-attr]
        failed = [c.folder.name for c in ran if c.status != "passed"]
        ok = not failed and not slow_tests.startswith("FAILED")
        return {"status": "PASSED" if ok else "FAILED",
                "checks_passed": sum(k.passed for k in checks), "checks_total": len(checks), "cases_run": len(ran), "cases_failed": failed,
                "cases_not_run": [c.folder.name for c in self.cases if c.outcome is None],
                "slow_tests": slow_tests}

    def write(self, slow: bool, slow_tests: str) -> Path:
        """Write ``index.html``, ``report.json`` and ``figures/``; returns the page's path.
        ``slow``: whether the slow cases were run; ``slow_tests``: "passed", "FAILED" or
        "not run"."""
        header = {**environment(), "slow_cases_included": slow,
                  "wall_time_s": round(time.perf_counter() - self.start, 1),
                  "verdict": self.verdict(slow_tests)}
        report = {"header": header, "cases": [_case_json(c) for c in self.cases]}
        figures = self.directory / "figures"
        figures.mkdir(exist_ok=True)
        for case in self.cases:
            for name, png in case.figures.items():
                (figures / name).write_bytes(png)
        (self.directory / "report.json").write_text(json.dumps(report, indent=2) + "\n")
        page = self.directory / "index.html"
        page.write_text(render(report, {c.folder.name: c.figures for c in self.cases},
                                {c.folder.name: c.folder for c in self.cases}))
        return page
