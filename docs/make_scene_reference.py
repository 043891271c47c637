"""Write ``docs/scene_reference.md`` from the scene dataclasses in :mod:`rodnet.config`.

Keys, types, defaults and section docstrings come from the code; the description and unit of
every key come from ``DESCRIPTIONS`` below. ``tests/test_docs.py`` regenerates the page in memory
and fails when the committed file differs, or when a key has no description.

Usage: ``python docs/make_scene_reference.py`` (from the repository root or anywhere else).
"""

from __future__ import annotations

import dataclasses
import inspect
import types
import typing
from pathlib import Path
from typing import Any, Literal

from rodnet import config

OUTPUT = Path(__file__).with_name("scene_reference.md")

# "section.key": (unit, description). Units are SI; "-" means dimensionless, "" not a quantity.
DESCRIPTIONS: dict[str, tuple[str, str]] = {
    # [simulation]
    "simulation.type": (
        "", '"dynamic": integrate in time. "static": the equilibrium under the loads, raised in '
        "`load_steps` equal increments of a load factor; one frame per load step, with the load "
        "factor as its `time`. Structures that only their load holds are solved (a slack cable "
        "between two pins, a net hung from its knots, a rod whose supports leave it free to "
        "twist, a rod or chain on one pin that must turn to its load); where the loads have a "
        "potential (forces and gravity; not moments or contact), an unstable equilibrium is "
        "left for a stable one where one is found, else reported in the summary's `warnings` "
        "(under moments it is not checked: a shaft past Greenhill's torque stays straight; a "
        "damped dynamic run tells); "
        "a static scene with a part that has no node with a supported position, or that no "
        "support of the part holds along one of the axes x, y, z, and no fixed body to rest on, "
        "is refused (no load holds it: it would drift along that axis). See "
        "[the rod model](rod_model.md#static-runs)."),
    "simulation.duration": ("s", "Simulated time of a dynamic run; > 0. Not used by static runs."),
    "simulation.dt": (
        "s", "> 0. Explicit integrator with `adaptive = false`: the step, shrunk so that a whole "
        "number of steps fits each frame interval; a `dt` above the explicit stability limit (S10) "
        "is refused. Implicit integrators: the first step (`adaptive = true`) or the fixed step "
        "(`adaptive = false`, shrunk, like the explicit one, so that a whole number of equal steps "
        "fits each interval between frames and the times where a load changes: a short last step "
        "before each frame cost generalized-alpha its second order, an outside check). Not used by the "
        "explicit integrator with `adaptive = true`, by `rk45` or by static runs."),
    "simulation.adaptive": (
        "", "Explicit integrator: `true` sets the step to `explicit_safety` times the stability "
        "limit (S10) of the scene, computed once before the run; `false` uses `dt`. Implicit "
        "integrators: `true` resizes every step from a local error estimate (see "
        "`error_tolerance`, which has a default) and halves a step whose Newton solve fails "
        "(200 iterations without convergence, no progress in 25, or its residual standing for "
        "50), up to `dt_max`; `false` "
        "keeps `dt`, Newton runs on while it makes progress (up to 1,000 iterations), and a step "
        "whose Newton solve fails ends the run. Not "
        "used by `rk45`, which controls its step with `rtol`."),
    "simulation.error_tolerance": (
        "m", "> 0. Implicit integrators with `adaptive = true`: the local error of the node "
        "positions a step may make, as the root-mean-square over the nodes of each node's "
        "estimated error (bdf2 `(1 + w)^2 / (6 w (1 + 2 w)) dt^2 |a1 - a0|` with `w` the step "
        "ratio, generalized-alpha `|beta - 1/6| dt^2 |a1 - a0|` (Zienkiewicz-Xie), midpoint "
        "`dt^2 |a1 - a0| / 12`, backward Euler `dt |v1 - v0| / 2`). A step above it is rejected; "
        "every step is resized by `0.9 (tolerance / error)^(1/(p+1))` (`p` the order), within "
        "0.2 to 2. Not set: 3e-5 times the size of the structure (the largest distance "
        "between two of its nodes at rest): 0.9 mm on the reference net, 30 um on a 1 m thread; "
        "of the structure's size, not of the motion, so vibrations much smaller than the "
        "structure need a smaller value (a fraction of their amplitude) or `dt_max` (rod model, "
        "Limits). Not used by `explicit`, `rk45` or fixed steps."),
    "simulation.integrator": (
        "", 'Not set: "explicit" for `model.type = "lumped"` and `"kirchhoff"`, "bdf2" '
        'otherwise (Kirchhoff threads run "explicit" or "rk45" only). '
        '"generalized-alpha": implicit, second order, numerical dissipation set by `rho_inf`; '
        "a step that raises the mechanical energy (a thread snapping taut or a penalty contact "
        "within one step) is taken again as backward Euler. "
        '"bdf2": implicit, second order, L-stable (variable-step BDF2; each step the '
        "minimisation of an incremental potential; a step that raises the mechanical energy is "
        "taken again as backward Euler, as for generalized-alpha). "
        '"backward-euler": implicit, first order, strongly dissipative. "midpoint": implicit, '
        "second order, conserves linear and angular momentum, no numerical dissipation. "
        '"explicit": symplectic '
        'Euler, compiled; with Cosserat rods on a raised rotary inertia (`rotary_inertia_scaling`). '
        '"rk45": scipy\'s adaptive Dormand-Prince, the reference, for the lumped model and cable '
        'threads (`model.type = "cosserat"` with `bending` and `torsion` both false) only. '
        "Static runs do not use it. See [the rod model](rod_model.md#integrators)."),
    "simulation.rho_inf": (
        "-", '"generalized-alpha": spectral radius at infinite frequency, in [0, 1]. 1 keeps the '
        "highest frequencies undamped (fragile on stiff rods), 0 removes them within a step; the "
        'default 0.7 damps the unresolved modes and keeps second order. Not used by the other '
        "integrators."),
    "simulation.gravity": (
        "m/s^2", "Uniform gravitational acceleration; node `i` gets the force `m_i g`. Static runs "
        "raise it with the load factor, as the `[[loads]]`: the frame of load factor 0.5 is "
        "the equilibrium under half the gravity and half the loads."),
    "simulation.gravity_ramp": (
        "s", ">= 0. Dynamic runs: gravity grows linearly from zero to full over this time (as "
        "`[[loads]] ramp`); 0: in full from t = 0. Not in static runs or with `[[bodies]]`."),
    "simulation.gravity_table": (
        "s, -", "Dynamic runs: gravity's factor over time as `[[t, factor], ...]` rows (as "
        "`[[loads]] table`); replaces `gravity_ramp`. Not in static runs or with `[[bodies]]`."),
    "simulation.load_steps": (
        "", "Static runs: number of equal load increments, >= 1; each saves one frame. An "
        "increment whose Newton solve fails is split in two, up to 6 times. The solution does not "
        "depend on it; more steps can cost fewer Newton iterations on strongly nonlinear problems."),
    "simulation.explicit_safety": (
        "-", "Explicit integrator with `adaptive = true`: the step is this fraction of the "
        "stability limit (S10) (Cosserat rods: C48), in (0, 1]. The limit is an estimate, not a "
        "bound; see [the lumped model](lumped_model.md#time-step). With Cosserat rods and "
        "`rotary_inertia_scaling`, the rotations also run at this fraction of their limit."),
    "simulation.rotary_inertia_scaling": (
        "", "Explicit integrator with Cosserat rods: `true` raises the rotary inertia of rotation "
        "nodes just enough that their rotations ring no faster than the translations the step "
        "resolves anyway (FORMULATION.md C49); the raise shrinks with the square of the step, so "
        "refined runs converge to the unscaled rods. `false`: the true rotary inertia, whose shear "
        "mode limits the step to about 1e-7 s for a 1 mm thread. The largest factor is reported as "
        "`integrator.rotary_inertia_scale` in summary.json. Not used by other integrators or models."),
    "simulation.rtol": (
        "-", "In (0, 1). `rk45`: relative tolerance of the nodes' displacements and "
        "velocities relative to a frame moving with their initial mean velocity from their "
        "start (so a run depends neither on where the origin lies nor on a uniform velocity); "
        "the absolute tolerance is `rtol` x 1e-3 (metres, m/s). Implicit integrators and static runs: "
        "Newton's residual tolerance is `min(rtol, 1e-6)` x 1e-2 times the force scale (the "
        "forces acting in the step, at least 1 % of the largest `EA`), plus 1e-10 N."),
    "simulation.dt_max": (
        "s", "> 0. Implicit integrators with `adaptive = true`: the largest step the adaptive "
        "control may grow to, the first step included (a value below `dt` shortens the first "
        "step to it). Not set: the larger of `dt` and `output.frame_interval`."),
    "simulation.reuse_factorization": (
        "-", "Implicit integrators and static runs: an iterate whose residual fell to 0.3 of the "
        "last one's, with no thread changed between slack and taut and no contact opened or "
        "closed, takes its Newton correction from the last factorisation instead of a new one. "
        "Off by default: measure first."),
    # [model]
    "model.type": (
        "", '"cosserat": geometrically exact rod elements with bending, torsion and shear '
        "([element](../elements/cosserat/FORMULATION.md), [rod model](rod_model.md)); with "
        '`bending` and `torsion` both false, cable threads. "lumped": point masses joined by '
        "spring-dampers ([formulation](../elements/spring/FORMULATION.md), "
        '[lumped model](lumped_model.md)). "kirchhoff": the lumped cable plus a bending hinge at '
        "every node inside a thread: shear-free threads with bending, no rotational unknowns, "
        "the cable's explicit step ([formulation](../elements/kirchhoff/FORMULATION.md), "
        "[Kirchhoff threads](kirchhoff.md)); straight threads, pinned knots, pin supports and "
        'integrators "explicit" or "rk45" only.'),
    "model.elements_per_thread": (
        "", "Elements (segments) per net thread (mesh threads and corner threads), >= 1. "
        "`[[rods]]` give their own count in `elements`."),
    "model.bending": (
        "", '`model.type = "cosserat"`: false sets the bending stiffness `EI` to zero. With '
        "`torsion` also false the threads are cables: translations only, the lumped model's "
        'equations. `model.type = "kirchhoff"`: false leaves out the hinges (the cable exactly). '
        "No effect on the lumped model."),
    "model.torsion": (
        "", '`model.type = "cosserat"`: false sets the torsional stiffness `GJ` to zero; see '
        "`bending`. No effect on the lumped model, nor on Kirchhoff threads, whose round "
        "threads between pinned knots carry no twist (K6)."),
    "model.axial": (
        "", '"tension-only": `N = max(0, EA r(e) + tau EA r\'(e) de/dt)`, `tau = viscosity / E`: '
        'a thread never pushes (S5). "linear": `N = EA e + tau EA de/dt`, also resists '
        "compression (S3); beams, columns and static runs need it. Both models."),
    "model.knots": (
        "", 'Cosserat net: "rigid": the threads meeting at a knot share its rotation, so the knot '
        'passes bending and torsion from thread to thread; "pinned": shared position only, no '
        "moment passes. No effect on `[[rods]]`, the lumped model or cable threads, where every "
        'knot is a pin. Kirchhoff threads need "pinned".'),
    "model.kink_strain": (
        "-", "Kink strain `delta` of the C1 ramp that smooths the tension-only law at `e = 0` "
        "(S4), in [0, 0.01); 0 gives the sharp kink. Above `delta` the force is `EA delta / 2` "
        "lower than the linear law's."),
    "model.shear_correction": (
        "", '`model.type = "cosserat"` rods and threads: "none" uses the section\'s `GA`. '
        '"residual-bending" uses `1 / (1/GA + Le^2 / (12 EI))` per bending plane (C44, MacNeal): '
        "one element is then exact for a straight beam under end loads (a cantilever deflects "
        "by `P L^3 / (3 EI) + P L / GA`, not `P L^3 / (4 EI) + P L / GA`); the same limit as the "
        "mesh is refined. An element so corrected keeps its triad on its chord only while its "
        "axial force stays below about `12 EI / Le^2` (C45; 0.17 N for a 1 mm Kevlar thread in "
        "0.5 m elements), so threads in tension stop pulling: keep \"none\" for nets. See "
        "[the rod model](rod_model.md#shear-correction). No effect on cables and the lumped model."),
    # [[materials]]
    "materials.name": (
        "", "Unique, non-empty; named by `net.material` and `rods.material`."),
    "materials.density": (
        "kg/m^3", "> 0. Mass per length `rho A` and rotary inertia per length `rho I` of the solid "
        "circular section, unless `mass_per_length` or `rotary_inertia_per_length` is given."),
    "materials.youngs_modulus": (
        "Pa", "`E` > 0. `EA = E A` and `EI = E I`, unless overridden; also sets the retardation "
        "time `tau = viscosity / E`."),
    "materials.diameter": (
        "m", "`d` >= 1e-9 of the solid circular section: `A = pi d^2 / 4`, `I = pi d^4 / 64`, "
        "`J = 2 I`."),
    "materials.poisson_ratio": (
        "-", "`nu` in (-1, 0.5): `G = E / (2 (1 + nu))`; give either this or `shear_modulus`. "
        "Cosserat rods only (`GA`, `GJ`); no effect on the lumped model and cable threads."),
    "materials.shear_modulus": (
        "Pa", "`G` > 0; give either this or `poisson_ratio` (neither: `nu = 0.3`). Cosserat rods "
        "only."),
    "materials.viscosity": (
        "Pa s", "Kelvin-Voigt viscosity >= 0. The retardation time `tau = viscosity / E` damps "
        "every section mode: each stress resultant gains `tau` x its stiffness x its strain rate. "
        "Axially, a segment of rest length `l0` has the dashpot `c = tau EA / l0` [N s/m] "
        "(`= viscosity A / l0` without an `axial_stiffness` override)."),
    "materials.axial_stiffness": (
        "N", "Override of `EA`, > 0 (braided threads). The axial damping follows it: `tau EA`."),
    "materials.shear_stiffness": (
        "N", "Override of `GA`, > 0, for both shear directions. Cosserat rods only."),
    "materials.bending_stiffness": (
        "N m^2", "Override of `EI`, > 0, about both bending axes. Cosserat rods only."),
    "materials.torsional_stiffness": ("N m^2", "Override of `GJ`, > 0. Cosserat rods only."),
    "materials.mass_per_length": ("kg/m", "Override of `rho A`, > 0. Both models."),
    "materials.rotary_inertia_per_length": (
        "kg m", "Override of `rho I`, the rotary inertia per length about a bending axis, > 0; "
        "about the rod axis it is `2 rho I`. Cosserat rods only."),
    # [net]
    "net.material": ("", "Name of a `[[materials]]` entry; required."),
    "net.layout": (
        "", '"square": `Ns` x `Ns` knots; knot `i` is joined to `i+1` (same row) and to `i+Ns`; '
        "four corner threads join the corner knots to the corner masses."),
    "net.nodes_per_side": ("", "`Ns`, knots per side, >= 2."),
    "net.mesh_length": ("m", "Rest length of one mesh thread, > 0."),
    "net.center": ("m", "Centre of the net, deployed and packed."),
    "net.direction": (
        "-", "Shooting direction, non-zero (normalised). The net starts in the plane normal to "
        "it, knot `i` to `i+1` along `u`, the global x axis projected on that plane (the y "
        "axis when `|direction_x| >= 0.9` of its length), and knot `i` to `i+Ns` along "
        "`direction x u`; mouth area and distance are measured with it."),
    "net.packing": (
        "-", "Initial size / deployed size, in (0, 1]. Every initial position is the flat "
        "deployed layout scaled by `packing` about `center`; every thread keeps its direction, "
        "so the threads start straight with axial strain `packing - 1`: slack and free of force "
        'with `axial = "tension-only"`, compressed with `"linear"`.'),
    "net.knot_mass": ("kg", "Point mass added at every knot, >= 0."),
    "net.corner_mass": ("kg", "Each of the four corner masses, > 0 (no rotary inertia)."),
    "net.corner_thread_length": (
        "m", "Rest length of the thread from a corner knot to its corner mass, > 0; the corner "
        "mass lies on the extension of the net's diagonal."),
    "net.launch_speed": (
        "m/s", "Initial speed of every corner mass, >= 0. Knots and thread nodes start at rest."),
    "net.launch_angle_deg": (
        "deg", "Angle between a corner mass's initial velocity and `direction`, tilted outwards "
        "along the net's diagonal, in [0, 90)."),
    # [[rods]]
    "rods.name": (
        "", 'Unique, non-empty, without ":", not "net". Names the nodes: `"NAME:start"`, '
        '`"NAME:end"`, `"NAME:i"`.'),
    "rods.material": ("", "Name of a `[[materials]]` entry; required."),
    "rods.points": (
        "m", "Polyline of the stress-free centreline, at least two points, consecutive points "
        "at least 1e-9 m apart, within 1e9 m of the origin, never turning straight back (its "
        "members would overlap). The rod starts in this shape, free of stress. A rod is open: a "
        "polyline back to its first point gives a split ring (two end nodes at one place, not "
        "joined; the run warns), and a closed ring cannot be posed."),
    "rods.elements": (
        "", "Elements along the whole rod, at least one per polyline segment; spread by arc "
        "length, every polyline vertex kept as a node."),
    "rods.velocity": ("m/s", "Initial velocity of every node of the rod (rotations start at rest "
                      "unless `angular_velocity` is set)."),
    "rods.angular_velocity": (
        "rad/s", "Initial rigid rotation of the whole rod about `rotation_center`, added to "
        "`velocity`: every node moves at `omega x (x - center)` and, with Cosserat rods, every "
        "section turns at `omega` too, so the rod starts without strain rate. Explicit runs "
        "with scaled rotary inertia (`simulation.rotary_inertia_scaling`) start each section "
        "with the angular momentum of its real inertia instead, `omega` times its `J / "
        "J_scaled` (down to 1 / `integrator.rotary_inertia_scale`; C49: a thread end spun at "
        "hundreds of rad/s must "
        "not become a flywheel), so they start with a small strain rate; for a rod turning "
        "rigidly, `rotary_inertia_scaling = false` or an implicit integrator keeps `omega`."),
    "rods.rotation_center": (
        "m", "The point the `angular_velocity` turns the rod about; not set: the mean of the "
        "rod's nodes."),
    # [[supports]]
    "supports.node": ("", "Node selector, e.g. `\"beam:start\"`, `\"net:knot:12\"`."),
    "supports.fix": (
        "", '"clamp": position and rotation fixed; "pin": position fixed, free to turn. Not set: '
        '"clamp", unless `dofs` is given (`fix` beside `dofs` has no effect, and is warned of). '
        "In the lumped model, in cable threads, and at nodes without a single rotation (pinned "
        "knots, corner masses) both fix the position only."),
    "supports.dofs": (
        "-", "Optional list of the DOFs to fix instead of `fix`'s set: `x`, `y`, `z` (global "
        "translations) and `r1`, `r2`, `r3` (rotations about the node's material axes; `r1` is the "
        "twist about the rod axis, `r2`, `r3` bending). E.g. a roller sliding along x "
        "`[\"y\", \"z\"]`, a pin that also stops twist `[\"x\", \"y\", \"z\", \"r1\"]`. The lumped "
        "model and cable threads take whole nodes only (`[\"x\", \"y\", \"z\"]`)."),
    # [[loads]]
    "loads.node": ("", "Node selector."),
    "loads.force": ("N", "Dead load: fixed global direction and magnitude."),
    "loads.moment": (
        "N m", "Dead moment about fixed global axes. Cosserat rods only: refused in the lumped "
        "model and cable threads (no rotations), and at pinned knots and corner masses of a "
        "Cosserat net (no single rotation)."),
    "loads.ramp": (
        "s", ">= 0. Dynamic runs: the load grows linearly from zero at t = 0 to full at t = "
        "`ramp`, counted from t = 0, not from `start` (a load with a later `start` jumps there "
        "to `min(start / ramp, 1)`; a ramp from `start` is a `table`); 0 applies it in full. "
        "Static runs: must stay 0 (`simulation.load_steps` raises "
        "the loads). Not together with `table`."),
    "loads.table": (
        "s, -", "Dynamic runs: the load's factor over time as `[[t, factor], ...]` rows, times "
        ">= 0 in non-decreasing order, linear between rows, a repeated time a jump (the factor "
        "after it holds from that time on), the first and last factors held before and after. "
        "Replaces `ramp`; not set: `ramp` decides. The integrators land on every row's time; "
        "implicit schemes start afresh at its jumps only."),
    "loads.start": (
        "s", ">= 0. Dynamic runs: the load acts from this time on (factor 0 before); the "
        "integrators land on it and, where the factor jumps there, a multistep or "
        "generalized-alpha scheme starts afresh, so a pulse gives its impulse exactly. Static "
        "runs: must stay 0."),
    "loads.stop": (
        "s", "> start. Dynamic runs: the load acts until this time (factor 0 from it on), landed "
        "on like `start`; not set: to the end. Static runs: must be unset."),
    # [[line_loads]]
    "line_loads.on": ("", "A rod's `name`, or `\"net\"` for every thread of the net (corner "
                      "threads included)."),
    "line_loads.force_per_length": (
        "N/m", "Dead force per unit of stress-free length, fixed global direction; lumped on "
        "the nodes, each element's `q l0` half and half on its ends (the consistent load of a "
        "linear element)."),
    "line_loads.ramp": ("s", "As `[[loads]] ramp`."),
    "line_loads.table": ("s, -", "As `[[loads]] table`."),
    "line_loads.start": ("s", "As `[[loads]] start`."),
    "line_loads.stop": ("s", "As `[[loads]] stop`."),
    # [[masses]]
    "masses.node": ("", "Node selector."),
    "masses.mass": ("kg", "Point mass added at the node, > 0 (no rotary inertia)."),
    "masses.velocity": (
        "m/s", "Initial velocity of that node, replacing the rod's or net's; not set: unchanged."),
    # [[bodies]]
    "bodies.name": (
        "", "Unique, non-empty, without \":\". Names the body in messages and in the results "
        "(`body_names`, `summary.json` `bodies`)."),
    "bodies.shape": (
        "", '"box", "cylinder" (axis along the body z axis), "sphere", or "mesh" (a closed '
        "triangle mesh read from `file`). See [contact](contact.md)."),
    "bodies.size": (
        "m", "Box: the three edge lengths; cylinder: `[diameter, diameter, length]`; sphere: "
        '`[diameter, diameter, diameter]`; all > 0. Required for the primitives, not allowed '
        'for "mesh".'),
    "bodies.file": (
        "", 'shape = "mesh" only, and required there: any format trimesh reads (STL, OBJ, PLY, '
        "GLB ..., told by the file's extension), relative to the scene file; its coordinates are "
        "metres (there is no unit key: scale a file drawn in millimetres first). The mesh must be "
        "watertight and consistently "
        "oriented (checked before the run; inward-facing meshes are flipped); it is translated "
        "so that its centre of volume is the body origin."),
    "bodies.mass": (
        "kg", "> 0; give this or `density`, not both. Required for a free body; a fixed body "
        "only reports it."),
    "bodies.density": (
        "kg/m^3", "> 0; the mass is `density` x the shape's volume (a homogeneous body)."),
    "bodies.inertia": (
        "kg m^2", "Inertia tensor about the centre of mass in body axes: `[Ixx, Iyy, Izz]` "
        "(principal moments along the body axes) or `[Ixx, Iyy, Izz, Ixy, Ixz, Iyz]` (tensor "
        "components, `Ixy = -integral of x y dm`). Positive definite, and no principal moment "
        "above the sum of the other two. Not set: that of the homogeneous shape with the body's "
        "mass (closed form for box, cylinder and sphere; trimesh's polyhedral integrals for a "
        "mesh). Needs `mass` or `density`."),
    "bodies.position": ("m", "World position of the body origin (its centre of mass) at t = 0."),
    "bodies.orientation_deg": (
        "deg", "Rotations about the fixed world x, y and z axes, applied in that order "
        "(`R = R_z R_y R_x`); `R` maps body axes to world axes."),
    "bodies.velocity": (
        "m/s", "Initial velocity of the centre of mass of a free body; `[0, 0, 0]` for a fixed "
        "body."),
    "bodies.angular_velocity_deg": (
        "deg/s", "Initial angular velocity (tumbling rate) of a free body in body axes; "
        "`[0, 0, 0]` for a fixed body."),
    "bodies.fixed": (
        "", "`true`: the body is held in place and never moves (its pose is constant in the "
        "results). `false` (the default): a free 6-DOF rigid body moved by contact and gravity "
        "(needs `mass` or `density`; moves with the `explicit` and every implicit integrator, "
        "where it is six unknowns of the global system; refused in static runs). Contact with "
        "bodies works in the lumped model, cable threads and Cosserat rods, with the `explicit` "
        "and the implicit integrators, not `rk45`; a body that touches a thread at the start is refused, "
        "naming the first node inside it (in a dynamic run also a body within `contact.smoothing` "
        "of a thread)."),
    # [contact]
    "contact.stiffness": (
        "N/m", "Penalty stiffness `k` > 0 per contact point: `N = k delta` at a penetration "
        "`delta` of the thread surface into the body (N1)-(N3). Choose `k >= W / delta_allow` for "
        "a steady load `W` and `k >= m v^2 / delta_allow^2` for a point of mass `m` hitting at "
        "`v`, with `delta_allow` below the thread radius. Enters the explicit stability limit. "
        "See [contact](contact.md#parameters)."),
    "contact.damping": (
        "N s/m", ">= 0. Normal damping `c`, acting only in contact and fading in with it; the "
        "total normal force never pulls (N3). Critical for a point of mass `m`: `2 sqrt(k m)`. "
        "Enters the explicit stability limit."),
    "contact.friction": (
        "-", "Coulomb coefficient `mu` >= 0 of velocity-regularised friction "
        "`f_T = -mu N v_T / sqrt(|v_T|^2 + slip_velocity^2)` (F2); 0: frictionless. Static runs "
        "have no friction (it acts on velocities): see [contact](contact.md)."),
    "contact.smoothing": (
        "m", ">= 0. Half-width `s` of the C1 blend of the normal law around first touch (N1): "
        "the force starts at a gap `s` and is exactly `k delta` beyond `delta = s`. About a "
        "tenth of the admissible penetration; larger values calm implicit integrators at steps "
        "that do not resolve the contact frequency. Not set: 1e-6 m, or 1 % of the thinnest "
        "thread's radius where that is smaller (threads below 0.2 mm), so that a thin thread "
        "resting on a body is not held off it by the blend (a 2 um thread was held 0.8 um "
        "above a box by a fixed 1e-6 m). A dynamic run whose threads start closer to a body "
        "than `s` is refused naming this key (the blend's force already acts there)."),
    "contact.slip_velocity": (
        "m/s", "> 0. Regularisation `eps_v` of friction (F2): below it sticking is a creep; at "
        "a slip speed `v` friction is `mu N (1 - eps_v^2 / (2 v^2))`. Well below the sliding "
        "speeds of interest."),
    "contact.points_per_segment": (
        "", "1 to 64. Contact is checked at every node and at `points_per_segment - 1` equally "
        "spaced points inside each segment near a body (B2); the point spacing should not "
        "exceed the smallest body feature that matters (an edge can pass between two points)."),
    # [initial]
    "initial.from": (
        "", "Folder of an earlier run of the same structure (same scene apart from loads, "
        "steps, integrator, output and bodies), relative to the working directory (not the "
        "scene file), whose saved state starts this run: positions, rotations, velocities and, "
        "for the explicit integrator, the bodies (a run with bodies restarts with the explicit "
        "integrator only). Time continues from the saved frame's time to "
        "`simulation.duration` (the end time); loads over time act as they do at those times "
        "in the whole run. A static run's result "
        "starts a dynamic run from its equilibrium. A static run with `from` starts its first "
        "solve from the saved positions and rotations (not the velocities, time or bodies) and "
        "finds the equilibrium nearest them: the inverted one of a snapped arch, say. Checked: the same numbers of nodes, rotation "
        "nodes and bodies. Everything else comes from this scene (materials, stress-free "
        "shape, `[[supports]]`, loads), so a structure can be held differently from the saved "
        "state on (a thread stretched by a static load, then pinned at both ends: its tension "
        "kept to 1e-7, outside check); a changed material or shape starts it under other "
        "stresses, unchecked. Not set: the scene's own initial state."),
    "initial.frame": (
        "", "Which saved frame of `from`: an index, negative from the end (-1: the last)."),
    "initial.time": (
        "s", "Instead of `frame`: the saved frame at this time (within 1e-9 s)."),
    "initial.velocities": (
        "-, m/s", "`[[node, vx, vy, vz], ...]`: initial velocities of the named nodes (node "
        "selectors as in `[[supports]]`), replacing what the net, the rod or `[[masses]]` set; "
        "rods and nets. Not with `from` (the saved frame gives every velocity). Only nodes "
        "with a selector can be set: the inner nodes of a net's threads "
        "(`model.elements_per_thread` > 1) have none, so a net of several elements per thread "
        "cannot be given a uniform velocity here (a boost: `[[rods]]` take `velocity`)."),
    # [output]
    "output.directory": (
        "", "Output directory, relative to the working directory; `-o DIR` on the command line "
        "overrides it."),
    "output.frame_interval": (
        "s", "Dynamic runs: time between saved frames, > 0; a last frame is saved at `duration` "
        "when it is not a multiple. Static runs save one frame per load step instead."),
    "output.vtk": (
        "", "Write `vtk/frame_NNNNN.vtu` per frame and `result.pvd`."),
    "output.picture": (
        "", "`rodnet` command, a net, a successful run: draw `net.png`, the net at its maximum "
        "mouth area (pyvista, `viz` extra)."),
    "output.plot": (
        "", "`rodnet` command, a net, a successful run: draw `deployment.png`, mouth area and "
        "distance against time (matplotlib, `viz` extra)."),
}

