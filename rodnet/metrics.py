"""Deployment measures of a net: mouth area, distance travelled, and their summary scalars."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from rodnet.topology import NetLayout


def mouth_area(positions: NDArray[np.float64], net: NetLayout) -> NDArray[np.float64]:
    """Area [m^2] of the quadrilateral of the four corner masses projected on the net plane.

    Parameters
    ----------
    positions : (F, N, 3) float
        Node positions of F frames.

    Returns
    -------
    area : (F,) float
        Half the norm of the diagonals' cross product along the shooting direction: the shoelace
        area of the projected quadrilateral (corners 0, 1, 3, 2 go round its perimeter).
    """
    c = positions[:, net.corners, :]
    d1 = c[:, 3] - c[:, 0]
    d2 = c[:, 2] - c[:, 1]
    return 0.5 * np.abs(np.cross(d1, d2) @ net.direction)


def distance(positions: NDArray[np.float64], masses: NDArray[np.float64],
             net: NetLayout) -> NDArray[np.float64]:
    """Displacement [m] along the shooting direction of the centre of mass of the net itself
    (knots and thread nodes, without the corner masses), from its initial position, (F,)."""
    m = masses[net.net_nodes]
    com = np.einsum("fnk,n->fk", positions[:, net.net_nodes, :], m) / m.sum()
    along = com @ net.direction
    return along - along[0]


def net_metrics(time: NDArray[np.float64], area: NDArray[np.float64],
                dist: NDArray[np.float64]) -> dict[str, float]:
    """Maximum mouth area, its time and the distance travelled at that time."""
    i = int(np.argmax(area))
    return {"max_mouth_area": float(area[i]), "time_of_max_mouth_area": float(time[i]),
            "distance_at_max_mouth_area": float(dist[i])}


def geometric_ceiling(net_side: float, corner_thread_length: float) -> float:
    """Mouth area [m^2] of the flat, fully taut net: corner masses on the diagonals' extensions."""
    half_diagonal = net_side / np.sqrt(2.0) + corner_thread_length
    return 2.0 * half_diagonal**2


