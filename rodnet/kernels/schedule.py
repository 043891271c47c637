"""Time factors of the dead loads: every load's force and moment times a piecewise-linear
function of time, zero outside the load's ``[start, stop)`` window.

One mechanism for every ``[[loads]]`` entry: ``ramp = r`` is the table ``[[0, 0], [r, 1]]``, no
ramp and no table the constant 1, and ``table = [[t, factor], ...]`` is used as given (times
non-decreasing; a repeated time is a jump, the factor after it holds from that time on; the
first and last factors hold before and after the table). The window makes the load a pulse:
the factor is 0 for ``t < start`` and for ``t >= stop``. The same compiled function serves the
models (NumPy side) and the explicit loop.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import NamedTuple

import numba
import numpy as np


class LoadSchedule(NamedTuple):
    """The time factors of ``L`` loads: load ``j``'s table is ``times[ptr[j]:ptr[j + 1]]`` [s]
    with ``values`` (the factors), its window ``[start[j], stop[j])`` [s] (stop ``inf``: on to
    the end); ``repeats[j]``: load ``j``'s factor is load ``j - 1``'s (the same table and
    window, as the weights of a scheduled gravity or the nodes of one line load), so a loop
    over the loads takes it once."""

    ptr: np.ndarray
    times: np.ndarray
    values: np.ndarray
    start: np.ndarray
    stop: np.ndarray
    repeats: np.ndarray


def load_schedule(ramps: Sequence[float], tables: Sequence[Sequence[Sequence[float]] | None],
                  starts: Sequence[float], stops: Sequence[float | None]) -> LoadSchedule:
    """The schedule of loads with these ``ramp`` [s], ``table`` (rows ``(t, factor)`` or None),
    ``start`` and ``stop`` [s] (None: never) settings."""
    rows: list[list[tuple[float, float]]] = []
    for ramp, table in zip(ramps, tables):
        if table is not None:
            rows.append([(float(t), float(f)) for t, f in table])
        elif ramp > 0.0:
            rows.append([(0.0, 0.0), (float(ramp), 1.0)])
        else:
            rows.append([(0.0, 1.0)])
    ptr = np.concatenate([[0], np.cumsum([len(r) for r in rows])]).astype(np.int64)
    flat = [row for r in rows for row in r]
    times = np.array([t for t, _ in flat], dtype=np.float64)
    values = np.array([f for _, f in flat], dtype=np.float64)
    start = np.array(starts, dtype=np.float64)
    stop = np.array([np.inf if s is None else s for s in stops], dtype=np.float64)
    repeats = np.array([j > 0 and rows[j] == rows[j - 1] and start[j] == start[j - 1]
                        and stop[j] == stop[j - 1] for j in range(len(rows))], dtype=np.bool_)
    return LoadSchedule(ptr, times, values, start, stop, repeats)


def schedule_of(loads: Sequence[object]) -> LoadSchedule:
    """The schedule of the scene's ``[[loads]]`` entries (objects with ``ramp``, ``table``,
    ``start`` and ``stop``, as :class:`rodnet.config.LoadSpec`)."""
    return load_schedule([l.ramp for l in loads], [l.table for l in loads],  # type: ignore[attr-defined]
                         [l.start for l in loads], [l.stop for l in loads])  # type: ignore[attr-defined]


def break_times(schedule: LoadSchedule, duration: float) -> np.ndarray:
    """Times in ``(0, duration)`` where a load's factor has a kink or a jump (window ends and
    table times), sorted and unique: the time steppers land on them so that no step straddles
    one."""
    finite = np.concatenate([schedule.times, schedule.start, schedule.stop])
    finite = finite[np.isfinite(finite) & (finite > 0.0) & (finite < duration)]
    return np.unique(finite)


def jump_times(schedule: LoadSchedule, duration: float) -> np.ndarray:
    """The times of :func:`break_times` where a load's factor jumps (a window end where the
    factor is not zero, a repeated table time with another factor), sorted and unique: where an
    implicit scheme starts afresh (at a kink the state's accelerations are continuous)."""
    out = []
    for j in range(len(schedule.start)):
        a, b = schedule.ptr[j], schedule.ptr[j + 1]
        times, values = schedule.times[a:b], schedule.values[a:b]
        start, stop = schedule.start[j], schedule.stop[j]
        same = (times[1:] == times[:-1]) & (values[1:] != values[:-1])
        out += [t for t in times[1:][same] if start < t < stop]
        if start > 0.0 and _table_value(times, values, start, right=True) != 0.0:
            out.append(start)
        if math.isfinite(stop) and stop > start and \
                _table_value(times, values, stop, right=False) != 0.0:
            out.append(stop)
    jumps = np.array(out, dtype=np.float64)
    return np.unique(jumps[(jumps > 0.0) & (jumps < duration)])


def _table_value(times: np.ndarray, values: np.ndarray, t: float, right: bool) -> float:
    """A table's factor at ``t`` (window aside): the limit from the right (as
    :func:`load_factor`) or from the left (before a jump at ``t``)."""
    rows = np.searchsorted(times, t, side="right" if right else "left")
    if rows == 0:
        return float(values[0])
    k = rows - 1
    if k + 1 == len(times):
        return float(values[k])
    return float(values[k] + (values[k + 1] - values[k]) * (t - times[k])
                 / (times[k + 1] - times[k]))


@numba.njit(cache=True)
def load_factor(ptr, times, values, start, stop, j, t):  # pragma: no cover - compiled
    """The factor of load ``j`` at time ``t`` (see the module docstring)."""
    if t < start[j] or (t >= stop[j] and stop[j] < math.inf):   # a static run's t is inf
        return 0.0
    a, b = ptr[j], ptr[j + 1]
    if t < times[a]:
        return values[a]
    k = a
    while k + 1 < b and times[k + 1] <= t:   # the last row at or before t (after a jump)
        k += 1
    if k + 1 == b:
        return values[k]
    dt = times[k + 1] - times[k]
    return values[k] + (values[k + 1] - values[k]) * (t - times[k]) / dt


@numba.njit(cache=True)
def load_factors(ptr, times, values, start, stop, repeats, t):  # pragma: no cover - compiled
    """(L,) factors of every load at time ``t`` (a load that ``repeats`` the last one's factor
    takes it over)."""
    n = start.shape[0]
    out = np.empty(n)
    for j in range(n):
        out[j] = out[j - 1] if repeats[j] else load_factor(ptr, times, values, start, stop, j, t)
    return out


def factors(schedule: LoadSchedule, t: float) -> np.ndarray:
    """(L,) factors of every load at time ``t`` [s]."""
    if len(schedule.start) == 0:
        return np.zeros(0)
    return load_factors(schedule.ptr, schedule.times, schedule.values, schedule.start,
                        schedule.stop, schedule.repeats, float(t))


def factor_slopes(schedule: LoadSchedule, t0: float, t1: float) -> tuple[np.ndarray, np.ndarray]:
    """Each load's time factor on ``[t0, t1)``, where it is linear (the steppers land on every
    kink and jump): its slope (L,) [1/s] and its jump at ``t1`` (L,), ``s(t1)`` less the limit
    from the left; zeros for ``t1 <= t0``."""
    n = len(schedule.start)
    if n == 0 or not t1 > t0:
        return np.zeros(n), np.zeros(n)
    s0, mid, s1 = (factors(schedule, t) for t in (t0, 0.5 * (t0 + t1), t1))
    return 2.0 * (mid - s0) / (t1 - t0), s1 - (2.0 * mid - s0)


def factor_energy(schedule: LoadSchedule, force: np.ndarray, t0: float, t1: float,
                  x0: np.ndarray, v0: np.ndarray, x1: np.ndarray, v1: np.ndarray) -> float:
    """What the time factors ``s`` alone changed of the loads' potential ``-s(t) f . x`` over a
    step from ``t0`` to ``t1`` [s], ``-int s'(t) f . x(t) dt`` [J], for loads ``force`` (L, 3)
    [N] on points at ``x0``, ``x1`` [m] with velocities ``v0``, ``v1`` [m/s] (L, 3) at the
    step's ends: ``f . x(t)`` the cubic of those ends (exact for a constant acceleration, the
    trapezoid rule erred by a quarter of the work from rest), and a jump at ``t1`` at the end's
    positions. The energy of the frames less the sum of these is constant where nothing
    dissipates (docs/getting_started.md)."""
    slope, jump = factor_slopes(schedule, t0, t1)
    if not (slope.any() or jump.any()):
        return 0.0
    rate = slope[:, None] * force
    start = (float(np.einsum("li,li->", rate, x0)), float(np.einsum("li,li->", rate, v0)))
    end = (float(np.einsum("li,li->", rate, x1)), float(np.einsum("li,li->", rate, v1)))
    return factor_change(t1 - t0, start, end) - float(np.einsum("l,li,li->", jump, force, x1))


@numba.njit(cache=True)
def factor_change(h, start, end):  # pragma: no cover - compiled
    """``-int s' f . x dt`` [J] over a step of ``h`` [s] within which every factor is linear,
    from ``(sum s' f . x, sum s' f . v)`` [W, W/s] at the step's ``start`` and ``end``: ``f . x``
    the cubic of its ends' values and slopes, whose mean over the step is the ends' mean less
    ``h / 12`` times the change of the slope (:func:`factor_energy`)."""
    return -h * (0.5 * (start[0] + end[0]) - h / 12.0 * (end[1] - start[1]))