HEADER = """\
# Scene reference

<!-- Generated by docs/make_scene_reference.py from rodnet/config.py. Do not edit by hand:
     change the code or the descriptions in that script, then run it. -->

A scene is one TOML file with the sections below. Units are SI; angles are in degrees and their
keys end in `_deg`. Every key can be overridden on the command line, e.g.
`--set simulation.dt=5e-4` or `--set 'materials[0].viscosity=1e6'`.

Parsing is strict. An unknown section or key, a wrong type or a value out of range is an error
that names the key (with its section), the value and what is allowed; nothing is run and nothing
is written. Integers are accepted where a number is expected; an array of three numbers is
written `[x, y, z]`. "required" keys have no default; "not set" means the key is optional and
absent unless given. A scene needs a `[net]` or at least one `[[rods]]`, and a `[[materials]]`
entry for every material they name; the other sections may be left out.

Equation numbers (S1)-(S16) refer to
[elements/spring/FORMULATION.md](../elements/spring/FORMULATION.md), (C1)-(C55) to
[elements/cosserat/FORMULATION.md](../elements/cosserat/FORMULATION.md), (N1)-(N3), (F2) and
(B2) to [elements/contact/FORMULATION.md](../elements/contact/FORMULATION.md). "Cosserat rods" below
means `model.type = "cosserat"` with `bending` or `torsion` on; "cable threads" means
`model.type = "cosserat"` with both off, which runs the lumped model's equations.

Rigid bodies (`[[bodies]]`) are free unless `fixed = true`; free bodies move with the `explicit`
and the implicit integrators. Contact with bodies (`[contact]`) is modelled for the lumped model, cable
threads and Cosserat rods; see [contact](contact.md).
Keys that only one model or one kind of run uses are read and checked by all; the descriptions
say where a key has no effect.
"""


