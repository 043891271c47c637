"""The explicit step of Cosserat rods: stability limit, selective scaling of the rotary inertia,
and the step control of bent elements.

Scheme and step rule: ``elements/cosserat/FORMULATION.md`` §9b, (C46)-(C50); the compiled step
loop is :mod:`rodnet.kernels.explicit`, driven by :mod:`rodnet.integrate.explicit`.

A thin thread's rotary inertia is tiny (``rho I`` per length, ``I = pi d^4 / 64``), so the shear
mode that couples a node's rotation to its neighbours' positions rings at about ``sqrt(G / rho) / r``
(1.6e7 rad/s for a 1 mm Kevlar thread): an explicit step would have to be about 1e-7 s. The
rotational rows are raised to the inertia at which they ring no faster than the translational
rows the step must resolve anyway (C49); the scaling vanishes as the step is refined (C50), so
the refined solutions converge to the unscaled model.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from rodnet.errors import SceneError, at_most
from rodnet.kernels import so3
from rodnet.kernels.cosserat import internal_force_and_tangents_numpy
from rodnet.kernels.explicit import StepControl
from rodnet.models.cosserat.model import CosseratModel
from rodnet.models.lumped import damped_limit

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class ExplicitRodPlan:
    """The step of an explicit rod run and the rotary inertia it runs with.

    Attributes
    ----------
    dt : float
        The step [s] (before shrinking to fit whole steps between frames).
    stable_step : float
        The stability limit (C48) [s] of the whole structure at the inertia used.
    inertia : (R, 3) float
        Body-frame rotary inertia used [kg m^2]: the model's, raised by (C49) when scaled.
    scale : float
        The largest factor by which (C49) raised a rotary inertia (1 when unscaled).
    control : tuple
        ``angles`` (K,) [rad] and ``step_factor`` (K,): the step at the largest element rotation
        ``|psi|`` is ``dt`` times the interpolated factor (C50).
    """

    dt: float
    stable_step: float
    inertia: FloatArray
    scale: float
    control: tuple[FloatArray, FloatArray]

    def model(self, model: CosseratModel) -> CosseratModel:
        """``model`` with the rotary inertia the run uses (energies and frames are those of the
        system actually integrated)."""
        return dataclasses.replace(model, rotary_inertia=self.inertia)



def stress_free_element_states(model: CosseratModel, angle: float = 0.0) -> tuple[FloatArray, FloatArray]:
    """Every element alone, at its reference stretch and shear, bent by ``angle`` [rad] about its
    first bending axis on top of its reference curvature (0: the stress-free state): end
    positions (E, 2, 3) [m] and material quaternions (E, 2, 4), the first end at the origin with
    the identity triad (§Kinematics: ``psi = Le K0 + angle e_2``, ``g = Le Gamma0``)."""
    return _stress_free_states(model.rest_length, model.reference_strain, angle)


def _stress_free_states(rest_length: FloatArray, reference_strain: FloatArray,
                        angle: float) -> tuple[FloatArray, FloatArray]:
    """:func:`stress_free_element_states` of elements of rest lengths ``rest_length`` (E,) and
    reference strains ``reference_strain`` (E, 6)."""
    n = len(rest_length)
    Le = rest_length[:, None]
    psi = Le * reference_strain[:, 3:]
    psi[:, 1] += angle
    midpoint = so3.quat_to_matrix(so3.quat_from_rotvec(0.5 * psi))
    x = np.zeros((n, 2, 3))
    x[:, 1] = np.einsum("eij,ej->ei", midpoint, Le * reference_strain[:, :3])
    q = np.zeros((n, 2, 4))
    q[:, 0, 0] = 1.0
    q[:, 1] = so3.quat_from_rotvec(psi)
    return x, q


def element_stiffness(model: CosseratModel, angle: float = 0.0) -> FloatArray:
    """(E, 12, 12) symmetric part of every element's stiffness at rest in the state of
    :func:`stress_free_element_states`, axial law linear (a taut thread: the tension-only clamp
    only removes stiffness)."""
    kinds, kind = _stiffness_kinds(model, angle)
    return kinds[kind]


def _stiffness_kinds(model: CosseratModel, angle: float) -> tuple[FloatArray, NDArray[np.intp]]:
    """:func:`element_stiffness` as ``kinds[kind]``: the stiffness (k, 12, 12) of each kind of
    element (alike in rest length, reference strains, stiffness and tau: most of a net's
    elements are of a few kinds), evaluated once per kind, and each element's kind (E,)."""
    sections = np.column_stack([model.rest_length, model.reference_strain, model.stiffness,
                                model.tau])
    kinds, kind = _distinct_rows(sections)
    rest_length, reference_strain = kinds[:, 0], kinds[:, 1:7]
    x, q = _stress_free_states(rest_length, reference_strain, angle)
    # NumPy: a net has few kinds, and compiling the tangent kernel would cost a fresh install
    # about 30 CPU s before its first explicit step
    _, K, _ = internal_force_and_tangents_numpy(rest_length, reference_strain, kinds[:, 7:13],
                                                kinds[:, 13], x, q, np.zeros((len(x), 12)),
                                                False, model.kink_strain)
    return 0.5 * (K + K.transpose(0, 2, 1)), kind


