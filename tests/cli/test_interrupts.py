"""A run stopped by SIGTERM (timeout, batch schedulers, dask workers) or Ctrl-C keeps every
frame and its summary, says it was interrupted and exits non-zero; a run whose standard error is
not a terminal logs its progress there."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from tests.conftest import small_net_toml


def _start(tmp_path: Path, duration: float, integrator: str) -> tuple[subprocess.Popen, Path, Path]:
    scene = tmp_path / "net.toml"
    scene.write_text(small_net_toml(duration=duration, integrator=integrator))
    out, log = tmp_path / "out", tmp_path / "stderr.txt"
    # Ctrl-C as at a terminal: a shell's background job (a CI script run with &) inherits
    # SIGINT ignored, and rodnet then rightly leaves it ignored
    process = subprocess.Popen([sys.executable, "-m", "rodnet", "run", str(scene), "-o", str(out)],
                               preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
                               stdout=subprocess.DEVNULL, stderr=log.open("w"), cwd=tmp_path)
    return process, out, log


@pytest.mark.parametrize("sent, code, name", [(signal.SIGTERM, 143, "SIGTERM"),
                                              (signal.SIGINT, 130, "SIGINT")])
def test_a_signal_keeps_the_frames_and_the_summary(tmp_path: Path, sent: int, code: int,
                                                   name: str) -> None:
    # explicit, about 12 s simulated per s: the first line (10 %) after a few seconds
    process, out, log = _start(tmp_path, duration=300.0, integrator="explicit")
    try:
        deadline = time.monotonic() + 240.0
        while "rodnet: t = " not in log.read_text():   # a progress line: it is stepping
            assert process.poll() is None, log.read_text()
            assert time.monotonic() < deadline, "no progress line"
            time.sleep(0.2)
        process.send_signal(sent)
        assert process.wait(timeout=120) == code
    finally:
        if process.poll() is None:
            process.kill()
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "interrupted" and summary["signal"] == name
    assert "kept" in summary["message"]
    frames = np.load(out / "result.npz")["time"]
    assert len(frames) == summary["frames"] >= 2 and 0.0 < frames[-1] < 300.0
    assert "was stopped" in log.read_text()


def test_progress_lines_go_to_a_file(tmp_path: Path) -> None:
    process, out, log = _start(tmp_path, duration=0.3, integrator="bdf2")
    assert process.wait(timeout=300) == 0
    lines = [line for line in log.read_text().splitlines() if line.startswith("rodnet: t = ")]
    # every 10 % of the simulated time (or 30 s): ten lines, the last at the end
    assert len(lines) >= 10 and "(100 %)" in lines[-1] and "s left" in lines[-1]
    quiet = subprocess.run([sys.executable, "-m", "rodnet", "run", str(tmp_path / "net.toml"),
                            "-o", str(tmp_path / "quiet"), "--quiet"],
                           capture_output=True, text=True, cwd=tmp_path, timeout=300)
    assert quiet.returncode == 0 and "rodnet: t = " not in quiet.stderr


def test_a_failed_static_run_is_told_by_its_load_factor(capsys: pytest.CaptureFixture) -> None:
    """A static frame's time is its load factor: the report says so, not ``t = ... s``."""
    from types import SimpleNamespace

    from rodnet.cli import _report
    for kind, said in (("static", "up to load factor 0.7917 are"), ("dynamic", "up to t = 0.7917 s")):
        summary = {"frames": 3, "simulated_time_s": 0.79166, "scene": {"simulation": {"type": kind}}}
        _report(SimpleNamespace(status="failed", message="no static equilibrium found",
                                summary=summary, directory="out"))
        assert said in capsys.readouterr().err


def test_a_reader_that_goes_away_leaves_the_runs_status(tmp_path: Path) -> None:
    """``rodnet run ... 2>&1 | head -1`` (outside check): the report's lines can no longer be
    written; the run completed and wrote its results, so the status is 0, not 1, without a
    traceback."""
    (tmp_path / "net.toml").write_text(small_net_toml(duration=0.05))
    read, write = os.pipe()
    os.close(read)     # the reader is gone before the first line
    done = subprocess.run([sys.executable, "-m", "rodnet", "run", str(tmp_path / "net.toml"),
                           "-o", str(tmp_path / "out")], stdout=write, stderr=write)
    os.close(write)
    assert done.returncode == 0
    assert json.loads((tmp_path / "out" / "summary.json").read_text())["status"] == "ok"


@pytest.mark.parametrize("delay", [0.2, 0.5])
def test_ctrl_c_while_loading_ends_with_a_line(tmp_path: Path, delay: float) -> None:
    """Ctrl-C in the first second, while numpy, scipy and numba load (or, on a fast machine,
    just after): exit status 130 and a line, not the 46-line traceback of an import (outside
    check). (Before the interpreter itself has started, SIGINT ends it as any process.)"""
    process, out, log = _start(tmp_path, duration=300.0, integrator="explicit")
    try:
        time.sleep(delay)
        process.send_signal(signal.SIGINT)
        assert process.wait(timeout=60) == 130
    finally:
        if process.poll() is None:
            process.kill()
    err = log.read_text()
    assert "Traceback" not in err and "interrupted" in err, err
