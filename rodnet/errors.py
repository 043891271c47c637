"""Exceptions that carry a message meant for the user, not a traceback."""

from __future__ import annotations

from typing import Any


class SceneError(ValueError):
    """A scene (or a command-line override) that cannot be run.

    Parameters
    ----------
    key : str
        Dotted path of the offending key, e.g. ``"net.packing"`` or ``"materials[0].density"``.
    value : Any
        The value found (``None`` when the key is missing).
    allowed : str
        What would have been accepted.
    """

    def __init__(self, key: str, value: Any, allowed: str) -> None:
        self.key, self.value, self.allowed = key, value, allowed
        super().__init__(f"{key} = {value!r}: {allowed}" if key else allowed)

    def within(self, prefix: str) -> SceneError:
        """Return the same error with ``prefix`` put in front of its key."""
        key = f"{prefix}.{self.key}" if self.key else prefix
        return SceneError(key, self.value, self.allowed)


class SimulationFailed(RuntimeError):
    """A run that stopped before its end (divergence, NaN, solver failure, interruption)."""
