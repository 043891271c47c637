"""``result.npz`` and ``summary.json``."""

from __future__ import annotations

import dataclasses
import json
import math
import os
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from rodnet.config import Scene, toml_key
from rodnet.errors import SceneError


def output_directory(path: str | Path, key: str = "output.directory") -> Path:
    """Create the output directory ``path`` (and its parents) or raise :class:`SceneError`
    naming ``key`` when it cannot be used: a file of that name, a parent that is a file, no
    permission to write there."""
    if not str(path).strip():
        raise SceneError(key, str(path), "is empty: name a directory for the results (\".\" "
                         "for the working directory)")
    path = Path(path)
    if path.exists() and not path.is_dir():
        raise SceneError(key, str(path), "names an existing file, not a directory: choose a "
                         "directory for the results (it is created when missing)")
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise SceneError(key, str(path), f"cannot be created as the output directory: "
                         f"{exc.strerror}") from None
    if not os.access(path, os.W_OK | os.X_OK):
        raise SceneError(key, str(path), "is not writable: choose a directory you may write to")
    return path


def write_npz(path: Path, arrays: dict[str, NDArray[Any]]) -> None:
    """Write the result arrays (atomically: a partial file never replaces a good one)."""
    tmp = path.with_suffix(".tmp.npz")
    np.savez(tmp, **arrays)
    tmp.replace(path)


def scene_as_dict(scene: Scene, unused: tuple[str, ...] = ()) -> dict[str, Any]:
    """The scene as run, in the TOML layout: unset optional keys and the ``unused`` keys
    (``"section.key"``: keys the run's model has no use for) left out."""
    out = dataclasses.asdict(scene)
    for dotted in unused:
        section, key = dotted.split(".")
        if isinstance(out.get(section), dict):
            out[section].pop(key, None)
    out.pop("source")
    def clean(value: Any) -> Any:
        if isinstance(value, dict):
            return {toml_key(k): clean(v) for k, v in value.items() if v is not None}
        if isinstance(value, (list, tuple)):
            return [clean(v) for v in value]
        return value
    out = clean(out)
    out["simulation"]["integrator"] = scene.integrator
    if scene.net is None:
        out.pop("net", None)
    return {k: v for k, v in out.items() if v != []}


def _json_safe(value: Any) -> Any:
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, dict):
        return {k: _json_safe(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_json_safe(v) for v in value]
    if isinstance(value, np.generic):
        return value.item()
    return value


def write_summary(path: Path, summary: dict[str, Any]) -> None:
    """Write ``summary.json`` (non-finite numbers become null)."""
    tmp = path.with_suffix(".tmp")
    tmp.write_text(json.dumps(_json_safe(summary), indent=2) + "\n")
    tmp.replace(path)
