"""Two-node Simo-Reissner (Cosserat) element: stress resultants, energy, internal force, tangents.

Formulation card: ``elements/cosserat/FORMULATION.md`` (§Strains, §Constitutive law, §Energy,
§Internal force, §Tangent); the axial law is the shared one of :mod:`rodnet.kernels.tension`.
Shapes: n = number of elements. Arguments come in the order model arrays, state arrays, scalars:

- ``rest_length (n,)``: ``Le``;
- ``reference_strain (n, 6)``: ``[Gamma0, K0]`` of the stress-free state (:func:`reference_strains`);
- ``stiffness (n, 6)``: section stiffness diagonals ``[EA, GA2, GA3, GJ, EI2, EI3]``;
- ``tau (n,)``: Kelvin-Voigt retardation time (viscosity / E) [s];
- ``x (n, 2, 3)``, ``q (n, 2, 4)``: node positions and unit quaternions (w, x, y, z) per element;
- ``velocity (n, 12)``: ``[v1, W1, v2, W2]``, v global, W body angular velocity;
- ``tension_only`` (bool): tension-only axial law with the Kelvin-Voigt total clamped at zero,
  else linear; ``kink_strain`` (float): width ``delta`` of the C1 ramp.

Element vectors are ordered ``[dx1, dtheta1, dx2, dtheta2]``, rotations as body-frame increments.

:func:`internal_force`, :func:`internal_force_and_tangents`, :func:`strain_energy`,
:func:`stress_resultants` and :func:`section_state` run the compiled per-element loops of
:mod:`rodnet.kernels.cosserat_compiled`; the ``*_numpy`` variants are the same equations in
NumPy, kept as the reference for the compiled path.
"""

from __future__ import annotations

import numpy as np

from rodnet.kernels.cosserat_strain import (
    expand_vector, kinematics, midpoint_coefficient, reduce_velocity, rotation_stop,
    reference_strains as reference_strains, strain_matrix as strain_matrix,
    strain_rates_from_kinematics, strains as strains, strains_from_kinematics,
)
from rodnet.kernels import cosserat_compiled, tension
from rodnet.kernels.cosserat_tangent import tangents
from rodnet.kernels.so3 import FloatArray, dexp_inv_apply
from rodnet.kernels.tension import REVERSED_STIFFNESS, axial_energy, axial_force, ramp


