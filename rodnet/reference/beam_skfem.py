"""Linear beam and bar reference models on scikit-fem.

An independent check for rodnet's nonlinear rod element in the small-amplitude limit: natural
frequencies, Euler buckling loads, static deflections and longitudinal bar frequencies of a
straight, uniform, planar beam of length ``L`` meshed in its arc length ``s`` in ``[0, L]``.

Models
------
- Euler-Bernoulli: C1 Hermite cubics, DOFs per node ``(w, w')``.
- Timoshenko: independent quadratic (P2) deflection ``w`` and rotation ``theta``; shear strain
  ``w' - theta``. The shear term is integrated with a 2-point Gauss rule (selective reduced
  integration); the full 3-point rule locks for slender beams. Rotary inertia ``rhoI`` enters
  the mass matrix.
- Bar: P1 or P2 Lagrange elements for the axial displacement.

Supports at each end are ``"clamp"`` (deflection and rotation fixed), ``"pin"`` (deflection
fixed, rotation free) or ``"free"``. For the bar, ``"clamp"`` and ``"pin"`` both fix the axial
displacement. Units are SI throughout; ``GA`` is the effective shear stiffness (shear
correction factor included).

Eigenproblems are solved densely (meant for up to a few hundred elements). The Timoshenko
shear term acts as a penalty on slender beams: relative round-off in its results grows like
``1e-16 * GA L^2 / EI * n_elements^2``, so use the Euler-Bernoulli model when
``GA L^2 / EI`` exceeds about 1e6.
"""

from __future__ import annotations

from typing import Sequence

import numpy as np
import scipy.linalg
from scipy.sparse import csr_matrix
from skfem import (Basis, BilinearForm, ElementLineHermite, ElementLineP1, ElementLineP2,
                   LinearForm, MeshLine, condense, solve)
from skfem.helpers import d, dd

SUPPORTS = ("clamp", "pin", "free")
MODELS = ("euler-bernoulli", "timoshenko")

# scikit-fem DOF names fixed by each support; "u^1" is w and "u^2" is theta in the P2 x P2 pair.
_FIXED_DOFS = {
    "euler-bernoulli": {"clamp": ("u", "u_x"), "pin": ("u",), "free": ()},
    "timoshenko": {"clamp": ("u^1", "u^2"), "pin": ("u^1",), "free": ()},
    "bar": {"clamp": ("u",), "pin": ("u",), "free": ()},
}
_DEFLECTION_DOF = {"euler-bernoulli": "u", "timoshenko": "u^1"}


def _check_positive(**values: float | None) -> None:
    for name, value in values.items():
        if value is not None and not (np.isfinite(value) and value > 0):
            raise ValueError(f"{name} must be a positive finite number, got {value!r}")


def _check_options(supports: Sequence[str], n_elements: int, model: str = MODELS[0]) -> None:
    if len(supports) != 2 or any(s not in SUPPORTS for s in supports):
        raise ValueError(f"supports must be two of {SUPPORTS}, got {supports!r}")
    if not isinstance(n_elements, (int, np.integer)) or n_elements < 1:
        raise ValueError(f"n_elements must be a positive integer, got {n_elements!r}")
    if model not in MODELS:
        raise ValueError(f"model must be one of {MODELS}, got {model!r}")


def _check_restrained(supports: Sequence[str]) -> None:
    """Beam supports must stop rigid translation and rotation: one clamp or two pins."""
    if "clamp" not in supports and tuple(supports) != ("pin", "pin"):
        raise ValueError(f"supports {tuple(supports)!r} allow rigid-body motion; "
                         "use at least one 'clamp' or ('pin', 'pin')")


def _fixed_dofs(basis: Basis, length: float, supports: Sequence[str], kind: str) -> np.ndarray:
    """Global indices of the DOFs held at zero by the two end supports."""
    fixed = []
    for s_end, support in zip((0.0, length), supports):
        names = _FIXED_DOFS[kind][support]
        if names:
            end = basis.get_dofs(lambda x, s_end=s_end: np.isclose(x[0], s_end))
            fixed.extend(end.nodal[name] for name in names)
    return np.concatenate(fixed) if fixed else np.zeros(0, dtype=int)


def _beam_system(length: float, EI: float, rhoA: float, GA: float | None, rhoI: float,
                 n_elements: int, model: str):
    """Basis, stiffness K, mass M and unit-axial-load geometric stiffness K_G of a beam.

    K_G is the matrix of ``int w' v' ds``: a compressive axial force P adds ``-P K_G`` to K.
    """
    mesh = MeshLine(np.linspace(0.0, length, n_elements + 1))
    if model == "euler-bernoulli":
        basis = Basis(mesh, ElementLineHermite())
        K = BilinearForm(lambda u, v, _: EI * dd(u)[0, 0] * dd(v)[0, 0]).assemble(basis)
        M = BilinearForm(lambda u, v, _: rhoA * u * v).assemble(basis)
        KG = BilinearForm(lambda u, v, _: d(u)[0] * d(v)[0]).assemble(basis)
        return basis, K, M, KG
    element = ElementLineP2() * ElementLineP2()
    basis = Basis(mesh, element, intorder=4)  # 3-point Gauss: exact for products of P2
    reduced = Basis(mesh, element, intorder=2)  # 2-point Gauss for the shear term only
    bending = BilinearForm(lambda w, th, v, ph, _: EI * d(th)[0] * d(ph)[0])
    shear = BilinearForm(lambda w, th, v, ph, _: GA * (d(w)[0] - th) * (d(v)[0] - ph))
    mass = BilinearForm(lambda w, th, v, ph, _: rhoA * w * v + rhoI * th * ph)
    geometric = BilinearForm(lambda w, th, v, ph, _: d(w)[0] * d(v)[0])
    K = bending.assemble(basis) + shear.assemble(reduced)
    return basis, K, mass.assemble(basis), geometric.assemble(basis)