def toml_value(value: Any) -> str:
    """``value`` written as in a TOML file."""
    if value is None:
        return "not set"
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return f'"{value}"'
    if isinstance(value, (tuple, list)):
        return "[" + ", ".join(toml_value(v) for v in value) + "]"
    return repr(value)


def type_name(hint: Any) -> str:
    """A TOML-level name of a type hint of :mod:`rodnet.config`."""
    origin, args = typing.get_origin(hint), typing.get_args(hint)
    if origin in (typing.Union, types.UnionType):
        inner = [a for a in args if a is not type(None)]
        return type_name(inner[0]) + " (optional)"
    if origin is Literal:
        return " or ".join(toml_value(a) for a in args)
    if origin is tuple:
        if len(args) == 2 and args[1] is Ellipsis:
            return f"array of ({type_name(args[0])})"
        if all(a is float for a in args):
            return f"array of {len(args)} numbers"
        return "array of [" + ", ".join(type_name(a) for a in args) + "]"
    names = {float: "number", int: "integer", bool: "boolean", str: "string"}
    if hint in names:
        return names[hint]
    raise TypeError(f"no name for type {hint!r}")


def default_text(f: dataclasses.Field) -> str:
    if f.default is not dataclasses.MISSING:
        return toml_value(f.default)
    if f.default_factory is not dataclasses.MISSING:
        return toml_value(f.default_factory())
    return "required"


