"""Benchmark: what the movie of the reference deployment costs.

Runs ``rodnet demo -o DIR`` once (the run, its pictures and its movie), then times, alternating,
``--repeats`` times each:

- ``rodnet render DIR`` with the defaults (MP4, 800 x 600, 301 frames at 30 frames a second),
  at 640 x 480 and 1280 x 720, and ``--gif``: wall time of the whole command (interpreter start,
  imports, OpenGL set-up, the frames, the encoder) and its CPU time with the encoder's;
- what the movie adds to ``rodnet demo``: the demo's rendering child process
  (:func:`rodnet.viz.figures.render_in_subprocess`) with the picture, the plot and the movie
  against the picture and the plot alone;
- where the CPU time of the default movie goes, in a fresh interpreter: imports, the plotter's
  set-up (first render included), drawing the frames, and the encoder.

Wall times depend on the load of the machine (the load average is printed with the table); the
CPU times less so. Prints a Markdown table and writes it to ``results/render_movie.md``.

Usage, from the repository root:
``.venv/bin/python validation/benchmarks/render_movie.py [--repeats 3] [--reuse DIR]``
(``--reuse``: a folder where ``rodnet demo -o DIR`` already ran).
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Callable

from rodnet.viz.figures import render_in_subprocess

HERE = Path(__file__).parent


def timed(action: Callable[[], object]) -> tuple[float, float]:
    """Wall time and CPU time of ``action`` [s], the CPU of the child processes it waited for
    included."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN), resource.getrusage(resource.RUSAGE_SELF)
    start = time.perf_counter()
    action()
    wall = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN), resource.getrusage(resource.RUSAGE_SELF)
    cpu = sum(a.ru_utime + a.ru_stime - b.ru_utime - b.ru_stime for a, b in zip(after, before))
    return wall, cpu


def rodnet(*args: str) -> None:
    """``rodnet ARGS`` of this source tree; fails loudly."""
    env = dict(os.environ, PYTHONPATH=str(HERE.parents[1]))
    done = subprocess.run([sys.executable, "-m", "rodnet", *args], capture_output=True,
                          text=True, env=env)
    if done.returncode != 0:
        raise RuntimeError(f"rodnet {' '.join(args)} failed: {done.stderr}")


def cases(folder: Path, scratch: Path) -> dict[str, Callable[[], object]]:
    """What is timed, by the name of its row."""
    return {
        "rodnet render (MP4, 800 x 600)": lambda: rodnet("render", str(folder), "-o",
                                                         str(scratch / "a.mp4")),
        "rodnet render --size 640x480": lambda: rodnet("render", str(folder), "--size", "640x480",
                                                       "-o", str(scratch / "b.mp4")),
        "rodnet render --size 1280x720": lambda: rodnet("render", str(folder), "--size",
                                                        "1280x720", "-o", str(scratch / "c.mp4")),
        "rodnet render --gif": lambda: rodnet("render", str(folder), "--gif", "-o",
                                              str(scratch / "d.gif")),
        "demo child: picture + plot": lambda: _child(folder, movie=False),
        "demo child: picture + plot + movie": lambda: _child(folder, movie=True),
    }


def _child(folder: Path, movie: bool) -> None:
    warnings = render_in_subprocess(folder, picture=True, plot=True, movie=movie)
    if warnings:
        raise RuntimeError("; ".join(warnings))


