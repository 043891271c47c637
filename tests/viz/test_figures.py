"""The capture pictures: the panels of ``deployment.png`` with and without bodies, the bodies and
contact of ``net.png``, and both PNGs rendered for a small capture run (skipped where off-screen
rendering does not work)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

import rodnet
from rodnet.viz.figures import (bodies_at_frame, contact_nodes, deployment_panels,
                                 render_in_subprocess)
from tests.conftest import small_net_toml
from tests.viz.rendering import SPHERE_TARGET, require_offscreen

# the small net of conftest thrown up at a fixed sphere it reaches near its largest mouth area
CAPTURE = small_net_toml(duration=0.6) + SPHERE_TARGET


@pytest.fixture(scope="module")
def capture_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("capture")
    r = rodnet.run(rodnet.scene_from_toml(CAPTURE), out, progress=False)
    assert r.status == "ok", r.message
    assert r.arrays["contact_force"].max() > 0            # the net did reach the sphere
    return out


def test_plot_without_bodies_keeps_its_one_panel(tmp_path: Path) -> None:
    rodnet.run(rodnet.scene_from_toml(small_net_toml(duration=0.1)), tmp_path, progress=False)
    panels = deployment_panels(np.load(tmp_path / "result.npz"))
    assert [p.title for p in panels] == ["Net deployment"]
    labels = [c.label for c in panels[0].curves + panels[0].right_curves]
    assert labels == ["mouth area", "distance"]


def test_plot_with_bodies_adds_contact_motion_and_energy_panels(capture_run: Path) -> None:
    data = dict(np.load(capture_run / "result.npz"))
    panels = deployment_panels(data)
    assert [p.title for p in panels] == ["Net deployment", "Contact force",
                                         "Target velocity and spin", "Energy"]
    motion, energy = panels[2], panels[3]
    assert [c.label for c in motion.curves] == ["target speed"]
    assert motion.right_ylabel == "spin [deg/s]"
    assert [c.label for c in energy.curves] == ["kinetic", "elastic", "contact"]
    np.testing.assert_array_equal(panels[1].curves[0].values, data["contact_force"])
    # spin in deg/s from the world angular velocity in rad/s
    data["body_angular_velocities"] = np.zeros_like(data["body_angular_velocities"])
    data["body_angular_velocities"][:, 0, 1] = np.pi
    data["contact_energy"] = np.ones_like(data["time"])
    panels = deployment_panels(data)
    np.testing.assert_allclose(panels[2].right_curves[0].values, 180.0)
    assert [c.label for c in panels[3].curves] == ["kinetic", "elastic", "contact"]


def test_bodies_are_rebuilt_at_the_frame_and_contact_is_marked(capture_run: Path) -> None:
    data = dict(np.load(capture_run / "result.npz"))
    summary = json.loads((capture_run / "summary.json").read_text())
    frame = len(data["time"]) - 1
    bodies, missing = bodies_at_frame(capture_run, data, summary, frame)
    assert missing == [] and [b.name for b in bodies] == ["target"]
    radius = np.linalg.norm(bodies[0].vertices - [1.0, -2.0, 4.0], axis=1)
    np.testing.assert_allclose(radius, 0.5)                    # its vertices are on the sphere
    # a node on the surface, one a thread radius (0.5 mm) off it and one well clear
    probes = np.array([[1.0, -2.0, 3.5], [1.0, -2.0, 3.5 - 4e-4], [1.0, -2.0, 3.4]])
    np.testing.assert_array_equal(contact_nodes(probes, bodies, summary), [True, True, False])


def test_capture_figures_are_drawn(capture_run: Path) -> None:
    require_offscreen()
    pytest.importorskip("matplotlib")
    assert render_in_subprocess(capture_run, picture=True, plot=True) == []
    for name in ("net.png", "deployment.png"):
        png = (capture_run / name).read_bytes()
        assert png[:8] == b"\x89PNG\r\n\x1a\n" and len(png) > 10_000