_ROW_HASH = np.random.default_rng(20261202).integers(1, 2**63, 256, dtype=np.uint64) | 1
"""Odd multipliers of the columns of :func:`_distinct_rows`' hash."""


def _distinct_rows(a: FloatArray) -> tuple[FloatArray, NDArray[np.intp]]:
    """The distinct rows (bit for bit) of ``a`` (n, m) and for each row its index among them
    (n,).

    Rows are grouped by a hash of their bits (a sum modulo 2^64 of mixed bits, which no order of
    summation changes), and the grouping is checked bit for bit; should two different rows share
    a hash, the rows are sorted instead.
    """
    a = np.ascontiguousarray(a, dtype=np.float64)
    bits = a.view(np.uint64)
    m = a.shape[1]
    weights = _ROW_HASH[:m] if m <= len(_ROW_HASH) else np.resize(_ROW_HASH, m)
    mixed = (bits ^ (bits >> np.uint64(29))) * weights   # the sign and exponent bits too
    key = (mixed ^ (mixed >> np.uint64(32))).sum(axis=1, dtype=np.uint64)
    _, rows, kind = np.unique(key, return_index=True, return_inverse=True)
    kind = kind.ravel()
    if not np.array_equal(bits, bits[rows][kind]):
        _, rows, kind = np.unique(bits, axis=0, return_index=True, return_inverse=True)
        kind = kind.ravel()
    return a[rows], kind


def _first_of_each(kind: NDArray[np.intp]) -> NDArray[np.intp]:
    """For each kind ``0 .. kind.max()`` of ``kind`` (n,), its first index."""
    first = np.zeros(kind.max() + 1 if len(kind) else 0, np.intp)
    first[kind[::-1]] = np.arange(len(kind) - 1, -1, -1)
    return first


def frequency_for_step(h: float, tau: FloatArray, safety: float) -> FloatArray:
    """The frequency [rad/s] whose damped limit (C48) is ``h / safety``: the solution of
    ``h omega = safety 2 (sqrt(1 + zeta^2) - zeta)``, ``zeta = tau omega / 2`` (C49)."""
    return 1.0 / (h * np.sqrt(1.0 / (4.0 * safety**2) + tau / (2.0 * h * safety)))


ANGLES = np.linspace(0.0, 0.985 * 2.0 * math.pi, 34)
"""Angles [rad] at which the stiffening of bent elements (C50) is tabulated; beyond the last the
step keeps the last factor. At 2 pi the element's coefficients are singular (C11); an element
driven past it continues on the double cover with a reflected rotation vector."""

ROTATION_SAFETY = 0.7
"""The fraction of their stability limit at which the modes that move rotations may run (C49),
whatever ``explicit_safety``: a smaller step then also means less added inertia."""

TRANSLATION = np.r_[0:3, 6:9]
"""Element DOFs of the two end positions (the others are the end rotations)."""


