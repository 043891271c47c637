"""Build a :class:`~rodnet.models.cosserat.model.CosseratModel` from a scene's structure: rods
here, nets in :mod:`rodnet.models.cosserat.net` (triads and quaternion signs:
:mod:`rodnet.models.cosserat.geometry`)."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from rodnet.config import Scene
from rodnet.errors import SceneError
from rodnet.kernels import so3
from rodnet.kernels.cosserat_strain import reference_strains
from rodnet.models.cosserat.geometry import (corner_triads, oriented_ends,
                                             residual_bending_shear, support_dofs)
from rodnet.models.cosserat.model import CosseratModel
from rodnet.models.cosserat.net import build_cosserat_net
from rodnet.models.loads import constant_gravity, dead_loads
from rodnet.state import Configuration
from rodnet.topology import Structure

FloatArray = NDArray[np.float64]


def build_cosserat(scene: Scene, structure: Structure) -> tuple[CosseratModel, Configuration, FloatArray]:
    """The rod model, its initial configuration and initial velocities (n_dof,)."""
    if structure.net is not None and scene.rods:
        raise SceneError("rods", [r.name for r in scene.rods], "a Cosserat [net] scene cannot also "
                         "hold [[rods]] in this version")
    mats = scene.materials
    m_idx = structure.material
    bending, torsion = scene.model.bending, scene.model.torsion
    ea = np.array([m.EA for m in mats])[m_idx]
    ga = np.array([m.GA for m in mats])[m_idx]
    gj = np.array([m.GJ if torsion else 0.0 for m in mats])[m_idx]
    ei = np.array([m.EI if bending else 0.0 for m in mats])[m_idx]
    stiffness = np.column_stack([ea, ga, ga, gj, ei, ei])
    tau = np.array([m.retardation_time for m in mats])[m_idx]
    rho_a = np.array([m.rhoA for m in mats])[m_idx]
    rho_i = np.array([m.rhoI for m in mats])[m_idx]
    le = structure.rest_length
    if scene.model.shear_correction == "residual-bending":
        stiffness = residual_bending_shear(stiffness, le)
    if structure.net is not None:
        return build_cosserat_net(scene, structure, {"stiffness": stiffness, "tau": tau,
                                                     "rho_a": rho_a, "rho_i": rho_i})
    seg = structure.segments
    n = structure.n_nodes
    node_mass = structure.point_mass.copy()
    for end in (0, 1):
        np.add.at(node_mass, seg[:, end], 0.5 * rho_a * le)
    R0, offset_R = corner_triads(structure.rest_positions, seg, structure.thread)
    quat0, end_offset, ends0, rotary = oriented_ends(R0, seg, offset_R, le, rho_i)
    free = np.ones(6 * n, bool)
    for i, s in enumerate(scene.supports):
        node = structure.node(s.node, f"supports[{i}].node")
        free[support_dofs(s.fixed, node, node, n)] = False
    loads = dead_loads(scene, structure, node_mass)
    model = CosseratModel(
        pos_nodes=seg, rot_nodes=seg, rest_length=le,
        reference_strain=reference_strains(le, structure.rest_positions[seg], ends0),
        stiffness=stiffness, tau=tau, node_mass=node_mass, rotary_inertia=rotary, free=free,
        gravity=constant_gravity(scene), load_nodes=loads.nodes,
        load_force=loads.force, load_moment=loads.moment, load_schedule=loads.schedule,
        tension_only=scene.model.axial == "tension-only", kink_strain=scene.model.kink_strain,
        end_offset=end_offset, size=structure.size)
    v0 = np.zeros(6 * n)
    v0[:3 * n] = structure.velocities.ravel()
    # a rod's rigid rotation: its sections turn at omega too, R^T omega in their own frame
    R = so3.quat_to_matrix(quat0)
    for rod in scene.rods:
        nodes = [structure.selectors[f"{rod.name}:{k}"] for k in range(rod.elements + 1)]
        spin = np.einsum("nji,j->ni", R[nodes], np.asarray(rod.angular_velocity, float))
        v0[3 * n + 3 * np.array(nodes)[:, None] + np.arange(3)] = spin
    v0[~free] = 0.0
    return model, Configuration(structure.positions.copy(), quat0), v0