def stress_resultants_and_moduli(
    # Model:
    stiffness: FloatArray, tau: FloatArray,
    # State in:
    strain: FloatArray, strain_rate: FloatArray,
    # Scalars:
    tension_only: bool, kink_strain: float,
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Stress resultants ``[N, M]`` with Kelvin-Voigt damping and their derivatives.

    §Constitutive law; the axial component is :func:`rodnet.kernels.tension.axial_force`.

    Parameters
    ----------
    stiffness : (n, 6), tau : (n,)
        See the module docstring.
    strain, strain_rate : (n, 6)
        ``[Gamma, K]`` and its time derivative.
    tension_only : bool, kink_strain : float
        Axial law switch and ramp width.

    Returns
    -------
    stress : (n, 6)
        ``[N, M]`` (material components).
    modulus, viscous_modulus : (n, 6)
        Diagonals of ``d stress / d strain`` and ``d stress / d strain_rate`` (the law is
        uncoupled between components). Zero in the axial slot where the clamp holds.
    """
    damping = tau[:, None] * stiffness
    stress = stiffness * strain + damping * strain_rate
    modulus = stiffness.copy()
    viscous_modulus = damping
    EA, e, e_rate = stiffness[:, 0], strain[:, 0], strain_rate[:, 0]
    stress[:, 0] = axial_force(e, e_rate, EA, tau * EA, kink_strain, tension_only)
    if tension_only:
        # taut (N > 0) on the ramp of e; pushing (N < 0, (C51)) on the ramp of s = -1 - e, whose
        # moduli with respect to e and de/dt have the same form in s and ds/dt = -de/dt
        taut, pushing = stress[:, 0] > 0.0, stress[:, 0] < 0.0
        s = np.where(pushing, -1.0 - e, e)
        s_rate = np.where(pushing, -e_rate, e_rate)
        _, slope = ramp(s, kink_strain)
        curvature = np.zeros_like(e)
        if kink_strain > 0.0:
            curvature[(s > 0.0) & (s < kink_strain)] = 1.0 / kink_strain
        acting = taut | pushing
        k = np.where(pushing, REVERSED_STIFFNESS, 1.0) * EA
        modulus[:, 0] = np.where(acting, k * (slope + tau * curvature * s_rate), 0.0)
        viscous_modulus[:, 0] = np.where(acting, tau * k * slope, 0.0)
    return stress, modulus, viscous_modulus


def stress_resultants(
    # Model:
    stiffness: FloatArray, tau: FloatArray,
    # State in:
    strain: FloatArray, strain_rate: FloatArray,
    # Scalars:
    tension_only: bool, kink_strain: float,
) -> FloatArray:
    """Stress resultants ``[N, M]`` (n, 6); see :func:`stress_resultants_and_moduli`. Compiled."""
    return cosserat_compiled.stress_resultants(stiffness, tau, strain, strain_rate, tension_only,
                                               kink_strain)


def stress_resultants_numpy(
    # Model:
    stiffness: FloatArray, tau: FloatArray,
    # State in:
    strain: FloatArray, strain_rate: FloatArray,
    # Scalars:
    tension_only: bool, kink_strain: float,
) -> FloatArray:
    """:func:`stress_resultants` in NumPy."""
    return stress_resultants_and_moduli(stiffness, tau, strain, strain_rate, tension_only,
                                        kink_strain)[0]


def section_state(
    # Model:
    rest_length: FloatArray, reference_strain: FloatArray, stiffness: FloatArray, tau: FloatArray,
    # State in:
    x: FloatArray, q: FloatArray, velocity: FloatArray,
    # Scalars:
    tension_only: bool, kink_strain: float,
) -> tuple[FloatArray, FloatArray]:
    """Strains ``[Gamma, K]`` (n, 6) and stress resultants ``[N, M]`` (n, 6) with Kelvin-Voigt
    damping (§Strains, §Strain rates, §Constitutive law); ``M`` includes the rotation stop's
    moment (C52) of an element turned beyond it. Compiled."""
    return cosserat_compiled.section_state(rest_length, reference_strain, stiffness, tau, x, q,
                                           velocity, tension_only, kink_strain)


def section_state_numpy(
    # Model:
    rest_length: FloatArray, reference_strain: FloatArray, stiffness: FloatArray, tau: FloatArray,
    # State in:
    x: FloatArray, q: FloatArray, velocity: FloatArray,
    # Scalars:
    tension_only: bool, kink_strain: float,
) -> tuple[FloatArray, FloatArray]:
    """:func:`section_state` in NumPy."""
    _, eps, (stress, _, _), _ = _stress_state(rest_length, reference_strain, stiffness, tau, x, q,
                                              velocity, tension_only, kink_strain)
    return eps, stress


def strain_energy(
    # Model:
    rest_length: FloatArray, reference_strain: FloatArray, stiffness: FloatArray,
    # State in:
    x: FloatArray, q: FloatArray,
    # Scalars:
    tension_only: bool, kink_strain: float,
) -> FloatArray:
    """Elastic strain energy of each element (§Energy): (n,). Compiled.

    ``Le [EA Rint(Gamma_0) + (GA2 Gamma_1^2 + GA3 Gamma_2^2 + K^T C_M K) / 2]``, with the linear
    axial energy ``EA Gamma_0^2 / 2`` when not tension-only, plus the rotation stop's energy
    (C52) of elements turned beyond :data:`rodnet.kernels.cosserat_strain.ROTATION_STOP`.
    """
    return cosserat_compiled.strain_energy(rest_length, reference_strain, stiffness, x, q,
                                           tension_only, kink_strain)


def step_potential(
    # Model:
    rest_length: FloatArray, reference_strain: FloatArray, stiffness: FloatArray, tau: FloatArray,
    # State in:
    x: FloatArray, q: FloatArray,
    # Scalars:
    tension_only: bool, kink_strain: float,
    step: tuple[FloatArray, float] | None = None,
) -> FloatArray:
    """Incremental potential of each element over an implicit step (C53): (n,).

    ``Le [Psi_axial + sum_k D_k (eps_k^2 + tau inv_h (eps_k - eps_ref_k)^2) / 2] + stop``, with
    ``Psi_axial`` the clamped axial integral of :func:`rodnet.kernels.tension.step_potential`
    and ``k`` over shear, torsion and bending: with the step's strain rates
    (``step = (eps_ref, inv_h)``) the gradient of its sum is :func:`internal_force`. Without
    ``step``: :func:`strain_energy`.
    """
    if step is None:
        return strain_energy(rest_length, reference_strain, stiffness, x, q, tension_only,
                             kink_strain)
    return cosserat_compiled.step_potential(rest_length, reference_strain, stiffness, tau, x, q,
                                            tension_only, kink_strain, step)


def step_potential_numpy(
    # Model:
    rest_length: FloatArray, reference_strain: FloatArray, stiffness: FloatArray, tau: FloatArray,
    # State in:
    x: FloatArray, q: FloatArray,
    # Scalars:
    tension_only: bool, kink_strain: float,
    step: tuple[FloatArray, float],
) -> FloatArray:
    """:func:`step_potential` with a step, in NumPy (the compiled kernel's reference)."""
    reference, inv_h = step
    eps, _ = cosserat_compiled.strains_and_rates(rest_length, reference_strain, x, q,
                                                 np.zeros((len(rest_length), 12)))
    D = stiffness[:, 1:]
    bulk = 0.5 * rest_length * np.sum(D * (eps[:, 1:] ** 2 + (tau * inv_h)[:, None]
                                           * (eps[:, 1:] - reference[:, 1:]) ** 2), axis=1)
    psi = (eps[:, 3:] + reference_strain[:, 3:]) * rest_length[:, None]
    stop = rotation_stop(psi, rest_length, stiffness[:, 1])[0]
    return bulk + stop + tension.step_potential(eps[:, 0], reference[:, 0], inv_h, stiffness[:, 0],
                                                tau * stiffness[:, 0], rest_length, kink_strain,
                                                tension_only)


def strain_energy_numpy(
    # Model:
    rest_length: FloatArray, reference_strain: FloatArray, stiffness: FloatArray,
    # State in:
    x: FloatArray, q: FloatArray,
    # Scalars:
    tension_only: bool, kink_strain: float,
) -> FloatArray:
    """:func:`strain_energy` in NumPy."""
    psi, _, g = kinematics(x, q)
    eps = strains_from_kinematics(psi, g, rest_length, reference_strain)
    bulk = 0.5 * rest_length * np.sum(stiffness[:, 1:] * eps[:, 1:] ** 2, axis=1)
    stop = rotation_stop(psi, rest_length, stiffness[:, 1])[0]
    return bulk + stop + axial_energy(eps[:, 0], stiffness[:, 0], rest_length, kink_strain,
                                      tension_only)


def _reduced_force(psi: FloatArray, R_m: FloatArray, g: FloatArray, stress: FloatArray) -> FloatArray:
    """``B9^T [N; M]`` (n, 9) without forming B9 (§Internal force).

    ``[R_m N, P2 h - A M, P2^T h + A^T M]`` with ``h = N x g`` and ``A = T(psi)^-1``.
    """
    N, M = stress[:, :3], stress[:, 3:]
    beta = midpoint_coefficient(np.linalg.norm(psi, axis=1))[0]
    h = np.cross(N, g)
    beta_psi_h = beta[:, None] * np.cross(psi, h)
    A_M = dexp_inv_apply(psi, M)
    AT_M = A_M - np.cross(psi, M)  # A - A^T = hat(psi)
    return np.concatenate([np.einsum("nij,nj->ni", R_m, N), 0.5 * h + beta_psi_h - A_M,
                           0.5 * h - beta_psi_h + AT_M], axis=1)


def _stress_state(rest_length, reference_strain, stiffness, tau, x, q, velocity, tension_only,
                  kink_strain):
    """Kinematics ``(psi, R_m, g)``, the strains, the constitutive response (the stress with the
    rotation stop's moment, C52) and the chord-reduced velocity."""
    psi, R_m, g = kinematics(x, q)
    velocity9 = reduce_velocity(velocity)
    eps = strains_from_kinematics(psi, g, rest_length, reference_strain)
    eps_rate = strain_rates_from_kinematics(psi, R_m, g, velocity9, rest_length)
    stress, modulus, viscous = stress_resultants_and_moduli(stiffness, tau, eps, eps_rate,
                                                           tension_only, kink_strain)
    stress = stress.copy()
    stress[:, 3:] += rotation_stop(psi, rest_length, stiffness[:, 1])[1]   # (C52)
    return (psi, R_m, g), eps, (stress, modulus, viscous), velocity9


def internal_force(
    # Model:
    rest_length: FloatArray, reference_strain: FloatArray, stiffness: FloatArray, tau: FloatArray,
    # State in:
    x: FloatArray, q: FloatArray, velocity: FloatArray,
    # Scalars:
    tension_only: bool, kink_strain: float,
    step: tuple[FloatArray, float] | None = None,
) -> FloatArray:
    """Internal force ``f_int = Le B^T [N; M]`` of each element (§Internal force): (n, 12).

    Translational rows are global forces, rotational rows body-frame moments; with ``tau = 0`` it
    is the gradient of :func:`strain_energy` on the Lie algebra. With ``step = (eps_ref (n, 6),
    inv_h)`` the strain rates are an implicit step's, ``(eps - eps_ref) inv_h`` (C53), and the
    force is the gradient of :func:`step_potential`. Compiled: one loop over the elements from
    the node state to the force.
    """
    return cosserat_compiled.internal_force(rest_length, reference_strain, stiffness, tau, x, q,
                                            velocity, tension_only, kink_strain, step)


def internal_force_numpy(
    # Model:
    rest_length: FloatArray, reference_strain: FloatArray, stiffness: FloatArray, tau: FloatArray,
    # State in:
    x: FloatArray, q: FloatArray, velocity: FloatArray,
    # Scalars:
    tension_only: bool, kink_strain: float,
) -> FloatArray:
    """:func:`internal_force` in NumPy."""
    kinematics_, _, (stress, _, _), _ = _stress_state(
        rest_length, reference_strain, stiffness, tau, x, q, velocity, tension_only, kink_strain)
    return expand_vector(_reduced_force(*kinematics_, stress))


def internal_force_and_tangents(
    # Model:
    rest_length: FloatArray, reference_strain: FloatArray, stiffness: FloatArray, tau: FloatArray,
    # State in:
    x: FloatArray, q: FloatArray, velocity: FloatArray,
    # Scalars:
    tension_only: bool, kink_strain: float,
    step: tuple[FloatArray, float] | None = None,
    strain_shift: FloatArray | None = None,
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Internal force with its stiffness and damping tangents (§Tangent); ``step`` as in
    :func:`internal_force` (the damping tangent is then zero).

    Compiled: the force loop of :func:`internal_force` keeps the kinematics and the constitutive
    state, and the tangent loop assembles from them; :func:`internal_force_and_tangents_numpy`
    gives the same result in NumPy.

    Returns
    -------
    force : (n, 12)
        As :func:`internal_force`.
    stiffness_tangent : (n, 12, 12)
        ``K_T = d f_int / d q`` along ``x + eps dx``, ``R exp(eps hat(dtheta))`` at fixed
        velocity: ``Le B^T (D B + D_v d(B u)/dq) + Le (d B^T / d q) [N; M]``, where ``D``, ``D_v``
        are the moduli of :func:`stress_resultants_and_moduli`. Not symmetric in general.
    damping_tangent : (n, 12, 12)
        ``C_T = d f_int / d velocity = Le B^T D_v B``.
    """
    return cosserat_compiled.internal_force_and_tangents(
        rest_length, reference_strain, stiffness, tau, x, q, velocity, tension_only, kink_strain,
        step, strain_shift)


def internal_force_and_tangents_numpy(
    # Model:
    rest_length: FloatArray, reference_strain: FloatArray, stiffness: FloatArray, tau: FloatArray,
    # State in:
    x: FloatArray, q: FloatArray, velocity: FloatArray,
    # Scalars:
    tension_only: bool, kink_strain: float,
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """:func:`internal_force_and_tangents` in NumPy (no compilation)."""
    kinematics_, _, (stress, modulus, viscous_modulus), velocity9 = _stress_state(
        rest_length, reference_strain, stiffness, tau, x, q, velocity, tension_only, kink_strain)
    force = expand_vector(_reduced_force(*kinematics_, stress))
    return (force, *tangents(*kinematics_, stress, modulus, viscous_modulus, velocity9,
                             rest_length))
