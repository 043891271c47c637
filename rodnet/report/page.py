"""The HTML page of a validation report: one self-contained file, its figures embedded as
base64 PNG, written from the report's JSON data (:mod:`rodnet.report.build`)."""

from __future__ import annotations

import base64
import html
import re
from pathlib import Path
from typing import Any

STYLE = """
body { font-family: system-ui, -apple-system, "Segoe UI", sans-serif; max-width: 1100px;
       margin: 1.5em auto; padding: 0 1em; color: #1d1d1f; line-height: 1.45; }
h1 { margin-bottom: 0.2em; }
h2 { border-bottom: 1px solid #ccc; padding-bottom: 0.2em; margin-top: 2em; }
table { border-collapse: collapse; margin: 0.6em 0; font-size: 0.92em; }
th, td { border: 1px solid #ccc; padding: 0.25em 0.55em; text-align: left; vertical-align: top; }
th { background: #f2f2f2; }
td.num { text-align: right; font-variant-numeric: tabular-nums;
         font-family: ui-monospace, monospace; }
.verdict { font-size: 1.25em; font-weight: bold; padding: 0.5em 0.8em; border-radius: 4px; }
.passed { color: #0a6b1f; } .FAILED { color: #b00020; } .not-run { color: #777; }
.verdict.passed { background: #e3f5e6; } .verdict.FAILED { background: #fde7ea; color: #b00020; }
.badge { font-size: 0.7em; padding: 0.1em 0.5em; border-radius: 3px; border: 1px solid currentColor;
         vertical-align: middle; margin-left: 0.5em; }
.failure { background: #fde7ea; padding: 0.5em; border-left: 4px solid #b00020; }
figure { margin: 1em 0; } figure img { max-width: 100%; border: 1px solid #eee; }
figcaption { font-size: 0.9em; color: #444; }
details { margin: 0.5em 0; } summary { cursor: pointer; font-weight: 600; }
pre { background: #f7f7f7; padding: 0.6em; overflow-x: auto; font-size: 0.85em; }
.readme { border-left: 3px solid #ddd; padding-left: 1em; }
"""

ENVIRONMENT_ROWS = (("rodnet version", "rodnet_version"), ("git commit", "git_commit"),
                    ("tracked files changed since the commit", "git_modified"),
                    ("Python", "python"), ("NumPy", "numpy"), ("SciPy", "scipy"),
                    ("Numba", "numba"), ("Matplotlib", "matplotlib"), ("platform", "platform"),
                    ("CPU count", "cpu_count"), ("CPU model", "cpu_model"), ("date", "date"),
                    ("slow cases run", "slow_cases_included"),
                    ("time to build this report [s]", "wall_time_s"))


def _e(value: Any) -> str:
    return html.escape(str(value))


def _num(value: float | None, fmt: str = ".7g") -> str:
    return "-" if value is None else format(value, fmt)


def _word(value: Any) -> Any:
    """Yes and no for booleans, "unknown" for ``None``."""
    if isinstance(value, bool):
        return "yes" if value else "no"
    return "unknown" if value is None else value


def _status_class(status: str) -> str:
    return "not-run" if status.startswith("not run") else status


def markdown(text: str) -> str:
    """``text`` rendered from Markdown (tables included; raw HTML escaped), or preformatted where
    markdown-it-py is not installed."""
    try:
        from markdown_it import MarkdownIt
    except ImportError:
        return f"<pre>{_e(text)}</pre>"
    rendered = MarkdownIt("commonmark", {"html": False}).enable("table").render(text)
    # the README's headings below the case's own (h2) and its sections (h3)
    return re.sub(r"<(/?)h([1-6])>", lambda m: f"<{m[1]}h{min(int(m[2]) + 3, 6)}>", rendered)


def _header(report: dict[str, Any]) -> str:
    head, verdict = report["header"], report["header"]["verdict"]
    status = verdict["status"]
    words = (f"{status}: {verdict['checks_passed']} of {verdict['checks_total']} checks passed in "
             f"{verdict['cases_run']} cases")
    if verdict["cases_failed"]:
        words += f"; failed: {', '.join(verdict['cases_failed'])}"
    if verdict["cases_not_run"]:
        words += f"; {len(verdict['cases_not_run'])} slow cases not run"
    words += f"; slow validation tests: {verdict['slow_tests']}"
    rows = "".join(f"<tr><th>{_e(label)}</th><td>{_e(_word(head[key]))}</td></tr>"
                   for label, key in ENVIRONMENT_ROWS)
    return (f'<h1>rodnet validation report</h1>\n<p class="verdict {status}" id="verdict">'
            f"{_e(words)}</p>\n<table class=\"environment\">{rows}</table>\n")


def _summary(report: dict[str, Any]) -> str:
    rows = []
    for case in report["cases"]:
        checks = case["checks"]
        passed = sum(c["passed"] for c in checks)
        ref = case["refinement"]
        order = "-" if not ref or ref["orders"][-1] is None else f"{ref['orders'][-1]:.3f}"
        rows.append(
            f'<tr><td><a href="#case-{_e(case["name"])}">{_e(case["name"])}</a></td>'
            f'<td>{_e(case["description"])}</td>'
            f'<td class="num">{passed if case["run_status"] else "-"} / {len(checks) or "-"}</td>'
            f'<td class="{_status_class(case["status"])}">{_e(case["status"])}</td>'
            f'<td class="num">{_num(case["wall_time_s"], ".2f")}</td>'
            f'<td class="num">{order}</td></tr>')
    return ("<h2>Cases</h2>\n<table><tr><th>case</th><th>what it checks</th><th>checks passed</th>"
            "<th>status</th><th>wall time [s]</th><th>observed order (finest pair)</th></tr>"
            + "".join(rows) + "</table>\n")


