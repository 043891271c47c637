"""``rodnet validate --report DIR``: the page and report.json list every case with its checks,
figures and header; a failing case shows as FAILED; the page renders in headless Chromium; the
reference curves of the figures pass through the cases' expected values."""

from __future__ import annotations

import base64
import datetime
import io
import json
import os
import platform
import runpy
import shutil
import subprocess
import time
import tomllib
from dataclasses import dataclass
from html.parser import HTMLParser
from importlib import metadata
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from matplotlib.image import imread

import rodnet
from rodnet.cli import EXIT_BAD_INPUT, EXIT_FAILED, main

ROOT = Path(__file__).parents[2]
CASES = ROOT / "validation" / "cases"
PNG = b"\x89PNG\r\n\x1a\n"


def _cases() -> dict[str, dict[str, Any]]:
    """Every case folder (scene.toml + expected.toml) with its expected.toml, read here."""
    return {p.parent.name: tomllib.loads(p.read_text()) for p in sorted(CASES.glob("*/expected.toml"))
            if (p.parent / "scene.toml").exists()}


class Sections(HTMLParser):
    """Per ``<section class="case">``: its status, its images (``src``) and the cells of the rows
    of its ``table.checks``."""

    def __init__(self) -> None:
        super().__init__()
        self.cases: dict[str, dict[str, Any]] = {}
        self.current: dict[str, Any] | None = None
        self.in_checks = False
        self.cell: list[str] | None = None

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        a = dict(attrs)
        if tag == "section" and a.get("class") == "case":
            self.current = {"status": a["data-status"], "images": [], "rows": []}
            self.cases[str(a["data-case"])] = self.current
        elif self.current is None:
            return
        elif tag == "img":
            self.current["images"].append(a["src"])
        elif tag == "table":
            self.in_checks = a.get("class") == "checks"
        elif tag == "tr" and self.in_checks:
            self.current["rows"].append([])
        elif tag == "td" and self.in_checks:
            self.cell = []

    def handle_endtag(self, tag: str) -> None:
        if tag == "section":
            self.current = None
        elif tag == "table":
            self.in_checks = False
        elif tag == "td" and self.cell is not None and self.current is not None:
            self.current["rows"][-1].append("".join(self.cell).strip())
            self.cell = None

    def handle_data(self, data: str) -> None:
        if self.cell is not None:
            self.cell.append(data)


@dataclass
class Built:
    status: int
    directory: Path
    data: dict[str, Any]
    sections: dict[str, dict[str, Any]]
    seconds: float
    out: str


def _build(args: list[str], directory: Path, capsys: Any = None) -> Built:
    start = time.perf_counter()
    status = main(["validate", "--report", str(directory), "-o", str(directory / "md"), *args])
    seconds = time.perf_counter() - start
    out = capsys.readouterr().out if capsys is not None else ""
    page = directory / "index.html"
    parser = Sections()
    if page.exists():
        parser.feed(page.read_text())
    data = json.loads((directory / "report.json").read_text()) if page.exists() else {}
    return Built(status, directory, data, parser.cases, seconds, out)


@pytest.fixture(scope="module")
def quick(tmp_path_factory: pytest.TempPathFactory) -> Built:
    """The quick report of the repository's cases, built once."""
    built = _build(["--cases", str(CASES)], tmp_path_factory.mktemp("quick") / "report")
    print(f"quick report built in {built.seconds:.1f} s")
    return built


def test_the_page_lists_every_case_with_its_checks_and_figures(quick: Built) -> None:
    assert quick.status == 0
    assert set(quick.sections) == set(_cases())
    for name, expected in _cases().items():
        section = quick.sections[name]
        if expected.get("slow", False):
            assert section["status"] == "not run (slow)" and not section["images"]
            continue
        assert section["status"] == "passed"
        assert len(section["images"]) >= 1 + ("refinement" in expected), name
        rows = [r for r in section["rows"] if r]
        assert len(rows) == len(expected["checks"]), name
        for row, check in zip(rows, expected["checks"]):
            assert float(row[2]) == pytest.approx(check["expected"], rel=1e-6, abs=1e-300)
            assert row[-1] == "passed"


def test_every_figure_is_a_png_that_is_not_blank(quick: Built) -> None:
    for case in quick.data["cases"]:
        embedded = [s for s in quick.sections[case["name"]]["images"]]
        assert len(embedded) == len(case["figures"])
        for src, figure in zip(embedded, case["figures"]):
            png = (quick.directory / figure["file"]).read_bytes()
            assert png.startswith(PNG) and src == "data:image/png;base64," + base64.b64encode(png).decode()
            image = imread(io.BytesIO(png))
            assert image.shape[0] >= 300 and image.shape[1] >= 500
            assert (image[..., :3] < 0.9).mean() > 0.01, f"{figure['file']} is nearly blank"
            assert figure["caption"]


