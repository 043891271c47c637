"""``rodnet sweep``: every row of sweep.csv is what ``rodnet run --set ...`` of the same settings
gives; a second call resumes and runs nothing; a bad value refuses the whole sweep before
anything is written; a run that fails at run time, or raises in its worker, is a row.

The sweep: the 5 x 5 lumped net (0.3 s) at a fixed step of 0.05 s and a loose tolerance
``rtol`` of 0.5, integrator backward Euler or RK45 times three launch speeds, on two local
workers. With that tolerance RK45 gains energy on the slack-and-taut net and the energy guard
stops its runs: every scene passes the checks, three runs fail while running.
"""

from __future__ import annotations

import csv
import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from rodnet.cli import EXIT_BAD_INPUT, EXIT_FAILED, main
from tests.conftest import small_net_toml

ROOT = Path(__file__).resolve().parents[2]
SETS = ["simulation.adaptive=false", "simulation.dt=0.05", "simulation.rtol=0.5"]
INTEGRATORS, SPEEDS = ["backward-euler", "rk45"], [8, 10, 12]
VARY = [f"simulation.integrator={','.join(INTEGRATORS)}",
        f"net.launch_speed={','.join(map(str, SPEEDS))}"]


def _args(scene: Path, out: Path, vary: list[str] = VARY) -> list[str]:
    return ["sweep", str(scene), "-o", str(out), *[a for v in vary for a in ("--vary", v)],
            *[a for s in SETS for a in ("--set", s)]]


@pytest.fixture(scope="module")
def swept(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path, subprocess.CompletedProcess]:
    """The sweep, run once by the command on a two-worker local cluster."""
    folder = tmp_path_factory.mktemp("sweep")
    scene = folder / "net.toml"
    scene.write_text(small_net_toml(duration=0.3))
    done = subprocess.run([sys.executable, "-m", "rodnet", *_args(scene, folder / "out"),
                           "--workers", "2"], capture_output=True, text=True, cwd=folder,
                          env={**os.environ, "PYTHONPATH": str(ROOT)}, timeout=300)
    return scene, folder / "out", done


def _table(out: Path) -> list[dict[str, str]]:
    with (out / "sweep.csv").open() as f:
        return list(csv.DictReader(f))


def test_every_row_is_what_rodnet_run_gives(swept, tmp_path: Path,
                                            capsys: pytest.CaptureFixture) -> None:
    scene, out, done = swept
    assert done.returncode == EXIT_FAILED, done.stderr   # the sweep ends; some runs failed
    rows = _table(out)
    assert [int(r["index"]) for r in rows] == list(range(6))
    assert {(r["simulation.integrator"], int(r["net.launch_speed"])) for r in rows} == \
        {(i, s) for i in INTEGRATORS for s in SPEEDS}
    assert {"status", "message", "wall_time_s", "steps", "max_mouth_area",
            "max_tension"} <= set(rows[0])
    references = {}
    for r in rows:
        ref = tmp_path / f"ref{r['index']}"
        sets = [*SETS, f"simulation.integrator={r['simulation.integrator']}",
                f"net.launch_speed={r['net.launch_speed']}"]
        main(["run", str(scene), "-o", str(ref), "--quiet", *[a for s in sets for a in ("--set", s)]])
        expected = references[r["index"]] = json.loads((ref / "summary.json").read_text())
        assert (r["status"], r["message"]) == (expected["status"], expected["message"])
        assert int(r["steps"]) == expected["steps"] and expected["metrics"]
        for name, value in expected["metrics"].items():
            assert float(r[name]) == value, (r["index"], name)
        folder = out / "runs" / f"{int(r['index']):04d}"
        assert sorted(p.name for p in folder.iterdir()) == sorted(p.name for p in ref.iterdir())
        own = json.loads((folder / "summary.json").read_text())
        assert own["metrics"] == expected["metrics"] and float(r["wall_time_s"]) == own["wall_time_s"]
    capsys.readouterr()
    failed = [r for r in rows if r["status"] != "ok"]
    assert {r["simulation.integrator"] for r in failed} == {"rk45"} and len(failed) == 3
    assert all("energy grew" in r["message"] for r in failed)
    assert "run 0003" in done.stderr and "energy grew" in done.stderr
    assert sorted(p.name for p in out.glob("sweep_*.png")) == \
        sorted(f"sweep_{m}.png" for m in references["0"]["metrics"])   # an ok run's metrics
    definition = json.loads((out / "sweep.json").read_text())
    assert definition["scene"]["text"] == scene.read_text() and definition["vary"] == VARY
    assert [r["overrides"] for r in definition["runs"]][4] == \
        ['simulation.integrator="rk45"', "net.launch_speed=10"]
    assert {"rodnet", "numpy", "scipy", "numba", "dask", "distributed", "python"} <= \
        set(definition["versions"])


def test_a_second_call_runs_nothing_and_another_sweep_is_refused(
        swept, capsys: pytest.CaptureFixture) -> None:
    scene, out, _ = swept
    summaries = sorted((out / "runs").glob("*/summary.json"))
    before = [p.stat().st_mtime_ns for p in summaries]
    assert main(_args(scene, out)) == EXIT_FAILED
    err = capsys.readouterr().err
    assert "6 complete, 0 to run" in err
    assert [p.stat().st_mtime_ns for p in summaries] == before and len(summaries) == 6
    assert [r["status"] for r in _table(out)].count("ok") == 3
    # the same options spelt otherwise (a value 0.05 as 5e-2, 8 as 8.0) resume it too; they had
    # been taken for another sweep (outside check)
    respelt = [a.replace("simulation.dt=0.05", "simulation.dt=5e-2").replace("=8,", "=8.0,")
               for a in _args(scene, out)]
    assert respelt != _args(scene, out) and main(respelt) == EXIT_FAILED
    assert "6 complete, 0 to run" in capsys.readouterr().err
    other = [VARY[0], "net.launch_speed=8,10,14"]
    assert main(_args(scene, out, other)) == EXIT_BAD_INPUT
    err = capsys.readouterr().err
    assert "holds another sweep" in err and "vary" in err
    assert [p.stat().st_mtime_ns for p in summaries] == before


