"""Reference curve of the cantilever_elastica case: the inextensible, unshearable Euler
elastica of a cantilever under a dead tip force, from its closed form in elliptic integrals."""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import brentq
from scipy.special import ellipe, ellipeinc, ellipk, ellipkinc


def elastica_tip(alpha: float) -> tuple[float, float]:
    """Tip (x / L, deflection / L) at alpha = P L^2 / EI: with phi0 the tip slope and parameter
    m = (1 + sin phi0) / 2, sin phi1 = 1 / sqrt(2 m), sqrt(alpha) = K(m) - F(phi1, m),
    x / L = sqrt(2 sin(phi0) / alpha), deflection / L = 1 - 2 (E(m) - E(phi1, m)) / sqrt(alpha)."""
    if alpha <= 0.0:
        return 1.0, 0.0

    def phi1(m: float) -> float:
        return float(np.arcsin(1.0 / np.sqrt(2.0 * m)))

    def mismatch(phi0: float) -> float:
        m = (1.0 + np.sin(phi0)) / 2.0
        return float(ellipk(m) - ellipkinc(phi1(m), m) - np.sqrt(alpha))

    phi0 = brentq(mismatch, 1e-12, np.pi / 2 - 1e-12, xtol=1e-15)
    m = (1.0 + np.sin(phi0)) / 2.0
    deflection = 1.0 - 2.0 / np.sqrt(alpha) * (ellipe(m) - ellipeinc(phi1(m), m))
    return float(np.sqrt(2.0 * np.sin(phi0) / alpha)), float(deflection)


def tip(load_factor: NDArray[np.float64], scene: dict[str, Any]) -> dict[str, NDArray[np.float64]]:
    """Tip position x and z (n,) [m] at the load factors (n,) of the dead force P along -z:
    alpha = load factor * P L^2 / EI, EI = E pi d^4 / 64."""
    material, rod = scene["materials"][0], scene["rods"][0]
    ei = material["youngs_modulus"] * np.pi * material["diameter"]**4 / 64.0
    length = float(np.linalg.norm(np.subtract(rod["points"][-1], rod["points"][0])))
    full = -scene["loads"][0]["force"][2] * length**2 / ei
    shape = np.array([elastica_tip(full * f) for f in np.ravel(load_factor)]).reshape(-1, 2)
    return {"x": shape[:, 0] * length, "z": -shape[:, 1] * length}