def sections() -> list[tuple[str, str, type]]:
    """``(name, TOML header, dataclass)`` of every section of :class:`rodnet.config.Scene`."""
    hints = typing.get_type_hints(config.Scene)
    out = []
    for f in dataclasses.fields(config.Scene):
        hint = hints[f.name]
        origin, args = typing.get_origin(hint), typing.get_args(hint)
        if origin is tuple and len(args) == 2 and args[1] is Ellipsis:
            out.append((f.name, f"[[{f.name}]]", args[0]))
        elif origin in (typing.Union, types.UnionType):
            out.append((f.name, f"[{f.name}]", next(a for a in args if a is not type(None))))
        elif dataclasses.is_dataclass(hint):
            out.append((f.name, f"[{f.name}]", hint))
        # anything else (``source``) is not a TOML section
    return out


def keys() -> list[str]:
    """Every ``section.key`` the scene dataclasses define."""
    return [f"{name}.{config.toml_key(f.name)}" for name, _, cls in sections()
            for f in dataclasses.fields(cls)]


def missing_descriptions() -> list[str]:
    return [k for k in keys() if k not in DESCRIPTIONS]


def stale_descriptions() -> list[str]:
    defined = set(keys())
    return [k for k in DESCRIPTIONS if k not in defined]


def _cell(text: str) -> str:
    return text.replace("|", "\\|").replace("\n", " ")