def test_a_bad_value_refuses_the_whole_sweep(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    scene = tmp_path / "net.toml"
    scene.write_text(small_net_toml(duration=0.3))
    out = tmp_path / "out"
    assert main(["sweep", str(scene), "-o", str(out), "--vary", "net.packing=0.5,1.5",
                 "--vary", "net.launch_speed=8,10"]) == EXIT_BAD_INPUT
    err = capsys.readouterr().err
    assert "net.packing = 1.5" in err and "must be in (0, 1]" in err and "Traceback" not in err
    assert not out.exists()
    assert main(["sweep", str(scene), "-o", str(out), "--vary", "output.directory=a,b"]) \
        == EXIT_BAD_INPUT
    assert "runs/NNNN" in capsys.readouterr().err and not out.exists()


def test_a_folder_that_cannot_be_made_is_bad_input(tmp_path: Path,
                                                  capsys: pytest.CaptureFixture) -> None:
    """A sweep folder below a file: the same refusal (exit 2, naming -o) as ``rodnet run``,
    before any worker starts (it was a traceback and exit 1)."""
    scene = tmp_path / "net.toml"
    scene.write_text(small_net_toml(duration=0.3))
    blocker = tmp_path / "a_file"
    blocker.write_text("")
    assert main(["sweep", str(scene), "-o", str(blocker / "out"),
                 "--vary", "net.launch_speed=8,10"]) == EXIT_BAD_INPUT
    err = capsys.readouterr().err
    assert "-o (sweep folder)" in err and "cannot be created" in err and "Traceback" not in err


def test_a_scheduler_that_does_not_answer_leaves_no_folder(
        tmp_path: Path, capsys: pytest.CaptureFixture, monkeypatch: pytest.MonkeyPatch) -> None:
    """``--scheduler`` at an address where no scheduler answers (here the refusal without the
    20 s wait): exit 2 and, as the docs say, no folder (an empty one had been left)."""
    from rodnet.errors import SceneError
    from rodnet.sweep import cluster

    def unreachable(workers, scheduler):  # type: ignore[no-untyped-def]
        raise SceneError("--scheduler", scheduler, "no dask scheduler answers at this address")

    monkeypatch.setattr(cluster, "_connect", unreachable)
    scene = tmp_path / "net.toml"
    scene.write_text(small_net_toml(duration=0.3))
    out = tmp_path / "out"
    assert main(["sweep", str(scene), "-o", str(out), "--scheduler", "tcp://127.0.0.1:9",
                 "--vary", "net.launch_speed=8,10"]) == EXIT_BAD_INPUT
    assert "no dask scheduler answers" in capsys.readouterr().err and not out.exists()


def test_an_exception_in_a_worker_is_a_row(swept, tmp_path: Path,
                                           capsys: pytest.CaptureFixture) -> None:
    """A run folder replaced by a file: the worker's task raises on it; the other runs stay."""
    scene, out, _ = swept
    copy = tmp_path / "out"
    shutil.copytree(out, copy)
    shutil.rmtree(copy / "runs" / "0001")
    (copy / "runs" / "0001").write_text("in the way")
    assert main(_args(scene, copy) + ["--workers", "1"]) == EXIT_FAILED
    assert "5 complete, 1 to run" in capsys.readouterr().err
    rows = _table(copy)
    assert rows[1]["status"] == "failed" and "NotADirectoryError" in rows[1]["message"]
    assert [r["status"] for r in rows].count("ok") == 2


@pytest.mark.slow   # about 12 s on a quiet machine, and it keeps both cores busy meanwhile
def test_sigterm_keeps_the_finished_runs(tmp_path: Path) -> None:
    """Stopped by SIGTERM while long runs go on: exit status 143, the finished run's row and
    folder kept, the others pending in sweep.csv (and no summary of theirs)."""
    scene = tmp_path / "net.toml"
    scene.write_text(small_net_toml(duration=0.3))
    out = tmp_path / "out"
    process = subprocess.Popen([sys.executable, "-m", "rodnet", "sweep", str(scene), "-o", str(out),
                                "--vary", "simulation.duration=0.1,3600,3601", "--workers", "2"],
                               stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
                               cwd=tmp_path, env={**os.environ, "PYTHONPATH": str(ROOT)})
    try:
        deadline = time.monotonic() + 240.0
        while not (out / "sweep.csv").is_file() or _table(out)[0]["status"] != "ok":
            assert process.poll() is None and time.monotonic() < deadline
            time.sleep(0.2)
        process.send_signal(signal.SIGTERM)
        assert process.wait(timeout=120) == 143
    finally:
        if process.poll() is None:
            process.kill()
    assert "stopped by SIGTERM" in process.stderr.read()
    rows = _table(out)
    assert [r["status"] for r in rows] == ["ok", "pending", "pending"]
    assert float(rows[0]["max_mouth_area"]) > 0
    assert not (out / "runs" / "0001" / "summary.json").exists()