def test_report_json_holds_the_cases_checks_and_header(quick: Built) -> None:
    cases = _cases()
    assert [c["name"] for c in quick.data["cases"]] == list(cases)
    total = 0
    for case in quick.data["cases"]:
        expected = cases[case["name"]]
        assert case["source"] == expected["source"] and case["description"] == expected["description"]
        if expected.get("slow", False):
            assert case["status"] == "not run (slow)" and case["checks"] == []
            continue
        assert len(case["checks"]) == len(expected["checks"])
        total += len(expected["checks"])
        for got, check in zip(case["checks"], expected["checks"]):
            tol = check.get("abs_tol", 0.0) + check.get("rel_tol", 0.0) * abs(check["expected"])
            assert got["expected"] == check["expected"]
            assert got["tolerance"] == pytest.approx(tol, rel=1e-12)
            assert got["passed"] is (abs(got["value"] - check["expected"]) <= tol)
    head = quick.data["header"]
    assert head["rodnet_version"] == rodnet.__version__
    git = shutil.which("git") and subprocess.run(["git", "-C", str(ROOT), "rev-parse", "HEAD"],
                                                 capture_output=True, text=True)
    assert head["git_commit"] == (git.stdout.strip() if git and git.returncode == 0 else "unknown")
    for library in ("numpy", "scipy", "numba"):
        assert head[library] == metadata.version(library)
    assert head["python"] == platform.python_version() and head["cpu_count"] == os.cpu_count()
    assert head["platform"] and head["cpu_model"]
    age = datetime.datetime.now(datetime.timezone.utc) - datetime.datetime.fromisoformat(head["date"])
    assert abs(age.total_seconds()) < 3600
    verdict = head["verdict"]
    assert (verdict["status"], verdict["checks_passed"], verdict["checks_total"]) == ("PASSED", total, total)
    assert verdict["slow_tests"] == "not run" and head["slow_cases_included"] is False
    assert f"{total} of {total} checks passed" in (quick.directory / "index.html").read_text()


def test_the_refinement_shows_the_observed_order_two(quick: Built) -> None:
    """The roll-up's half-circle tip on n elements: the nodes lie on a circle of radius
    h / (2 sin(pi / (2 n))), so the tip y is off by (2 L / pi) ((pi / 2n) / sin(pi / 2n) - 1)."""
    (case,) = [c for c in quick.data["cases"] if c["refinement"]]
    ref = case["refinement"]
    n = np.asarray(ref["values"], float)
    predicted = 2 / np.pi * ((np.pi / (2 * n)) / np.sin(np.pi / (2 * n)) - 1)
    np.testing.assert_allclose(ref["errors"], predicted, rtol=1e-6)
    assert len(ref["orders"]) == len(n) - 1
    np.testing.assert_allclose(ref["orders"], 2.0, atol=0.02)
    assert "Observed convergence order" in (quick.directory / "index.html").read_text()


def _chromium() -> str | None:
    return shutil.which("chromium") or shutil.which("chromium-browser")


@pytest.mark.skipif(_chromium() is None, reason="headless Chromium is not installed "
                    "(Debian: apt-get install chromium)")
def test_the_page_renders_in_headless_chromium(quick: Built, tmp_path: Path) -> None:
    page = (quick.directory / "index.html").resolve().as_uri()
    base = [str(_chromium()), "--headless", "--disable-gpu", "--no-sandbox",
            f"--user-data-dir={tmp_path / 'profile'}"]
    dom = subprocess.run([*base, "--dump-dom", page], capture_output=True, text=True, timeout=300)
    for name in _cases():
        assert f'data-case="{name}"' in dom.stdout
    shot = tmp_path / "page.png"
    subprocess.run([*base, "--hide-scrollbars", "--window-size=1200,1600", f"--screenshot={shot}",
                    page], capture_output=True, timeout=300)
    image = imread(shot)
    assert image.shape[:2] == (1600, 1200)
    assert (image[..., :3] < 0.9).mean() > 0.02, "the screenshot is blank"


# --- a failing case, slow cases, bad input ---------------------------------------------------------

def _copy_case(source: str, target: Path, expected: str | None = None, scene: str | None = None) -> None:
    target.mkdir(parents=True)
    for name in ("scene.toml", "README.md", "reference.py"):
        if (CASES / source / name).exists():
            shutil.copy(CASES / source / name, target / name)
    if scene is not None:
        (target / "scene.toml").write_text(scene)
    (target / "expected.toml").write_text(expected if expected is not None
                                          else (CASES / source / "expected.toml").read_text())