def _checks_table(checks: list[dict[str, Any]]) -> str:
    rows = []
    for c in checks:
        dev = None if c["value"] is None else abs(c["value"] - c["expected"])
        status = "passed" if c["passed"] else "FAILED"
        rows.append(f'<tr><td>{_e(c["label"])}</td><td class="num">{_num(c["value"])}</td>'
                    f'<td class="num">{_num(c["expected"])}</td>'
                    f'<td class="num">{_num(c["tolerance"], ".3g")}</td>'
                    f'<td class="num">{_num(dev, ".3g")}</td>'
                    f'<td class="{status}">{status}</td></tr>')
    return ("<h3>Checks</h3>\n<table class=\"checks\"><tr><th>check</th><th>value</th>"
            "<th>expected</th><th>tolerance</th><th>|value - expected|</th><th>pass</th></tr>"
            + "".join(rows) + "</table>\n")


def _refinement_table(ref: dict[str, Any]) -> str:
    rows = "".join(
        f'<tr><td class="num">{_e(v)}</td><td class="num">{_num(found, ".10g")}</td>'
        f'<td class="num">{_num(err, ".4g")}</td>'
        f'<td class="num">{"" if i == 0 else _num(ref["orders"][i - 1], ".3f")}</td></tr>'
        for i, (v, found, err) in enumerate(zip(ref["values"], ref["values_found"], ref["errors"])))
    expected = "" if ref["expected_order"] is None else \
        f" The method's order is {ref['expected_order']:g}."
    failures = "".join(f'<p class="failure">{_e(f)}</p>' for f in ref["failures"])
    return (f"<h3>Observed convergence order</h3>\n<p>The check <code>{_e(ref['check'])}</code> "
            f"(expected {ref['expected']:.10g}) with <code>{_e(ref['key'])}</code> set to each "
            f"value; the order between a value and the one before is log(e<sub>k-1</sub> / "
            f"e<sub>k</sub>) / log(h<sub>k-1</sub> / h<sub>k</sub>), h = "
            f"{'1 / value' if ref['scale'] == 'count' else 'value'}.{expected}</p>\n"
            f"{failures}<table class=\"refinement\"><tr><th>{_e(ref['key'])}</th><th>value</th>"
            f"<th>error</th><th>observed order</th></tr>{rows}</table>\n")


def _figures(case: dict[str, Any], pngs: dict[str, bytes]) -> str:
    parts = []
    for entry in case["figures"]:
        name = Path(entry["file"]).name
        data = base64.b64encode(pngs[name]).decode("ascii")
        parts.append(f'<figure><img alt="{_e(name)}" src="data:image/png;base64,{data}">'
                     f"<figcaption>{_e(entry['caption'])}</figcaption></figure>")
    parts += [f"<p><em>{_e(note)}</em></p>" for note in case["notes"]]
    return "\n".join(parts) + "\n"


def _case(case: dict[str, Any], pngs: dict[str, bytes], folder: Path) -> str:
    status, name = case["status"], case["name"]
    out = [f'<section class="case" id="case-{_e(name)}" data-case="{_e(name)}" '
           f'data-status="{_e(status)}">',
           f'<h2>{_e(name)} <span class="badge {_status_class(status)}">{_e(status)}</span></h2>',
           f"<p>{_e(case['description'])}</p>",
           f"<p><strong>Source of the expected values:</strong> {_e(case['source'])}</p>"]
    if case["run_status"] is None:
        out.append("<p class=\"not-run\">Not run: a slow case. <code>rodnet validate --report DIR "
                   "--slow</code> runs it.</p>")
    else:
        if case["message"]:
            what = "raised an error" if case["run_status"] == "error" else "failed"
            out.append(f'<p class="failure">The run {what}: {_e(case["message"])}</p>')
        out.append(_figures(case, pngs))
        out.append(_checks_table(case["checks"]))
        if case["refinement"] is not None:
            out.append(_refinement_table(case["refinement"]))
    readme = folder / "README.md"
    if readme.is_file():
        out.append(f"<details><summary>README.md: where the expected values come from</summary>"
                   f'<div class="readme">{markdown(readme.read_text())}</div></details>')
    scene = _e((folder / "scene.toml").read_text())
    out.append(f"<details><summary>scene.toml</summary><pre>{scene}</pre></details>")
    out.append("</section>")
    return "\n".join(out) + "\n"


HOW_TO_READ = """<h2>How to read this report</h2>
<p>Each case runs its <code>scene.toml</code> as <code>rodnet run</code> would and reads the values
of its <code>expected.toml</code>; a check passes when the run ended well and |value - expected|
&le; tolerance. The upper panel of a figure shows rodnet (lines with markers) against the
reference (dashed); the lower panel, where there is a reference curve, shows rodnet less the
reference. Squares with bars are the checks: the expected value with its tolerance (in the lower
panel less the reference), so a check passes where rodnet's curve runs inside its bar.</p>
"""


def render(report: dict[str, Any], figures: dict[str, dict[str, bytes]],
           folders: dict[str, Path]) -> str:
    """The page: header and verdict, the table of cases, a section per case."""
    body = [_header(report), _summary(report)]
    body += [_case(c, figures[c["name"]], folders[c["name"]]) for c in report["cases"]]
    body.append(HOW_TO_READ)
    return ("<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n"
            "<title>rodnet validation report</title>\n"
            f"<style>{STYLE}</style>\n</head>\n<body>\n" + "".join(body) + "</body>\n</html>\n")
