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
                 stream: TextIO | None = None) -> None:
        self.duration = duration
        self.stream = sys.stderr if stream is None else stream   # the one of the time of the run
        tty = self.stream.isatty()
        self.mode = "off" if enabled is False else "bar" if enabled or tty else "log"
        self.enabled = self.mode != "off"
        self.start = time.perf_counter()
        self.last_draw = self.start if self.mode == "log" else 0.0
        self.next_fraction = LOG_FRACTION
        self.last_line = (0.0, 0.0)   # wall time [s] and simulated time [s] at the last log line

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
            # at the pace since the last line: a run that slows down (short steps near a body,
            # Newton's method at snaps) is not told the average's pace of its easy start
            wall_before, t_before = self.last_line
            left = (wall - wall_before) / (t - t_before) * (self.duration - t) if t > t_before \
                else float("nan")
            self.last_line = (wall, t)
            self._write(f"rodnet: t = {t:.4g} of {self.duration:.4g} s ({100 * fraction:.0f} %), "
                        f"{stats.steps} steps, dt = {dt:.2e} s, wall {wall:.0f} s, "
                        f"about {left:.0f} s left\n")
            return
        if now - self.last_draw < 0.1 and t < self.duration:
            return
        self.last_draw = now
        bar = "#" * int(30 * fraction) + "-" * (30 - int(30 * fraction))
        speed = t / wall if wall > 0 else 0.0
        self._write(f"\r[{bar}] t = {t:.4g}/{self.duration:.4g} s  dt = {dt:.2e} s  "
                    f"steps {stats.steps}  {speed:.3g} s simulated per s wall ")

    def note(self, text: str) -> None:
        """Write ``text`` as a line of its own before the progress starts (not in silent
        mode)."""
        if self.mode != "off":
            self._write(text + "\n")

    def close(self) -> None:
        """End the progress line."""
        if self.mode == "bar":
            self._write("\n")

    def _write(self, text: str) -> None:
        if not _written(self.stream, text):
            self.mode, self.enabled = "off", False


class RunsProgress:
    """Progress of a sweep over runs: how many finished and failed, how many are running and
    about how long the rest takes.

    On a terminal a one-line bar (redrawn at most ten times a second); otherwise a log line every
    :data:`LOG_FRACTION` of the runs or :data:`LOG_SECONDS` of wall time, whichever comes first.
    :meth:`note` writes a line of its own (a failed run) in either mode.

    Parameters
    ----------
    total : int
        Runs of the sweep.
    done : int
        Runs already complete when this invocation starts (a resumed sweep).
    enabled : bool, optional
        As for :class:`Progress`.
    stream : text stream
        Where to write (default: standard error).
    """

    def __init__(self, total: int, done: int = 0, enabled: bool | None = None,
                 stream: TextIO | None = None) -> None:
        self.total, self.done_before = total, done
        self.stream = sys.stderr if stream is None else stream
        self.mode = "off" if enabled is False else "bar" if enabled or self.stream.isatty() else "log"
        self.start = time.perf_counter()
        self.last_draw = self.start
        self.next_fraction = LOG_FRACTION
        self.finished = self.failed = self.running = 0
        self.width = 0

    def time_left(self) -> float:
        """About how many wall seconds the runs not yet finished take (nan before the first)."""
        new = self.finished
        left = self.total - self.done_before - new
        return (time.perf_counter() - self.start) * left / new if new else float("nan")

    def line(self) -> str:
        done = self.done_before + self.finished
        left = self.time_left()
        eta = f"about {left:.0f} s left" if left == left else "time left unknown yet"
        return (f"{done} of {self.total} runs finished ({self.failed} failed), {self.running} "
                f"running, wall {time.perf_counter() - self.start:.0f} s, {eta}")

    def update(self, finished: int, failed: int, running: int) -> None:
        """Report the counts of this invocation: runs finished (failed ones included), failed,
        running now."""
        changed = finished != self.finished
        self.finished, self.failed, self.running = finished, failed, running
        now = time.perf_counter()
        if self.mode == "log":
            fraction = (self.done_before + finished) / self.total if self.total else 1.0
            if (fraction < self.next_fraction or not changed) and now - self.last_draw < LOG_SECONDS:
                return
            while self.next_fraction <= fraction:
                self.next_fraction += LOG_FRACTION
            self.last_draw = now
            self._write(f"rodnet: sweep: {self.line()}\n")
        elif self.mode == "bar" and (changed or now - self.last_draw >= 0.1):
            self.last_draw = now
            self._draw()

    def _draw(self) -> None:
        fraction = (self.done_before + self.finished) / self.total if self.total else 1.0
        bar = "#" * int(30 * fraction) + "-" * (30 - int(30 * fraction))
        text = f"\r[{bar}] {self.line()}"
        self._write(text.ljust(self.width))
        self.width = len(text)

    def note(self, text: str) -> None:
        """Write ``text`` as a line of its own (not in silent mode)."""
        if self.mode == "off":
            return
        if self.mode == "bar":
            self._write("\r" + " " * self.width + "\r")
            self._write(text + "\n")
            self._draw()
        else:
            self._write(text + "\n")

    def close(self) -> None:
        """End the bar's line."""
        if self.mode == "bar":
            self._write("\n")

    def _write(self, text: str) -> None:
        if not _written(self.stream, text):
            self.mode = "off"


def _written(stream: TextIO, text: str) -> bool:
    """Write and flush ``text``; False when ``stream`` can no longer be written (a closed pipe:
    ``rodnet run ... 2>&1 | head``), which silences a progress report instead of stopping the
    run."""
    try:
        stream.write(text)
        stream.flush()
    except (OSError, ValueError):
        return False
    return True
