"""Free rigid bodies: their start state and kinetic energy.

A free body's state (:class:`rodnet.state.BodyMotion`) is its centre of mass and velocity
(world), its orientation (a unit quaternion, body to world) and its angular momentum about the
centre of mass in world axes, ``L = R J R^T omega`` (``J`` the inertia tensor about the centre of
mass in body axes). The explicit step (R1)-(R4) of ``elements/contact/FORMULATION.md`` section 8
that moves them is :func:`rodnet.kernels.rigid_body.advance_bodies`.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from rodnet.kernels import so3
from rodnet.state import BodyMotion

FloatArray = NDArray[np.float64]


def start_motion(position: FloatArray, quaternion: FloatArray, velocity: FloatArray,
                 omega: FloatArray, inertia: FloatArray) -> BodyMotion:
    """The state at t = 0 from the pose, velocity and world angular velocity of every body.

    Parameters
    ----------
    position, velocity, omega : (B, 3) float
    quaternion : (B, 4) float
    inertia : (B, 3, 3) float
        Inertia about the centre of mass in body axes [kg m^2].
    """
    rotation = np.array([so3.quat_to_matrix(q) for q in quaternion]).reshape(-1, 3, 3)
    momentum = np.einsum("bij,bjk,blk,bl->bi", rotation, inertia, rotation, omega)
    return BodyMotion(np.array(position, float), np.array(velocity, float),
                      np.array(quaternion, float), rotation, momentum, np.array(omega, float))


def kinetic_energy(mass: FloatArray, inertia: FloatArray, motion: BodyMotion,
                   free: NDArray[np.bool_]) -> float:
    """Kinetic energy of the free bodies [J]: ``m |v|^2 / 2 + L . omega / 2``."""
    e = 0.5 * mass * np.einsum("bi,bi->b", motion.velocity, motion.velocity) \
        + 0.5 * np.einsum("bi,bi->b", motion.momentum, motion.omega)
    return float(e[free].sum())
