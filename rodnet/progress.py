"""Progress of long runs: simulated time, step size, speed and time left.

On a terminal a one-line bar redrawn at most ten times a second; otherwise (a batch log, a file)
a line every 10 % of the simulated time or every 30 s of wall time, whichever comes first.
"""

from __future__ import annotations

import sys
import time
from typing import TextIO

from rodnet.integrate.frames import StepStats

LOG_FRACTION = 0.1
"""A log line at least every this fraction of the simulated time..."""

LOG_SECONDS = 30.0
"""...and at least every this many wall seconds."""


class Progress:
    """Callable progress report; ``Progress(duration)(t, dt, stats)`` after every step.

    Parameters
    ----------
    duration : float
        Simulated time of the run [s].
    enabled : bool, optional
        False: silent. True: the bar. None (default): the bar when ``stream`` is a terminal,
        log lines otherwise.
    stream : text stream
        Where to write (default: standard error).
    """

    def __init__(self, duration: float, enabled: bool | None = None,
                 stream: TextIO = sys.stderr) -> None:
        self.duration, self.stream = duration, stream
        tty = stream.isatty()
        self.mode = "off" if enabled is False else "bar" if enabled or tty else "log"
        self.enabled = self.mode != "off"
        self.start = time.perf_counter()
        self.last_draw = self.start if self.mode == "log" else 0.0
        self.next_fraction = LOG_FRACTION

    def __call__(self, t: float, dt: float, stats: StepStats) -> None:
        if self.mode == "off":
            return
        now = time.perf_counter()
        wall = now - self.start
        fraction = min(1.0, t / self.duration) if self.duration > 0 else 1.0
        if self.mode == "log":
            if fraction < self.next_fraction and now - self.last_draw < LOG_SECONDS:
                return
            while self.next_fraction <= fraction:
                self.next_fraction += LOG_FRACTION
            self.last_draw = now
            left = wall * (1.0 - fraction) / fraction if fraction > 0 else float("nan")
            self.stream.write(f"rodnet: t = {t:.4g} of {self.duration:.4g} s ({100 * fraction:.0f} %), "
                              f"{stats.steps} steps, dt = {dt:.2e} s, wall {wall:.0f} s, "
                              f"about {left:.0f} s left\n")
            self.stream.flush()
            return
        if now - self.last_draw < 0.1 and t < self.duration:
            return
        self.last_draw = now
        bar = "#" * int(30 * fraction) + "-" * (30 - int(30 * fraction))
        speed = t / wall if wall > 0 else 0.0
        self.stream.write(f"\r[{bar}] t = {t:.4g}/{self.duration:.4g} s  dt = {dt:.2e} s  "
                          f"steps {stats.steps}  {speed:.3g} s simulated per s wall ")
        self.stream.flush()

    def close(self) -> None:
        """End the progress line."""
        if self.mode == "bar":
            self.stream.write("\n")
            self.stream.flush()
