"""What every integrator reports (saved frames and step statistics), and how a fixed step fills a
frame interval."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Callable

import numpy as np
from numpy.typing import NDArray

from rodnet.state import AcceptedStep


@dataclass
class StepStats:
    """Counters of the work an integrator did."""

    steps: int = 0
    newton_iterations: int = 0
    factorizations: int = 0
    rejected_steps: int = 0
    retaken_steps: int = 0
    """Accepted steps of a second-order implicit scheme that its energy guard took again as
    backward Euler (first order)."""
    function_evaluations: int = 0
    max_tension: float = 0.0
    dt_min: float = float("inf")
    dt_max: float = 0.0
    max_element_rotation: float | None = None
    """Largest element relative rotation |psi| [rad] over every step (explicit rods only)."""
    max_contact_force: float = 0.0
    """Largest sum of the contact point forces [N] over the steps (with bodies)."""
    max_contact_count: int = 0
    """Most contact points at a step (with bodies)."""
    max_contact_depth: float = 0.0
    """Deepest a thread's surface went into a body at a step [thread radii] (with bodies)."""
    extra: dict[str, float] = field(default_factory=dict)

    def record_step(self, dt: float, count: int = 1) -> None:
        self.record_steps(count, dt, dt)

    def record_accepted(self, step: AcceptedStep) -> None:
        """Fold an accepted step's record into the run's (the integrators that step in Python)."""
        self.max_tension = max(self.max_tension, step.max_tension)
        self.record_contact(step.contact_force, step.contact_count, step.contact_depth)

    def record_contact(self, force: float, count: int, depth: float) -> None:
        """Fold one step's (or a run of steps') contact peaks into the run's."""
        self.max_contact_force = max(self.max_contact_force, force)
        self.max_contact_count = max(self.max_contact_count, int(count))
        self.max_contact_depth = max(self.max_contact_depth, depth)

    def record_steps(self, count: int, dt_min: float, dt_max: float) -> None:
        """``count`` accepted steps, the shortest ``dt_min`` and the longest ``dt_max`` [s]."""
        self.steps += count
        self.dt_min = min(self.dt_min, dt_min)
        self.dt_max = max(self.dt_max, dt_max)


ProgressSink = Callable[[float, float, StepStats], None]
"""Called now and then with simulated time [s], current step [s] and the counters."""


def frame_times(duration: float, frame_interval: float) -> NDArray[np.float64]:
    """Times of the saved frames: 0, frame_interval, ..., and ``duration`` itself, (F,)."""
    n = int(np.floor(duration / frame_interval + 1e-9))
    times = np.arange(n + 1) * frame_interval
    if duration - times[-1] > 1e-9 * min(frame_interval, duration):
        times = np.append(times, duration)
    else:
        times[-1] = duration   # not 6 x 0.05 = 0.30000000000000004
    return times


def whole_steps(t_start: float, t_end: float, step: float) -> tuple[int, float]:
    """Steps from ``t_start`` to ``t_end`` [s]: ``step`` [s] shrunk so that a whole number fits.

    Returns
    -------
    n_steps : int
        How many steps, at least one.
    h : float
        Their length [s].
    """
    n_steps = max(1, math.ceil((t_end - t_start) / step - 1e-9))
    return n_steps, (t_end - t_start) / n_steps
