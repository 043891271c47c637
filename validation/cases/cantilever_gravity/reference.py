"""Reference curve of the cantilever_gravity case: the Euler-Bernoulli cantilever under its
own weight."""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray


def deflection(s: NDArray[np.float64], scene: dict[str, Any]) -> dict[str, NDArray[np.float64]]:
    """Vertical position z (n,) [m] of the rod's axis at the arc lengths ``s`` (n,) [m]:
    w(s) = q s^2 (6 L^2 - 4 L s + s^2) / (24 EI) downwards, q = rho A g, EI = E pi d^4 / 64."""
    material, rod = scene["materials"][0], scene["rods"][0]
    d = material["diameter"]
    q = material["density"] * np.pi * d**2 / 4.0 * -scene["simulation"]["gravity"][2]
    ei = material["youngs_modulus"] * np.pi * d**4 / 64.0
    length = float(np.linalg.norm(np.subtract(rod["points"][-1], rod["points"][0])))
    return {"z": -q * s**2 * (6.0 * length**2 - 4.0 * length * s + s**2) / (24.0 * ei)}
