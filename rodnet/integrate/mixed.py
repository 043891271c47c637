"""The mixed Newton step: the geometric stiffness takes the stresses of linearised strains.

In a displacement formulation Newton's matrix at an iterate takes the stresses of that iterate.
After a correction that turns a stiff thread (a rod under an end moment, a cable swinging
taut), the linearised motion stretches it by a length of second order in the turn, and the
next matrix carries the large, spurious tension that stretch produces in its geometric
stiffness: the iteration zig-zags and converges slowly (a 32-element rod with EA L^2 / EI =
1e7 rolled up in ten load steps: ten iterations per step). The mixed integration point
strategy (Magisano, Leonetti and Garcea 2017, "How to improve efficiency and robustness of
the Newton method in geometrically non-linear structural problem analysis", IJNME 109) is
Newton's method on the Hellinger-Reissner form of the same problem with the stresses condensed
element by element: the residual is the usual one, and the geometric stiffness takes the
stresses of the strains linearised along the last correction, ``e(u_k) + de/du (u_{k+1} -
u_k)`` (cosserat FORMULATION.md C55). The solution does not change; at it the two strains
agree, so the convergence stays quadratic.

:class:`MixedStrains` keeps the last accepted iterate's strains and hands the shift
``e_lin - e(u)`` of a trial ``u`` to the model through :class:`~rodnet.state.Linearization`; the
directional derivative is a central difference in the chart of the step, so any model that
reports its strains takes part.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from rodnet.integrate.system import System
from rodnet.state import Configuration, Linearization

FloatArray = NDArray[np.float64]

DIFFERENCE_STEP = 1e-6
"""Length [m or rad] of the central difference along a correction, in its largest component."""

EXACT_BELOW = 1e-4
"""After a move that turns no node by more than this [rad] and moves none by more than this
times the length scale, the matrix takes the stresses of the iterate itself (the exact
tangent): the shift is of second order in the move, and near the solution Newton's
corrections, and the convergence test on their size, are then exact."""


class MixedStrains:
    """The strain shift of the mixed Newton step for iterates ``origin o exp(dq)``.

    Parameters
    ----------
    system : System
    origin : Configuration
        The configuration the increments are measured from (the step's start, or the static
        solve's current base).
    enabled : bool
        False: no shift (Newton's matrix takes the stresses of each iterate).
    """

    def __init__(self, system: System, origin: Configuration, enabled: bool = True) -> None:
        self.system = system
        self.origin = origin
        self._zero = np.zeros(system.n_dof)
        self.dq = np.zeros(system.n_dof)
        self.strains: Any = self._strains(origin) if enabled else None
        self._origin_strains = self.strains
        self._start_shift: Any = None
        self._last: tuple[FloatArray, Any] | None = None
        self._scale = np.full(system.n_dof, 1.0 / system.length_scale)
        self._scale[system.rotation_dofs()] = 1.0

    def _strains(self, q: Configuration) -> Any:
        return self.system.strains(q, self._zero)[0]

    def linearization(self, dq: FloatArray, q: Configuration, convex: bool = False,
                      ) -> Linearization:
        """How the matrix at ``q = origin o exp(dq)`` is formed: the strain shift is the strains
        linearised from the last accepted iterate along the move to ``dq``, minus those of
        ``q``."""
        if self.strains is None:
            return Linearization(None, convex)
        actual = self._actual(dq, q)
        delta = dq - self.dq
        if self._start_shift is not None and not np.any(delta):
            return Linearization(self._start_shift, convex)
        size = float(np.abs(delta).max(initial=0.0))
        if float(np.abs(delta * self._scale).max(initial=0.0)) <= EXACT_BELOW:
            return Linearization(None, convex)
        s = DIFFERENCE_STEP / size
        ahead = self._strains(self.system.retract(self.origin, self.dq + s * delta))
        behind = self._strains(self.system.retract(self.origin, self.dq - s * delta))
        return Linearization(self.strains + (ahead - behind) / (2.0 * s) - actual, convex)

    def accept(self, dq: FloatArray, q: Configuration) -> None:
        """``q = origin o exp(dq)`` is the new accepted iterate."""
        if self.strains is not None:
            self.strains = self._actual(dq, q)
            self.dq = np.array(dq, dtype=float)
            self._start_shift = None

    def start(self, dq: FloatArray, q: Configuration) -> None:
        """``q = origin o exp(dq)`` is a step's extrapolated start: the first iterate, whose
        matrix takes the stresses of the origin (the last converged state).

        The extrapolation's small errors in the positions stretch stiff threads: on the
        clamped 1.5 m thread of the peers benchmark the start's axial forces are ten times
        the thread's weight, of either sign. The geometric stiffness of those forces is what
        holds the soft directions, the swing and the bending, whose stiffness is the
        tension's; Newton's first correction from a matrix carrying them left the velocity
        error of the soft directions where it was (1e-2 m/s before, 0.7e-2 after), while
        with the origin's stresses it falls to 1e-5 m/s.
        """
        if self.strains is not None:
            self.accept(dq, q)
            self._start_shift = self._origin_strains - self.strains

    def rebase(self, origin: Configuration) -> None:
        """Measure later increments from ``origin`` (the last accepted iterate)."""
        self.origin, self.dq = origin, np.zeros(self.system.n_dof)

    def _actual(self, dq: FloatArray, q: Configuration) -> Any:
        """The strains of ``q`` (kept for the last ``dq`` asked)."""
        if self._last is not None and np.array_equal(self._last[0], dq):
            return self._last[1]
        strains = self._strains(q)
        self._last = (np.array(dq, dtype=float), strains)
        return strains
