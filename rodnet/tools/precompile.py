"""``rodnet compile``: compile the kernels of the common runs ahead of time, into numba's cache.

rodnet's kernels are compiled by numba on their first call and cached on disk
(:mod:`rodnet.kernels.cache`), so only the first run after installing pays for compiling them
(validation/benchmarks/results/cold_start.md). This command pays it once, at install time (the
README's set-up runs it): it runs each scene of :func:`runs` for a few steps, with its results
written to a temporary folder and thrown away, in two processes where the machine has two cores.
A later run of a scene that needs other kernels (contact with bodies, another integrator) still
compiles those on its first call.
"""

from __future__ import annotations

import os
import signal
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor
from multiprocessing import get_context
from multiprocessing.process import BaseProcess
from typing import NamedTuple

from rodnet.demo import demo_scenes
from rodnet.scene import Scene, scene_from_toml


class Warm(NamedTuple):
    """A short run whose kernels are compiled: ``label``, its ``scene`` and ``threads`` (None: as
    a run chooses, every core for the reference net)."""

    label: str
    scene: Scene
    threads: int | None = None


SHORT = ("simulation.duration=0.02", "output.frame_interval=0.01")
"""Two frame intervals: every kernel of the run is called, the frames' outputs included."""

ROD = """
[simulation]
type = "{type}"
duration = 0.004
dt = 0.001
gravity = [0.0, 0.0, -9.81]
[model]
type = "cosserat"
[[materials]]
name = "steel"
density = 7800.0
youngs_modulus = 2.0e11
poisson_ratio = 0.3
diameter = 0.01
[[rods]]
name = "beam"
material = "steel"
points = [[0, 0, 0], [1, 0, 0]]
elements = 20
[[supports]]
node = "beam:start"
fix = "clamp"
[[loads]]
node = "beam:end"
force = [0.0, 0.0, -10.0]
[output]
vtk = false
frame_interval = 0.002
"""
"""A small cantilever under gravity and a tip load, static or dynamic at the default integrator:
20 elements, as in getting started, so that Newton's matrix is above the dense LU's limit and the
sparse LU's kernels compile too (with 8 elements and no load the getting-started cantilever
still compiled those and the loads' time factors, 3 - 5 s, outside check)."""


def runs() -> tuple[Warm, ...]:
    """The short runs whose kernels are compiled: the demo's two scenes (:func:`demo_scenes`,
    the Cosserat one on every core and on one thread) and a small rod at the default integrator
    (on one thread, and on every core: an implicit run on one thread calls the element loops
    without a parallel region) and static."""
    from rodnet.kernels import threads

    (_, rods, _), (_, lumped, _) = demo_scenes(list(SHORT), quick=False)
    rod = {kind: scene_from_toml(ROD.format(type=kind), source=f"rodnet compile ({kind} rod)")
           for kind in ("dynamic", "static")}
    cores = threads.available()
    return (
        Warm("rodnet demo: Cosserat threads, explicit, every core", rods),
        Warm("rodnet demo: Cosserat threads, explicit, one thread", rods, 1),
        Warm("rodnet demo: lumped reference", lumped),
        Warm("Cosserat rod, dynamic, default integrator", rod["dynamic"], 1),
        *([Warm("Cosserat rod, dynamic, default integrator, every core", rod["dynamic"], cores)]
          if cores > 1 else []),
        Warm("Cosserat rod, static", rod["static"]),
    )


def _warm(run: Warm, folder: str) -> tuple[str, float, str]:
    """Run ``run`` into ``folder``; returns its label, the CPU seconds it took and its status
    ("ok", or what went wrong: its kernels then compile on their first call in a run)."""
    from rodnet.run import run as run_scene

    start = time.process_time()
    try:
        summary = run_scene(run.scene, folder, progress=False, threads=run.threads).summary
        status = str(summary.get("status"))
        if status != "ok":
            status = f"{status}: {summary.get('message', '')}"
    except Exception as exc:  # reported, not raised: the other runs' kernels are still cached
        status = f"failed: {type(exc).__name__}: {exc}"
    return run.label, time.process_time() - start, status


def precompile(processes: int | None = None,
               say=print) -> tuple[float, bool]:  # type: ignore[no-untyped-def]
    """Compile the kernels of :func:`runs` into numba's cache; returns the wall seconds taken
    and whether every run ended "ok".

    Parameters
    ----------
    processes : int, optional
        Worker processes; default: two where the machine has two cores or more.
    say : callable
        Receives one line per run done.
    """
    import rodnet  # noqa: F401  (refreshes the cache's stamp before the workers start)

    todo = runs()
    workers = processes or min(2, os.cpu_count() or 1)
    start = time.time()
    with tempfile.TemporaryDirectory(prefix="rodnet-compile-") as work:
        folders = [os.path.join(work, str(k)) for k in range(len(todo))]
        with ProcessPoolExecutor(workers, mp_context=get_context("spawn")) as pool:
            statuses = []
            for label, cpu, status in pool.map(_warm, todo, folders):
                say(f"  {label}: {cpu:.1f} CPU s ({status})")
                statuses.append(status)
    return time.time() - start, all(status == "ok" for status in statuses)


def _compile_rest_of_demo(rods: Scene, lumped: Scene, threads: int | None) -> None:
    """The process of :func:`warm_up`: the frames' kernels of the Cosserat run, then a short
    lumped run; at a lower priority, silent (a kernel it has not cached in time is compiled by
    the run that needs it)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)   # Ctrl-C is the demo's: it ends this process
    try:
        os.nice(10)
        from rodnet.run import compile_frames

        compile_frames(rods)
        with tempfile.TemporaryDirectory(prefix="rodnet-warm-") as folder:
            _warm(Warm("lumped reference", lumped, threads), folder)
    except Exception:  # noqa: S110  (nothing to report: the runs compile what is missing)
        pass


def warm_up(overrides: list[str], threads: int | None) -> BaseProcess | None:
    """Start compiling, on a second core, the kernels ``rodnet demo`` needs after its Cosserat
    run's step loop: that run's frames and the lumped run. The explicit integrator compiles its
    loop before the first frame, so the two compile side by side on a first run after
    installing (a warm run loads both from the cache in a second). Returns the process (a
    daemon: it ends with the demo), or None on a single core.

    Parameters
    ----------
    overrides : list of str
        The demo's ``--set`` overrides (they choose the kernels: another integrator, model).
    threads : int or None
        The demo's ``--threads``.
    """
    if (os.cpu_count() or 1) < 2:
        return None
    (_, rods, _), (_, lumped, _) = demo_scenes([*overrides, *SHORT], quick=False)
    process = get_context("spawn").Process(target=_compile_rest_of_demo,
                                           args=(rods, lumped, threads), daemon=True)
    process.start()
    return process
