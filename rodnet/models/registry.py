"""Which thread models there are, what each supports, and how a scene becomes a system.

:data:`MODELS` maps every model (a ``model.type``, and for Cosserat threads whether they bend or
twist) to its builder and to the table of what it supports. That table is the only place such
rules live: :func:`refusal` reads it to refuse a scene naming the key, and the scene reference
(``docs/make_scene_reference.py``) prints it. :func:`build` composes the thread model with the
contact term of a scene with bodies into the :class:`~rodnet.models.system.ThreadSystem` that the
integrators advance, and chooses the explicit loop's step control.

Adding a thread model: write its module (a builder returning the model, its configuration and
velocities; the model with the :class:`~rodnet.models.system.ThreadModel` methods) and
:func:`register` a :class:`ModelType` for it; ``docs/developing.md`` walks through it.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Callable

import numpy as np
from numpy.typing import NDArray

from rodnet import config
from rodnet.config import Scene
from rodnet.contact.bodies import build_body_contact
from rodnet.contact.term import ContactTerm
from rodnet.errors import SceneError
from rodnet.kernels.explicit import StepControl
from rodnet.models.cosserat.build import build_cosserat
from rodnet.models.cosserat.explicit import rod_explicit_plan
from rodnet.models.kirchhoff import build_kirchhoff
from rodnet.models.lumped import build_lumped, lumped_explicit_plan
from rodnet.models.system import ThreadSystem
from rodnet.state import State
from rodnet.topology import Structure, build_structure

IMPLICIT = ("bdf2", "generalized-alpha", "backward-euler", "midpoint")
"""The implicit integrators."""

MIN_STEP_FRACTION = 1e-6
"""An explicit run ends when a travel-limited step (E3) falls below this fraction of its step."""


@dataclass(frozen=True)
class Supports:
    """What a model runs.

    Attributes
    ----------
    integrators : tuple of str
        The integrators of its dynamic runs.
    static : bool
        Whether it runs static equilibria.
    fixed_bodies, free_bodies : tuple of str
        The integrators that take fixed (free) rigid bodies.
    knots : tuple of str
        The ``model.knots`` it takes in a net.
    why : dict
        Why a rule is there, by rule name (``integrators``, ``static``, ``knots``), for messages.
    """

    integrators: tuple[str, ...]
    static: bool
    fixed_bodies: tuple[str, ...]
    free_bodies: tuple[str, ...]
    knots: tuple[str, ...] = ("rigid", "pinned")
    why: dict[str, str] = field(default_factory=dict)


@dataclass(frozen=True)
class ModelType:
    """One entry of the model table.

    Attributes
    ----------
    label : str
        What messages and docs call it (plural: "Kirchhoff threads").
    build : callable
        ``build(scene, structure) -> (model, configuration, velocities)``.
    explicit_plan : callable
        ``explicit_plan(model, v0, dt, adaptive, safety, scale_rotary_inertia) -> (model, v0,
        StepControl)``: the model the explicit loop runs, its start velocities and step control.
    supports : Supports
    stable_step : callable, optional
        ``stable_step(model) -> float``: the explicit limit [s] reported for any run of it.
    advice : str
        What to use instead, appended to a refusal.
    """

    label: str
    build: Callable[[Scene, Structure], tuple[Any, Any, NDArray[np.float64]]]
    explicit_plan: Callable[..., tuple[Any, NDArray[np.float64], StepControl]]
    supports: Supports
    stable_step: Callable[[Any], float] | None = None
    advice: str = ""
    unused: tuple[str, ...] = ()
    """Scene keys the model does not read (left out of ``summary.json``)."""


ALL = (*IMPLICIT, "explicit", "rk45")
ROTATION_KEYS = ("model.bending", "model.torsion", "model.knots", "model.shear_correction",
                 "simulation.rotary_inertia_scaling")
"""Keys that only rod elements with rotations read."""
MODELS: dict[str, ModelType] = {
    "lumped": ModelType(
        "the lumped model", build_lumped, lumped_explicit_plan,
        Supports(ALL, True, (*IMPLICIT, "explicit"), (*IMPLICIT, "explicit")),
        stable_step=lambda m: m.stable_step(), unused=ROTATION_KEYS),
    "cable": ModelType(   # bending = torsion = false select it: they stay in the record
        "cable threads", build_lumped, lumped_explicit_plan,
        Supports(ALL, True, (*IMPLICIT, "explicit"), (*IMPLICIT, "explicit")),
        stable_step=lambda m: m.stable_step(),
        unused=tuple(k for k in ROTATION_KEYS if k not in ("model.bending", "model.torsion"))),
    "rods": ModelType(
        "Cosserat rods", build_cosserat, rod_explicit_plan,
        Supports((*IMPLICIT, "explicit"), True, (*IMPLICIT, "explicit"), (*IMPLICIT, "explicit"),
                 why={"integrators": "RK45 integrates no rotations"})),
    "kirchhoff": ModelType(
        "Kirchhoff threads", build_kirchhoff, lumped_explicit_plan,
        Supports(("explicit", "rk45"), False, ("explicit",), ("explicit",), knots=("pinned",),
                 why={"integrators": "the hinges have no tangent for implicit steps",
                      "static": "the hinges have no tangent for the static solver",
                      "knots": "a hinge joins segments of one thread, so the knots pass no "
                               "moment"}),
        stable_step=lambda m: m.stable_step(), advice="use model.type = 'cosserat' for it",
        unused=("model.torsion", "model.shear_correction", "simulation.rotary_inertia_scaling")),
}
"""The model table: variant name -> entry (see :func:`variant`)."""

TYPES: dict[str, Callable[[Scene], str]] = {
    "lumped": lambda scene: "lumped",
    "kirchhoff": lambda scene: "kirchhoff",
    "cosserat": lambda scene: "rods" if scene.model.bending or scene.model.torsion else "cable",
}
"""``model.type`` -> the variant of :data:`MODELS` a scene of that type runs."""


def register(model_type: str, entry: ModelType, default_integrator: str = "explicit",
             variant_of: Callable[[Scene], str] | None = None) -> None:
    """Make ``model.type = model_type`` a model: its entry, the integrator its scenes run with
    when they name none, and (optionally) how a scene picks one of several variants."""
    MODELS[model_type] = entry
    TYPES[model_type] = variant_of or (lambda scene: model_type)
    config.MODEL_TYPES[model_type] = default_integrator


def variant(scene: Scene) -> str:
    """The entry of :data:`MODELS` that runs ``scene``."""
    return TYPES[scene.model.type](scene)


def _quoted(names: tuple[str, ...]) -> str:
    quoted = [repr(n) for n in names]
    return quoted[0] if len(quoted) == 1 else ", ".join(quoted[:-1]) + " or " + quoted[-1]


def refusal(scene: Scene) -> SceneError | None:
    """Why the model table refuses ``scene`` (the error to raise), or None."""
    entry = MODELS[variant(scene)]
    s, sim = entry.supports, scene.simulation
    dynamic, integrator = sim.type == "dynamic", scene.integrator
    advice = f"; {entry.advice}" if entry.advice else ""
    free = [i for i, b in enumerate(scene.bodies) if not b.fixed]
    if scene.bodies and dynamic and integrator not in s.fixed_bodies + s.free_bodies:
        return SceneError("simulation.integrator", integrator, f"{integrator} does not model "
                          f"contact; scenes with [[bodies]] need {_quoted(s.fixed_bodies)}")
    if free:
        which = f"bodies[{free[0]}] ('{scene.bodies[free[0]].name}') is free (fixed = false)"
        if not dynamic:
            return SceneError("simulation.type", "static", f"{which}: a static run needs every "
                              "body fixed; set fixed = true or run it with type = 'dynamic'")
        if integrator not in s.free_bodies:
            return SceneError("simulation.integrator", integrator,
                              f"{which}: free bodies move with the {_quoted(s.free_bodies)} "
                              f"integrator only; use integrator = {s.free_bodies[0]!r} or set "
                              "fixed = true on every body")
    if not dynamic and not s.static:
        why = f" ({s.why['static']})" if "static" in s.why else ""
        return SceneError("simulation.type", sim.type, f"{entry.label} run 'dynamic' only"
                          f"{why}{advice}")
    if dynamic and integrator not in s.integrators:
        why = f" ({s.why['integrators']})" if "integrators" in s.why else ""
        return SceneError("simulation.integrator", integrator, f"{entry.label} run with "
                          f"{_quoted(s.integrators)} only{why}{advice}")
    if scene.net is not None and scene.model.knots not in s.knots:
        why = f": {s.why['knots']}" if "knots" in s.why else ""
        default = scene.model.knots == config.ModelSpec().knots
        return SceneError("model.knots", scene.model.knots, ("(the default) " if default else "")
                          + f"{entry.label} need {_quoted(s.knots)} knots{why}{advice}")
    return None


@dataclass(frozen=True)
class Built:
    """A scene turned into a system and its initial state.

    Attributes
    ----------
    system : ThreadSystem
    state : State
    structure : Structure
    variant : str
        The entry of :data:`MODELS` that built it.
    stable_step : float or None
        The explicit stability limit [s] (explicit runs, and models that report one).
    rotary_inertia_scale : float or None
        Explicit rods: the largest factor by which (C49) raised a rotary inertia.
    """

    system: ThreadSystem
    state: State
    structure: Structure
    variant: str
    stable_step: float | None = None
    rotary_inertia_scale: float | None = None


def _contact(scene: Scene, structure: Structure, model: Any) -> ContactTerm | None:
    """The contact term of a scene with bodies, for the node masses of ``model``."""
    bodies = build_body_contact(scene, structure)
    if bodies is None:
        return None
    n = model.n_nodes
    free = model.free[:3 * n].reshape(-1, 3).any(axis=1)
    return ContactTerm(bodies, np.where(free, 1.0 / np.maximum(model.node_mass, 1e-300), 0.0))


def _explicit(entry: ModelType, scene: Scene, model: Any, v0: NDArray[np.float64],
              contact: ContactTerm | None) -> tuple[Any, NDArray[np.float64], StepControl]:
    """The explicit loop's model, start velocities and step control: the threads' step, and
    with bodies the step while one is within reach of a thread, with the contact springs (E1)."""
    sim = scene.simulation
    model, v0, control = entry.explicit_plan(model, v0, sim.dt, sim.adaptive, sim.explicit_safety,
                                             sim.rotary_inertia_scaling)
    near = control.dt
    if contact is not None:
        combined = contact.combined_step(control.stable_step)
        near = sim.explicit_safety * combined if sim.adaptive else min(control.dt, combined)
    return model, v0, control._replace(near_dt=min(near, control.dt),
                                       min_dt=MIN_STEP_FRACTION * control.dt)


def build(scene: Scene) -> Built:
    """The system, initial state and structure of ``scene``.

    Raises
    ------
    SceneError
        For a scene the model table refuses, or that its model cannot represent.
    """
    structure = build_structure(scene)
    name = variant(scene)
    entry = MODELS[name]
    refused = refusal(scene)
    if refused is not None:
        raise refused
    model, q0, v0 = entry.build(scene, structure)
    contact = _contact(scene, structure, model)
    control, stable, scale = None, None, None
    if scene.simulation.type == "dynamic" and scene.integrator == "explicit":
        rotations = model.rotation_dofs()
        inertia = model.dof_mass[rotations]
        model, v0, control = _explicit(entry, scene, model, v0, contact)
        stable = control.stable_step
        if len(rotations):  # the rotary inertia of (C49), when the model has rotations
            scale = float((model.dof_mass[rotations] / inertia).max())
    elif entry.stable_step is not None:
        stable = entry.stable_step(model)
    moving = scene.simulation.type == "dynamic" and scene.integrator in IMPLICIT
    system = ThreadSystem(model, contact, control, moving_bodies=moving)
    return Built(system, system.initial_state(q0, v0), structure, name, stable, scale)


def unused_keys(scene: Scene) -> tuple[str, ...]:
    """The scene keys that have no effect on the run of ``scene`` (left out of
    ``summary.json``): its model's, and ``rotary_inertia_scaling`` outside explicit runs."""
    unused = MODELS[variant(scene)].unused
    if scene.integrator != "explicit" and "simulation.rotary_inertia_scaling" not in unused:
        unused = (*unused, "simulation.rotary_inertia_scaling")
    return unused
