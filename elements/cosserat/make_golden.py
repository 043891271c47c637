"""Regenerate ``golden.json``: frozen random element states and the oracle's outputs.

Run ``python elements/cosserat/make_golden.py``. It is seeded, so a rerun reproduces the file
unless ``reference.py`` changed; tests check the file against the oracle.
"""

from __future__ import annotations

import dataclasses
import importlib.util
import json
import re
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
SEED = 20240611


def _load_reference():
    spec = importlib.util.spec_from_file_location("cosserat_reference", HERE / "reference.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    return module


ref = _load_reference()


def random_state(
    rng: np.random.Generator, target_strain: np.ndarray, with_velocities: bool
) -> dict:
    """A random deformed element whose strains (Gamma) equal ``target_strain`` exactly."""
    Le = float(rng.uniform(0.05, 0.2))
    q1 = rng.normal(size=4)
    q1 /= np.linalg.norm(q1)
    psi = rng.normal(size=3)
    psi *= rng.uniform(0.2, 1.5) / np.linalg.norm(psi)
    x1 = rng.normal(size=3)
    _, q2 = ref.retract_node(x1, q1, np.zeros(3), psi)
    R_m = ref.quat_to_matrix(q1) @ ref.so3_exp(0.5 * psi)
    chord = np.array([1.0, 0.0, 0.0]) + rng.uniform(-0.05, 0.05, size=3)
    x2 = x1 + Le * R_m @ chord
    Gamma_raw, K_raw = ref.stress_free_strains(x1, q1, x2, q2, Le)
    K0 = K_raw - rng.uniform(-2.0, 2.0, size=3)  # curved reference, deformed curvature
    velocities = None
    if with_velocities:
        velocities = np.concatenate([0.1 * rng.normal(size=3), rng.normal(size=3),
                                     0.1 * rng.normal(size=3), rng.normal(size=3)])
    return dict(
        x1=x1, q1=q1, x2=x2, q2=q2, Le=Le, Gamma0=Gamma_raw - target_strain, K0=K0,
        velocities=velocities,
    )


CASES = [
    ("taut, tension-only, damped", [0.02, 0.004, -0.003], True,
     dict(EA=1e3, GA2=4e2, GA3=3.5e2, GJ=2e-2, EI2=3e-2, EI3=2.5e-2, tau=2e-3)),
    ("slack, tension-only, damped", [-0.01, 0.002, 0.005], True,
     dict(EA=1e3, GA2=4e2, GA3=4e2, GJ=1e-2, EI2=2e-2, EI3=2e-2, tau=1e-3)),
    ("compressed, linear, damped", [-0.01, -0.003, 0.002], True,
     dict(EA=5e2, GA2=2e2, GA3=1.5e2, GJ=5e-3, EI2=8e-3, EI3=6e-3, tau=1e-3, axial="linear")),
    ("inside the ramp, tension-only, static", [0.02, 0.001, 0.001], False,
     dict(EA=1e3, GA2=4e2, GA3=4e2, GJ=1e-2, EI2=2e-2, EI3=2e-2, delta=0.05)),
]


def _jsonable(value):
    if isinstance(value, np.ndarray):
        return value.tolist()
    return value


def _compact_lists(text: str) -> str:
    """Put each innermost list of numbers (a vector, a matrix row) on one line."""
    return re.sub(r"\[\s+([-+0-9.eE,\s]+?)\s+\]",
                  lambda m: "[" + ", ".join(x.strip() for x in m.group(1).split(",")) + "]", text)


def main() -> None:
    rng = np.random.default_rng(SEED)
    cases = []
    for name, target, with_velocities, params in CASES:
        state = random_state(rng, np.array(target), with_velocities)
        section = ref.Section(**params)
        args = (state["x1"], state["q1"], state["x2"], state["q2"], state["Le"],
                state["Gamma0"], state["K0"])
        vel = state["velocities"]
        Gamma, K = ref.strains(*args)
        outputs = dict(
            Gamma=Gamma, K=K, energy=ref.energy(*args, section), B=ref.b_matrix(*args[:5]),
            internal_force=ref.internal_force(*args, section, vel),
            tangent_fd=ref.tangent_fd(*args, section, vel),
            damping_matrix=ref.damping_matrix(*args, section, vel),
        )
        cases.append(dict(
            name=name,
            inputs={k: _jsonable(v) for k, v in state.items()}
            | {"section": dataclasses.asdict(section)},
            outputs={k: _jsonable(v) for k, v in outputs.items()},
        ))
    data = dict(
        formulation="cosserat",
        generator="elements/cosserat/make_golden.py",
        seed=SEED,
        layout="DOF [dx1, dtheta1, dx2, dtheta2]; quaternions (w, x, y, z); "
        "velocities [v1, W1, v2, W2]",
        cases=cases,
    )
    (HERE / "golden.json").write_text(_compact_lists(json.dumps(data, indent=1)) + "\n")


if __name__ == "__main__":
    main()