def _lowest_frequencies(K: csr_matrix, M: csr_matrix, free: np.ndarray, n_modes: int,
                        shift: float) -> np.ndarray:
    """Lowest ``n_modes`` frequencies [Hz] of K x = omega^2 M x on the free DOFs.

    Massless DOFs (Timoshenko rotations without rotary inertia) are condensed out exactly.
    The dense solve is of ``M x = mu (K + shift M) x`` for the largest mu, so that the lowest
    frequencies keep full relative precision on fine meshes and rigid-body modes (singular K)
    need no special case; ``shift`` [rad^2/s^2] should be of the order of the first omega^2.
    """
    Kf = K[free][:, free].toarray()
    Mf = M[free][:, free].toarray()
    massless = np.diag(Mf) == 0.0
    if massless.any():
        m, z = np.ix_(~massless, ~massless), np.ix_(massless, massless)
        coupling = Kf[np.ix_(~massless, massless)]
        Kf = Kf[m] - coupling @ np.linalg.solve(Kf[z], coupling.T)
        Mf = Mf[m]
    n = Kf.shape[0]
    if not 1 <= n_modes <= n:
        raise ValueError(f"n_modes must be between 1 and {n}, got {n_modes!r}")
    mu = scipy.linalg.eigh(Mf, Kf + shift * Mf, eigvals_only=True,
                           subset_by_index=[n - n_modes, n - 1])
    omega2 = np.sort(1.0 / mu - shift)
    return np.sqrt(np.clip(omega2, 0.0, None)) / (2.0 * np.pi)


def natural_frequencies(length: float, EI: float, rhoA: float, n_modes: int = 3,
                        supports: Sequence[str] = ("clamp", "free"), GA: float | None = None,
                        rhoI: float | None = None, n_elements: int = 64,
                        model: str = "euler-bernoulli") -> np.ndarray:
    """Lowest bending natural frequencies of a uniform beam.

    Parameters
    ----------
    length : float
        Beam length L [m].
    EI : float
        Bending stiffness [N m^2].
    rhoA : float
        Mass per unit length [kg/m].
    n_modes : int
        Number of frequencies returned.
    supports : (str, str)
        Supports at s = 0 and s = L, each ``"clamp"``, ``"pin"`` or ``"free"``.
    GA : float, optional
        Effective shear stiffness [N]; required for ``model="timoshenko"``, ignored otherwise.
    rhoI : float, optional
        Rotary inertia per unit length [kg m]; Timoshenko only, default 0.
    n_elements : int
        Number of elements.
    model : {"euler-bernoulli", "timoshenko"}
        Hermite cubic Euler-Bernoulli beam, or P2 x P2 Timoshenko beam with selective
        reduced integration of the shear term.

    Returns
    -------
    numpy.ndarray, shape (n_modes,)
        Frequencies [Hz] in ascending order; rigid-body modes of an unrestrained beam
        appear as (near-)zero values.
    """
    _check_options(supports, n_elements, model)
    _check_positive(length=length, EI=EI, rhoA=rhoA, GA=GA)
    if model == "timoshenko" and GA is None:
        raise ValueError("GA is required for model='timoshenko'")
    if rhoI is not None and rhoI < 0:
        raise ValueError(f"rhoI must be non-negative, got {rhoI!r}")
    basis, K, M, _ = _beam_system(length, EI, rhoA, GA, rhoI or 0.0, n_elements, model)
    free = basis.complement_dofs(_fixed_dofs(basis, length, supports, model))
    return _lowest_frequencies(K, M, free, n_modes, shift=EI / (rhoA * length**4))


