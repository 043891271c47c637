"""The explicit driver splits a frame interval of many steps into several calls of the compiled
loop, so that progress is shown and a stop is acted on between them: fixed steps (the lumped
model) stay the same to the last bit; rods, whose step control adapts within a call, start it
afresh at each call (1.1e-8 of the motion here, at calls of 7 steps). And the bound a refused fixed step quotes is one
the scene may use."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from rodnet.errors import at_most
from rodnet.integrate import explicit
from rodnet.run import run
from rodnet.scene import scene_from_toml
from tests.conftest import small_net_toml


@pytest.mark.parametrize("model", ['type = "lumped"', 'type = "cosserat"'])
def test_a_split_frame_interval_steps_the_same(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                               model: str) -> None:
    scene = scene_from_toml(small_net_toml(duration=0.02, n=2).replace('type = "lumped"', model))
    whole = run(scene, tmp_path / "whole", progress=False)
    reports: list[float] = []
    monkeypatch.setattr(explicit, "CALL_STEPS", 7)
    from rodnet.progress import Progress
    original = Progress.__call__

    def noted(self, t, *rest):  # type: ignore[no-untyped-def]
        reports.append(t)
        return original(self, t, *rest)

    monkeypatch.setattr(Progress, "__call__", noted)
    split = run(scene, tmp_path / "split", progress=False)
    assert whole.status == split.status == "ok"
    if model == 'type = "lumped"':
        np.testing.assert_array_equal(split.arrays["positions"], whole.arrays["positions"])
        np.testing.assert_array_equal(split.arrays["velocities"], whole.arrays["velocities"])
        assert split.summary["steps"] == whole.summary["steps"]
    else:
        motion = np.abs(whole.arrays["positions"] - whole.arrays["positions"][0]).max()
        assert np.abs(split.arrays["positions"] - whole.arrays["positions"]).max() < 1e-7 * motion
    per_frame = whole.summary["steps"] / 2
    assert len(reports) >= 2 * (per_frame // 7)          # told between the calls too


def test_the_quoted_bound_is_below_the_limit() -> None:
    for limit in (6.3849e-05, 6.3800e-05, 1.49e-4, 9.9999e-3, 2.0):
        text = at_most(limit)
        assert float(text) <= limit and float(text) >= limit * (1 - 2e-2), (limit, text)
    assert at_most(6.3849e-05) == "6.38e-05" and at_most(6.3851e-05) == "6.38e-05"
