"""Benchmark: rodnet beside the codes a user would pick instead, on the same scenes.

1. The reference deployment (``rodnet demo``: lumped net, explicit) in MuJoCo: one point mass
   per node (freejoint bodies with the lumped model's masses, launch velocities and packed
   positions, taken from rodnet's own build of the scene), every segment a spatial tendon driven
   by a tension-only Kelvin-Voigt actuator (force ``-(k (L - L0) + c dL/dt)`` clamped to
   ``[-inf, 0]``, k = EA / L0, c = eta A / L0: the scene contract's law), no gravity, no
   contact, MuJoCo's Euler integrator (symplectic for these forces, like rodnet's loop), frames
   every 0.01 s, the mouth area by rodnet's own function. MuJoCo runs at rodnet's step and at
   twice it (rodnet's computed stability limit of symplectic Euler).
2. The clamped 1.5 m x 1 mm nylon thread under gravity of ``thread_gravity.py`` in PyElastica
   (20 elements, position Verlet at its largest stable step, 5.6e-7 s) and in rodnet (20
   Cosserat elements, default settings). PyElastica simulates only ``ELASTICA_SECONDS`` and its
   time is scaled to one simulated second; rodnet's thread runs 1 s.

Every case runs in its own process, the cases interleaved and repeated; times are the least of
the repeats (other work on a shared machine only ever adds to them). ``--old DIR`` adds rodnet
from another source tree (e.g. a checkout of an earlier version) as a case of each scene, on
PYTHONPATH.
Writes ``results/peers.md``.

Usage: ``python validation/benchmarks/peers.py [--repeats N] [--old DIR] [--output FILE]``
(needs ``pip install -e '.[peers]'``: mujoco, pyelastica).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).parent
ROOT = HERE.parent.parent
ELASTICA_SECONDS = 0.05
ELASTICA_DT = 5.6e-7
MUJOCO_SAME = "MuJoCo, rodnet's step"
OFF = ["output.vtk=false", "output.picture=false", "output.plot=false"]

COMMON = r"""
import json, os, sys, tempfile, time
import numpy as np
def report(**kw):
    print(json.dumps({**kw, "load": os.getloadavg()[0]}))
"""

RODNET_NET = COMMON + r"""
from rodnet.cli import demo_scene_text
from rodnet.run import run
from rodnet.scene import scene_from_toml
scene = scene_from_toml(demo_scene_text(), json.loads(sys.argv[1]))
warm = scene_from_toml(demo_scene_text(), json.loads(sys.argv[1]) + ["simulation.duration=0.01"])
run(warm, tempfile.mkdtemp(prefix="rodnet-peers-"), progress=False)   # compiled-kernel cache
wall, cpu = time.perf_counter(), time.process_time()
r = run(scene, tempfile.mkdtemp(prefix="rodnet-peers-"), progress=False)
wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
m = r.summary["metrics"]
report(status=r.status, steps=r.summary["steps"], integration_wall=r.summary["wall_time_s"],
       run_wall=wall, run_cpu=cpu, area=m["max_mouth_area"], t_max=m["time_of_max_mouth_area"],
       dt=r.summary["integrator"]["dt"])
"""

MUJOCO_NET = COMMON + r"""
import mujoco
from rodnet.cli import demo_scene_text
from rodnet.metrics import mouth_area
from rodnet.run import prepare
from rodnet.scene import scene_from_toml
factor = float(sys.argv[1])
p = prepare(scene_from_toml(demo_scene_text(), json.loads(sys.argv[2])))
model, s = p.model, p.structure
x0, v0 = p.q0.x.tolist(), p.v0.reshape(-1, 3)
frame, duration = p.scene.output.frame_interval, p.scene.simulation.duration
per_frame = max(1, round(frame / (factor * p.dt)))
dt = frame / per_frame
k = (model.EA / model.rest_length).tolist()
c = (model.etaA / model.rest_length).tolist()
bodies = "".join(
    f'<body name="n{i}" pos="{x[0]!r} {x[1]!r} {x[2]!r}"><freejoint/>'
    f'<inertial pos="0 0 0" mass="{m!r}" diaginertia="{1e-6 * m!r} {1e-6 * m!r} {1e-6 * m!r}"/>'
    f'<site name="s{i}"/></body>' for i, (x, m) in enumerate(zip(x0, model.mass.tolist())))
tendons = "".join(f'<spatial name="t{j}"><site site="s{a}"/><site site="s{b}"/></spatial>'
                  for j, (a, b) in enumerate(model.segments.tolist()))
actuators = "".join(
    f'<general tendon="t{j}" gainprm="0" biastype="affine" '
    f'biasprm="{k[j] * L!r} {-k[j]!r} {-c[j]!r}" forcelimited="true" forcerange="-1e12 0"/>'
    for j, L in enumerate(model.rest_length.tolist()))
