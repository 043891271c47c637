"""``rodnet sweep``: many runs of one scene over a grid or a Latin hypercube of scene keys,
executed by dask.distributed.

A sweep is planned and checked here without dask: every run's scene is built and prepared as
``rodnet run`` would (:func:`plan`), so one bad value refuses the whole sweep before anything is
written. :func:`execute` then runs what is not complete yet on a dask cluster (a
``LocalCluster`` of single-threaded worker processes, or an existing scheduler) and keeps its
folder current after every finished run:

- ``sweep.json``: the definition (scene path and text, ``--vary``, ``--set``, samples and
  seed, every run's overrides) and the versions of the packages that ran it;
- ``sweep.csv``: one row per run (``index``, the varied keys, ``status``, ``message``,
  ``wall_time_s``, ``steps``, the scalar metrics of its ``summary.json``);
- ``runs/NNNN/``: each run's own outputs, as ``rodnet run -o runs/NNNN --set ...`` writes them;
- ``sweep_<metric>.png``: each metric against each varied key (:mod:`rodnet.viz.sweep_plots`).

A run is complete when its ``summary.json`` holds a final status (``"ok"`` or ``"failed"``);
the same command run again skips those, so an interrupted sweep resumes where it stopped.
"""

from rodnet.sweep.cluster import Outcome, execute, run_one
from rodnet.sweep.folder import complete, row, versions, write_table
from rodnet.sweep.plan import Run, Sweep, Vary, parse_vary, plan

__all__ = ["Outcome", "Run", "Sweep", "Vary", "complete", "execute", "parse_vary", "plan", "row",
           "run_one", "versions", "write_table"]
