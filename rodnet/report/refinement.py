"""Observed orders of convergence: a case's scene run at several values of one key (the
``[refinement]`` table, :mod:`rodnet.report.spec`), one check's error at each."""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from rodnet.report.spec import RefinementSpec
from rodnet.run import run
from rodnet.scene import load_scene
from rodnet.validate import check_label, check_value


@dataclass(frozen=True)
class Refinement:
    """The runs of a refinement: per value the check's value and error |value - expected|
    (NaN where the run failed, its reason in ``failures``), and the observed orders between
    successive values."""

    spec: RefinementSpec
    label: str
    expected: float
    values_found: tuple[float, ...]
    errors: tuple[float, ...]
    orders: tuple[float, ...]
    failures: tuple[str, ...]


def observed_orders(resolution: NDArray[np.float64], errors: NDArray[np.float64]
                    ) -> NDArray[np.float64]:
    """``log(e_k / e_k+1) / log(h_k / h_k+1)`` for successive resolutions ``h`` (n,) and errors
    ``e`` (n,); (n - 1,), NaN where an error is zero or missing."""
    e = np.where(errors > 0, errors, np.nan)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.log(e[:-1] / e[1:]) / np.log(resolution[:-1] / resolution[1:])


def _toml_value(value: float) -> str:
    return str(value) if isinstance(value, int) else repr(float(value))


def refine(folder: Path, spec: RefinementSpec, checks: list[dict[str, Any]], output: Path
           ) -> Refinement:
    """Run ``folder``'s scene with ``spec.key`` set to each value (into ``output/<value>``)."""
    check = checks[spec.check]
    found, failures = [], []
    for value in spec.values:
        setting = f"{spec.key}={_toml_value(value)}"
        try:
            result = run(load_scene(folder / "scene.toml", [setting]), output / _toml_value(value),
                         progress=False)
        except Exception as exc:  # noqa: BLE001 -- reported with the refinement
            found.append(math.nan)
            failures.append(f"{setting}: {type(exc).__name__}: {exc}")
            continue
        found.append(check_value(check, result) if result.status == "ok" else math.nan)
        if result.status != "ok":
            failures.append(f"{setting}: {result.message}")
    expected = float(check["expected"])
    errors = np.abs(np.asarray(found, float) - expected)
    orders = observed_orders(spec.resolution(), errors)
    return Refinement(spec, check_label(check), expected, tuple(found), tuple(errors.tolist()),
                      tuple(orders.tolist()), tuple(failures))
