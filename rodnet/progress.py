"""A one-line progress display for long runs: simulated time, step size and speed.

Shown only when standard error is a terminal; otherwise every call does nothing.
"""

from __future__ import annotations

import sys
import time
from typing import TextIO

from rodnet.integrate.frames import StepStats


class Progress:
    """Callable progress bar; ``Progress(duration)(t, dt, stats)`` redraws at most 10 times a second."""

    def __init__(self, duration: float, enabled: bool | None = None, stream: TextIO = sys.stderr) -> None:
        self.duration, self.stream = duration, stream
        self.enabled = stream.isatty() if enabled is None else enabled
        self.start = time.perf_counter()
        self.last_draw = 0.0

    def __call__(self, t: float, dt: float, stats: StepStats) -> None:
        if not self.enabled:
            return
        now = time.perf_counter()
        if now - self.last_draw < 0.1 and t < self.duration:
            return
        self.last_draw = now
        wall = now - self.start
        fraction = min(1.0, t / self.duration) if self.duration > 0 else 1.0
        bar = "#" * int(30 * fraction) + "-" * (30 - int(30 * fraction))
        speed = t / wall if wall > 0 else 0.0
        self.stream.write(f"\r[{bar}] t = {t:.4g}/{self.duration:.4g} s  dt = {dt:.2e} s  "
                          f"steps {stats.steps}  {speed:.3g} s simulated per s wall ")
        self.stream.flush()

    def close(self) -> None:
        """End the progress line."""
        if self.enabled:
            self.stream.write("\n")
            self.stream.flush()