def buckling_load(length: float, EI: float, supports: Sequence[str] = ("pin", "pin"),
                  GA: float | None = None, n_elements: int = 64) -> float:
    """Lowest critical compressive axial load of a uniform beam (linearised buckling).

    Solves ``(K - P K_G) x = 0`` for the smallest P, with ``K_G`` the geometric stiffness
    ``int w' v' ds`` of a unit compressive force. With ``GA`` the Timoshenko model is used and
    the pin-pin result is Engesser's ``P_E / (1 + P_E / GA)``.

    Parameters
    ----------
    length : float
        Beam length L [m].
    EI : float
        Bending stiffness [N m^2].
    supports : (str, str)
        Supports at s = 0 and s = L; must hold the beam (one ``"clamp"`` or two ``"pin"``).
    GA : float, optional
        Effective shear stiffness [N]; None gives the Euler-Bernoulli model.
    n_elements : int
        Number of elements.

    Returns
    -------
    float
        Critical load P [N] (compression positive).
    """
    _check_options(supports, n_elements)
    _check_restrained(supports)
    _check_positive(length=length, EI=EI, GA=GA)
    model = "euler-bernoulli" if GA is None else "timoshenko"
    basis, K, _, KG = _beam_system(length, EI, 1.0, GA, 0.0, n_elements, model)
    free = basis.complement_dofs(_fixed_dofs(basis, length, supports, model))
    Kf = K[free][:, free].toarray()
    KGf = KG[free][:, free].toarray()
    # K is positive definite on restrained beams while K_G is singular on the rotations of the
    # Timoshenko model, so solve K_G x = (1/P) K x for its largest eigenvalue 1/P.
    n = Kf.shape[0]
    inverse_load = scipy.linalg.eigh(KGf, Kf, eigvals_only=True, subset_by_index=[n - 1, n - 1])
    return float(1.0 / inverse_load[0])


def static_deflection(length: float, EI: float, supports: Sequence[str] = ("clamp", "free"),
                      tip_force: float = 0.0, distributed_load: float = 0.0,
                      n_elements: int = 64, GA: float | None = None) -> tuple[np.ndarray, float]:
    """Transverse deflection of a uniform beam under a tip force and a uniform load.

    Parameters
    ----------
    length : float
        Beam length L [m].
    EI : float
        Bending stiffness [N m^2].
    supports : (str, str)
        Supports at s = 0 and s = L; must hold the beam (one ``"clamp"`` or two ``"pin"``).
    tip_force : float
        Transverse point force at s = L [N], positive along +w.
    distributed_load : float
        Uniform transverse load q [N/m], positive along +w.
    n_elements : int
        Number of elements.
    GA : float, optional
        Effective shear stiffness [N]; None gives the Euler-Bernoulli model, otherwise
        Timoshenko (cantilever tip: ``P L^3 / (3 EI) + P L / GA``).

    Returns
    -------
    deflection : numpy.ndarray, shape (n_elements + 1,)
        Deflection w [m] at the nodes ``s = numpy.linspace(0, length, n_elements + 1)``.
    tip : float
        Deflection at s = L [m].
    """
    _check_options(supports, n_elements)
    _check_restrained(supports)
    _check_positive(length=length, EI=EI, GA=GA)
    model = "euler-bernoulli" if GA is None else "timoshenko"
    basis, K, _, _ = _beam_system(length, EI, 1.0, GA, 0.0, n_elements, model)
    name = _DEFLECTION_DOF[model]
    q = float(distributed_load)
    if model == "euler-bernoulli":
        f = LinearForm(lambda v, _: q * v).assemble(basis)
    else:
        f = LinearForm(lambda v, ph, _: q * v).assemble(basis)
    tip_dof = basis.get_dofs(lambda x: np.isclose(x[0], length)).nodal[name]
    f[tip_dof] += tip_force
    x = solve(*condense(K, f, D=_fixed_dofs(basis, length, supports, model)))
    # nodal_dofs[0] lists the deflection DOF of each mesh vertex in vertex (= s) order
    deflection = x[basis.nodal_dofs[0]]
    return deflection, float(x[tip_dof][0])


def axial_frequencies(length: float, EA: float, rhoA: float,
                      supports: Sequence[str] = ("clamp", "free"), n_modes: int = 3,
                      n_elements: int = 64, order: int = 2) -> np.ndarray:
    """Lowest longitudinal natural frequencies of a uniform bar.

    Parameters
    ----------
    length : float
        Bar length L [m].
    EA : float
        Axial stiffness [N].
    rhoA : float
        Mass per unit length [kg/m].
    supports : (str, str)
        Supports at s = 0 and s = L; ``"clamp"`` or ``"pin"`` fix the axial displacement,
        ``"free"`` leaves it free.
    n_modes : int
        Number of frequencies returned.
    n_elements : int
        Number of elements.
    order : {1, 2}
        Lagrange element order (P1 or P2).

    Returns
    -------
    numpy.ndarray, shape (n_modes,)
        Frequencies [Hz] in ascending order; a free-free bar starts with a zero mode.
    """
    _check_options(supports, n_elements)
    _check_positive(length=length, EA=EA, rhoA=rhoA)
    if order not in (1, 2):
        raise ValueError(f"order must be 1 or 2, got {order!r}")
    mesh = MeshLine(np.linspace(0.0, length, n_elements + 1))
    basis = Basis(mesh, ElementLineP1() if order == 1 else ElementLineP2())
    K = BilinearForm(lambda u, v, _: EA * d(u)[0] * d(v)[0]).assemble(basis)
    M = BilinearForm(lambda u, v, _: rhoA * u * v).assemble(basis)
    free = basis.complement_dofs(_fixed_dofs(basis, length, supports, "bar"))
    return _lowest_frequencies(K, M, free, n_modes, shift=EA / (rhoA * length**2))
