"""``rodnet bench``: the error measures and the tables, on hand-made run records."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from rodnet.tools.bench import (COLUMNS, BenchRun, Study, baseline_ratios, defaults_study, errors, history_orders, interpolated_peak, peak_orders, perturbed,
                          run_one, sensitivity, setting_orders, spatial_orders, write_outputs)


def _record(area: float, t_max: float, dist: float, path: list[float], status: str = "ok") -> dict:
    return {"summary": {"status": status, "steps": 10, "newton_iterations": 20, "factorizations": 20,
                        "metrics": {"max_mouth_area": area, "time_of_max_mouth_area": t_max,
                                    "distance_at_max_mouth_area": dist}},
            "series": {"distance": path}, "process_wall_s": 1.5, "peak_rss_mb": 100.0,
            "run": {"curve": "x"}}


def test_errors_against_the_reference() -> None:
    ref = _record(400.0, 1.30, 15.0, [0.0, 1.0, 2.0])
    run = _record(404.0, 1.32, 14.5, [0.0, 1.1, 1.7])
    e = errors(run, ref)
    assert e["max_mouth_area"] == pytest.approx(0.01)
    assert e["time_of_max"] == pytest.approx(0.02)
    assert e["distance_at_max"] == pytest.approx(-0.5)   # signed, as the README's table
    assert e["com_path"] == pytest.approx(0.3)
    failed = errors(_record(0, 0, 0, [], status="failed"), ref)
    assert all(np.isnan(v) for v in failed.values())


def test_tables_and_observed_spatial_order(tmp_path: Path) -> None:
    """Areas converging as A_n = A + C / n^2 give an observed order of 2."""
    runs = [BenchRun(f"cosserat n={n}", "tol 1e-4", "bending", ()) for n in (1, 2, 4)]
    records = {r.label: _record(450.0 + 8.0 / n**2, 1.3, 15.0, [0.0, 1.0])
               for r, n in zip(runs, (1, 2, 4))}
    study = Study(runs, {"bending": runs[-1].label}, 3.0)
    lines = spatial_orders(study, records)
    assert lines[-1].endswith("2.00")
    text = write_outputs(study, records, tmp_path)
    assert text.count("\n| cosserat") == 3
    assert (tmp_path / "work_precision.csv").read_text().count("\n") == 4
    row = text.splitlines()[6].split(" | ")
    error = float(row[COLUMNS.index("err max area %")])
    assert error == pytest.approx(100 * 7.5 / 450.5, rel=1e-3)  # n = 1


def test_orders_are_per_model_and_setting() -> None:
    """Runs of another setting at the same n (a reference at a smaller step) do not enter the
    order of the setting refined in n, and each model gets its own line."""
    runs = [BenchRun(f"rods explicit n={n}", "safety 0.5", "bending", ()) for n in (1, 2, 4)]
    runs += [BenchRun("rods explicit n=2", "safety 0.25", "bending", ()),
             BenchRun("cables n=1", "safety 0.5", "none", ()),
             BenchRun("cables n=2", "safety 0.5", "none", ())]
    areas = [450.0 + 8.0 / n**4 for n in (1, 2, 4)] + [400.0, 460.0, 455.0]
    records = {r.label: _record(a, 1.3, 15.0, [0.0, 1.0]) for r, a in zip(runs, areas)}
    lines = spatial_orders(Study(runs, {"bending": runs[3].label}, 3.0), records)
    assert lines[1] == "rods explicit, safety 0.5: observed order, n = 1, 2, 4: 4.00"
    assert any(line.startswith("cables, safety 0.5: max mouth area 460") for line in lines)
    assert not any("safety 0.25" in line and "order" in line for line in lines)


def test_observed_order_in_the_setting() -> None:
    """Areas converging as A_s = A + C s along one curve give an observed order of 1 in the
    setting halved twice, 2 for A + C tol^2 over tenfold steps; values not refined by one
    constant ratio give no line, differences of opposite sign no order."""
    runs = [BenchRun("rods n=2", f"safety {s:g}", "bending", ()) for s in (0.5, 0.25, 0.125)]
    runs += [BenchRun("rods n=1", f"tol {t:g}", "bending", ()) for t in (1e-2, 1e-3, 1e-4)]
    runs += [BenchRun("cables n=2", f"safety {s:g}", "none", ()) for s in (0.5, 0.25, 0.1)]
    runs += [BenchRun("cables n=4", f"safety {s:g}", "none", ()) for s in (0.5, 0.25, 0.125)]
    areas = ([450.0 + 4.0 * s for s in (0.5, 0.25, 0.125)] + [450.0 + 1e4 * t**2 for t in (1e-2, 1e-3, 1e-4)]
             + [450.0, 451.0, 452.5] + [450.0, 451.0, 450.5])
    records = {r.label: _record(a, 1.3, 15.0, [0.0, 1.0]) for r, a in zip(runs, areas)}
    lines = setting_orders(Study(runs, {"bending": runs[2].label}, 3.0), records)
    assert len(lines) == 3
    assert lines[0].startswith("rods n=2: max mouth area 452 m^2 at safety 0.5, 451 m^2")
    assert lines[0].endswith("observed order in safety: 1.00")
    assert lines[1].endswith("observed order in tol: 2.00")
    assert lines[2].endswith("observed order in safety: none, not monotone (differences -1, +0.5 m^2)")


def test_no_spatial_order_when_not_monotone() -> None:
    """455.19, 454.86, 455.97 (the pinned rods at n = 2, 4, 8): the differences change sign."""
    runs = [BenchRun(f"rods n={n}", "safety 0.5", "bending", ()) for n in (2, 4, 8)]
    records = {r.label: _record(a, 1.3, 15.0, [0.0, 1.0]) for r, a in zip(runs, (455.19, 454.86, 455.97))}
    lines = spatial_orders(Study(runs, {"bending": runs[0].label}, 3.0), records)
    assert lines[-1] == ("rods, safety 0.5: observed order, n = 2, 4, 8: none, not monotone "
                         "(differences +0.33, -1.11 m^2)")


def _history_record(area: np.ndarray, distance: np.ndarray, time: np.ndarray) -> dict:
    rec = _record(float(area.max()), float(time[np.argmax(area)]), 1.0, distance.tolist())
    rec["series"].update(time=time.tolist(), mouth_area=area.tolist())
    return rec


def test_perturbed_launch_speed() -> None:
    """A sensitivity run launches 1 + relative times as fast as its twin (the run's own launch
    speed when it sets one, else the reference deployment's 20 m/s) and keeps its other
    overrides."""
    run = BenchRun("lumped n=2", "safety 0.5", "none", ("model.type=lumped",))
    twin = perturbed(run, 1e-9)
    assert twin.twin == run.label and twin.label != run.label and twin.family == "none"
    assert twin.overrides[0] == "model.type=lumped"
    assert float(twin.overrides[-1].split("=")[1]) == pytest.approx(20.0 * (1 + 1e-9), rel=1e-15)
    slow = perturbed(BenchRun("q", "safety 0.5", "none", ("net.launch_speed=10.0",)), -1e-9)
    assert float(slow.overrides[-1].split("=")[1]) == pytest.approx(10.0 * (1 - 1e-9), rel=1e-15)
    assert perturbed(run, -1e-9).label != twin.label


def test_history_orders_and_the_sensitivity_floor() -> None:
    """Histories converging as A_n(t) = A(t) + t^2 / n^2 (distance t / n) give an order of 2 in
    every window; a sensitivity run that differs from its twin by more than the finest
    difference stars it and takes no order from it; sensitivity runs stay out of the orders."""
    t = np.linspace(0.0, 1.0, 101)
    runs = [BenchRun(f"rods n={n}", "safety 0.5", "bending", ()) for n in (1, 2, 4, 8)]
    records = {r.label: _history_record(400.0 + 50.0 * t + t**2 / n**2, t / n, t)
               for r, n in zip(runs, (1, 2, 4, 8))}
    study = Study(runs, {"bending": runs[-1].label}, 1.0, order_windows=(0.5,))
    lines = history_orders(study, records)
    assert len(lines) == 2 and "*" not in "".join(lines)
    assert lines[0].startswith("rods, safety 0.5, n = 1, 2, 4, 8, t <= 0.5 s:")
    assert "mouth-area history 0.188, 0.0469, 0.0117 m^2 (orders 2.00, 2.00)" in lines[0]
    assert "centre-of-mass distance 0.5, 0.25, 0.125 m (orders 1.00, 1.00)" in lines[1]
    # a twin of n = 2 whose area differs by 0.06 t^6: above the n = 4 -> 8 difference at t = 1
    twin = perturbed(runs[1], 1e-9)
    records[twin.label] = _history_record(400.0 + 50.0 * t + t**2 / 4 + 0.06 * t**6, t / 2, t)
    study.runs.append(twin)
    text, floor = sensitivity(study, records)
    assert floor[("bending", "mouth_area", 1.0)] == pytest.approx(0.06)
    assert floor[("bending", "distance", 1.0)] == 0.0
    assert "largest mouth area +0.06 m^2" in text[0]
    lines = history_orders(study, records)
    assert len(lines) == 3 and lines[-1].startswith("*:")
    assert "mouth-area history 0.75, 0.188, 0.0469* m^2 (orders 2.00, -)" in lines[1]
    assert "centre-of-mass distance 0.5, 0.25, 0.125 m (orders 1.00, 1.00)" in lines[1]
    assert lines[0].count("*") == 0  # t <= 0.5 s: floor 0.06 / 64 below every difference


def test_interpolated_peak() -> None:
    """The parabola through the largest frame and its neighbours finds the vertex of a parabolic
    history exactly between frames, that of a cosine to O(dt^4) in time; none at an end."""
    t = np.arange(0.0, 1.0001, 0.01)
    peak = interpolated_peak(_history_record(450.0 - 3000.0 * (t - 0.5337) ** 2, t, t))
    assert peak == pytest.approx((0.5337, 450.0), abs=1e-12)
    time, area = interpolated_peak(_history_record(450.0 + 20.0 * np.cos(3.0 * (t - 0.5337)), t, t))
    assert abs(time - 0.5337) < 1e-6 and abs(area - 470.0) < 1e-5
    assert interpolated_peak(_history_record(400.0 + t, t, t)) is None


def test_peak_orders_in_n() -> None:
    """Peaks at t = 0.5 + 0.04 / n^2 with area 450 + 8 / n give orders 2 (time) and 1 (area)
    between the frames, though every run's largest frame is at 0.5 s or 0.51 s; a sensitivity
    run shifting the peak by more than the finest time difference stars it."""
    t = np.arange(0.0, 1.0001, 0.01)
    runs = [BenchRun(f"rods n={n}", "safety 0.5", "bending", ()) for n in (1, 2, 4, 8)]
    records = {r.label: _history_record(450.0 + 8.0 / n - 500.0 * (t - 0.5 - 0.04 / n**2) ** 2, t, t)
               for r, n in zip(runs, (1, 2, 4, 8))}
    study = Study(runs, {"bending": runs[-1].label}, 1.0)
    line = peak_orders(study, records)[0]
    assert "largest mouth area 458, 454, 452, 451 m^2 (differences +4, +2, +1; orders 1.00, 1.00)" in line
    assert "its time 540, 510, 502.5, 500.625 ms (differences +30, +7.5, +1.88; orders 2.00, 2.00)" in line
    twin = perturbed(runs[0], 1e-9)
    records[twin.label] = _history_record(458.0 - 500.0 * (t - 0.5425) ** 2, t, t)
    study.runs.append(twin)
    line = peak_orders(study, records)[0]
    assert "(differences +30, +7.5, +1.88*; orders 2.00, -)" in line


def test_defaults_study_runs_each_model_at_its_defaults() -> None:
    """The default runs carry no integrator or step key (except the lumped model stepped
    implicitly), every family's reference is its explicit run at a quarter of the stability
    limit, and wall times are given against the lumped explicit default."""
    study = defaults_study()
    step_keys = ("simulation.integrator", "simulation.dt", "simulation.adaptive",
                 "simulation.error_tolerance", "simulation.explicit_safety")
    defaults = [r for r in study.runs if r.setting == "default"]
    assert {r.curve for r in defaults} == {"lumped explicit", "cable n=2 implicit",
                                           "cosserat pinned n=2 implicit",
                                           "cosserat rigid n=2 implicit"}
    for run in defaults:
        assert not any(o.startswith(step_keys) for o in run.overrides), run
    for family, label in study.references.items():
        ref = next(r for r in study.runs if r.label == label)
        assert ref.family == family and "simulation.explicit_safety=0.25" in ref.overrides
    records = {r.label: _record(450.0, 1.3, 20.0, [1.0]) for r in study.runs}
    for k, r in enumerate(study.runs):
        records[r.label]["process_wall_s"] = 2.0 if r.label == study.baseline else 2.0 * (k + 1)
    (line,) = baseline_ratios(study, records)
    assert "cosserat rigid n=2 implicit, default: " in line and line.count(";") == len(study.runs) - 2
    last = study.runs[-1]
    assert line.endswith(f"{last.curve}, {last.setting}: {len(study.runs):.3g}")


def test_a_run_past_its_time_limit_is_interrupted_with_what_it_computed(tmp_path: Path) -> None:
    """A run still going at the limit is interrupted and keeps its frames, also when the study
    runs as a background job (which ignores Ctrl-C, and so do the runs it starts)."""
    import signal

    run = BenchRun("lumped implicit", "bdf2 default", "lumped",
                   ("model.type=lumped", "simulation.integrator=bdf2"))
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN)   # as in a background job
    try:
        record = run_one(run, tmp_path, timeout=8.0, grace=20.0)
    finally:
        signal.signal(signal.SIGINT, previous)
    assert record["timed_out"] and not record["hung"], record["summary"]
    summary = record["summary"]
    assert summary["status"] == "interrupted", summary
    assert 0.0 < summary["simulated_time_s"] < 3.0
    assert len(record["series"]["time"]) >= 2           # the frames computed so far


def test_a_runs_progress_lines_are_passed_on(tmp_path: Path, capsys) -> None:
    """The progress lines of a run reach the study's standard error, naming the simulated time
    of the run (a long bench run is not silent for the hour it takes)."""
    run = BenchRun("lumped explicit", "short", "lumped",
                   ("model.type=lumped", "simulation.duration=0.05"))
    record = run_one(run, tmp_path, progress_every=0.0)
    assert record["summary"]["status"] == "ok", record["summary"]
    lines = [line for line in capsys.readouterr().err.splitlines()
             if line.startswith("rodnet bench:     t = ")]
    assert lines and "of 0.05 s (100 %)" in lines[-1], lines
