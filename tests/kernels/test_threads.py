"""The thread count and wait policy of the compiled parallel loops."""

from __future__ import annotations

import os
import subprocess
import sys

import numba

from rodnet.kernels import threads


def test_small_problems_run_on_one_thread_and_a_request_is_capped() -> None:
    before = numba.get_num_threads()
    try:
        assert threads.use_threads(threads.PARALLEL_FROM - 1) == 1
        assert numba.get_num_threads() == 1
        assert threads.use_threads(threads.PARALLEL_FROM) == threads.available()
        assert threads.use_threads(10, requested=10_000) == threads.available()
        assert threads.use_threads(10_000, requested=1) == 1
    finally:
        numba.set_num_threads(before)


def test_idle_threads_spin_briefly_unless_the_user_says_otherwise() -> None:
    """rodnet sets GOMP_SPINCOUNT (an idle thread spins about a microsecond, then sleeps) and
    prefers the OpenMP layer, before numba starts its threads; a user's setting stays."""
    code = ("import os, rodnet, numba; "
            "print(os.environ['GOMP_SPINCOUNT'], ' '.join(numba.config.THREADING_LAYER_PRIORITY))")
    env = {k: v for k, v in os.environ.items()
           if k not in ("GOMP_SPINCOUNT", "NUMBA_THREADING_LAYER_PRIORITY")}
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True,
                         check=True).stdout.split(maxsplit=1)
    assert out == [threads.SPIN_COUNT, threads.LAYER_PRIORITY + "\n"]
    mine = subprocess.run([sys.executable, "-c", code], env={**env, "GOMP_SPINCOUNT": "5"},
                          capture_output=True, text=True, check=True).stdout.split()[0]
    assert mine == "5"