def _derived(cls: type) -> list[str]:
    """Bullets for the documented properties of ``cls`` (derived quantities)."""
    lines = []
    for name, member in inspect.getmembers(cls, lambda m: isinstance(m, property)):
        doc = inspect.getdoc(member)
        if doc:
            lines.append(f"- `{name}`: {' '.join(doc.split())}")
    return lines


def render() -> str:
    """The whole page."""
    parts = [HEADER]
    hints_scene = typing.get_type_hints(config.Scene)
    optional_tables = {n for n, _, _ in sections()
                       if typing.get_origin(hints_scene[n]) in (typing.Union, types.UnionType)}
    for name, header, cls in sections():
        hints = typing.get_type_hints(cls)
        doc = " ".join((inspect.getdoc(cls) or "").split())
        doc = doc.split(":", 1)[1].strip() if doc.startswith("``") and ":" in doc else doc
        doc = doc[:1].upper() + doc[1:]
        parts.append(f"## `{header}`\n")
        if header.startswith("[["):
            doc += f" An array of tables: repeat `{header}` for each entry."
        elif name in optional_tables:
            doc += " Optional section."
        parts.append(f"{doc}\n")
        rows = ["| key | type | default | unit | description |", "|---|---|---|---|---|"]
        for f in dataclasses.fields(cls):
            key = config.toml_key(f.name)
            unit, text = DESCRIPTIONS.get(f"{name}.{key}", ("", "(no description)"))
            if name == "materials" and f.name in config.MATERIAL_LIMITS:
                text += f" At most {config.MATERIAL_LIMITS[f.name]:g}."
            default = default_text(f)
            default = default if default in ("required", "not set") else f"`{_cell(default)}`"
            kind = type_name(hints[f.name])
            if f"{name}.{f.name}" in CHOICES:  # names registered by the models and integrators
                kind = " or ".join(toml_value(c) for c in CHOICES[f"{name}.{f.name}"]) + \
                    (" (optional)" if kind.endswith("(optional)") else "")
            rows.append(f"| `{key}` | {_cell(kind)} | {default} | "
                        f"{_cell(unit)} | {_cell(text)} |")
        parts.append("\n".join(rows) + "\n")
        derived = _derived(cls)
        if derived:
            parts.append("Derived quantities (read-only, used by the models):\n")
            parts.append("\n".join(derived) + "\n")
    parts.append(support_table())
    return "\n".join(parts)