class ElementBound:
    """Irons' element eigenvalue bound (C48) for a rod structure.

    The lumped masses are shared out among the elements at each node (``m_i / n_i``, ``J_i / n_i``
    with ``n_i`` elements at the node); then the largest eigenvalue of ``M^-1 K`` of the whole
    structure is at most the largest over elements of the eigenvalue of the element's stiffness
    against its share of the masses. Supported DOFs are left out.
    """

    def __init__(self, model: CosseratModel):
        self.model = model
        n = model.n_nodes
        dofs = model.element_dofs
        count_t = np.bincount(model.pos_nodes.ravel(), minlength=n)
        count_r = np.bincount(model.rot_nodes.ravel(), minlength=model.n_rot)
        self.count_r = count_r
        share_t = model.node_mass[model.pos_nodes] / count_t[model.pos_nodes]          # (E, 2)
        self.mass_t = np.repeat(share_t, 3, axis=1)                                      # (E, 6)
        self.free = model.free[dofs]                                                     # (E, 12)
        self.tau = model.tau

    def rotary_shares(self, inertia: FloatArray) -> FloatArray:
        """(E, 2, 3) each element's share of its end rotation nodes' inertia (R, 3)."""
        m = self.model
        return inertia[m.rot_nodes] / self.count_r[m.rot_nodes][:, :, None]

    def inverse_sqrt_mass(self, inertia: FloatArray) -> FloatArray:
        """(E, 12) ``1 / sqrt`` of each element's share of the masses, 0 on supported DOFs, for
        the rotary inertia ``inertia`` (R, 3)."""
        return self.inverse_sqrt_of_shares(self.rotary_shares(inertia))

    def inverse_sqrt_of_shares(self, share_r: FloatArray) -> FloatArray:
        """(E, 12) as :meth:`inverse_sqrt_mass`, from the rotary shares ``share_r`` (E, 2, 3)."""
        mass = np.concatenate([self.mass_t[:, :3], share_r[:, 0], self.mass_t[:, 3:], share_r[:, 1]],
                              axis=1)
        with np.errstate(divide="ignore"):
            return np.where(self.free, 1.0 / np.sqrt(mass), 0.0)

    @staticmethod
    def largest(K: FloatArray | tuple[FloatArray, NDArray[np.intp]], inv_sqrt_mass: FloatArray,
                dofs: slice | NDArray[np.int64] = slice(None)) -> FloatArray:
        """(E,) largest eigenvalue [rad^2/s^2] of ``M_e^-1/2 K_e M_e^-1/2`` over ``dofs``;
        ``K`` (E, 12, 12), or ``(kinds, kind)`` of :func:`_stiffness_kinds` for ``kinds[kind]``.

        Elements alike in stiffness and masses have the same matrix: it is solved once.
        """
        kinds, kind = (K, np.arange(len(K))) if isinstance(K, np.ndarray) else K
        _, alike = _distinct_rows(np.column_stack([kind.astype(float), inv_sqrt_mass]))
        first = _first_of_each(alike)
        s = inv_sqrt_mass[first]
        A = s[:, :, None] * kinds[kind[first]] * s[:, None, :]
        return np.linalg.eigvalsh(A[:, dofs][:, :, dofs])[alike, -1]


def explicit_plan(model: CosseratModel, dt: float, adaptive: bool, safety: float,
                  scale_rotary_inertia: bool = True) -> ExplicitRodPlan:
    """The step, the rotary inertia and the step control of an explicit run (C48)-(C50).

    Parameters
    ----------
    dt : float
        The scene's step [s]; used when ``adaptive`` is False.
    adaptive : bool
        Take ``safety`` times the stability limit (C48) at the raised inertia as the step.
    safety : float
        ``simulation.explicit_safety``: the fraction of the stability limit the step may use.
    scale_rotary_inertia : bool
        Raise the rotary inertia by (C49); without it the rotations' own limit binds.

    Raises
    ------
    SceneError
        A free node without mass, or a fixed ``dt`` above the stability limit.
    """
    free_nodes = model.free[:3 * model.n_nodes].reshape(-1, 3).any(axis=1)
    free_rot = model.free[3 * model.n_nodes:].reshape(-1, 3).any(axis=1)
    if np.any(model.node_mass[free_nodes] <= 0.0) or np.any(model.rotary_inertia[free_rot] <= 0.0):
        raise SceneError("materials.density", 0.0, "the explicit integrator needs mass and rotary "
                         "inertia at every free node: a positive density (or mass_per_length)")
    bound = ElementBound(model)
    K = _stiffness_kinds(model, 0.0)
    inertia = model.rotary_inertia.copy()
    if scale_rotary_inertia:
        # the step the translations would allow with the rotations held (C48) sets how fast the
        # modes with rotations may ring: the rotary inertia is raised to that (C49)
        lam_t = bound.largest(K, bound.inverse_sqrt_mass(inertia), TRANSLATION)
        limit_t = float(damped_limit(np.sqrt(lam_t), bound.tau).min())
        h_t = safety * limit_t if adaptive else dt
        if not adaptive and dt > ROTATION_SAFETY * limit_t:
            # no rotary inertia brings the modes with rotations to ROTATION_SAFETY of their
            # limit: the translations alone ring too fast for this step (the raised inertia
            # would grow without bound and hold the sections still)
            raise SceneError("simulation.dt", dt, f"leaves no room for the scaled rotary inertia "
                             f"(C49): with the rotations held, the translations' stability limit "
                             f"is {limit_t:.3g} s, and the rotations may run at "
                             f"{ROTATION_SAFETY:g} of theirs; use dt <= "
                             f"{at_most(ROTATION_SAFETY * limit_t)} s (about half of it for accurate "
                             "snap loads), adaptive = true, or "
                             "simulation.rotary_inertia_scaling = false with a smaller dt")
        target = frequency_for_step(h_t, bound.tau, ROTATION_SAFETY) ** 2
        inertia = _raised_inertia(model, bound, K, target)
    lam = bound.largest(K, bound.inverse_sqrt_mass(inertia))
    stable = float(damped_limit(np.sqrt(lam), bound.tau).min())
    h = safety * stable if adaptive else dt
    if not adaptive and dt > stable:
        raise SceneError("simulation.dt", dt, f"exceeds the explicit stability limit {stable:.3g} s "
                         f"of this scene; use dt <= {at_most(stable)} (about half of it for accurate "
                         "snap loads) or adaptive = true")
    # bent elements stiffen: the step shrinks with the largest rotation in the structure (C50)
    inv_sqrt = bound.inverse_sqrt_mass(inertia)
    moving = lam > 0.0       # an element whose ends are both held has no bound to scale
    ratio = np.array([float(np.max(bound.largest(K if a == 0.0 else _stiffness_kinds(model, a),
                                                 inv_sqrt)[moving] / lam[moving], initial=1.0))
                      for a in ANGLES])
    factor = 1.0 / np.sqrt(np.maximum(1.0, np.maximum.accumulate(ratio)))
    scale = float((inertia / model.rotary_inertia).max()) if model.n_rot else 1.0
    return ExplicitRodPlan(h, stable, inertia, scale, (ANGLES.copy(), factor))


