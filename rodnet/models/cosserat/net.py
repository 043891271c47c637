"""A net of Cosserat threads: rotation nodes, element-end triads and masses of a square net.

Every thread is straight in the deployed layout, with the material triad ``d1`` along the thread,
``d2`` along the shooting direction (normal to the net) and ``d3 = d1 x d2``; its interior nodes
carry that triad. At a knot:

- ``knots = "rigid"``: one rotation node per knot, shared by the four threads, with the triad
  ``(u, w, d)`` of the net plane; each thread end sees it through a constant offset rotation
  (``end_offset``), so the knot transmits bending and torsion between threads;
- ``knots = "pinned"``: every thread end at the knot has its own rotation node (shared position
  only), so no moment passes from thread to thread, as in the lumped model.

The corner mass is a point mass with no rotary inertia; the corner thread's end there has its own
rotation node. The packed initial state is the deployed one scaled about the centre: every
thread keeps its direction, so bending, torsion and shear strains are exactly zero and the axial
strain is ``packing - 1 < 0``, which the tension-only law turns into zero force.

Initial spin of thread ends. A corner mass starts moving while its thread's other nodes are at
rest, so the chord of the element at the corner mass turns from the first instant. A thread end
with a rotation node of its own (at a corner mass, or at a pinned knot) starts with the angular
velocity that makes its element's initial shear and twist rates zero (:func:`end_spin`). Started at
rest instead, the end would be turned by the Kelvin-Voigt shear force acting on its tiny rotary
inertia (about 2e10 rad/s^2 in the reference deployment), a transient over the retardation time
that no step of a deployment resolves.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from rodnet.config import Scene
from rodnet.errors import SceneError
from rodnet.kernels.cosserat_strain import reference_strains, strain_matrix
from rodnet.models.cosserat.geometry import oriented_ends, support_dofs
from rodnet.models.cosserat.model import CosseratModel
from rodnet.models.loads import constant_gravity, dead_loads
from rodnet.state import Configuration
from rodnet.topology import Structure, in_plane_axes

FloatArray = NDArray[np.float64]


def build_cosserat_net(scene: Scene, structure: Structure, section: dict[str, FloatArray],
                       ) -> tuple[CosseratModel, Configuration, FloatArray]:
    """The net model, its packed initial configuration and initial velocities (n_dof,).

    ``section`` holds per-segment ``stiffness`` (E, 6), ``tau`` (E,), ``rho_a`` (E,), ``rho_i`` (E,).
    """
    net = structure.net
    assert net is not None
    seg, le = structure.segments, structure.rest_length
    n_nodes, n_seg = structure.n_nodes, len(seg)
    u, w, d = in_plane_axes(scene.net.direction)  # type: ignore[union-attr]
    chord = structure.rest_positions[seg[:, 1]] - structure.rest_positions[seg[:, 0]]
    d1 = chord / le[:, None]
    thread_R = np.stack([d1, np.broadcast_to(d, d1.shape), np.cross(d1, d)], axis=2)  # (E, 3, 3)

    knot_set = np.zeros(n_nodes, bool)
    knot_set[net.knots] = True
    rigid = scene.model.knots == "rigid"
    rot_nodes = np.empty((n_seg, 2), np.int64)
    rot_R: list[FloatArray] = []
    node_rotation = np.full(n_nodes, -1, np.int64)
    if rigid:
        node_rotation[net.knots] = np.arange(len(net.knots))
        rot_R += [np.column_stack([u, w, d])] * len(net.knots)
    corner_set = np.zeros(n_nodes, bool)
    corner_set[net.corners] = True
    for e in range(n_seg):
        for end in (0, 1):
            node = seg[e, end]
            if rigid and knot_set[node]:        # the knot's shared rotation
                rot_nodes[e, end] = node_rotation[node]
            elif knot_set[node] or corner_set[node]:  # a thread end's own rotation
                rot_nodes[e, end] = len(rot_R)
                rot_R.append(thread_R[e])
            else:                               # a thread's interior node
                if node_rotation[node] < 0:
                    node_rotation[node] = len(rot_R)
                    rot_R.append(thread_R[e])
                rot_nodes[e, end] = node_rotation[node]
    R_nodes = np.array(rot_R)
    offset_R = np.einsum("enji,enjk->enik", R_nodes[rot_nodes], thread_R[:, None].repeat(2, axis=1))
    quat_nodes, end_offset, quat_ends, rotary = oriented_ends(R_nodes, rot_nodes, offset_R, le,
                                                              section["rho_i"])
    node_mass = structure.point_mass.copy()
    for end in (0, 1):
        np.add.at(node_mass, seg[:, end], 0.5 * section["rho_a"] * le)
    n_rot = len(R_nodes)
    free = np.ones(3 * (n_nodes + n_rot), bool)
    for i, s in enumerate(scene.supports):
        node = structure.node(s.node, f"supports[{i}].node")
        free[support_dofs(s.fixed, node, node_rotation[node], n_nodes)] = False
    loads = dead_loads(scene, structure, node_mass)
    load_nodes = loads.nodes
    for i, l in enumerate(scene.loads):
        if any(l.moment) and node_rotation[load_nodes[i]] < 0:
            raise SceneError(f"loads[{i}].moment", l.moment, "this node has no single rotation "
                             "(a pinned knot or a corner mass): apply moments to rigid knots or thread nodes")
    model = CosseratModel(
        pos_nodes=seg, rot_nodes=rot_nodes, rest_length=le,
        reference_strain=reference_strains(le, structure.rest_positions[seg], quat_ends),
        stiffness=section["stiffness"], tau=section["tau"], node_mass=node_mass,
        rotary_inertia=rotary, free=free, gravity=constant_gravity(scene),
        load_nodes=load_nodes, load_force=loads.force, load_moment=loads.moment,
        load_schedule=loads.schedule,
        tension_only=scene.model.axial == "tension-only", kink_strain=scene.model.kink_strain,
        load_rot_nodes=np.maximum(node_rotation[load_nodes], 0), end_offset=end_offset,
        size=structure.size)
    v0 = np.zeros(model.n_dof)
    v0[:3 * n_nodes] = structure.velocities.ravel()
    v0[3 * n_nodes:] = end_spin(n_rot, rot_nodes, offset_R, le, structure.positions[seg],
                                quat_ends, v0[:3 * n_nodes].reshape(-1, 3)[seg]).ravel()
    v0[~free] = 0.0
    return model, Configuration(structure.positions.copy(), quat_nodes), v0


def end_spin(n_rot: int, rot_nodes: NDArray[np.int64], offset_R: FloatArray,
             rest_length: FloatArray, x: FloatArray, quat_ends: FloatArray,
             velocity: FloatArray) -> FloatArray:
    """Body angular velocities of the rotation nodes (R, 3) [rad/s]: zero, except at element
    ends whose rotation node is their own, which get the smallest spin that makes the element's
    shear and twist rates (C21) zero, given the translational velocities.

    Parameters
    ----------
    n_rot : int
        Number of rotation nodes R.
    rot_nodes : (E, 2) int
        Rotation node of each element end.
    offset_R : (E, 2, 3, 3) float
        ``Q`` of each end, ``R_end = R_node Q``.
    rest_length : (E,) float
    x : (E, 2, 3) float, quat_ends : (E, 2, 4) float
        End positions [m] and material quaternions of the initial state.
    velocity : (E, 2, 3) float
        End velocities [m/s].
    """
    spin = np.zeros((n_rot, 3))
    own = np.bincount(rot_nodes.ravel(), minlength=n_rot)[rot_nodes] == 1     # (E, 2)
    B = strain_matrix(rest_length, x, quat_ends)[:, 1:4]      # shear 2, shear 3, twist rows
    rate = np.einsum("eij,ej->ei", B[:, :, [0, 1, 2, 6, 7, 8]], velocity.reshape(-1, 6))
    for e in np.flatnonzero(own.any(axis=1) & (np.abs(rate).max(axis=1) > 0.0)):
        ends = np.flatnonzero(own[e])
        columns = np.concatenate([np.arange(3, 6) + 6 * end for end in ends])
        w = -np.linalg.lstsq(B[e][:, columns], rate[e], rcond=None)[0].reshape(-1, 3)
        for end, w_end in zip(ends, w):     # W_end = Q^T W_node
            spin[rot_nodes[e, end]] = offset_R[e, end] @ w_end
    return spin
