"""Reference curve of the axial_wave_bar case: the 1-D wave equation's tip displacement."""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray


def tip_displacement(t: NDArray[np.float64], scene: dict[str, Any]) -> dict[str, NDArray[np.float64]]:
    """Axial tip displacement (n,) [m] at the times ``t`` (n,) [s] of the fixed-free bar
    released with a uniform axial velocity v0: the triangle wave between +-v0 L / c of period
    4 L / c, c = sqrt(E / rho), written as v0 (L / c) (2 / pi) arcsin(sin(pi c t / (2 L)))."""
    material, rod = scene["materials"][0], scene["rods"][0]
    c = np.sqrt(material["youngs_modulus"] / material["density"])
    length = float(np.linalg.norm(np.subtract(rod["points"][-1], rod["points"][0])))
    v0 = rod["velocity"][0]
    return {"x": v0 * length / c * 2.0 / np.pi * np.arcsin(np.sin(np.pi * c * t / (2.0 * length)))}
