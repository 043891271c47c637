"""The guard of tests/conftest.py fails a test that writes into the working directory."""

from __future__ import annotations

from pathlib import Path

pytest_plugins = ["pytester"]


def test_a_test_writing_into_the_working_directory_fails(pytester) -> None:  # type: ignore[no-untyped-def]
    pytester.makeconftest((Path(__file__).parent / "conftest.py").read_text())
    pytester.makepyfile(test_inner="""
import pathlib

def test_writes_here():
    pathlib.Path("summary.json").write_text("{}")

def test_writes_to_its_tmp_path(tmp_path):
    (tmp_path / "summary.json").write_text("{}")
""")
    result = pytester.runpytest_inprocess("-p", "no:cacheprovider")
    result.assert_outcomes(passed=2, errors=1)
    result.stdout.fnmatch_lines(["*wrote into the working directory*summary.json*"])
