"""Scene configuration: frozen, validated dataclasses, one per TOML section.

Every class checks its own values in ``__post_init__`` and raises :class:`SceneError` naming the
key, the value and what is allowed; :mod:`rodnet.scene` adds the section path in front of the key.
The keys and their meaning are the public contract of ``SCENE_FORMAT.md``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Literal

from rodnet.errors import SceneError

Vec3 = tuple[float, float, float]


MODEL_TYPES: dict[str, str] = {"cosserat": "bdf2", "lumped": "explicit",
                               "kirchhoff": "explicit"}
"""Every ``model.type`` and the integrator a scene of that type runs with when it names none.
The model registry (:mod:`rodnet.models.registry`) enters every model it knows here."""

INTEGRATORS: list[str] = ["bdf2", "generalized-alpha", "backward-euler", "midpoint", "explicit",
                          "rk45"]
"""Every ``simulation.integrator`` (the run module enters every integrator it has)."""


def require(ok: bool, key: str, value: Any, allowed: str) -> None:
    """Raise :class:`SceneError` for ``key`` unless ``ok``."""
    if not ok:
        raise SceneError(key, value, allowed)


def _positive(obj: Any, *keys: str) -> None:
    for key in keys:
        value = getattr(obj, key)
        if value is not None:
            require(math.isfinite(value) and value > 0, key, value, "must be a finite number > 0")


MATERIAL_LIMITS = {"density": 1e6, "youngs_modulus": 1e15, "diameter": 1e3,
                   "shear_modulus": 1e15, "viscosity": 1e15, "axial_stiffness": 1e20,
                   "shear_stiffness": 1e20, "bending_stiffness": 1e20, "torsional_stiffness": 1e20,
                   "mass_per_length": 1e6, "rotary_inertia_per_length": 1e6}
"""The largest value of each material key, orders of magnitude above any real thread or rod
(osmium 2.3e4 kg/m^3, diamond 1.2e12 Pa): far beyond them the section's properties and the
stability limit leave the floating-point range (an outside check's diameter of 1e150 m made
every node's mass infinite)."""


def _at_most(obj: Any, limits: dict[str, float]) -> None:
    for key, limit in limits.items():
        value = getattr(obj, key)
        if value is not None:
            require(value <= limit, key, value, f"must be at most {limit:g}: far beyond any "
                    "material, and beyond what the section's properties can hold in floating "
                    "point (a unit written wrongly?)")


def _non_negative(obj: Any, *keys: str) -> None:
    for key in keys:
        value = getattr(obj, key)
        require(math.isfinite(value) and value >= 0, key, value, "must be a finite number >= 0")


def _principal_moments(values: tuple[float, ...]) -> list[float]:
    """Ascending eigenvalues of the symmetric 3 x 3 tensor given by 3 diagonal or 6 components
    [xx, yy, zz, xy, xz, yz]."""
    import numpy as np

    xx, yy, zz = values[:3]
    xy, xz, yz = values[3:] if len(values) == 6 else (0.0, 0.0, 0.0)
    tensor = np.array([[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]], dtype=float)
    return [float(m) for m in np.linalg.eigvalsh(tensor)]


def _finite_vector(obj: Any, *keys: str) -> None:
    for key in keys:
        value = getattr(obj, key)
        require(all(math.isfinite(c) for c in value), key, value, "must hold finite numbers")


@dataclass(frozen=True, slots=True, kw_only=True)
class SimulationSpec:
    """``[simulation]``: what kind of run and how it is stepped."""

    type: Literal["dynamic", "static"] = "dynamic"
    duration: float = 3.0
    dt: float = 1.0e-3
    adaptive: bool = True
    integrator: str | None = None
    rho_inf: float = 0.7
    gravity: Vec3 = (0.0, 0.0, 0.0)
    gravity_ramp: float = 0.0
    gravity_table: tuple[tuple[float, float], ...] | None = None
    load_steps: int = 10
    explicit_safety: float = 0.5
    rotary_inertia_scaling: bool = True
    rtol: float = 1.0e-6
    reuse_factorization: bool = False
    dt_max: float | None = None
    error_tolerance: float | None = None

    def __post_init__(self) -> None:
        _positive(self, "duration", "dt", "rtol", "dt_max", "error_tolerance")
        require(self.integrator is None or self.integrator in INTEGRATORS, "integrator",
                self.integrator, f"must be one of {INTEGRATORS}")
        require(0.0 <= self.rho_inf <= 1.0, "rho_inf", self.rho_inf, "must be in [0, 1]")
        require(self.load_steps >= 1, "load_steps", self.load_steps, "must be an integer >= 1")
        require(0.0 < self.explicit_safety <= 1.0, "explicit_safety", self.explicit_safety,
                "must be in (0, 1]: the fraction of the explicit stability limit used as step")
        require(self.rtol < 1.0, "rtol", self.rtol, "must be < 1 (a relative tolerance)")
        _finite_vector(self, "gravity")
        _non_negative(self, "gravity_ramp")
        if self.gravity_table is not None:
            _check_table(self.gravity_table, "gravity_table")
            require(self.gravity_ramp == 0.0, "gravity_ramp", self.gravity_ramp,
                    "must be 0 (unset) when gravity_table is given: give one or the other")

    @property
    def gravity_scheduled(self) -> bool:
        """Whether gravity has a time factor (a ramp or a table)."""
        return self.gravity_ramp > 0.0 or self.gravity_table is not None


SHEAR_CORRECTIONS = ("none", "residual-bending")
"""Values of ``model.shear_correction``: the rod element's shear stiffness as given, or lowered by
the residual bending flexibility of the element (FORMULATION.md, C44)."""


@dataclass(frozen=True, slots=True, kw_only=True)
class ModelSpec:
    """``[model]``: which mechanical model represents the threads."""

    type: str = "cosserat"
    elements_per_thread: int = 4
    bending: bool = True
    torsion: bool = True
    axial: Literal["tension-only", "linear"] = "tension-only"
    knots: Literal["rigid", "pinned"] = "rigid"
    kink_strain: float = 1.0e-6
    shear_correction: Literal["none", "residual-bending"] = "none"

    def __post_init__(self) -> None:
        require(self.type in MODEL_TYPES, "type", self.type, f"must be one of {list(MODEL_TYPES)}")
        require(self.elements_per_thread >= 1, "elements_per_thread", self.elements_per_thread,
                "must be an integer >= 1")
        require(self.shear_correction in SHEAR_CORRECTIONS, "shear_correction",
                self.shear_correction, f"must be one of {list(SHEAR_CORRECTIONS)}")
        require(0.0 <= self.kink_strain < 1e-2, "kink_strain", self.kink_strain,
                "must be in [0, 0.01): the strain over which the tension-only law is smoothed")


@dataclass(frozen=True, slots=True, kw_only=True)
class MaterialSpec:
    """``[[materials]]``: a thread or rod material and its (optionally overridden) section."""

    name: str
    density: float
    youngs_modulus: float
    diameter: float
    poisson_ratio: float | None = None
    shear_modulus: float | None = None
    viscosity: float = 0.0
    axial_stiffness: float | None = None
    shear_stiffness: float | None = None
    bending_stiffness: float | None = None
    torsional_stiffness: float | None = None
    mass_per_length: float | None = None
    rotary_inertia_per_length: float | None = None

    def __post_init__(self) -> None:
        _positive(self, "density", "youngs_modulus", "diameter", "shear_modulus",
                  "axial_stiffness", "shear_stiffness", "bending_stiffness",
                  "torsional_stiffness", "mass_per_length", "rotary_inertia_per_length")
        _non_negative(self, "viscosity")
        _at_most(self, MATERIAL_LIMITS)
        require(self.diameter >= 1e-9, "diameter", self.diameter,
                "must be at least 1e-9 m (a unit written wrongly?)")
        require(self.name != "", "name", self.name, "must be a non-empty string")
        if self.poisson_ratio is not None:
            require(-1.0 < self.poisson_ratio < 0.5, "poisson_ratio", self.poisson_ratio,
                    "must be in (-1, 0.5)")
            require(self.shear_modulus is None, "shear_modulus", self.shear_modulus,
                    "give either poisson_ratio or shear_modulus, not both")

    @property
    def area(self) -> float:
        """Cross-section area A = pi d^2 / 4 [m^2] of the solid circular section."""
        return math.pi * self.diameter**2 / 4.0

    @property
    def second_moment(self) -> float:
        """Second moment of area I = pi d^4 / 64 [m^4] of the solid circular section."""
        return math.pi * self.diameter**4 / 64.0

    @property
    def shear_modulus_value(self) -> float:
        """G [Pa]: given, or E / (2 (1 + nu)); nu = 0.3 when neither is given."""
        if self.shear_modulus is not None:
            return self.shear_modulus
        nu = 0.3 if self.poisson_ratio is None else self.poisson_ratio
        return self.youngs_modulus / (2.0 * (1.0 + nu))

    @property
    def EA(self) -> float:
        """Axial stiffness [N]."""
        return self.axial_stiffness or self.youngs_modulus * self.area

    @property
    def GA(self) -> float:
        """Shear stiffness [N], with the circular-section shear factor 6(1+nu)/(7+6nu)."""
        if self.shear_stiffness is not None:
            return self.shear_stiffness
        nu = self.youngs_modulus / (2.0 * self.shear_modulus_value) - 1.0
        return 6.0 * (1.0 + nu) / (7.0 + 6.0 * nu) * self.shear_modulus_value * self.area

    @property
    def EI(self) -> float:
        """Bending stiffness [N m^2]."""
        return self.bending_stiffness or self.youngs_modulus * self.second_moment

    @property
    def GJ(self) -> float:
        """Torsional stiffness [N m^2] (J = 2 I for the solid circular section)."""
        return self.torsional_stiffness or self.shear_modulus_value * 2.0 * self.second_moment

    @property
    def rhoA(self) -> float:
        """Mass per length [kg/m]."""
        return self.mass_per_length or self.density * self.area

    @property
    def rhoI(self) -> float:
        """Rotary inertia per length about a bending axis, rho I [kg m]."""
        return self.rotary_inertia_per_length or self.density * self.second_moment

    @property
    def retardation_time(self) -> float:
        """Kelvin-Voigt retardation time tau = viscosity / E [s]: every section resultant gets a
        viscous part tau times its stiffness times the strain rate."""
        return self.viscosity / self.youngs_modulus

    @property
    def damping_coefficient(self) -> float:
        """Axial Kelvin-Voigt coefficient tau EA [N s] (= viscosity A for the solid section): a
        segment of rest length l0 has c = tau EA / l0."""
        return self.retardation_time * self.EA


@dataclass(frozen=True, slots=True, kw_only=True)
class NetSpec:
    """``[net]``: the square net, its packed initial state and the launch of its corner masses."""

    material: str
    layout: Literal["square"] = "square"
    nodes_per_side: int = 21
    mesh_length: float = 1.0
    center: Vec3 = (0.0, 0.0, 0.0)
    direction: Vec3 = (0.0, 0.0, 1.0)
    packing: float = 0.1
    knot_mass: float = 0.0
    corner_mass: float = 1.0
    corner_thread_length: float = 1.0
    launch_speed: float = 20.0
    launch_angle_deg: float = 45.0

    def __post_init__(self) -> None:
        require(self.nodes_per_side >= 2, "nodes_per_side", self.nodes_per_side,
                "must be an integer >= 2")
        _positive(self, "mesh_length", "corner_thread_length", "corner_mass")
        _non_negative(self, "knot_mass", "launch_speed")
        require(0.0 < self.packing <= 1.0, "packing", self.packing, "must be in (0, 1]")
        require(0.0 <= self.launch_angle_deg < 90.0, "launch_angle_deg", self.launch_angle_deg,
                "must be in [0, 90) degrees")
        _finite_vector(self, "center", "direction")
        require(math.hypot(*self.direction) > 1e-12, "direction", self.direction,
                "must be a non-zero vector")


@dataclass(frozen=True, slots=True, kw_only=True)
class RodSpec:
    """``[[rods]]``: a free-standing rod along a polyline."""

    name: str
    material: str
    points: tuple[Vec3, ...]
    elements: int = 10
    velocity: Vec3 = (0.0, 0.0, 0.0)
    angular_velocity: Vec3 = (0.0, 0.0, 0.0)
    rotation_center: Vec3 | None = None

    def __post_init__(self) -> None:
        require(self.name != "" and ":" not in self.name, "name", self.name,
                "must be a non-empty string without ':'")
        require(len(self.points) >= 2, "points", self.points,
                "needs at least two points (a rod of one node has no element)")
        require(all(abs(c) <= 1e9 for p in self.points for c in p), "points", self.points,
                "must lie within 1e9 m of the origin (a unit written wrongly?)")
        for a, b in zip(self.points[:-1], self.points[1:]):
            require(math.dist(a, b) > 0.0, "points", self.points,
                    "consecutive points must differ (zero-length segment)")
            require(math.dist(a, b) >= 1e-9, "points", self.points,
                    "consecutive points must be at least 1e-9 m apart (a unit written wrongly?)")
        for i, (a, b, c) in enumerate(zip(self.points[:-2], self.points[1:-1], self.points[2:])):
            u = [q - p for p, q in zip(a, b)]
            w = [q - p for p, q in zip(b, c)]
            cos = sum(x * y for x, y in zip(u, w)) / (math.hypot(*u) * math.hypot(*w))
            require(cos > -1.0 + 1e-12, "points", self.points,
                    f"the polyline turns straight back at point {i + 1}, so its two members "
                    "would lie on each other; give the turn a width (a hairpin as two bends)")
        require(self.elements >= len(self.points) - 1, "elements", self.elements,
                f"must be an integer >= {len(self.points) - 1} (one per polyline segment)")
        _finite_vector(self, "velocity", "angular_velocity")
        if self.rotation_center is not None:
            _finite_vector(self, "rotation_center")


SUPPORT_DOFS = ("x", "y", "z", "r1", "r2", "r3")


@dataclass(frozen=True, slots=True, kw_only=True)
class SupportSpec:
    """``[[supports]]``: a fixed node; ``dofs`` fixes a subset instead of ``fix``'s set.

    ``x, y, z``: global translations; ``r1, r2, r3``: rotations about the node's material axes
    (``r1`` about the rod axis d1: twist; ``r2``, ``r3``: bending).
    """

    node: str
    fix: Literal["clamp", "pin"] | None = None
    dofs: tuple[str, ...] | None = None

    def __post_init__(self) -> None:
        if self.dofs is not None:
            require(len(self.dofs) > 0 and all(d in SUPPORT_DOFS for d in self.dofs)
                    and len(set(self.dofs)) == len(self.dofs), "dofs", list(self.dofs),
                    f"must be a non-empty list of distinct names from {list(SUPPORT_DOFS)}")

    @property
    def clamped(self) -> bool:
        """Whether the support is a clamp: ``fix = "clamp"`` or, the default, no ``fix`` and no
        ``dofs``."""
        return self.dofs is None and self.fix != "pin"

    @property
    def fixed(self) -> tuple[str, ...]:
        """The fixed DOF names."""
        if self.dofs is not None:
            return self.dofs
        return SUPPORT_DOFS if self.clamped else SUPPORT_DOFS[:3]


@dataclass(frozen=True, slots=True, kw_only=True)
class LoadSpec:
    """``[[loads]]``: a dead force and moment on a node, times a factor of time: ramped from
    zero over ``ramp`` seconds, or a piecewise-linear ``table`` of ``[t, factor]`` rows; zero
    before ``start`` and from ``stop`` on."""

    node: str
    force: Vec3 = (0.0, 0.0, 0.0)
    moment: Vec3 = (0.0, 0.0, 0.0)
    ramp: float = 0.0
    table: tuple[tuple[float, float], ...] | None = None
    start: float = 0.0
    stop: float | None = None

    def __post_init__(self) -> None:
        _finite_vector(self, "force", "moment")
        _check_timing(self)


@dataclass(frozen=True, slots=True, kw_only=True)
class LineLoadSpec:
    """``[[line_loads]]``: a dead force per unit length along a rod or every thread of the
    net, lumped on the nodes (half of each element's share at each end), with the time factor
    of ``[[loads]]``."""

    on: str
    force_per_length: Vec3
    ramp: float = 0.0
    table: tuple[tuple[float, float], ...] | None = None
    start: float = 0.0
    stop: float | None = None

    def __post_init__(self) -> None:
        _finite_vector(self, "force_per_length")
        _check_timing(self)


def _check_timing(load: LoadSpec | LineLoadSpec) -> None:
    """The ``ramp``, ``table``, ``start`` and ``stop`` of a load."""
    _non_negative(load, "ramp", "start")
    if load.stop is not None:
        require(math.isfinite(load.stop) and load.stop > load.start, "stop", load.stop,
                f"must be a finite time > start ({load.start:g} s)")
    if load.table is not None:
        _check_table(load.table, "table")
        require(load.ramp == 0.0, "ramp", load.ramp,
                "must be 0 (unset) when the load has a table: give one or the other")


def _check_table(rows: tuple[tuple[float, float], ...], key: str) -> None:
    """A table of ``[t, factor]`` rows."""
    require(len(rows) >= 1 and all(len(r) == 2 and all(math.isfinite(c) for c in r)
                                   for r in rows), key, [list(r) for r in rows],
            "must be a non-empty list of [t, factor] pairs of finite numbers")
    require(all(rows[k][0] <= rows[k + 1][0] for k in range(len(rows) - 1))
            and all(r[0] >= 0.0 for r in rows), key, [list(r) for r in rows],
            "must have times >= 0 in non-decreasing order (a repeated time is a jump)")


@dataclass(frozen=True, slots=True, kw_only=True)
class MassSpec:
    """``[[masses]]``: a point mass added to a node, with that node's initial velocity."""

    node: str
    mass: float
    velocity: Vec3 | None = None

    def __post_init__(self) -> None:
        _positive(self, "mass")
        if self.velocity is not None:
            _finite_vector(self, "velocity")


@dataclass(frozen=True, slots=True, kw_only=True)
class BodySpec:
    """``[[bodies]]``: a rigid body the threads touch, free (6 DOF, the default) or fixed."""

    name: str
    shape: Literal["box", "cylinder", "sphere", "mesh"]
    size: Vec3 | None = None
    file: str | None = None
    mass: float | None = None
    density: float | None = None
    inertia: tuple[float, ...] | None = None
    position: Vec3 = (0.0, 0.0, 0.0)
    orientation_deg: Vec3 = (0.0, 0.0, 0.0)
    velocity: Vec3 = (0.0, 0.0, 0.0)
    angular_velocity_deg: Vec3 = (0.0, 0.0, 0.0)
    fixed: bool = False

    def __post_init__(self) -> None:
        require(self.name != "" and ":" not in self.name, "name", self.name,
                "must be a non-empty string without ':'")
        if self.shape == "mesh":
            require(self.file is not None and self.file != "", "file", self.file,
                    'is required for shape = "mesh": a triangle mesh file (STL, OBJ, PLY ...), '
                    "relative to the scene file")
            require(self.size is None, "size", self.size,
                    'must not be given for shape = "mesh": the file gives the size')
        else:
            require(self.file is None, "file", self.file,
                    f'is only read for shape = "mesh", not "{self.shape}"')
            self._check_size()
        _positive(self, "mass", "density")
        require(self.mass is None or self.density is None, "density", self.density,
                "give either mass or density, not both")
        _finite_vector(self, "position", "orientation_deg", "velocity", "angular_velocity_deg")
        if self.inertia is not None:
            self._check_inertia()
        if self.fixed:
            require(not any(self.velocity), "velocity", self.velocity,
                    "must be [0, 0, 0] for a fixed body")
            require(not any(self.angular_velocity_deg), "angular_velocity_deg",
                    self.angular_velocity_deg, "must be [0, 0, 0] for a fixed body")
        else:
            require(self.mass is not None or self.density is not None, "mass", self.mass,
                    "a free body (fixed = false) needs its mass: give mass [kg] > 0 or "
                    "density [kg/m^3] > 0, or set fixed = true")

    def _check_inertia(self) -> None:
        """``inertia``: 3 principal moments along the body axes, or the 6 components
        [Ixx, Iyy, Izz, Ixy, Ixz, Iyz] of the tensor about the centre of mass [kg m^2]; positive
        definite and a possible mass distribution (each principal moment at most the sum of the
        other two)."""
        values = self.inertia
        assert values is not None
        require(len(values) in (3, 6), "inertia", list(values),
                "must be [Ixx, Iyy, Izz] (principal moments along the body axes) or "
                "[Ixx, Iyy, Izz, Ixy, Ixz, Iyz] [kg m^2], about the centre of mass")
        require(self.mass is not None or self.density is not None, "inertia", list(values),
                "needs the body's mass too: give mass or density")
        require(all(v > 0.0 for v in values[:3]), "inertia", list(values),
                "the moments of inertia Ixx, Iyy, Izz must be > 0 [kg m^2]")
        moments = _principal_moments(values)
        require(moments[0] > 1e-12 * moments[2], "inertia", list(values),
                "must be positive definite: its principal moments are "
                f"{[float(f'{m:.6g}') for m in moments]} kg m^2")
        require(moments[2] <= (moments[0] + moments[1]) * (1.0 + 1e-9), "inertia", list(values),
                "is not the inertia of any mass distribution: the largest principal moment "
                f"{moments[2]:.6g} exceeds the sum of the other two "
                f"({moments[0]:.6g} + {moments[1]:.6g}) kg m^2")

    def _check_size(self) -> None:
        size = self.size
        require(size is not None, "size", size, f'is required for shape = "{self.shape}": '
                "box [length_x, length_y, length_z], cylinder [diameter, diameter, length], "
                "sphere [diameter, diameter, diameter], in metres")
        assert size is not None
        require(all(math.isfinite(v) and v > 0.0 for v in size), "size", size,
                "must hold three finite lengths > 0 [m]")
        if self.shape == "cylinder":
            require(size[0] == size[1], "size", size,
                    "a cylinder is [diameter, diameter, length] (axis along the body z axis)")
        elif self.shape == "sphere":
            require(size[0] == size[1] == size[2], "size", size,
                    "a sphere is [diameter, diameter, diameter]")


@dataclass(frozen=True, slots=True, kw_only=True)
class ContactSpec:
    """``[contact]``: the penalty contact law between thread points and bodies."""

    stiffness: float = 1.0e5
    damping: float = 0.0
    friction: float = 0.3
    smoothing: float | None = None
    """Not set: :data:`SMOOTHING` [m], or :data:`SMOOTHING_RADIUS` of the thinnest thread's
    radius where that is smaller (:meth:`smoothing_for`)."""
    slip_velocity: float = 1.0e-3
    points_per_segment: int = 2

    def __post_init__(self) -> None:
        _positive(self, "stiffness", "slip_velocity")
        _non_negative(self, "damping", "friction")
        if self.smoothing is not None:
            _non_negative(self, "smoothing")
        require(1 <= self.points_per_segment <= 64, "points_per_segment", self.points_per_segment,
                "must be an integer in 1 .. 64")

    def smoothing_for(self, radius: float) -> float:
        """The blend's half-width [m] for threads whose thinnest radius is ``radius`` [m]."""
        if self.smoothing is not None:
            return self.smoothing
        return min(SMOOTHING, SMOOTHING_RADIUS * radius)


SMOOTHING = 1.0e-6
"""The default ``contact.smoothing`` [m] of threads of 0.2 mm and thicker."""

SMOOTHING_RADIUS = 0.01
"""The default ``contact.smoothing`` of thinner threads, as a fraction of the thinnest radius: a
fixed 1e-6 m held a thread of 1 um radius 0.8 um above a box it rested on (outside check), where
its twin 1,000 times larger sank m g / k into it."""


def toml_key(field_name: str) -> str:
    """The TOML name of a field: the field's, without the trailing underscore that escapes a
    Python keyword (``from_`` is ``from``)."""
    return field_name.rstrip("_")


@dataclass(frozen=True, slots=True, kw_only=True)
class InitialSpec:
    """``[initial]``: the initial state beyond what the net and rods set: a saved state of an
    earlier run (``from``), and node velocities."""

    from_: str | None = None
    frame: int = -1
    time: float | None = None
    velocities: tuple[tuple[str, float, float, float], ...] = ()

    def __post_init__(self) -> None:
        for i, (node, *v) in enumerate(self.velocities):
            require(all(math.isfinite(c) for c in v), f"velocities[{i}]", [node, *v],
                    "must be [node, vx, vy, vz] with finite numbers")
        if self.from_ is None:
            require(self.frame == -1 and self.time is None, "frame" if self.time is None
                    else "time", self.time if self.time is not None else self.frame,
                    "needs initial.from (the folder of the run to start from)")
        else:
            require(not self.velocities, "velocities", [list(v) for v in self.velocities],
                    "must be unset with initial.from (the saved frame gives every velocity)")
        if self.time is not None:
            _non_negative(self, "time")
            require(self.frame == -1, "frame", self.frame, "must be unset when time is given")


@dataclass(frozen=True, slots=True, kw_only=True)
class OutputSpec:
    """``[output]``: where results go and which ones are written."""

    directory: str = "out"
    frame_interval: float = 0.01
    vtk: bool = True
    picture: bool = False
    plot: bool = False

    def __post_init__(self) -> None:
        _positive(self, "frame_interval")
        require(self.directory != "", "directory", self.directory, "must be a non-empty path")


@dataclass(frozen=True, slots=True, kw_only=True)
class Scene:
    """A whole scene: everything a run needs."""

    simulation: SimulationSpec = field(default_factory=SimulationSpec)
    model: ModelSpec = field(default_factory=ModelSpec)
    materials: tuple[MaterialSpec, ...] = ()
    net: NetSpec | None = None
    rods: tuple[RodSpec, ...] = ()
    supports: tuple[SupportSpec, ...] = ()
    loads: tuple[LoadSpec, ...] = ()
    line_loads: tuple[LineLoadSpec, ...] = ()
    masses: tuple[MassSpec, ...] = ()
    bodies: tuple[BodySpec, ...] = ()
    contact: ContactSpec | None = None
    initial: InitialSpec | None = None
    output: OutputSpec = field(default_factory=OutputSpec)
    source: str = "<scene>"

    def __post_init__(self) -> None:
        names = [m.name for m in self.materials]
        for i, name in enumerate(names):
            require(names.index(name) == i, f"materials[{i}].name", name, "must be unique")
        used = ([("net.material", self.net.material)] if self.net else []) + [
            (f"rods[{i}].material", r.material) for i, r in enumerate(self.rods)]
        for key, name in used:
            require(name in names, key, name, f"must name a material defined in [[materials]]: {names}")
        rod_names = [r.name for r in self.rods]
        for i, name in enumerate(rod_names):
            require(rod_names.index(name) == i and name != "net", f"rods[{i}].name", name,
                    "must be unique and not 'net'")
        require(self.net is not None or len(self.rods) > 0, "net", None,
                "a scene needs a [net] or at least one [[rods]]")
        body_names = [b.name for b in self.bodies]
        for i, name in enumerate(body_names):
            require(body_names.index(name) == i, f"bodies[{i}].name", name, "must be unique")
        for i, line in enumerate(self.line_loads):
            require(line.on in rod_names or (line.on == "net" and self.net is not None),
                    f"line_loads[{i}].on", line.on,
                    (f"must name a rod {rod_names} or be \"net\" (with a [net])" if rod_names
                     else "must be \"net\": the scene has no [[rods]]"))
        if self.simulation.gravity_scheduled:
            key = "simulation.gravity_ramp" if self.simulation.gravity_table is None \
                else "simulation.gravity_table"
            value = self.simulation.gravity_ramp if self.simulation.gravity_table is None \
                else [list(r) for r in self.simulation.gravity_table]
            require(self.simulation.type == "dynamic", key, value,
                    "must be unset in a static run (simulation.load_steps raises gravity)")
            require(not self.bodies, key, value, "must be unset in a scene with [[bodies]] (the "
                    "bodies' weight has no time factor in this version)")
        if self.simulation.type == "static":
            timed = [(f"loads[{i}]", l) for i, l in enumerate(self.loads)] + \
                [(f"line_loads[{i}]", l) for i, l in enumerate(self.line_loads)]
            for name, load in timed:
                for key, unset in (("ramp", load.ramp == 0.0), ("start", load.start == 0.0),
                                   ("stop", load.stop is None), ("table", load.table is None)):
                    require(unset, f"{name}.{key}", getattr(load, key),
                            "must be unset in a static run (it has no time; simulation.load_steps "
                            "raises the loads)")

    @property
    def integrator(self) -> str:
        """The integrator in use: the scene's, or the model's default."""
        if self.simulation.integrator is not None:
            return self.simulation.integrator
        return MODEL_TYPES[self.model.type]

    def material(self, name: str) -> MaterialSpec:
        """The material called ``name``."""
        return next(m for m in self.materials if m.name == name)
