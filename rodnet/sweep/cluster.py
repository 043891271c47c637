"""Running a sweep on dask.distributed: a local cluster of single-threaded workers or an
existing scheduler, one task per run, the table rewritten after every finished run; and the task
itself (:func:`run_one`)."""

from __future__ import annotations

import os
import shutil
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from rodnet.errors import SceneError
from rodnet.io.results import output_directory
from rodnet.run import Terminated
from rodnet.run import run as run_scene
from rodnet.scene import scene_from_toml
from rodnet.sweep.folder import complete, row, start, write_table
from rodnet.sweep.plan import Run, Sweep
from rodnet.viz.figures import draw_run_figures

SINGLE_THREAD = {name: "1" for name in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS",
                                        "MKL_NUM_THREADS", "NUMBA_NUM_THREADS")}
"""The environment of the local workers: one BLAS and one numba thread per single-threaded
worker, so that N workers keep N cores busy and no more."""


def run_one(text: str, source: str, overrides: list[str], directory: str) -> dict[str, Any]:
    """Run one scene of a sweep into ``directory`` (emptied first: a run left half-written by an
    interrupted sweep starts afresh) as ``rodnet run`` does, pictures included; one thread.

    Returns
    -------
    summary : dict
        ``status``, ``message``, ``wall_time_s``, ``steps``, ``metrics`` and ``warnings``
        (the run's, and those of drawing its pictures) of its ``summary.json``.
    """
    out = Path(directory)
    if out.exists():
        shutil.rmtree(out)
    scene = scene_from_toml(text, overrides, source=source)
    result = run_scene(scene, out, progress=False, threads=1)
    summary = {k: result.summary.get(k) for k in ("status", "message", "wall_time_s", "steps",
                                                   "metrics")}
    summary["warnings"] = list(result.summary.get("warnings", [])) + \
        draw_run_figures(result, scene.output)
    return summary


def local_workers(requested: int | None) -> int:
    """Workers of the local cluster: ``requested``, else one per core."""
    return requested or os.cpu_count() or 1


# --- executing a sweep on dask --------------------------------------------------------------


@dataclass(frozen=True)
class Outcome:
    """What one invocation of a sweep did."""

    total: int
    skipped: int
    """Runs complete before it started."""
    ok: int
    """Runs with status ``"ok"`` in the table now (skipped ones included)."""
    failed: int
    pending: int
    """Runs not finished (an interrupted sweep)."""
    wall_s: float
    table: Path
    signal: str | None = None
    """``"SIGINT"`` or ``"SIGTERM"`` when it was interrupted."""


def execute(sweep: Sweep, directory: str | Path, *, workers: int | None = None,
            scheduler: str | None = None, progress: bool | None = None) -> Outcome:
    """Run the runs of ``sweep`` not complete in ``directory`` on a dask cluster.

    Parameters
    ----------
    sweep : Sweep
        A planned (checked) sweep.
    directory : str or Path
        The sweep's folder; created when missing, resumed when it holds this sweep.
    workers : int, optional
        Single-threaded worker processes of the local cluster (default: one per core).
    scheduler : str, optional
        Address of an existing dask scheduler (``tcp://host:8786``) instead of a local cluster.
    progress : bool, optional
        The bar; default: on a terminal, else log lines (:class:`rodnet.progress.RunsProgress`).

    Raises
    ------
    SceneError
        Before anything is written: the folder holds another sweep, or the options or the
        scheduler cannot be used.
    """
    import signal
    import sys
    import time

    from rodnet.progress import RunsProgress

    directory = Path(directory).resolve()
    if scheduler is not None and workers is not None:
        raise SceneError("--workers", workers, "sizes the local cluster; with --scheduler the "
                         "workers of that cluster run the sweep")
    done = complete(sweep, directory)
    created = not directory.exists()
    output_directory(directory, "-o (sweep folder)")
    todo = [r for r in sweep.runs if r.index not in done]
    n_local = local_workers(workers)
    where = f"the dask scheduler at {scheduler}" if scheduler else \
        f"{n_local} local worker{'s' if n_local != 1 else ''}"
    print(f"rodnet: sweep of {len(sweep.runs)} runs: {len(done)} complete, {len(todo)} to run"
          + (f" on {where}" if todo else ""), file=sys.stderr, flush=True)
    started = time.perf_counter()
    rows = {r.index: row(sweep, r, done.get(r.index)) for r in sweep.runs}
    stopped, client, cluster, table = None, None, None, directory / "sweep.csv"
    bar = RunsProgress(len(sweep.runs), len(done), enabled=progress)
    previous = _raise_on_sigterm()
    try:
        if todo:
            try:
                client, cluster = _connect(workers, scheduler)
            except SceneError:   # nothing was written: the folder goes too, as it came
                if created and not any(directory.iterdir()):
                    directory.rmdir()
                raise
        start(sweep, directory)
        write_table(sweep, directory, list(rows.values()))
        if client is not None:
            _run_all(client, sweep, todo, directory, rows, bar)
    except KeyboardInterrupt as exc:
        stopped = exc.args[0] if exc.args and exc.args[0] == "SIGTERM" else "SIGINT"
    finally:
        if previous is not None:
            signal.signal(signal.SIGTERM, previous)
        bar.close()
        if client is not None:
            _close(client, cluster)
    if stopped is not None:   # a run that finished after the stop has its summary on disk
        on_disk = complete(sweep, directory)
        for r in sweep.runs:
            if rows[r.index]["status"] == "pending" and r.index in on_disk:
                rows[r.index] = row(sweep, r, on_disk[r.index])
        write_table(sweep, directory, list(rows.values()))
    if stopped is None and (todo or not any(directory.glob("sweep_*.png"))):
        from rodnet.viz.sweep_plots import plot_sweep   # (drawn again only when a run ran)

        for warning in plot_sweep(directory, sweep.keys, list(rows.values())):
            print(f"rodnet: warning: {warning}", file=sys.stderr)
    statuses = [r["status"] for r in rows.values()]
    return Outcome(len(sweep.runs), len(done), statuses.count("ok"),
                   sum(s not in ("ok", "pending") for s in statuses), statuses.count("pending"),
                   time.perf_counter() - started, table, stopped)