WRONG = '''description = "the gravity cantilever with a wrong tip value"
source = "deliberately wrong"
[[checks]]
quantity = "position"
node = "beam:end"
component = "z"
expected = -0.0080
rel_tol = 1.0e-3
[[checks]]
quantity = "position"
node = "beam:10"
component = "z"
expected = -0.0027100125
rel_tol = 2.0e-3
[figure]
x = "arc_length"
quantity = "position"
rod = "beam"
components = ["z"]
reference = "deflection"
'''


@pytest.fixture
def mixed_cases(tmp_path: Path) -> Path:
    """A good case, one with a wrong expected value, one whose run raises (a static rod with no
    support) and a slow one."""
    cases = tmp_path / "cases"
    _copy_case("cantilever_gravity", cases / "good")
    _copy_case("cantilever_gravity", cases / "wrong", expected=WRONG)
    unsupported = (CASES / "cantilever_gravity" / "scene.toml").read_text().replace(
        '[[supports]]\nnode = "beam:start"\nfix = "clamp"\n', "")
    _copy_case("cantilever_gravity", cases / "unsupported", scene=unsupported)
    slow = (CASES / "cantilever_elastica" / "expected.toml").read_text().replace(
        "slow = false", "slow = true")
    _copy_case("cantilever_elastica", cases / "slowcase", expected=slow)
    return cases


def _no_pytest(monkeypatch: pytest.MonkeyPatch, calls: list[list[str]], returncode: int | None
               ) -> None:
    """Record the slow-test runs of ``rodnet validate`` instead of running pytest (``returncode
    None``: fail the test if one is started); everything else runs as usual."""
    real = subprocess.Popen

    class Fake:
        """pytest's last lines, and its exit status."""

        def __init__(self, command: list[str]) -> None:
            self.stdout = iter(["..s.\n", "\n", "3 passed, 1 skipped in 2.50s\n"])
            self.returncode = returncode

        def __enter__(self) -> "Fake":
            return self

        def __exit__(self, *exc: Any) -> None:
            return None

    def fake(command: list[str], *args: Any, **kwargs: Any) -> Any:
        if "pytest" in command:
            assert returncode is not None, f"started the slow tests: {command}"
            calls.append(list(command))
            return Fake(command)
        return real(command, *args, **kwargs)

    monkeypatch.setattr(subprocess, "Popen", fake)


def test_failing_cases_show_as_failed(mixed_cases: Path, tmp_path: Path, capsys: Any,
                                      monkeypatch: pytest.MonkeyPatch) -> None:
    _no_pytest(monkeypatch, [], None)
    built = _build(["--cases", str(mixed_cases)], tmp_path / "report", capsys)
    assert built.status == EXIT_FAILED
    status = {c["name"]: c for c in built.data["cases"]}
    assert {n: c["status"] for n, c in status.items()} == {
        "good": "passed", "wrong": "FAILED", "unsupported": "FAILED", "slowcase": "not run (slow)"}
    assert [c["passed"] for c in status["wrong"]["checks"]] == [False, True]
    assert status["unsupported"]["run_status"] == "error" and "supports" in status["unsupported"]["message"]
    assert all(c["passed"] is False and c["value"] is None for c in status["unsupported"]["checks"])
    sections = built.sections
    assert sections["wrong"]["status"] == "FAILED" and len(sections["wrong"]["images"]) == 1
    assert [r[-1] for r in sections["wrong"]["rows"] if r] == ["FAILED", "passed"]
    assert sections["unsupported"]["status"] == "FAILED" and not sections["unsupported"]["images"]
    assert sections["slowcase"]["status"] == "not run (slow)"
    verdict = built.data["header"]["verdict"]
    assert verdict["status"] == "FAILED" and verdict["cases_failed"] == ["unsupported", "wrong"]
    assert verdict["cases_not_run"] == ["slowcase"]
    page = (built.directory / "index.html").read_text()
    assert 'class="verdict FAILED"' in page and "slow validation tests: not run" in page
    assert "rodnet validate: FAILED" in built.out and "1 slow cases not run" in built.out


