"""The sweep's folder: ``sweep.json`` (and whether it holds this sweep), the complete runs,
and ``sweep.csv``."""

from __future__ import annotations

import csv
import json
import platform
from importlib import metadata
from pathlib import Path
from typing import Any

from rodnet.errors import SceneError
from rodnet.sweep.plan import Run, Sweep, by_value

FINAL = ("ok", "failed")
"""Statuses of a complete run (``"interrupted"`` runs again)."""


PACKAGES = ("rodnet", "numpy", "scipy", "numba", "dask", "distributed")
"""Whose versions ``sweep.json`` records (with Python's)."""


def complete(sweep: Sweep, directory: Path) -> dict[int, dict[str, Any]]:
    """The complete runs in ``directory``: index -> its ``summary.json``.

    Raises
    ------
    SceneError
        ``directory`` is a file, or its ``sweep.json`` describes another sweep.
    """
    if directory.exists() and not directory.is_dir():
        raise SceneError("-o (output directory)", str(directory), "names an existing file, "
                         "not a directory: choose a directory for the sweep")
    stored = directory / "sweep.json"
    if not stored.is_file():
        return {}   # written before any run: without it no run of this sweep is there
    try:
        old = json.loads(stored.read_text())
    except (OSError, ValueError):
        old = {}
    theirs, ours = _identity(old), _identity(sweep.definition())
    if theirs != ours:
        what = [k for k in ours if theirs.get(k) != ours[k]]
        raise SceneError("-o (output directory)", str(directory), f"holds another sweep: its "
                         f"sweep.json differs in {', '.join(what)} (the scene's text, --vary, "
                         "--set, --samples and --seed must be the same to resume); choose "
                         "another directory, or remove this one to start afresh")
    done = {}
    for run in sweep.runs:
        summary = _read_summary(directory / run.folder / "summary.json")
        if summary.get("status") in FINAL:
            done[run.index] = summary
    return done


def _identity(definition: Any) -> dict[str, Any]:
    """What must match to resume: the definition with the scene's text, not its path."""
    if not isinstance(definition, dict):
        return {}
    out = {k: definition.get(k) for k in ("scene", "vary", "set", "samples", "seed", "runs")}
    out["scene"] = out["scene"].get("text") if isinstance(out["scene"], dict) else None
    # options by key and value, not text: --set simulation.duration=3 resumes a sweep of 3.0
    out["vary"] = by_value(out["vary"], split=True)
    out["set"] = by_value(out["set"], split=False)
    if isinstance(out["runs"], list):
        out["runs"] = [{**r, "overrides": by_value(r.get("overrides"), split=False)}
                       if isinstance(r, dict) else r for r in out["runs"]]
    return out


def _read_summary(path: Path) -> dict[str, Any]:
    try:
        return json.loads(path.read_text())
    except (OSError, ValueError):
        return {}


def versions() -> dict[str, str]:
    """Versions of Python and of :data:`PACKAGES` (``"not installed"`` where missing)."""
    found = {"python": platform.python_version()}
    for name in PACKAGES:
        try:
            found[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            found[name] = "not installed"
    return found


def row(sweep: Sweep, run: Run, summary: dict[str, Any] | None) -> dict[str, Any]:
    """The ``sweep.csv`` row of ``run`` from its summary (None: not finished, ``"pending"``)."""
    out: dict[str, Any] = {"index": run.index, **dict(run.values)}
    if summary is None:
        return {**out, "status": "pending", "message": ""}
    out.update(status=summary.get("status", "failed"), message=summary.get("message", ""),
               wall_time_s=summary.get("wall_time_s"), steps=summary.get("steps"))
    for name, value in (summary.get("metrics") or {}).items():
        if isinstance(value, (int, float)) and not isinstance(value, bool):
            out[name] = value
    return out


def write_table(sweep: Sweep, directory: Path, rows: list[dict[str, Any]]) -> Path:
    """Write ``sweep.csv`` (atomically: a reader never sees half of it)."""
    columns = ["index", *sweep.keys, "status", "message", "wall_time_s", "steps"]
    for r in rows:
        columns += [c for c in r if c not in columns]
    path, tmp = directory / "sweep.csv", directory / "sweep.csv.tmp"
    with tmp.open("w", newline="") as f:
        writer = csv.DictWriter(f, columns)
        writer.writeheader()
        writer.writerows({k: _cell(v) for k, v in r.items()} for r in rows)
    tmp.replace(path)
    return path


def _cell(value: Any) -> Any:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, (list, tuple)):
        return json.dumps(list(value))
    return "" if value is None else value


def start(sweep: Sweep, directory: Path) -> None:
    """Create the sweep's folder and write ``sweep.json`` (kept when it is there already)."""
    (directory / "runs").mkdir(parents=True, exist_ok=True)
    if not (directory / "sweep.json").is_file():
        text = json.dumps({**sweep.definition(), "versions": versions()}, indent=1)
        (directory / "sweep.json").write_text(text + "\n")
