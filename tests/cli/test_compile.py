"""``rodnet compile``: the kernels of the demo compiled ahead of time into numba's cache, so that
the demo's first run after it compiles nothing."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from rodnet.cli import main

PROBE = r"""
import json, sys
from numba.core import event
compiled = []
class Listener(event.Listener):
    def on_start(self, e):
        compiled.append(e.data["dispatcher"].py_func.__qualname__)
    def on_end(self, e):
        pass
event.register("numba:compile", Listener())
from rodnet.demo import demo_scenes
from rodnet.run import run
for threads in (None, 1):
    for label, scene, folder in demo_scenes(["simulation.duration=0.02"], False):
        assert run(scene, sys.argv[1] + f"/{threads}/{folder}", progress=False,
                   threads=threads).summary["status"] == "ok"
print(json.dumps(compiled))
"""

CANTILEVER = PROBE.split("from rodnet.demo")[0] + r"""
from rodnet.run import run
from rodnet.scene import scene_from_toml
text = open(sys.argv[2]).read()
assert run(scene_from_toml(text), sys.argv[1], progress=False).summary["status"] == "ok"
print(json.dumps(compiled))
"""
"""Runs the scene file ``argv[2]`` into ``argv[1]`` and prints what numba compiled."""



def test_compile_refuses_a_bad_process_count(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit):
        main(["compile", "--processes", "0"])
    assert "--processes" in capsys.readouterr().err


@pytest.mark.slow
def test_after_compile_the_demo_compiles_nothing(tmp_path: Path) -> None:
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "cache")}
    done = subprocess.run([sys.executable, "-m", "rodnet", "compile"], env=env, cwd=tmp_path,
                          capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    from rodnet.tools.precompile import runs

    assert done.stderr.count("(ok)") == len(runs())
    probe = subprocess.run([sys.executable, "-c", PROBE, str(tmp_path / "runs")], env=env,
                           cwd=tmp_path, capture_output=True, text=True)
    assert probe.returncode == 0, probe.stderr
    assert json.loads(probe.stdout.splitlines()[-1]) == []
    # nor the static cantilever of getting started (it compiled the sparse LU and the loads'
    # time factors)
    from tests.test_docs_examples import _examples

    page = (Path(__file__).resolve().parents[2] / "docs" / "getting_started.md").read_text()
    [scene] = [b.text for b in _examples().blocks(page) if b.label == "cantilever.toml"]
    (tmp_path / "cantilever.toml").write_text(scene)
    probe = subprocess.run([sys.executable, "-c", CANTILEVER, str(tmp_path / "cantilever"),
                            str(tmp_path / "cantilever.toml")],
                           env=env, cwd=tmp_path, capture_output=True, text=True)
    assert probe.returncode == 0, probe.stderr
    assert json.loads(probe.stdout.splitlines()[-1]) == []
    # and a fresh cache does compile them (the probe sees compiling)
    env["NUMBA_CACHE_DIR"] = str(tmp_path / "fresh")
    probe = subprocess.run([sys.executable, "-c", PROBE, str(tmp_path / "again")], env=env,
                           cwd=tmp_path, capture_output=True, text=True)
    assert probe.returncode == 0, probe.stderr
    assert "march_parallel_free" in json.loads(probe.stdout.splitlines()[-1]) or \
        "march_free" in json.loads(probe.stdout.splitlines()[-1])


def test_a_run_that_fails_is_reported_not_raised(monkeypatch: pytest.MonkeyPatch) -> None:
    from rodnet.scene import scene_from_toml
    from rodnet.tools import precompile as module

    # a scene that reads but is refused when run: a fixed explicit step far above its limit
    refused = scene_from_toml(module.ROD.format(type="dynamic"), [
        "simulation.integrator=explicit", "simulation.adaptive=false", "simulation.dt=1.0"])
    bad = module.Warm("a step too long", refused)
    monkeypatch.setattr(module, "runs", lambda: (bad,))
    lines: list[str] = []
    seconds, ok = module.precompile(1, say=lines.append)
    assert not ok and seconds > 0.0
    assert len(lines) == 1 and lines[0].startswith("  a step too long:")
    assert "failed: SceneError" in lines[0]


WARM = r"""
import sys
from rodnet.demo import demo_scenes
from rodnet.tools.precompile import SHORT, _compile_rest_of_demo
(_, rods, _), (_, lumped, _) = demo_scenes(list(SHORT), False)
_compile_rest_of_demo(rods, lumped, None)
"""


@pytest.mark.slow
def test_the_demos_warm_up_leaves_only_the_cosserat_loop_to_compile(tmp_path: Path) -> None:
    """What ``rodnet demo`` compiles on a second core (the Cosserat run's frames, the lumped
    run) is what its runs then load from the cache: they compile the Cosserat loop alone."""
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "cache")}
    done = subprocess.run([sys.executable, "-c", WARM], env=env, cwd=tmp_path,
                          capture_output=True, text=True)
    assert done.returncode == 0 and done.stderr == "", done.stderr
    probe = subprocess.run([sys.executable, "-c", PROBE.replace("(None, 1)", "(None,)"),
                            str(tmp_path / "runs")], env=env, cwd=tmp_path,
                           capture_output=True, text=True)
    assert probe.returncode == 0, probe.stderr
    compiled = set(json.loads(probe.stdout.splitlines()[-1]))
    assert compiled & {"march_parallel_free", "march_free"}
    assert not compiled & {"_section_state_kernel", "_step_potential_kernel", "element_pose",
                           "element_velocities", "march_nodes", "segment_states"}, compiled
