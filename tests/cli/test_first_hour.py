"""What a new user meets first: bad paths and files get a clear message and exit status 2, the
version, the validation verdict, and a summary without keys the model does not read."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from rodnet.cli import EXIT_BAD_INPUT, main
from tests.conftest import small_net_toml


def _scene(tmp_path: Path, text: str | None = None) -> Path:
    path = tmp_path / "net.toml"
    path.write_text(small_net_toml(duration=0.05) if text is None else text)
    return path


@pytest.mark.parametrize("where", ["file", "under a file"])
def test_an_unusable_output_directory_is_refused_by_name(tmp_path: Path, where: str,
                                                         capsys: pytest.CaptureFixture) -> None:
    taken = tmp_path / "taken"
    taken.write_text("not a directory")
    target = taken if where == "file" else taken / "run"
    assert main(["run", str(_scene(tmp_path)), "-o", str(target), "--quiet"]) == EXIT_BAD_INPUT
    err = capsys.readouterr().err
    assert "-o (output directory)" in err and str(target) in err and "Traceback" not in err
    assert taken.read_text() == "not a directory"


def test_a_missing_or_broken_scene_file_is_named(tmp_path: Path,
                                                 capsys: pytest.CaptureFixture) -> None:
    missing = tmp_path / "nowhere.toml"
    assert main(["run", str(missing)]) == EXIT_BAD_INPUT
    assert str(missing) in capsys.readouterr().err
    broken = _scene(tmp_path, "[simulation\nduration = 1\n")
    assert main(["run", str(broken)]) == EXIT_BAD_INPUT
    err = capsys.readouterr().err
    assert str(broken) in err and "not valid TOML" in err and "line 1" in err


def test_version(capsys: pytest.CaptureFixture) -> None:
    from rodnet import __version__

    with pytest.raises(SystemExit) as done:
        main(["--version"])
    assert done.value.code == 0 and capsys.readouterr().out.strip() == f"rodnet {__version__}"


def test_validate_ends_with_a_verdict(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    cases = tmp_path / "cases"
    (cases / "pendulum").mkdir(parents=True)
    (cases / "pendulum" / "scene.toml").write_text(small_net_toml(duration=0.02))
    (cases / "pendulum" / "expected.toml").write_text(
        'description = "d"\nsource = "s"\n[[checks]]\nquantity = "metric"\n'
        'name = "time_of_max_mouth_area"\nexpected = 0.0\nabs_tol = 1.0\n'
        '[[checks]]\nquantity = "metric"\nname = "max_mouth_area"\nexpected = -1.0\nabs_tol = 0.1\n')
    status = main(["validate", "--cases", str(cases), "-o", str(tmp_path / "report"), "--fast"])
    last = capsys.readouterr().out.strip().splitlines()[-1]
    assert status == 1
    assert last.startswith("rodnet validate: FAILED: 1 of 2 checks passed in 1 cases")
    assert str(tmp_path / "report" / "validation.md") in last


def test_fast_says_how_many_slow_cases_it_left_out(tmp_path: Path,
                                                   capsys: pytest.CaptureFixture) -> None:
    """``--fast`` without ``--report`` leaves the slow cases out, and the verdict says so (it
    had said nothing: outside check)."""
    cases = tmp_path / "cases"
    check = '[[checks]]\nquantity = "metric"\nname = "max_mouth_area"\nexpected = 0.0\n' \
        'abs_tol = 1e3\n'
    for name, slow in (("quick", "false"), ("long", "true")):
        (cases / name).mkdir(parents=True)
        (cases / name / "scene.toml").write_text(small_net_toml(duration=0.02))
        (cases / name / "expected.toml").write_text(f"slow = {slow}\n{check}")
    status = main(["validate", "--cases", str(cases), "-o", str(tmp_path / "report"), "--fast"])
    last = capsys.readouterr().out.strip().splitlines()[-1]
    assert status == 0 and "1 of 1 checks passed in 1 cases, 1 slow cases not run" in last, last


@pytest.mark.parametrize("entry, key", [
    ('metric = "max_tension"\nexpected = 1.0\nabs_tol = 1.0', "checks[0].metric"),
    ('quantity = "metric"\nexpected = 1.0\nabs_tol = 1.0', "checks[0].name"),
    ('quantity = "position"\nnode = "net:corner:0"\nabs_tol = 1.0', "checks[0].expected"),
    ('quantity = "velocity"\nnode = "net:corner:0"\nexpected = 1.0', "checks[0].quantity"),
    ('quantity = "metric"\nname = "max_tension"\nexpected = 1.0\nabs_tl = 1.0',
     "checks[0].abs_tl"),
])
def test_a_malformed_check_is_bad_input_and_nothing_runs(
        tmp_path: Path, capsys: pytest.CaptureFixture, entry: str, key: str) -> None:
    """A ``[[checks]]`` entry with a missing, unknown or misspelt key: exit 2 naming the file,
    the entry and the key, before any case runs (an outside check had a traceback, a check
    counted as a failed run, a velocity read as a position and a misspelt tolerance dropped)."""
    cases = tmp_path / "cases"
    (cases / "c").mkdir(parents=True)
    (cases / "c" / "scene.toml").write_text(small_net_toml(duration=0.02))
    (cases / "c" / "expected.toml").write_text(f"[[checks]]\n{entry}\n")
    status = main(["validate", "--cases", str(cases), "-o", str(tmp_path / "report"), "--fast"])
    err = capsys.readouterr().err
    assert status == 2 and f"expected.toml: {key}" in err and "Nothing was run" in err, err
    assert "Traceback" not in err and not (tmp_path / "report").exists()


def test_summary_of_a_lumped_run_leaves_out_the_rod_keys(tmp_path: Path) -> None:
    assert main(["run", str(_scene(tmp_path)), "-o", str(tmp_path / "o"), "--quiet"]) == 0
    scene = json.loads((tmp_path / "o" / "summary.json").read_text())["scene"]
    for key in ("bending", "torsion", "knots", "shear_correction"):
        assert key not in scene["model"]
    assert "rotary_inertia_scaling" not in scene["simulation"]
    assert scene["model"]["axial"] == "tension-only"


def test_bench_refuses_two_studies_at_once(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    with pytest.raises(SystemExit) as done:
        main(["bench", "--quick", "--defaults", "-o", str(tmp_path / "bench")])
    assert done.value.code == 2
    assert "--defaults: not allowed with argument --quick" in capsys.readouterr().err
    assert not (tmp_path / "bench").exists()


def test_validate_finds_its_cases_from_any_folder(tmp_path: Path, monkeypatch) -> None:  # type: ignore[no-untyped-def]
    """``rodnet validate`` run outside the source tree found no case ("no validation cases
    under validation/cases"): its default is the source tree's folder."""
    from rodnet.cli import _parser
    from rodnet.validate import case_folders

    monkeypatch.chdir(tmp_path)
    cases = _parser().parse_args(["validate"]).cases
    assert cases.is_absolute() and len(case_folders(cases)) >= 6