def _connect(workers: int | None, scheduler: str | None) -> tuple[Any, Any]:
    """A dask client and the local cluster it runs on (None with ``scheduler``)."""
    import logging

    from dask.distributed import Client, LocalCluster

    if scheduler is not None:
        try:
            return Client(scheduler, timeout="20s"), None
        except (OSError, TimeoutError, ValueError) as exc:
            raise SceneError("--scheduler", scheduler, f"no dask scheduler answers at this "
                             f"address ({exc}); start one with `dask scheduler` and workers "
                             "with `dask worker ADDRESS`") from None
    with _environment(SINGLE_THREAD), _children_ignore_ctrl_c():
        cluster = LocalCluster(n_workers=local_workers(workers), threads_per_worker=1,
                               processes=True, env=SINGLE_THREAD, dashboard_address=None,
                               silence_logs=logging.CRITICAL)
    return Client(cluster), cluster


@contextmanager
def _environment(values: dict[str, str]) -> Iterator[None]:
    """``os.environ`` with ``values`` set within the block, as it was after it: the workers
    spawned there inherit them before they import numpy (and with it BLAS), which dask's
    ``env`` of a worker, applied after that, would be too late for."""
    before = {k: os.environ.get(k) for k in values}
    os.environ.update(values)
    try:
        yield
    finally:
        for key, value in before.items():
            if value is None:
                os.environ.pop(key, None)
            else:
                os.environ[key] = value


@contextmanager
def _children_ignore_ctrl_c() -> Iterator[None]:
    """SIGINT ignored within the block (main thread only), so that the worker processes spawned
    there inherit that: Ctrl-C at a terminal goes to the whole process group, and the sweep,
    not each worker, stops the runs (else every worker prints a traceback)."""
    import signal
    import threading

    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)


def _close(client: Any, cluster: Any) -> None:
    """Close the client and stop the local cluster's workers (runs still going are lost; their
    folders are emptied and run again on resume)."""
    import contextlib

    with contextlib.suppress(Exception):
        client.close(timeout=10)
    if cluster is not None:
        with contextlib.suppress(Exception):
            cluster.close(timeout=20)


def _raise_on_sigterm() -> Any:
    """Make SIGTERM raise :class:`rodnet.run.Terminated` (as Ctrl-C raises KeyboardInterrupt),
    in the main thread; returns the handler it replaced (None elsewhere)."""
    import signal
    import threading

    if threading.current_thread() is not threading.main_thread():
        return None

    def handler(signum: int, frame: Any) -> None:
        raise Terminated("SIGTERM")

    return signal.signal(signal.SIGTERM, handler)


def _run_all(client: Any, sweep: Sweep, todo: list[Run], directory: Path,
             rows: dict[int, dict[str, Any]], bar: Any) -> None:
    """Submit ``todo``, and as each run finishes put its row in ``rows`` and rewrite the table."""
    import time
    import uuid

    from dask.distributed import as_completed

    runs, submitted = {}, []
    tag = uuid.uuid4().hex[:12]   # keys unique on a scheduler that other sweeps share
    for run in todo:
        future = client.submit(run_one, sweep.text, str(sweep.scene_path), sweep.overrides(run),
                               str(directory / run.folder),
                               key=f"rodnet-run-{run.index:04d}-{tag}", pure=False)
        runs[future.key] = run
        submitted.append(future)
    finished = failed = 0
    slots = sum(client.nthreads().values())
    futures = as_completed(submitted)
    while not futures.is_empty():
        batch = futures.next_batch(block=False)
        for future in batch:
            run = runs[future.key]
            try:
                summary = future.result()
            except Exception as exc:  # a run's exception, or a worker lost: a row, not a stop
                summary = {"status": "failed", "message": f"{type(exc).__name__}: {exc}"}
            rows[run.index] = row(sweep, run, summary)
            write_table(sweep, directory, list(rows.values()))
            finished += 1
            name = f"run {run.index:04d} ({', '.join(run.overrides)})"
            for warning in summary.get("warnings", []):
                bar.note(f"rodnet: warning: {name}: {warning}")
            if summary["status"] != "ok":
                failed += 1
                bar.note(f"rodnet: sweep: {name} {summary['status']}: {summary['message']}")
        if batch:
            slots = sum(client.nthreads().values()) or slots
        bar.update(finished, failed, min(slots, len(todo) - finished))
        if not batch:
            time.sleep(0.2)
