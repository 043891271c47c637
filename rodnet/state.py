"""The state that integrators advance: plain arrays, no physics.

As in MuJoCo's ``mjModel``/``mjData`` split, a model (:mod:`rodnet.models`) holds read-only
arrays that describe the structure, and a :class:`State` holds what changes during a run: the
configuration (node positions, rotation-node quaternions), the generalized velocities, the free
rigid bodies' motion and the work friction has dissipated so far. Models build the initial state;
integrators advance copies of it; frames are taken from it.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class Configuration:
    """Positions ``x`` (N, 3) [m] and unit quaternions ``quat`` (R, 4) (w, x, y, z) of the
    rotation nodes; ``R = 0`` for models without rotations (the lumped model, cables). In an
    implicit run with free rigid bodies also their centres ``body_x`` (F, 3) [m] and the
    rotations of their principal axes ``body_quat`` (F, 4) (principal to world); F = 0
    otherwise (the bodies' motion is then in :attr:`State.bodies`)."""

    x: FloatArray
    quat: FloatArray = field(default_factory=lambda: np.zeros((0, 4)))
    body_x: FloatArray = field(default_factory=lambda: np.zeros((0, 3)))
    body_quat: FloatArray = field(default_factory=lambda: np.zeros((0, 4)))

    def copy(self) -> Configuration:
        return Configuration(self.x.copy(), self.quat.copy(), self.body_x.copy(),
                             self.body_quat.copy())


@dataclass(frozen=True)
class StepRate:
    """The strain rates of an implicit step, ``(strain - reference) * inv_h``: a scheme that moves
    the configuration as ``q1 = q* o exp(h_bar (v1 - v*))`` passes the strains of ``q*`` moved
    back by ``h_bar`` times their rate at ``v*``, and ``inv_h = 1 / h_bar``, so that damping has
    a potential over the step (spring FORMULATION.md, S11).

    Attributes
    ----------
    reference : object
        The model's strains (as :meth:`strains` of the model returns them) at the reference.
    inv_h : float
        1 / h_bar [1/s].
    start : Configuration or None
        The midpoint rule's start configuration, for a model that takes its forces in secant
        form (``secant_forces``): forces at the midpoint ``q`` from the change of the stored
        energy between ``start`` and the step's end ``2 q - start``, damping at the rate
        ``(e_end - e_start) inv_h / 2`` (spring FORMULATION.md, S15).
    """

    reference: object
    inv_h: float
    start: Configuration | None = None


@dataclass(frozen=True)
class Linearization:
    """How Newton's iteration matrix departs from the exact tangent.

    Attributes
    ----------
    strain_shift : object
        Added to the model's strains (as :meth:`strains` returns them) for the stresses of the
        geometric stiffness: the mixed Newton step (cosserat FORMULATION.md, C55), where those
        are the stresses of the strains linearised along the last correction. None: the
        stresses of the configuration.
    convex : bool
        Replace every element block whose symmetric part is indefinite by the projection of
        that part on the positive semidefinite matrices, so that the matrix gives a direction of
        descent of the step's potential.
    inertia : (n_dof,) float or None
        With ``convex``: the iteration matrix's diagonal (the masses' term) over its stiffness
        coefficient, per DOF of the model (zero on held DOFs) [N/m, N m/rad]. Half of it is
        shared among the elements at each DOF and counted in their blocks' curvature before the
        projection (:func:`rodnet.kernels.convex.convex_blocks`), so only what the masses do
        not outweigh is projected. None: the blocks alone.
    """

    strain_shift: object = None
    convex: bool = False
    inertia: FloatArray | None = None


@dataclass
class BodyMotion:
    """The current state of every rigid body (fixed bodies keep their start values).

    Attributes
    ----------
    position : (B, 3) float
        Centre of mass [m].
    velocity : (B, 3) float
        Velocity of the centre of mass [m/s].
    quaternion : (B, 4) float
        Body-to-world rotation (w, x, y, z).
    rotation : (B, 3, 3) float
        The same rotation as a matrix.
    momentum : (B, 3) float
        Angular momentum about the centre of mass, world axes [kg m^2/s].
    omega : (B, 3) float
        Angular velocity, world axes [rad/s].
    """

    position: FloatArray
    velocity: FloatArray
    quaternion: FloatArray
    rotation: FloatArray
    momentum: FloatArray
    omega: FloatArray

    FIELDS = ("position", "velocity", "quaternion", "rotation", "momentum", "omega")

    def copy(self) -> BodyMotion:
        return BodyMotion(*(np.array(getattr(self, k)) for k in self.FIELDS))


@dataclass
class State:
    """What a run advances.

    Attributes
    ----------
    q : Configuration
    v : (n_dof,) float
        Generalized velocities: node velocities (N, 3) [m/s], then body-frame angular
        velocities of the rotation nodes (R, 3) [rad/s], flattened.
    bodies : BodyMotion or None
        The rigid bodies (None in a scene without bodies).
    friction_work : float
        Work dissipated by friction since the start [J].
    load_factor_energy : float
        How much the dead forces' potential ``-s(t) f . x`` changed since the start by their
        time factors ``s`` alone, ``-int s' f . x dt``, summed step by step
        (:func:`~rodnet.kernels.schedule.factor_energy`) [J]: the frames' energy less it is
        constant where nothing dissipates.
    applied_to_bodies : tuple of two (B, 3) float, or None
        The force [N] and moment about the centre of mass [N m] the threads applied to every
        body in the explicit loop's last step (its friction (E2) is not the regularised law
        at the state); None: the frame computes them from the state.
    """

    q: Configuration
    v: FloatArray
    bodies: BodyMotion | None = None
    friction_work: float = 0.0
    load_factor_energy: float = 0.0
    applied_to_bodies: tuple[FloatArray, FloatArray] | None = None

    @property
    def velocities(self) -> FloatArray:
        """Node velocities (N, 3) [m/s], a view of ``v``."""
        return self.v[:self.q.x.size].reshape(-1, 3)

    @property
    def spin(self) -> FloatArray:
        """Body-frame angular velocities of the rotation nodes (R, 3) [rad/s], a view of ``v``."""
        n3 = self.q.x.size
        return self.v[n3:n3 + 3 * len(self.q.quat)].reshape(-1, 3)

    def copy(self) -> State:
        return replace(self, q=self.q.copy(), v=self.v.copy(),
                       bodies=None if self.bodies is None else self.bodies.copy())


class AcceptedStep(NamedTuple):
    """What one accepted step adds to a run's records (:meth:`StepStats.record_accepted`):
    ``friction_work`` [J] over it, and at its end the ``max_tension`` [N], the sum of the
    contact point forces ``contact_force`` [N], their number ``contact_count`` and the deepest
    thread surface in a body ``contact_depth`` [thread radii]; and the change of the dead
    forces' potential that their time factors made over it, ``load_factor_energy`` [J]
    (:attr:`State.load_factor_energy`)."""

    friction_work: float
    max_tension: float
    contact_force: float
    contact_count: int
    contact_depth: float
    load_factor_energy: float
