"""How many threads the compiled parallel loops use, and how their idle threads wait.

numba runs ``prange`` loops on a pool of threads (its OpenMP layer here). Two settings decide
what that costs on a shared machine:

- The wait policy. GNU OpenMP lets a thread that has finished its share spin for
  ``GOMP_SPINCOUNT`` (300,000 by default) iterations before it sleeps. An explicit step loop
  opens a parallel region or three per step, tens of microseconds apart, so with the default
  the idle thread spins through most of the run: when another process needs the core it burns
  it, and a thread descheduled by that process stalls every region (measured: the 11 x 11 rod
  net took 244 CPU s instead of 22 beside another job). :data:`SPIN_COUNT` spins about a
  microsecond, enough to catch the next region of a busy loop (the region overhead stays
  about 1.6 us) and short enough that a waiting thread yields its core.
- The thread count. Below a problem size (:data:`PARALLEL_FROM`) a region's work is too small
  to share; one thread is faster there, and it leaves the other core to other runs.

:func:`configure` sets the environment before numba's thread pool starts; rodnet calls it when
:mod:`rodnet.kernels` is imported. :func:`use_threads` picks the count for a run.
``NUMBA_NUM_THREADS`` caps the pool as numba documents; ``rodnet run --threads N`` (or
:func:`use_threads` with ``requested``) sets the count of one run.
"""

from __future__ import annotations

import os

SPIN_COUNT = "1000"
"""``GOMP_SPINCOUNT`` unless the environment sets it: spin about a microsecond, then sleep."""

LAYER_PRIORITY = "omp tbb workqueue"
"""numba's threading layers in order of preference: OpenMP first (TBB spins as GNU OpenMP does by
default; the workqueue layer has no spinning but costs about 100 us per parallel region)."""

PARALLEL_FROM = 150
"""Work items (elements, segments) from which a compiled loop runs on more than one thread:
two threads made an explicit rod step 1.10 times as fast at 32 elements, 1.34 at 88, 1.42 at
176 and 1.55 - 1.66 from 296 on, on a quiet 2-core machine (validation/benchmarks/threads.py)."""


PRANGE_ONLY = {"prange": True, "reduction": True, "comprehension": False, "inplace_binop": False,
               "setitem": False, "numpy": False, "stencil": False, "fusion": False}
"""numba's ``parallel`` options of rodnet's parallel kernels: their ``prange`` loops (and the
sums in them) on the threads, and no search for array expressions to turn into parallel loops,
which finds nothing worth it there (a zeroed array of moments) and cost about 0.9 s of the
explicit loop's 10 s compile (validation/benchmarks/results/cold_start.md)."""


def configure() -> None:
    """Set the wait policy and threading layer of numba's parallel loops, unless the user's
    environment sets them: before numba starts its thread pool (its first parallel loop)."""
    import sys

    os.environ.setdefault("GOMP_SPINCOUNT", SPIN_COUNT)
    if "NUMBA_THREADING_LAYER_PRIORITY" not in os.environ:
        os.environ["NUMBA_THREADING_LAYER_PRIORITY"] = LAYER_PRIORITY
        if "numba" in sys.modules:  # imported before rodnet: its configuration is read already
            sys.modules["numba"].config.THREADING_LAYER_PRIORITY = LAYER_PRIORITY.split()


def available() -> int:
    """The size of numba's thread pool: ``NUMBA_NUM_THREADS``, else the number of cores."""
    import numba

    return int(numba.config.NUMBA_NUM_THREADS)


def current() -> int:
    """The number of threads the compiled parallel loops use now."""
    import numba

    return int(numba.get_num_threads())


def use_threads(work_items: int, requested: int | None = None) -> int:
    """Set and return the number of threads of the compiled parallel loops for a problem with
    ``work_items`` independent items per loop (elements or segments).

    Parameters
    ----------
    work_items : int
        Size of the loops' work; below :data:`PARALLEL_FROM` one thread.
    requested : int, optional
        A count asked for (``--threads``); capped at :func:`available`.
    """
    import numba

    limit = available()
    if requested is not None:
        n = max(1, min(int(requested), limit))
    else:
        n = limit if work_items >= PARALLEL_FROM else 1
    numba.set_num_threads(n)
    return n
