"""Every validation case in validation/cases: its scene reproduces its expected values.

Cases marked ``slow = true`` in their expected.toml run only with ``pytest -m slow`` (or
``rodnet validate``).
"""

from __future__ import annotations

from pathlib import Path

import pytest

from rodnet.validate import case_folders, read_expected, run_case

CASES = Path(__file__).parents[2] / "validation" / "cases"


def _params():
    for folder in case_folders(CASES):
        marks = [pytest.mark.slow] if read_expected(folder).get("slow", False) else []
        yield pytest.param(folder, id=folder.name, marks=marks)


@pytest.mark.parametrize("folder", list(_params()))
def test_case(folder: Path, tmp_path: Path) -> None:
    result, checks = run_case(folder, tmp_path)
    assert result.status == "ok", result.message
    failed = [c for c in checks if not c.passed]
    assert checks and not failed, "\n".join(
        f"{c.label}: {c.value:.9g}, expected {c.expected:.9g} +- {c.tolerance:.2g}" for c in failed)