def test_slow_runs_the_slow_cases_and_tests(mixed_cases: Path, tmp_path: Path, capsys: Any,
                                            monkeypatch: pytest.MonkeyPatch) -> None:
    calls: list[list[str]] = []
    _no_pytest(monkeypatch, calls, 0)
    for name in ("wrong", "unsupported"):
        shutil.rmtree(mixed_cases / name)
    built = _build(["--cases", str(mixed_cases), "--slow"], tmp_path / "report", capsys)
    assert built.status == 0 and len(calls) == 1 and calls[0][-3:] == ["-m", "slow", "tests"]
    assert {c["name"]: c["status"] for c in built.data["cases"]} == {"good": "passed",
                                                                     "slowcase": "passed"}
    # pytest's counts, a skip too (it had said "passed" over "17 passed, 1 skipped")
    assert built.data["header"]["verdict"]["slow_tests"] == "passed (3 passed, 1 skipped)"
    assert built.data["header"]["slow_cases_included"] is True
    assert len(built.sections["slowcase"]["images"]) == 1
    calls.clear()
    again = _build(["--cases", str(mixed_cases), "--slow", "--no-tests"], tmp_path / "again", capsys)
    assert again.status == 0 and not calls
    assert again.data["header"]["verdict"]["slow_tests"] == "not run"


@pytest.mark.parametrize("table, key", [('x = "frequency"', "figure.x"),
                                        ('reference = "nowhere"', "figure.reference"),
                                        ('components = ["w"]', "figure.components")])
def test_a_bad_figure_table_is_refused_before_anything_runs(tmp_path: Path, capsys: Any,
                                                            table: str, key: str) -> None:
    cases = tmp_path / "cases"
    text = (CASES / "cantilever_rollup" / "expected.toml").read_text()
    line = {"figure.x": 'x = "load_factor"', "figure.reference": 'reference = "tip"',
            "figure.components": 'components = ["x", "y", "norm"]'}[key]
    assert line in text
    _copy_case("cantilever_rollup", cases / "bad", expected=text.replace(line, table))
    report = tmp_path / "report"
    assert main(["validate", "--cases", str(cases), "--report", str(report),
                 "-o", str(tmp_path / "md")]) == EXIT_BAD_INPUT
    err = capsys.readouterr().err
    assert key in err and table.split(" = ")[1].strip('[]"') in err and "validating" not in err
    assert not report.exists() and not (tmp_path / "md").exists()


def test_fast_and_slow_together_are_refused(capsys: Any) -> None:
    assert main(["validate", "--fast", "--slow", "--report", "nowhere"]) == EXIT_BAD_INPUT
    assert "--fast and --slow" in capsys.readouterr().err


# --- the reference curves of the figures against the expected values ------------------------------

def _abscissa(check: dict[str, Any], scene: dict[str, Any], figure: dict[str, Any]) -> float:
    """Where a check lies on its case's figure, from the scene alone: the load factor of a static
    frame, the time of a dynamic one, or the arc length of a node of a straight rod."""
    if figure["x"] == "arc_length":
        rod = scene["rods"][0]
        length = float(np.linalg.norm(np.subtract(rod["points"][-1], rod["points"][0])))
        index = check["node"].split(":")[1]
        return length if index == "end" else int(index) / rod["elements"] * length
    frame = int(check.get("frame", -1))
    if scene["simulation"]["type"] == "static":
        steps = scene["simulation"]["load_steps"]
        return (frame % steps + 1) / steps
    assert frame >= 0
    return frame * scene["output"]["frame_interval"]


@pytest.mark.parametrize("name", [n for n, e in _cases().items()
                                  if e.get("figure", {}).get("reference")])
def test_each_reference_curve_passes_through_the_expected_values(name: str) -> None:
    expected = _cases()[name]
    figure = expected["figure"]
    scene = tomllib.loads((CASES / name / "scene.toml").read_text())
    drawn = [c for c in expected["checks"] if c["quantity"] == figure["quantity"]
             and c.get("component", "norm") in figure["components"]
             and (c["node"] == figure["node"] if "node" in figure
                  else c["node"].split(":")[0] == figure["rod"])]
    assert drawn, "no check lies on the figure"
    x = np.array([_abscissa(c, scene, figure) for c in drawn])
    if figure["reference"].endswith(".csv"):
        lines = [line for line in (CASES / name / figure["reference"]).read_text().splitlines()
                 if line.strip() and not line.startswith("#")]
        header = lines[0].split(",")
        table = np.array([[float(v) for v in line.split(",")] for line in lines[1:]])
        values = {c: np.interp(x, table[:, header.index(figure["x"])], table[:, header.index(c)])
                  for c in figure["components"]}
    else:
        function = runpy.run_path(str(CASES / name / "reference.py"))[figure["reference"]]
        values = function(x, scene)
    for i, check in enumerate(drawn):
        tol = check.get("abs_tol", 0.0) + check.get("rel_tol", 0.0) * abs(check["expected"])
        assert values[check.get("component", "norm")][i] == pytest.approx(
            check["expected"], abs=1e-3 * tol), check