def _raised_inertia(model: CosseratModel, bound: ElementBound,
                    K: tuple[FloatArray, NDArray[np.intp]], target: FloatArray) -> FloatArray:
    """(C49): rotary inertia (R, 3) raised isotropically, never below the model's own, until
    every element's bound is at most ``target`` (E,) [rad^2/s^2].

    Per element, the smallest share ``j`` [kg m^2] of both end rotations (every axis at least its
    own share) is found by bisection on ``log j``, the bound falling as ``j`` grows; a rotation
    node takes ``n_i`` times the largest share its elements need. (Raising only the bending axes
    of thread ends, torsion keeping its own inertia, made bent elements unstable.)"""
    own_share = bound.rotary_shares(model.rotary_inertia)                 # (E, 2, 3)

    def bound_at(j: FloatArray) -> FloatArray:
        return bound.largest(K, bound.inverse_sqrt_of_shares(np.maximum(own_share, j[:, None, None])))

    lo = np.log(own_share.min(axis=(1, 2)))
    hi = lo + np.log(1e16)
    for _ in range(50):   # to 1e16 ** (2 ** -50): far below a per cent
        mid = 0.5 * (lo + hi)
        ok = bound_at(np.exp(mid)) <= target
        hi, lo = np.where(ok, mid, hi), np.where(ok, lo, mid)
    raised = np.zeros(model.n_rot)
    count = bound.count_r[model.rot_nodes]                                # (E, 2)
    np.maximum.at(raised, model.rot_nodes.ravel(), (np.exp(hi)[:, None] * count).ravel())
    return np.maximum(model.rotary_inertia, raised[:, None])


def rod_explicit_plan(model: CosseratModel, v0: FloatArray, dt: float, adaptive: bool,
                      safety: float, scale_rotary_inertia: bool,
                      ) -> tuple[CosseratModel, FloatArray, StepControl]:
    """The model the explicit loop runs (with the rotary inertia of (C49) when scaled), its
    start velocities and the rotation-controlled step control (C48)-(C50).

    The start velocities are ``v0`` (n_dof,) with each rotation node's angular velocity lowered
    so that its angular momentum ``J W`` under the raised inertia is that of the unscaled model
    (C49): a start spin given to the real, nearly massless rotations does not become a flywheel.
    The control's ``undamped_step`` is the stability limit of the same plan without the
    Kelvin-Voigt damping (for the warning of a step the viscosity shortens).
    """
    plan = explicit_plan(model, dt, adaptive, safety, scale_rotary_inertia)
    undamped = plan.stable_step
    if np.any(model.tau > 0.0):  # the limit the same scene would have without its viscosity
        undamped = explicit_plan(dataclasses.replace(model, tau=np.zeros_like(model.tau)), dt,
                                 adaptive, safety, scale_rotary_inertia).stable_step
    v = np.array(v0, dtype=float)
    v[3 * model.n_nodes:] *= (model.rotary_inertia / plan.inertia).ravel()
    control = StepControl(plan.dt, plan.dt, 0.0, True, *plan.control, plan.stable_step,
                          undamped_step=undamped)
    return plan.model(model), v, control