xml = (f'<mujoco><option timestep="{dt!r}" integrator="Euler" gravity="0 0 0" jacobian="sparse">'
       '<flag contact="disable" constraint="disable"/></option>'
       f'<worldbody>{bodies}</worldbody><tendon>{tendons}</tendon>'
       f'<actuator>{actuators}</actuator></mujoco>')
wall, cpu = time.perf_counter(), time.process_time()
m = mujoco.MjModel.from_xml_string(xml)
d = mujoco.MjData(m)
d.qvel.reshape(-1, 6)[:, :3] = v0
mujoco.mj_forward(m, d)
build = time.perf_counter() - wall
frames = [d.qpos.reshape(-1, 7)[:, :3].copy()]
n_frames = int(round(duration / frame))
wall, cpu = time.perf_counter(), time.process_time()
for _ in range(n_frames):
    mujoco.mj_step(m, d, nstep=per_frame)
    frames.append(d.qpos.reshape(-1, 7)[:, :3].copy())
wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
positions = np.array(frames)
area = mouth_area(positions, s.net)
finite = bool(np.isfinite(positions).all())
i = int(np.nanargmax(area)) if finite else 0
report(status="ok" if finite else "diverged", steps=n_frames * per_frame, dt=dt, build_wall=build,
       run_wall=wall, run_cpu=cpu, area=float(area[i]) if finite else float("nan"),
       t_max=i * frame)
"""

sys.path.insert(0, str(HERE))
from thread_defaults import DEFAULT_SCENE  # noqa: E402  (the same thread)

THREAD_SCENE = DEFAULT_SCENE.format(duration=1.0, elements=20)
"""The thread of ``thread_gravity.py`` with rodnet's default integrator and step control."""

RODNET_THREAD = COMMON + "SCENE = " + repr(THREAD_SCENE) + r"""
from rodnet.run import run
from rodnet.scene import scene_from_toml
t_tip = float(sys.argv[1])
run(scene_from_toml(SCENE, ["simulation.duration=0.02"]), tempfile.mkdtemp(), progress=False)
wall, cpu = time.perf_counter(), time.process_time()
r = run(scene_from_toml(SCENE), tempfile.mkdtemp(prefix="rodnet-peers-"), progress=False)
wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
t = r.arrays["time"]
tip = r.arrays["positions"][:, r.summary["nodes"]["thread:end"]]
at = [float(np.interp(t_tip, t, tip[:, k])) for k in range(3)]
report(status=r.status, steps=r.summary["steps"], run_wall=wall, run_cpu=cpu,
       per_second_cpu=cpu / t[-1], per_second_wall=r.summary["wall_time_s"] / t[-1], tip=at,
       integrator=r.summary["integrator"]["name"])
"""

ELASTICA_THREAD = COMMON + f"sys.path.insert(0, {str(HERE)!r})" + r"""
from thread_gravity import pyelastica_thread
seconds, dt = float(sys.argv[1]), float(sys.argv[2])
pyelastica_thread(200 * dt, dt)   # compiles its kernels
rod, cpu, wall, steps = pyelastica_thread(seconds, dt)
tip = rod.position_collection[:, -1]
report(status="ok" if np.isfinite(tip).all() else "diverged", steps=steps, run_wall=wall,
       run_cpu=cpu, per_second_cpu=cpu / seconds, per_second_wall=wall / seconds,
       tip=[float(v) for v in tip])
"""


def child(code: str, args: list[str], pythonpath: Path) -> dict:
    env = {**os.environ, "PYTHONPATH": str(pythonpath)}
    # -P: the working directory is not put before PYTHONPATH (run from a checkout, it would
    # shadow the tree under test)
    done = subprocess.run([sys.executable, "-P", "-c", code, *args], capture_output=True,
                          text=True, env=env)
    if done.returncode != 0:
        return {"status": "error: " + done.stderr.strip().splitlines()[-1][:120]}
    return json.loads(done.stdout.strip().splitlines()[-1])


def cases(old: Path | None) -> dict[str, tuple[str, list[str], Path]]:
    """Name -> (child code, arguments, source tree on PYTHONPATH)."""
    net = json.dumps(OFF)
    out = {"rodnet": (RODNET_NET, [net], ROOT)}
    if old is not None:
        out["rodnet (old)"] = (RODNET_NET, [net], old)
    out[MUJOCO_SAME] = (MUJOCO_NET, ["1.0", net], ROOT)
    out["MuJoCo, twice rodnet's step"] = (MUJOCO_NET, ["2.0", net], ROOT)
    out["rodnet thread"] = (RODNET_THREAD, [repr(ELASTICA_SECONDS)], ROOT)
    if old is not None:
        out["rodnet thread (old)"] = (RODNET_THREAD, [repr(ELASTICA_SECONDS)], old)
    out["PyElastica thread"] = (ELASTICA_THREAD, [repr(ELASTICA_SECONDS), repr(ELASTICA_DT)],
                                ROOT)
    return out


