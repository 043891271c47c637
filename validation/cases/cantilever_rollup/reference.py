"""Reference curve of the cantilever_rollup case: a rod of uniform curvature M / EI."""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray


def tip(load_factor: NDArray[np.float64], scene: dict[str, Any]) -> dict[str, NDArray[np.float64]]:
    """Tip position x, y and its distance from the root (n,) [m] at the load factors (n,) of the
    end moment M about z: the rod, clamped at the origin along +x, bends into a circular arc of
    curvature k = M / EI, so x = sin(k L) / k, y = (1 - cos(k L)) / k and the distance is
    |2 sin(k L / 2) / k|; EI = E pi d^4 / 64."""
    material, rod = scene["materials"][0], scene["rods"][0]
    ei = material["youngs_modulus"] * np.pi * material["diameter"]**4 / 64.0
    length = float(np.linalg.norm(np.subtract(rod["points"][-1], rod["points"][0])))
    angle = np.asarray(load_factor, float) * scene["loads"][0]["moment"][2] / ei * length  # k L
    safe = np.where(angle == 0.0, 1.0, angle)
    x = np.where(angle == 0.0, length, length * np.sin(safe) / safe)
    y = np.where(angle == 0.0, 0.0, length * (1.0 - np.cos(safe)) / safe)
    return {"x": x, "y": y, "norm": np.hypot(x, y)}
