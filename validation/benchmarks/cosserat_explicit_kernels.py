"""Benchmark: the explicit loop's force terms timed in isolation on the reference net's arrays.

The reference deployment (21 x 21 knots, two elements per thread, explicit) is prepared with
``model.knots`` = ``rigid``, ``pinned`` or ``cable`` (bending and torsion off), its start state
perturbed (rotation nodes turned by about 0.05 rad per axis, knots moved by 5 mm, random
velocities and spins: relative rotations and strains of the size a deployment reaches), and the
rod element forces with their scatter to the nodes, all forces of a step and the state update
are each run 300 times in a compiled loop; the CPU time of the thread (``time.thread_time``, one
numba thread) per call, minimum of nine, is printed. The code measured is the one on
``PYTHONPATH`` (old and new trees alike: the scratch arrays of an older loop are detected).

Usage, from the repository root: ``python validation/benchmarks/cosserat_explicit_kernels.py
rigid|pinned|cable`` (with ``NUMBA_NUM_THREADS=1``).
"""
import sys
import time

import numba
import numpy as np

from rodnet.cli import demo_scene_text
from rodnet.scene import scene_from_toml
from rodnet.run import prepare
from rodnet.integrate.explicit import scratch
from rodnet.kernels import explicit as kx
from rodnet.kernels.cosserat_compiled import rod_forces, scatter_forces
from rodnet.kernels import so3

knots = sys.argv[1]
base = ["model.elements_per_thread=2", "simulation.integrator=explicit", "simulation.duration=0.05",
        "output.vtk=false", "output.picture=false", "output.plot=false"]
if knots == "cable":
    extra = ["model.type=cosserat", "model.bending=false", "model.torsion=false", "model.knots=pinned"]
else:
    extra = ["model.type=cosserat", f"model.knots={knots}"]
scene = scene_from_toml(demo_scene_text(), base + extra, source="benchmark")
p = prepare(scene)
problem, control = p.system.explicit_problem()
s = scratch(problem)
st = p.state
x, quat, v, W = st.q.x, st.q.quat, st.velocities, st.spin
rng = np.random.default_rng(1)
if quat.shape[0]:
    quat[...] = so3.quat_multiply(quat, so3.quat_from_rotvec(rng.normal(size=(len(quat), 3)) * 0.05))
    W[...] = rng.normal(size=W.shape) * 10.0
x[...] += rng.normal(size=x.shape) * 0.005
v[...] = rng.normal(size=v.shape)
OLD = hasattr(s, 'xe')
import inspect
BLOCKS = "blocks" in inspect.signature(kx._update.py_func).parameters  # one block per thread
@numba.njit
def loop_rods(K, x, quat, v, W, rods, s):
    for _ in range(K):
        if OLD:
            rod_forces(x, quat, v, W, rods, s.xe, s.qe, s.ve, s.force, s.monitor)
        elif BLOCKS:
            rod_forces(x, quat, v, W, rods, s.force, s.monitor, 1)
        else:
            rod_forces(x, quat, v, W, rods, s.force, s.monitor)
        scatter_forces(s.force, rods.pos_nodes, rods.rot_nodes, rods.offset_R, s.f_node, s.m_node)

@numba.njit
def loop_forces(K, x, quat, v, W, p, s):
    for _ in range(K):
        if BLOCKS:
            kx._forces(0.0, x, quat, v, W, p, s, 1)
        else:
            kx._forces(0.0, x, quat, v, W, p, s)

@numba.njit
def loop_update(K, x, quat, v, W, p, s):
    for _ in range(K):
        if BLOCKS:
            kx._update(x, quat, v, W, s.f_node, s.m_node, p.nodes, p.rotations, 0.0, 1)
        else:
            kx._update(x, quat, v, W, s.f_node, s.m_node, p.nodes, p.rotations, 0.0)

def best(fn, *a, K=300, reps=9):
    fn(1, *a)
    ts = []
    for _ in range(reps):
        t0 = time.thread_time(); fn(K, *a); ts.append((time.thread_time() - t0) / K)
    return min(ts) * 1e6
E = problem.rods.rest_length.shape[0]; S = problem.segments.pairs.shape[0]
print("old" if OLD else "new", knots, "elements", E, "segments", S, "rot nodes", W.shape[0], "offsets", problem.rods.offset_q.shape[0])
if E:
    us = best(loop_rods, x, quat, v, W, problem.rods, s)
    print(f"rod_forces+scatter: {us:.1f} us/eval = {1e3*us/E:.1f} ns/element")
us = best(loop_forces, x, quat, v, W, problem, s)
print(f"_forces total: {us:.1f} us")
us = best(loop_update, x.copy(), quat.copy(), v.copy(), W.copy(), problem, s)
print(f"_update (h=0): {us:.1f} us")