def stages(folder: Path) -> dict[str, float]:
    """CPU time [s] of the stages of the default movie of ``folder``, in this process (run it
    in a fresh interpreter: ``--stages DIR``)."""
    def cpu() -> tuple[float, float]:
        own, kids = (resource.getrusage(w) for w in (resource.RUSAGE_SELF,
                                                      resource.RUSAGE_CHILDREN))
        return own.ru_utime + own.ru_stime, kids.ru_utime + kids.ru_stime

    start = cpu()
    import numpy as np
    import pyvista  # noqa: F401  (its plotting half is imported by the set-up)

    from rodnet.viz import movie
    imported = cpu()
    data = dict(np.load(folder / "result.npz"))
    summary = json.loads((folder / "summary.json").read_text())
    scene = movie._MovieScene(folder, data, summary, movie.DEFAULT_SIZE)
    ready = cpu()
    images = [scene.draw(frame) for frame in range(len(data["time"]))]
    drawn = cpu()
    with tempfile.TemporaryDirectory() as tmp:
        writer = movie._Mp4Writer(Path(tmp) / "stages.mp4", movie.default_fps(len(images)))
        for image in images:
            writer.append(image)
        writer.close()
    encoded = cpu()
    return {"imports": imported[0] - start[0], "set-up": ready[0] - imported[0],
            "frames": drawn[0] - ready[0], "per frame [ms]": 1e3 * (drawn[0] - ready[0]) / len(images),
            "encoder (ffmpeg)": encoded[1] - drawn[1] + encoded[0] - drawn[0]}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--reuse", type=Path, default=None,
                        help="a folder where rodnet demo -o DIR already ran")
    parser.add_argument("--stages", type=Path, default=None, metavar="DIR",
                        help="print the CPU time of the stages of DIR's movie as JSON, and stop")
    args = parser.parse_args()
    if args.stages is not None:
        print(json.dumps(stages(args.stages)))
        return
    with tempfile.TemporaryDirectory(prefix="rodnet-render-") as tmp:
        folder = args.reuse or Path(tmp) / "demo"
        demo_wall = None
        if args.reuse is None:
            demo_wall, _ = timed(lambda: rodnet("demo", "--quick", "-o", str(folder), "--quiet"))
        summary = json.loads((folder / "summary.json").read_text())
        scratch = Path(tmp) / "movies"
        scratch.mkdir()
        todo = cases(folder, scratch)
        walls: dict[str, list[float]] = {name: [] for name in todo}
        cpus: dict[str, list[float]] = {name: [] for name in todo}
        load_before = os.getloadavg()[0]
        for _ in range(args.repeats):
            for name, action in todo.items():
                wall, cpu = timed(action)
                walls[name].append(wall)
                cpus[name].append(cpu)
        load_after = os.getloadavg()[0]
        env = dict(os.environ, PYTHONPATH=str(HERE.parents[1]))
        parts = json.loads(subprocess.run(
            [sys.executable, __file__, "--stages", str(folder)], capture_output=True, text=True,
            env=env, check=True).stdout)
        sizes = {name: (scratch / f).stat().st_size / 1e6 for name, f in
                 zip(list(todo)[:4], ("a.mp4", "b.mp4", "c.mp4", "d.gif"))}
    lines = ["# The movie of the reference deployment", "",
             f"`rodnet demo` (lumped model, 3 s, {summary['frames']} saved frames), then each "
             f"case {args.repeats} times, alternating; best and all wall times, and the CPU time "
             "of the best-wall run (the command's processes, the encoder included). Load average "
             f"of the 2-core machine: {load_before:.1f} before, {load_after:.1f} after. Script: "
             "`validation/benchmarks/render_movie.py`.", ""]
    if demo_wall is not None:
        lines += [f"The whole `rodnet demo -o DIR` (run {summary['wall_time_s']:.2f} s wall, "
                  f"pictures, movie): {demo_wall:.1f} s wall.", ""]
    lines += ["| case | wall, best [s] | all runs [s] | CPU [s] | file [MB] |",
              "|---|---|---|---|---|"]
    for name in todo:
        best = min(range(args.repeats), key=walls[name].__getitem__)
        size = f"{sizes[name]:.2f}" if name in sizes else "-"
        lines.append(f"| {name} | {walls[name][best]:.2f} | "
                     f"{', '.join(f'{w:.2f}' for w in walls[name])} | {cpus[name][best]:.2f} | "
                     f"{size} |")
    extra = (min(walls["demo child: picture + plot + movie"])
             - min(walls["demo child: picture + plot"]))
    lines += ["", f"The movie adds {extra:.2f} s of wall time (best against best) to the demo's "
              "rendering.", "", "Where the CPU time of the default movie goes (one run in a "
              "fresh interpreter; the set-up includes pyvista's plotting imports, matplotlib "
              "among them, and the first render):", "", "| stage | CPU [s] |", "|---|---|"]
    lines += [f"| {name} | {value:.2f} |" if "ms" not in name else f"| {name} | {value:.1f} |"
              for name, value in parts.items()]
    text = "\n".join(lines) + "\n"
    print(text)
    (HERE / "results" / "render_movie.md").write_text(text)


if __name__ == "__main__":
    main()