def least(runs: list[dict]) -> dict:
    """The first run's results with every time the least over the runs."""
    ok = [r for r in runs if r.get("status") == "ok"] or runs
    best = dict(ok[0])
    for key in best:
        if key.endswith(("_wall", "_cpu")) and isinstance(best[key], float):
            best[key] = min(r[key] for r in ok)
    best["loads"] = [r.get("load") for r in runs]
    return best


def table(res: dict[str, dict], repeats: int, old: Path | None) -> str:
    ours, build = res["rodnet"], res[MUJOCO_SAME].get("build_wall", float("nan"))
    lines = ["## Reference deployment (lumped net, 3 s)", "",
             "| code | step s | steps | wall s | CPU s | max mouth area m^2 | vs rodnet | time of max s "
             "| CPU ratio to rodnet |", "|---|---|---|---|---|---|---|---|---|"]
    for name in [n for n in res if "thread" not in n]:
        r = res[name]
        if r.get("status") != "ok":
            lines.append(f"| {name} | | | | | {r.get('status')} | | | |")
            continue
        wall = r.get("integration_wall", r["run_wall"])
        lines.append(f"| {name} | {r['dt']:.3g} | {r['steps']} | {wall:.3f} | {r['run_cpu']:.3f} "
                     f"| {r['area']:.2f} | {100 * (r['area'] / ours['area'] - 1):+.3f} % "
                     f"| {r['t_max']:.2f} | {r['run_cpu'] / ours['run_cpu']:.2f} |")
    lines += ["", "rodnet's wall time is the integration's (`wall_time_s` of summary.json: the "
              "steps and the saved frames); its CPU time is the whole `run()` (the scene's build, "
              "the integration, the result files). MuJoCo's are its step loop with the copies "
              "of the frames; building its model from the MJCF is left out "
              f"({build:.2f} s wall)."]
    thread, peer = res["rodnet thread"], res["PyElastica thread"]
    lines += ["", "## Clamped thread under gravity (1.5 m x 1 mm nylon, 20 elements)", "",
              "| code | CPU s per simulated s | integration wall s per simulated s | steps | tip at "
              f"{ELASTICA_SECONDS:g} s m |", "|---|---|---|---|---|"]
    rows = [("rodnet (" + str(thread.get("integrator")) + ", default step control, 1 s)",
             thread)]
    if "rodnet thread (old)" in res:
        rows.append(("rodnet (old), the same", res["rodnet thread (old)"]))
    rows.append((f"PyElastica (position Verlet, dt {ELASTICA_DT:g} s, {ELASTICA_SECONDS:g} s "
                 "scaled to 1 s)", peer))
    for name, r in rows:
        if r.get("status") != "ok":
            lines.append(f"| {name} | {r.get('status')} | | | |")
            continue
        lines.append(f"| {name} | {r['per_second_cpu']:.3f} | {r['per_second_wall']:.3f} | "
                     f"{r['steps']} | {np.round(r['tip'], 4).tolist()} |")
    lines += ["", "rodnet's CPU time is the whole `run()` (build, steps, frames, result files), its "
              "wall time the integration's; PyElastica's are its time loop."]
    if thread.get("status") == "ok" and peer.get("status") == "ok":
        gap = 1e3 * float(np.linalg.norm(np.subtract(thread["tip"], peer["tip"])))
        lines += ["", f"PyElastica / rodnet, CPU per simulated second: "
                  f"{peer['per_second_cpu'] / thread['per_second_cpu']:.0f} times. Tips "
                  f"{gap:.2f} mm apart at {ELASTICA_SECONDS:g} s."]
        before = res.get("rodnet thread (old)", {})
        if before.get("status") == "ok":
            lines += [f"rodnet (old) / rodnet, the same: "
                      f"{before['per_second_cpu'] / thread['per_second_cpu']:.2f} times."]
    loads = [x for r in res.values() for x in r.get("loads", []) if x is not None]
    lines += ["", f"Least of {repeats} runs of each case, interleaved; 1-minute load average "
              f"during the runs {min(loads):.1f} - {max(loads):.1f} on {os.cpu_count()} cores."]
    if old is not None:
        lines.append("rodnet (old): the same run from an earlier source tree.")
    return "\n".join(lines)


def main(repeats: int = 3, old: Path | None = None,
         output: Path = HERE / "results" / "peers.md") -> str:
    plan = cases(old)
    runs: dict[str, list[dict]] = {name: [] for name in plan}
    for _ in range(repeats):
        for name, (code, args, path) in plan.items():
            runs[name].append(child(code, args, path))
    text = table({name: least(r) for name, r in runs.items()}, repeats, old)
    output.parent.mkdir(parents=True, exist_ok=True)
    output.write_text("# rodnet beside MuJoCo and PyElastica\n\n"
                                               + text + "\n")
    return text


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--old", type=Path, default=None)
    parser.add_argument("--output", type=Path, default=HERE / "results" / "peers.md")
    args = parser.parse_args()
    print(main(args.repeats, args.old, args.output))
