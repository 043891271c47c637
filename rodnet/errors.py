"""Exceptions that carry a message meant for the user, not a traceback."""

from __future__ import annotations

import math
from typing import Any

import numpy as np


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
        if not key:
            text = allowed
        elif value is None:
            text = f"{key} is not set: {allowed}"
        else:
            text = f"{key} = {shown(value)}: {allowed}"
        super().__init__(text)

    def within(self, prefix: str) -> SceneError:
        """Return the same error with ``prefix`` put in front of its key."""
        key = f"{prefix}.{self.key}" if self.key else prefix
        return SceneError(key, self.value, self.allowed)


SHOWN_ITEMS = 10
"""The longest list :func:`shown` writes out in full; a longer one is cut after its first
eight items, with its length."""


def shown(value: Any) -> str:
    """``value`` as it is written in a scene file (TOML): ``true``, ``'text'``, ``[1.0, 2]``."""
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, np.ndarray):
        value = value.tolist()
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):   # a literal string where it can be one, as the messages quote
        if "'" not in value and "\n" not in value:
            return f"'{value}'"
        return '"' + value.replace("\\", "\\\\").replace('"', '\\"').replace("\n", "\\n") + '"'
    if isinstance(value, (list, tuple)):
        if len(value) > SHOWN_ITEMS:   # a message quotes the start of a long list
            return ("[" + ", ".join(shown(v) for v in value[:SHOWN_ITEMS - 2])
                    + f", ... ({len(value)} items)]")
        return "[" + ", ".join(shown(v) for v in value) + "]"
    if isinstance(value, dict):
        return "{" + ", ".join(f"{k} = {shown(v)}" for k, v in value.items()) + "}"
    return repr(value)


def at_most(limit: float) -> str:
    """``limit`` written with 3 significant digits, rounded down: a bound a user can copy into
    the scene (``6.38e-05`` for 6.3849e-05, where ``:.3g`` would round up past it)."""
    text = f"{limit:.3g}"
    if float(text) > limit > 0.0:
        digit = 10.0 ** (math.floor(math.log10(limit)) - 2)
        text = f"{math.floor(limit / digit) * digit:.3g}"
    return text


class SimulationFailed(RuntimeError):
    """A run that stopped before its end (divergence, NaN, solver failure, interruption)."""