CHOICES = {"model.type": list(config.MODEL_TYPES), "simulation.integrator": config.INTEGRATORS}
"""Keys whose allowed values are names the model registry and the run module enter."""


def support_table() -> str:
    """The model table of :mod:`rodnet.models.registry`: what each model runs."""
    from rodnet.models.registry import MODELS

    rows = ["## What each model runs\n",
            "From the model table (`rodnet/models/registry.py`), which also refuses the rest "
            "with a message naming the key. \"Cosserat rods\" are `model.type = \"cosserat\"` "
            "with bending or torsion; \"cable threads\" with both off.\n",
            "| model | integrators | static runs | fixed bodies with | free bodies with | "
            "net knots |", "|---|---|---|---|---|---|"]
    for entry in MODELS.values():
        s = entry.supports
        rows.append(f"| {entry.label} | {', '.join(s.integrators)} | "
                    f"{'yes' if s.static else 'no'} | {', '.join(s.fixed_bodies)} | "
                    f"{', '.join(s.free_bodies)} | {', '.join(s.knots)} |")
    return "\n".join(rows) + "\n"


def main() -> None:
    problems = missing_descriptions()
    if problems:
        raise SystemExit(f"no description in DESCRIPTIONS for: {', '.join(problems)}")
    OUTPUT.write_text(render())
    print(f"wrote {OUTPUT}")


if __name__ == "__main__":
    main()
