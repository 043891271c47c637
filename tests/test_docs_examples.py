"""The worked examples of the documentation give the output their pages quote."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PAGES = sorted(p.name for p in (ROOT / "docs").glob("*.md") if "<!-- output:" in p.read_text())
SLOW_PAGES = {"capture.md"}
"""Pages whose examples run for more than a minute: run with ``-m slow``."""


def _examples():  # type: ignore[no-untyped-def]
    """docs/ is not a package: load the runner by file path."""
    spec = importlib.util.spec_from_file_location("docs_examples", ROOT / "docs" / "examples.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # its dataclass looks itself up there
    spec.loader.exec_module(module)  # type: ignore[union-attr]
    return module


def test_the_pages_have_examples() -> None:
    assert "getting_started.md" in PAGES


@pytest.mark.parametrize("page", [pytest.param(p, marks=pytest.mark.slow) if p in SLOW_PAGES
                                  else p for p in PAGES])
def test_quoted_output_is_what_the_example_gives(page: str, tmp_path: Path) -> None:
    examples = _examples()
    results = examples.run_page((ROOT / "docs" / page).read_text(), tmp_path)
    assert results
    for block, got in results:
        assert examples.same(block.text, got), (
            f"docs/{page}: the output of `{block.label}` changed; run "
            f"`python docs/examples.py --write docs/{page}` and check the prose around it.\n"
            f"quoted:\n{block.text}\nnow:\n{got}")
