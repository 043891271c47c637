"""``result.npz`` and ``summary.json``."""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from rodnet.config import Scene


def write_npz(path: Path, arrays: dict[str, NDArray[Any]]) -> None:
    """Write the result arrays (atomically: a partial file never replaces a good one)."""
    tmp = path.with_suffix(".tmp.npz")
    np.savez(tmp, **arrays)
    tmp.replace(path)


def scene_as_dict(scene: Scene) -> dict[str, Any]:
    """The scene as run, in the TOML layout (unset optional keys left out)."""
    out = dataclasses.asdict(scene)
    out.pop("source")
    def clean(value: Any) -> Any:
        if isinstance(value, dict):
            return {k: clean(v) for k, v in value.items() if v is not None}
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
