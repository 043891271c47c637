"""Dynamics of Cosserat rods against physics: wave speed, string frequencies, time order,
conservation laws and tension-only threads.

Every expected value is an analytic formula or a conservation law; rodnet's own output is only
ever the measured side. Scenes go through the public TOML path and :func:`rodnet.run.run`. The
free-flight checks need the body angular velocities, which a saved frame does not hold, so they
march the prepared model with the same stepper ``run`` uses and read ``q`` and ``v`` of every
frame (model API for momenta and energy only).

Measured values are printed (``pytest -s``); the numbers quoted in the comments were measured on
a 2-core machine.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from rodnet.integrate.implicit import integrate_implicit
from rodnet.integrate.newton import NewtonOptions
from rodnet.kernels import so3
from rodnet.run import RunResult, prepare, run
from rodnet.scene import load_scene, scene_from_toml
from tests.conftest import falling_thread_toml
from tests.systems import implicit_scheme

CASES = Path(__file__).parents[2] / "validation" / "cases"


def _run(toml: str, directory: Path, overrides: tuple[str, ...] = ()) -> RunResult:
    result = run(scene_from_toml(toml, list(overrides)), directory, progress=False)
    assert result.status == "ok", result.message
    return result


def _zero_crossings(t: np.ndarray, s: np.ndarray) -> np.ndarray:
    """Times where ``s`` changes sign, by linear interpolation between samples."""
    k = np.flatnonzero(np.sign(s[:-1]) * np.sign(s[1:]) < 0)
    return t[k] - s[k] * (t[k + 1] - t[k]) / (s[k + 1] - s[k])


def _half_period(t: np.ndarray, s: np.ndarray) -> float:
    """Least-squares spacing of the zero crossings of an oscillating signal."""
    tz = _zero_crossings(t, s)
    assert len(tz) >= 4, "too few zero crossings to measure a period"
    return float(np.polyfit(np.arange(len(tz)), tz, 1)[0])


def _observed_order(dts: list[float], errors: list[float]) -> float:
    return float(np.polyfit(np.log(dts), np.log(errors), 1)[0])


# --- 1. axial wave speed ------------------------------------------------------------------------


def test_axial_wave_speed_in_a_fixed_free_bar(tmp_path: Path) -> None:
    """A clamped bar released with a uniform axial velocity: the tip traces a triangle wave of
    period 4 L / c; its zero crossings give c, compared with sqrt(E / rho) (1-D wave equation).
    The scene is the validation case ``axial_wave_bar`` with every step saved."""
    E, rho, L = 2.0e11, 7800.0, 1.0
    c = np.sqrt(E / rho)
    period = 4.0 * L / c
    scene = load_scene(CASES / "axial_wave_bar" / "scene.toml",
                       [f"output.frame_interval={period / 200}"])
    result = run(scene, tmp_path, progress=False)
    assert result.status == "ok", result.message
    t = result.arrays["time"]
    u_tip = result.arrays["positions"][:, -1, 0] - L
    measured = 4.0 * L / (2.0 * _half_period(t[1:], u_tip[1:]))
    print(f"\naxial wave speed: measured {measured:.2f} m/s, sqrt(E/rho) {c:.2f} m/s, "
          f"error {measured / c - 1:+.3%}")
    assert measured == pytest.approx(c, rel=0.01)  # measured: +0.20 %


# --- 2. taut string -----------------------------------------------------------------------------

STRING = """
[simulation]
type = "dynamic"
integrator = "generalized-alpha"
rho_inf = 0.8
dt = {dt}
adaptive = false
duration = {duration}

[model]
type = "cosserat"
axial = "linear"

[[materials]]
name = "thread"
density = 1440.0
youngs_modulus = 7.0e10
poisson_ratio = 0.36
diameter = 1.0e-3
viscosity = {viscosity}
bending_stiffness = 1.0e-8      # a string: bending adds (n pi)^2 EI / (2 T L^2) ~ 1e-9 to f_n
torsional_stiffness = 1.0e-8

[[rods]]
name = "string"
material = "thread"
points = [[0.0, 0.0, 0.0], [0.2, {pluck}, 0.0], [1.0, 0.0, 0.0]]
elements = {elements}

[[supports]]
node = "string:start"
fix = "pin"

[[masses]]
node = "string:end"
mass = {end_mass}

[[loads]]
node = "string:end"
force = [{tension}, 0.0, 0.0]

[output]
frame_interval = {frame_interval}
vtk = false
"""


def test_taut_string_transverse_frequencies(tmp_path: Path) -> None:
    """A plucked string under tension T: f_n = n / (2 L) sqrt(T / mu) within 1 % for n = 1, 2, 3.

    The scene format starts every rod stress-free, so the tension comes from a dead axial load
    T = 1e-3 EA on a heavy end mass M = 1000 mu L (pinned start). The end mass is the string's
    second support: with it free to move sideways the exact condition tan(k L) = mu / (M k) moves
    f_n by mu L / (M n^2 pi^2) <= 1e-4. Kelvin-Voigt viscosity tau = 2 / omega_a damps the axial
    bounce of the end mass critically; linear transverse modes feel axial strain rates only at
    second order. The pluck (0.5 mm at 0.2 L) excites modes 1-3. Measured over the last 60 ms:
    T from the run's tension output, L from the end position, mu = string mass / L (stretched);
    the modal amplitudes are projections on the lumped string's eigenvectors sin(n pi i / N).
    """
    E, rho, d, elements = 7.0e10, 1440.0, 1.0e-3, 30
    area = np.pi * d * d / 4.0
    mu, EA = rho * area, E * area
    tension, end_mass = 1.0e-3 * EA, 1000.0 * mu * 1.0
    tau = 2.0 / np.sqrt(EA / (1.0 * end_mass))
    dt, duration, settle = 5.0e-5, 0.11, 0.05
    result = _run(STRING.format(dt=dt, duration=duration, viscosity=tau * E, pluck=5.0e-4,
                                elements=elements, end_mass=end_mass, tension=tension,
                                frame_interval=2 * dt), tmp_path)
    t, x = result.arrays["time"], result.arrays["positions"]
    window = t > settle
    T = float(result.arrays["tension"][window].mean())
    spread = float(result.arrays["tension"][window].std()) / T
    rest_length = 0.2 * np.hypot(1.0, 5.0e-4 / 0.2) + 0.8 * np.hypot(1.0, 5.0e-4 / 0.8)
    length = float(x[window, -1, 0].mean())
    mu_stretched = mu * rest_length / length
    node = np.arange(elements + 1)
    print(f"\ntaut string: T = {T:.4f} N (spread {spread:.2e}), L = {length:.6f} m")
    assert spread < 5e-3  # the tension is steady: measured 1.5e-3
    for n in (1, 2, 3):
        amplitude = x[:, :, 1] @ np.sin(n * np.pi * node / elements)
        f = 0.5 / _half_period(t[window], amplitude[window])
        exact = n / (2.0 * length) * np.sqrt(T / mu_stretched)
        print(f"  mode {n}: f = {f:.3f} Hz, n/(2L) sqrt(T/mu) = {exact:.3f} Hz, "
              f"error {f / exact - 1:+.3%}")
        # measured -0.05, -0.23, -0.50 %; the lumped string alone gives
        # sin(n pi / 2N) / (n pi / 2N) - 1 = -0.05, -0.18, -0.41 %
        assert f == pytest.approx(exact, rel=0.01)


# --- 3. observed time order ---------------------------------------------------------------------

HEAVY_L = """
[simulation]
type = "dynamic"
integrator = "{integrator}"
rho_inf = 0.7
dt = {dt}
adaptive = false
duration = 0.4
gravity = [0.0, 0.0, -9.81]
rtol = 1.0e-10

[model]
type = "cosserat"
axial = "linear"

[[materials]]
name = "steel"
density = 7800.0
youngs_modulus = 2.0e11
poisson_ratio = 0.3
diameter = 0.02
bending_stiffness = 1.6e5     # 100 x the solid section: elastic modes > 1 kHz, tumbling ~1 Hz

[[rods]]
name = "body"
material = "steel"
points = [[0.0, 0.0, 0.0], [0.4, 0.0, 0.0], [0.4, 0.25, 0.0]]
elements = 6

[[supports]]
node = "body:start"
fix = "pin"

[output]
frame_interval = 0.1
vtk = false
"""


def _heavy_l(integrator: str, dt: float, directory: Path) -> tuple[np.ndarray, np.ndarray]:
    """Tip positions (F, 3) and quaternions (F, 4) at the frames 0, 0.1, ..., 0.4 s."""
    result = _run(HEAVY_L.format(integrator=integrator, dt=dt), directory)
    return result.arrays["positions"][:, -1], result.arrays["rotations"][:, -1]


def _trajectory_errors(run_at, dts, reference) -> tuple[list[float], list[float]]:
    """Largest tip position error [m] and tip rotation angle error [rad] over the frames."""
    position_errors, angle_errors = [], []
    for dt in dts:
        x, q = run_at(dt)
        position_errors.append(float(np.linalg.norm(x - reference[0], axis=1).max()))
        cosine = np.clip(np.abs(np.sum(q * reference[1], axis=1)), 0.0, 1.0)
        angle_errors.append(float(2.0 * np.arccos(cosine).max()))
    return position_errors, angle_errors


def _order_study(tmp_path: Path, dt_ref: float,
                 studies: tuple[tuple[str, list[float], float], ...]) -> None:
    """A stiff L-shaped rod pinned at one end and released from rest, horizontal, under gravity:
    a heavy top that tumbles in 3-D, since its inertia tensor is not aligned with the gravity
    torque. Errors against generalized-alpha at ``dt_ref``; observed orders from log-log fits of
    each ``(integrator, steps, expected order)``."""
    reference = _heavy_l("generalized-alpha", dt_ref, tmp_path / "reference")
    assert np.ptp(reference[0][:, 1]) > 0.1 and reference[0][-1, 2] < -0.3  # it does tumble in 3-D
    for integrator, dts, order in studies:
        pos, ang = _trajectory_errors(
            lambda dt: _heavy_l(integrator, dt, tmp_path / f"{integrator}{dt:g}"), dts, reference)
        p_order, a_order = _observed_order(dts, pos), _observed_order(dts, ang)
        print(f"\n{integrator}: dt {dts}\n  tip position error [m] {np.array(pos)}, order "
              f"{p_order:.3f}\n  tip rotation error [rad] {np.array(ang)}, order {a_order:.3f}")
        assert p_order == pytest.approx(order, abs=0.1)
        assert a_order == pytest.approx(order, abs=0.1)


def test_time_order_generalized_alpha_2_and_backward_euler_1(tmp_path: Path) -> None:
    """Measured: generalized-alpha 2.00 (positions), midpoint 2.03, backward Euler 0.96. The
    midpoint rule is not energy-stable on this stiff rod at coarse steps: its energy (with the
    weight's potential) rose by 1.4 J at 5 ms and by 345 J at 20 ms (into the unresolved
    elastic modes; kinetic energy at most 4.4 J) while its tip still converged, and the energy
    guard stops such runs; it is measured at 2.5 ms and below (0.09 J)."""
    _order_study(tmp_path, 1.25e-4, (("generalized-alpha", [2e-2, 1e-2, 5e-3, 2.5e-3], 2.0),
                                     ("midpoint", [2.5e-3, 1.25e-3, 6.25e-4], 2.0),
                                     ("backward-euler", [5e-3, 2.5e-3, 1.25e-3], 1.0)))


OSCILLATOR = """
[simulation]
duration = 4.0
dt = {dt}
adaptive = false
integrator = "{integrator}"
[model]
type = "lumped"
axial = "linear"
[[materials]]
name = "soft"
density = 1000.0
youngs_modulus = 1.0e6
diameter = 0.01
[[rods]]
name = "spring"
material = "soft"
points = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]]
elements = 1
[[supports]]
node = "spring:start"
[[masses]]
node = "spring:end"
mass = 1.0
velocity = [0.1, 0.0, 0.0]
[output]
frame_interval = {frames}
vtk = false
"""


@pytest.mark.parametrize("integrator", ["generalized-alpha", "bdf2", "midpoint"])
def test_fixed_steps_keep_second_order_when_frames_do_not_divide_by_dt(tmp_path: Path,
                                                                       integrator: str) -> None:
    """A mass on a linear spring (one pinned element, 1 kg added at its end, pushed along it at
    0.1 m/s): ``x = v0 / w sin(w t)``, ``w^2 = EA / (L m)``, ``m`` the end node's mass. Frames
    every 3.5 ``dt``: the steps had been cut short to land on them (1, 1, 1, 0.5 dt), which
    took generalized-alpha's order from 2.0 to 1.7 here between 2 and 1 ms (1.3 in an outside
    check's); in equal steps it stays 2.0."""
    errors = []
    for dt in (2e-3, 1e-3):
        r = run(scene_from_toml(OSCILLATOR.format(dt=dt, frames=3.5 * dt, integrator=integrator)),
                tmp_path / str(dt), progress=False)
        assert r.status == "ok", r.message
        t, x = r.arrays["time"], r.arrays["positions"][:, 1, 0] - 1.0
        EA = 1.0e6 * np.pi * 0.005**2
        w = np.sqrt(EA / r.arrays["node_mass"][1])
        errors.append(np.abs(x - 0.1 / w * np.sin(w * t)).max())
    assert np.log2(errors[0] / errors[1]) >= 1.9, errors


@pytest.mark.slow
def test_time_order_with_finer_steps(tmp_path: Path) -> None:
    _order_study(tmp_path, 6.25e-5,
                 (("generalized-alpha", [1e-2, 5e-3, 2.5e-3, 1.25e-3], 2.0),
                  ("midpoint", [2.5e-3, 1.25e-3, 6.25e-4, 3.125e-4], 2.0),
                  ("backward-euler", [5e-3, 2.5e-3, 1.25e-3, 6.25e-4], 1.0)))


# --- 3b. error-controlled steps -----------------------------------------------------------------

FIXED_GA = 'integrator = "generalized-alpha"\ndt = {dt}\nadaptive = {adaptive}'


CANTILEVER = """
[simulation]
duration = 2.0
integrator = "{integrator}"
adaptive = false
dt = 0.001
[model]
type = "cosserat"
axial = "linear"
[[materials]]
name = "steel"
density = 7850.0
youngs_modulus = 2.0e11
poisson_ratio = 0.3
diameter = 0.01
[[rods]]
name = "beam"
material = "steel"
points = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]]
elements = 20
[[supports]]
node = "beam:start"
fix = "clamp"
[initial]
velocities = {velocities}
[output]
frame_interval = 0.001
vtk = false
"""


def _sdof_energy_ratio(scheme: str, omega: float, h: float, steps: int, window: int,
                       rho: float = 0.7) -> float:
    """The mean energy of the last ``window`` steps over that of the first, of the textbook
    scheme on ``x'' + omega^2 x = 0`` from ``x = 0, v = 1`` (BDF2 started by backward Euler;
    generalized-alpha of Chung and Hulbert 1993, rho_inf ``rho``)."""
    x, v, energy = [0.0], [1.0], []
    if scheme == "bdf2":
        for n in range(steps):    # (3/2) y1 - 2 y0 + (1/2) y_1 = h f(y1); the first step Euler
            a, b = (1.0, 1.0) if n == 0 else (1.5, 1.0)
            rx = x[-1] * (2.0 if n else 1.0) - (0.5 * x[-2] if n else 0.0)
            rv = v[-1] * (2.0 if n else 1.0) - (0.5 * v[-2] if n else 0.0)
            # a x1 - h v1 = rx, a v1 + h omega^2 x1 = rv
            det = a * a + h * h * omega * omega
            x.append((a * rx + h * rv) / det)
            v.append((a * rv - h * omega * omega * rx) / det)
    else:
        am, af = (2 * rho - 1) / (rho + 1), rho / (rho + 1)
        gamma, beta = 0.5 - am + af, 0.25 * (1 - am + af) ** 2
        acc = [0.0]
        for _ in range(steps):
            x0, v0, a0 = x[-1], v[-1], acc[-1]
            # (1 - am) a1 + am a0 + omega^2 ((1 - af) x1 + af x0) = 0, Newmark updates
            xp = x0 + h * v0 + h * h * (0.5 - beta) * a0
            a1 = -(am * a0 + omega ** 2 * ((1 - af) * xp + af * x0)) / \
                ((1 - am) + omega ** 2 * (1 - af) * beta * h * h)
            x.append(xp + beta * h * h * a1)
            v.append(v0 + h * ((1 - gamma) * a0 + gamma * a1))
            acc.append(a1)
    energy = 0.5 * (np.array(v) ** 2 + omega ** 2 * np.array(x) ** 2)
    return float(energy[-window:].mean() / energy[1:window + 1].mean())


@pytest.mark.parametrize("integrator", ["bdf2", "generalized-alpha"])
def test_a_cantilevers_first_mode_is_damped_as_the_scheme_says(tmp_path: Path,
                                                               integrator: str) -> None:
    """A steel cantilever (1 m x 10 mm, 20 elements) swinging 0.1 mm in its first mode at 142
    steps per period: its energy decays over 2 s as the textbook scheme's on a single mode of
    its frequency (BDF2 by 0.37 %, generalized-alpha by 4e-5), and no step is taken again by
    backward Euler. An outside check found 21 (BDF2) and 7 of 1,000 steps taken again and the
    damping 35 and 300 times the scheme's: predictors accepted within Newton's tolerance (a
    tenth of these forces) and an energy guard measured against the kinetic energy alone."""
    L, d, E, rho = 1.0, 0.01, 2.0e11, 7850.0
    EI, rhoA = E * np.pi * d ** 4 / 64, rho * np.pi * d ** 2 / 4
    omega = 1.875104 ** 2 / L ** 2 * np.sqrt(EI / rhoA)     # Euler-Bernoulli mode 1
    s = np.linspace(0.0, L, 21)[1:]
    k = 1.875104 / L
    shape = (np.cosh(k * s) - np.cos(k * s)
             - (np.cosh(k * L) + np.cos(k * L)) / (np.sinh(k * L) + np.sin(k * L))
             * (np.sinh(k * s) - np.sin(k * s))) / 2.0
    velocities = [[f"beam:{i + 1}", 0.0, 0.0, float(5e-5 * omega * w)] for i, w in enumerate(shape)]
    r = _run(CANTILEVER.format(integrator=integrator, velocities=velocities), tmp_path)
    a = r.arrays
    energy = a["kinetic_energy"] + a["elastic_energy"]
    window = 200
    measured = energy[-window:].mean() / energy[1:window + 1].mean()
    expected = _sdof_energy_ratio(integrator, omega, 1e-3, len(energy) - 1, window)
    print(integrator, "energy ratio", measured, "scheme", expected)
    assert r.summary["retaken_steps"] == 0
    assert abs(measured - expected) < 0.05 * (1.0 - expected) + 1e-5


@pytest.mark.parametrize("rho, per_period", [(0.7, 20), (0.7, 10), (0.5, 20)])
def test_generalized_alpha_damps_a_spring_as_the_scheme_says(tmp_path: Path, rho: float,
                                                             per_period: int) -> None:
    """Over 20 periods the energy falls as the textbook scheme's (Chung and Hulbert 1993), and no
    step is taken again by the energy guard. The scheme's start transient raises the energy by
    up to 4e-3 at its second step and gives it back; measured from the step's start alone, that
    step was taken again by backward Euler and cost 9 % (20 steps per period) and 28 % (10) of
    the energy (outside check). (At rho_inf 0.5 and 10 steps per period the steady swing, 1.4e-3,
    still has steps taken again: documented.) The mass on a spring of ``OSCILLATOR``."""
    mass = 1.0 + 1000.0 * np.pi * 0.005**2 / 2.0          # the end node's, half the element's
    omega = np.sqrt(1.0e6 * np.pi * 0.005**2 / mass)
    h = 2.0 * np.pi / omega / per_period
    steps = 20 * per_period
    r = _run(OSCILLATOR.format(dt=h, frames=h, integrator="generalized-alpha"), tmp_path,
             (f"simulation.duration={float(steps * h)!r}", f"simulation.rho_inf={rho}",
              "simulation.rtol=1e-10"))
    assert r.arrays["node_mass"][1] == pytest.approx(mass, rel=1e-12)
    energy = r.arrays["kinetic_energy"] + r.arrays["elastic_energy"]
    window = per_period    # a period's mean: the energy swings within one
    measured = energy[-window:].mean() / energy[1:window + 1].mean()
    expected = _sdof_energy_ratio("generalized-alpha", omega, h, steps, window, rho)
    assert r.summary["retaken_steps"] == 0
    assert measured == pytest.approx(expected, rel=1e-4), (measured, expected)


def test_error_controlled_steps_meet_the_tolerance(tmp_path: Path) -> None:
    """The benchmark thread (1.5 m nylon, clamped, released under gravity, 1 s) with
    generalized-alpha and the local error control, against a fixed step of 2e-4 s: the tip error
    falls with the tolerance (measured 1.36 mm at 1e-5 m, 0.31 mm at 1e-6 m, from 261 and 516
    steps; the tolerance bounds the root-mean-square of the nodes' local errors, the tip's own
    is larger), steps above the tolerance are rejected, and the steps stay within 0.2 ... 2
    times their predecessor, so the controller resizes rather than halves."""
    reference = _run(falling_thread_toml(simulation=FIXED_GA.format(dt=2e-4, adaptive="false")),
                     tmp_path / "r")
    tips, steps = [], []
    for tol in (1e-5, 1e-6):
        result = _run(falling_thread_toml(simulation=FIXED_GA.format(dt=1e-3, adaptive="true")
                                          + f"\nerror_tolerance = {tol}"), tmp_path / f"{tol}")
        tip = result.arrays["positions"][:, -1] - reference.arrays["positions"][:, -1]
        tips.append(float(np.linalg.norm(tip, axis=1).max()))
        steps.append(result.summary["steps"])
        assert result.summary["rejected_steps"] > 0
    print(f"\nerror control: tip error {tips[0] * 1e3:.3f} mm / {tips[1] * 1e3:.3f} mm from "
          f"{steps[0]} / {steps[1]} steps at 1e-5 / 1e-6 m")
    assert tips[0] < 2e-3 and tips[1] < 0.5e-3
    assert tips[1] < 0.5 * tips[0] and steps[1] > steps[0]


# --- 4. free flight: momentum and energy --------------------------------------------------------

FREE_ROD = """
[simulation]
type = "dynamic"
integrator = "{integrator}"
rho_inf = {rho_inf}
dt = {dt}
adaptive = false
duration = {duration}

[model]
type = "cosserat"
axial = "linear"

[[materials]]
name = "steel"
density = 7800.0
youngs_modulus = 2.0e11
poisson_ratio = 0.3
diameter = 0.01

[[rods]]
name = "bar"
material = "steel"
points = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]]
elements = 10
velocity = [0.3, 0.0, 0.1]

[[masses]]
node = "bar:start"
mass = 0.1
velocity = [0.0, -1.0, 0.0]

[[masses]]
node = "bar:end"
mass = 0.1
velocity = [0.2, 1.0, 0.5]

[output]
frame_interval = {frame_interval}
vtk = false
"""


def _free_flight(dt: float, steps: int, rho_inf: float = 1.0, frame_every: int = 10,
                 integrator: str = "generalized-alpha"):
    """March the free rod (no supports, loads or gravity) as ``run`` does; returns the model and
    ``(t, q, v)`` of every frame. The rod spins, flexes and drifts: the end masses start with
    opposite transverse velocities on top of a common drift."""
    scene = scene_from_toml(FREE_ROD.format(integrator=integrator, rho_inf=rho_inf, dt=dt,
                                            duration=dt * steps,
                                            frame_interval=dt * frame_every))
    prepared = prepare(scene)
    options = NewtonOptions(rtol=min(scene.simulation.rtol, 1e-6) * 1e-2)  # as rodnet.run does
    stepper = implicit_scheme(prepared.system, scene.integrator, scene.simulation.rho_inf, options)
    frames: list[tuple[float, object, np.ndarray]] = []
    integrate_implicit(stepper, prepared.state, prepared.times, dt, False,
                       lambda t, s: frames.append((t, s.q, s.v.copy())))
    return prepared.model, frames


def _momenta(model, q, v) -> tuple[np.ndarray, np.ndarray]:
    """Linear momentum sum m v and angular momentum about the origin
    sum m x cross v + sum R (J W), J the body rotary inertia and W the body angular velocity."""
    n = model.n_nodes
    velocity, omega = v[:3 * n].reshape(-1, 3), v[3 * n:].reshape(-1, 3)
    m = model.node_mass[:, None]
    spin = np.einsum("nij,nj->i", so3.quat_to_matrix(q.quat), model.rotary_inertia * omega)
    return (m * velocity).sum(axis=0), (m * np.cross(q.x, velocity)).sum(axis=0) + spin


def _invariant_errors(model, frames) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Relative errors of linear momentum, angular momentum and energy at every frame."""
    p0, l0 = _momenta(model, *frames[0][1:])
    e0 = sum(model.energy(*frames[0][1:]).values())
    dp, dl, de = [], [], []
    for _, q, v in frames:
        p, l = _momenta(model, q, v)
        dp.append(np.linalg.norm(p - p0) / np.linalg.norm(p0))
        dl.append(np.linalg.norm(l - l0) / np.linalg.norm(l0))
        de.append(sum(model.energy(q, v).values()) / e0 - 1.0)
    return np.array(dp), np.array(dl), np.array(de)


def _internal_torque(model, q, v) -> tuple[float, float]:
    """``|d L / dt|`` implied by the model's internal forces, and the scale ``sum |x| |f|``.

    ``M dv/dt = -g``, with ``g`` the internal force plus the gyroscopic term ``W x (J W)``; so
    ``dL/dt = -(sum x cross f + sum R f_rot)`` over the internal forces, which an objective
    element makes zero in every state: the model itself conserves angular momentum exactly.
    """
    n = model.n_nodes
    g = model.forces(q, v, 0.0, 1.0, False)[0]
    omega = v[3 * n:].reshape(-1, 3)
    f = g[:3 * n].reshape(-1, 3)
    moment = g[3 * n:].reshape(-1, 3) - np.cross(omega, model.rotary_inertia * omega)
    R = so3.quat_to_matrix(q.quat)
    torque = np.cross(q.x, f).sum(axis=0) + np.einsum("nij,nj->i", R, moment)
    scale = float(np.sum(np.linalg.norm(q.x, axis=1) * np.linalg.norm(f, axis=1))
                  + np.abs(moment).sum())
    return float(np.linalg.norm(torque)), scale


def test_generalized_alpha_free_flight_momentum_and_energy() -> None:
    """No supports, loads, gravity or damping; rho_inf = 1; 2000 steps of 1e-4 s.

    - Linear momentum: generalized-alpha enforces M dv/dt = -g at every step and the internal
      forces sum to zero, so it is conserved to round-off (1e-9 asserted; measured 3e-15).
    - Angular momentum: the model's internal forces exert no net torque in any state (1e-12
      asserted; measured 4e-17), so the rod conserves it exactly. Generalized-alpha does not:
      its Newmark-type update conserves no quadratic invariant, so sum x cross v + R J W drifts
      by O(dt^2): measured 8.5e-6 at dt 1e-4 s and 3.2e-5 at 2e-4 s over the first 0.1 s. The
      midpoint scheme conserves it (``test_midpoint_free_flight_conserves_momentum``).
    - Energy: bounded, oscillating about its start value with no upward trend (measured in
      [-1.4e-4, +1.5e-4], drift -7e-6; over 10^4 steps in [-1.4e-4, +1.4e-4], drift +6e-6:
      ``test_generalized_alpha_energy_over_ten_thousand_steps``).
    """
    model, frames = _free_flight(1e-4, 2000)
    dp, dl, de = _invariant_errors(model, frames)
    torques = [_internal_torque(model, q, v) for _, q, v in frames[1:]]  # frame 0 is stress-free
    worst_torque = max(t / s for t, s in torques)
    _, coarse = _free_flight(2e-4, 500, frame_every=5)  # the first 0.1 s, same frames
    dl_coarse = _invariant_errors(model, coarse)[1]
    dl_fine = dl[:len(dl_coarse)]
    fifth = len(de) // 5
    drift = float(de[-fifth:].mean() - de[:fifth].mean())
    print(f"\nfree flight, 2000 steps: linear momentum {dp.max():.2e}, internal torque "
          f"{worst_torque:.2e}, angular momentum {dl.max():.2e}; over 0.1 s {dl_fine.max():.2e} "
          f"(dt 1e-4) and {dl_coarse.max():.2e} (dt 2e-4), energy in "
          f"[{de.min():+.2e}, {de.max():+.2e}], drift {drift:+.2e}")
    assert dp.max() < 1e-9
    assert worst_torque < 1e-12
    assert dl.max() < 1e-4 and dl_coarse.max() > 2.5 * dl_fine.max()  # order > 1.3
    assert np.abs(de).max() < 1e-3
    assert drift < 2e-5


def _free_flight_invariants(integrator: str, steps: int = 10_000
                            ) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """Invariant errors of the free rod over ``steps`` steps of 1e-4 s, and the energy drift
    (mean of the last fifth of the frames minus that of the first fifth)."""
    model, frames = _free_flight(1e-4, steps, frame_every=20, integrator=integrator)
    dp, dl, de = _invariant_errors(model, frames)
    fifth = len(de) // 5
    drift = float(de[-fifth:].mean() - de[:fifth].mean())
    print(f"\n{integrator} free flight, {steps} steps: linear momentum {dp.max():.2e}, angular "
          f"momentum {dl.max():.2e}, energy in [{de.min():+.2e}, {de.max():+.2e}], drift {drift:+.2e}")
    return dp, dl, de, drift


@pytest.mark.parametrize("steps", [2000, pytest.param(10_000, marks=pytest.mark.slow)])
def test_midpoint_free_flight_conserves_momentum(steps: int) -> None:
    """The midpoint scheme on the same free rod, steps of 1e-4 s (10^4 steps: 1 s of spinning,
    flexing motion). Its forces act at one configuration, the step midpoint, where
    the objective element exerts no net force or moment, and its rotational update is the exact
    change of the spatial angular momentum R J W; so linear and angular momentum are conserved
    to Newton's tolerance: 1e-9 asserted, measured 2.7e-15 and 1.8e-13 over 10^4 steps (1.4e-15
    and 1.4e-13 over 2000). Energy is not a discrete invariant of the scheme but stays bounded
    with no trend: measured in [-7.0e-5, +7.1e-5], drift -2.9e-6 (first against last fifth of
    the run) over 10^4 steps; [-5.3e-5, +7.0e-5], drift +1.9e-6 over 2000."""
    dp, dl, de, drift = _free_flight_invariants("midpoint", steps)
    assert dp.max() < 1e-9
    assert dl.max() < 1e-9
    assert np.abs(de).max() < 1e-3
    assert abs(drift) < 2e-5


@pytest.mark.slow
def test_generalized_alpha_energy_over_ten_thousand_steps() -> None:
    """The same free rod over 10^4 steps with generalized-alpha: energy bounded, no upward
    drift. About 45 s, hence slow; the 2000-step version runs in the default suite."""
    dp, dl, de, drift = _free_flight_invariants("generalized-alpha")
    assert dp.max() < 1e-9
    assert dl.max() < 1e-4
    assert np.abs(de).max() < 1e-3
    assert drift < 2e-5


# --- 5. tension-only threads --------------------------------------------------------------------

CORD_EA, CORD_E = 500.0, 7.0e10
CORD = """
[[materials]]
name = "cord"                 # a soft elastic cord: EA = 500 N, 10 g/m
density = 1440.0
youngs_modulus = 7.0e10
poisson_ratio = 0.36
diameter = 1.0e-3
axial_stiffness = 500.0
mass_per_length = 0.01
viscosity = {viscosity}
"""

TETHERED_MASS = """
[simulation]
type = "dynamic"
integrator = "generalized-alpha"
rho_inf = 0.7
dt = 2.0e-4
adaptive = true
duration = {duration}

[model]
type = "cosserat"
axial = "{axial}"
{cord}
[[rods]]
name = "thread"
material = "cord"
points = [[0.0, 0.0, 0.0], [0.3, 0.0, 0.0]]
elements = 6

[[supports]]
node = "thread:start"
fix = "pin"

[[masses]]
node = "thread:end"
mass = 0.1
velocity = [-2.0, 4.0, 0.0]

[output]
frame_interval = 2.0e-4
vtk = false
"""


def _chord_strain_and_rate(result: RunResult, rest_length: float) -> tuple[np.ndarray, np.ndarray]:
    """Chord strain l / Le - 1 and its rate (F, E) from the saved positions and velocities."""
    seg = result.arrays["segments"]
    x, v = result.arrays["positions"], result.arrays["velocities"]
    chord, chord_velocity = x[:, seg[:, 1]] - x[:, seg[:, 0]], v[:, seg[:, 1]] - v[:, seg[:, 0]]
    length = np.linalg.norm(chord, axis=2)
    rate = np.sum(chord * chord_velocity, axis=2) / (length * rest_length)
    return length / rest_length - 1.0, rate


def test_tension_only_thread_never_pushes(tmp_path: Path) -> None:
    """A 0.1 kg mass on a 0.3 m Kelvin-Voigt cord, pinned at the other end, no gravity, launched
    inwards and sideways: it coasts inside the circle the cord allows and rebounds off it, so the
    cord goes slack and taut again and again (measured: the mass's element is pulled taut 5 times
    in 0.15 s).

    The law's physics: N = max(EA r(e) + eta A r'(e) de/dt, 0). So every element in every frame
    has N >= 0, and an element whose chord is shorter than its rest length (from the saved
    positions; the cord is straight at rest, so its axial strain cannot exceed the chord strain)
    carries exactly zero. The clamp is exercised: on stretched elements that shorten fast the
    viscous term alone would push (estimated from the chord strain rate: down to -6.8 N); there
    the output is 0. With ``axial = "linear"`` the same cord pushes at once: at t = 0 the mass's
    element shortens at de/dt = -2 m/s / Le = -40 /s, so N = eta A de/dt = tau EA de/dt = -30 N.

    Adaptive steps: the viscosity damps shear too (all modes), which on this cord's tiny rotary
    inertia makes the start acceleration ~3e13 rad/s^2 and a fixed first step of 2e-4 s fail.
    """
    tau = 1.5e-3                        # damping ratio ~0.1 of the taut cord-mass oscillation
    rest_length = 0.3 / 6
    cord = CORD.format(viscosity=tau * CORD_E)
    result = _run(TETHERED_MASS.format(duration=0.15, axial="tension-only", cord=cord),
                  tmp_path / "a")
    tension = result.arrays["tension"]
    strain, rate = _chord_strain_and_rate(result, rest_length)
    taut = tension[:, -1] > 0.0
    pulls = np.count_nonzero(np.diff(taut.astype(int)) == 1)
    kelvin_voigt = CORD_EA * strain + tau * CORD_EA * rate           # unclamped, stretched chords
    viscous_push = (strain > 0.0) & (kelvin_voigt < -0.1)
    print(f"\ntension-only cord: tension in [{tension.min()}, {tension.max():.2f}] N, "
          f"{pulls} slack-to-taut switches, {np.count_nonzero(strain < 0)} compressed chords, "
          f"{np.count_nonzero(viscous_push)} element-frames where the viscous term alone would "
          f"push "
          f"(down to {kelvin_voigt[strain > 0.0].min():.2f} N)")
    assert np.all(tension >= 0.0)
    assert np.all(tension[strain < 0.0] == 0.0)
    assert pulls >= 3 and np.count_nonzero(~taut) > 0.2 * len(taut)
    assert np.count_nonzero(viscous_push) > 0 and np.all(tension[viscous_push] == 0.0)
    linear = _run(TETHERED_MASS.format(duration=0.02, axial="linear", cord=cord), tmp_path / "b")
    pushed = float(linear.arrays["tension"][0, -1])
    print(f"  the same cord with the linear law: {pushed:.4f} N at t = 0, min "
          f"{linear.arrays['tension'].min():.2f} N")
    assert pushed == pytest.approx(tau * CORD_EA * -2.0 / rest_length, rel=1e-9)
    assert tension[0, -1] == 0.0


SNAP = """
[simulation]
type = "dynamic"
integrator = "generalized-alpha"
rho_inf = 0.7
dt = {dt}
adaptive = false
duration = 0.02

[model]
type = "cosserat"
axial = "tension-only"
{cord}
[[rods]]
name = "thread"
material = "cord"
points = [[0.0, 0.0, 0.0], [0.15, 0.006, 0.0], [0.3, 0.0, 0.0]]
elements = 6

[[supports]]
node = "thread:start"
fix = "pin"

[[masses]]
node = "thread:end"
mass = 0.1
velocity = [2.0, 0.0, 0.0]

[output]
frame_interval = {dt}
vtk = false
"""


def _snap_study(tmp_path: Path, dts: list[float]) -> list[float]:
    """A slack cord (rest length 0.08 % over the span, a shallow V) pinned at one end; its 0.1 kg
    end mass is launched away from the pin at 2 m/s and jerks it taut. Peak tension [N] per dt.

    Physics for scale: a massless cord would stop the mass at v sqrt(m EA / L0) = 25.8 N; the
    cord's own 3 g rings on top of that. Energy conservation bounds any element's tension by
    sqrt(2 E0 EA / Le), E0 = m v^2 / 2, as the cord starts unstretched and at rest (63.2 N)."""
    rest = 2.0 * np.hypot(0.15, 0.006)
    peaks = []
    for dt in dts:
        result = _run(SNAP.format(dt=dt, cord=CORD.format(viscosity=0.0)), tmp_path / f"{dt:g}")
        peaks.append(float(result.arrays["tension"].max()))
        assert result.arrays["tension"].min() >= 0.0
    massless = 2.0 * np.sqrt(0.1 * CORD_EA / rest)
    bound = np.sqrt(2.0 * (0.5 * 0.1 * 2.0**2) * CORD_EA / (rest / 6))
    changes = np.abs(np.diff(peaks))
    print(f"\nsnap: dt {dts}\n  peak tension {np.round(peaks, 3)} N, "
          f"changes {np.round(changes, 3)} N"
          f"\n  massless-cord value {massless:.2f} N, energy bound {bound:.1f} N")
    assert np.all(np.isfinite(peaks)) and max(peaks) < bound
    assert np.all(changes[1:] < changes[:-1])
    return peaks


def test_snap_peak_tension_converges_with_dt(tmp_path: Path) -> None:
    # measured: 27.87, 29.62, 29.33 N (changes 1.75, 0.29 N); the slow study adds
    # 29.286 N at 2.5e-5 s and 29.285 N at 1.25e-5 s
    _snap_study(tmp_path, [2e-4, 1e-4, 5e-5])


@pytest.mark.slow
def test_snap_peak_tension_with_finer_steps(tmp_path: Path) -> None:
    _snap_study(tmp_path, [2e-4, 1e-4, 5e-5, 2.5e-5, 1.25e-5])


POLYLINE_ROD = """
[simulation]
duration = 0.05
gravity = {gravity}
integrator = "bdf2"
adaptive = false
dt = 0.001
[model]
type = "cosserat"
axial = "linear"
[[materials]]
name = "soft"
density = 1200.0
youngs_modulus = 2.0e7
poisson_ratio = 0.4
diameter = 0.005
viscosity = 2000.0
[[rods]]
name = "r"
material = "soft"
points = {points}
elements = 8
[[supports]]
node = "r:start"
[[masses]]
node = "r:end"
mass = 0.02
[[loads]]
node = "r:end"
force = {force}
ramp = 0.02
[output]
vtk = false
frame_interval = 0.005
"""
"""A clamped three-member polyline rod (two corners out of plane) under gravity and a ramped
tip force, from an outside check of rotation invariance."""


@pytest.mark.parametrize("steps", ["fixed", "adaptive"])
def test_a_polyline_rod_turned_with_the_scene_moves_turned(tmp_path: Path, steps: str) -> None:
    """Every vector of the scene (points, gravity, load) turned by 37 degrees about (1, 2, 3):
    the positions are the turned ones and the tensions and the lumped rotary inertia the same,
    to round-off. A corner node's triad had taken its d2 from the global z axis, and its
    rotary inertia, kept diagonal in that triad, changed by 4.8 % with the turn (positions
    6.3e-6 of the motion apart at fixed steps); and the default error tolerance, a fraction of
    the structure's size, took the size from the axis-aligned bounding box (0.9811 m against
    0.9605 m turned), so adaptive runs took other steps."""
    axis = np.array([1.0, 2.0, 3.0]) / np.sqrt(14.0)
    R = so3.so3_exp((np.radians(37.0) * axis)[None])[0]
    points = np.array([[0.0, 0.0, 0.0], [0.4, 0.0, 0.0], [0.7, 0.25, 0.1], [0.9, 0.3, -0.15]])
    gravity, force = np.array([0.0, 0.0, -9.81]), np.array([0.3, 0.2, -0.5])

    def go(turn: np.ndarray, name: str) -> RunResult:
        text = POLYLINE_ROD.format(points=(points @ turn.T).tolist(),
                                   gravity=(turn @ gravity).tolist(),
                                   force=(turn @ force).tolist())
        overrides = ["simulation.adaptive=true"] if steps == "adaptive" else []
        result = run(scene_from_toml(text, overrides), tmp_path / name, progress=False)
        assert result.status == "ok", result.message
        return result

    base, turned = go(np.eye(3), "base").arrays, go(R, "turned").arrays
    motion = np.abs(base["positions"] - base["positions"][:1]).max()
    assert motion > 0.02
    np.testing.assert_allclose(turned["positions"], base["positions"] @ R.T, rtol=0,
                               atol=1e-11 * motion)
    np.testing.assert_allclose(turned["tension"], base["tension"], rtol=0,
                               atol=1e-9 * np.abs(base["tension"]).max())
    np.testing.assert_allclose(turned["rotation_node_inertia"], base["rotation_node_inertia"],
                               rtol=1e-12)


SPINNING_ROD = """
[simulation]
type = "dynamic"
duration = 5.0
integrator = "explicit"
gravity = [0.0, 0.0, 0.0]

[model]
type = "cosserat"
axial = "linear"

[[materials]]
name = "svq"
density = 1.0
youngs_modulus = 1.0
diameter = 1.0
axial_stiffness = 1.0e4
shear_stiffness = 1.0e4
bending_stiffness = 500.0
torsional_stiffness = 500.0
mass_per_length = 1.0
rotary_inertia_per_length = 10.0

[[rods]]
name = "rod"
material = "svq"
points = [[-5.0, 0.0, 0.0], [5.0, 0.0, 0.0]]
elements = 20
angular_velocity = [10.0, 0.0, 2.0]

[output]
frame_interval = 0.05
vtk = false
picture = false
plot = false
"""
"""A free rod (Simo and Vu-Quoc's section data) spinning about its axis and tumbling: no loads,
no damping."""


def test_explicit_rod_spinning_and_tumbling_keeps_momentum_and_energy(tmp_path: Path) -> None:
    """The explicit scheme's free rotation of the sections (C47a) keeps the spatial angular
    momentum of a free rod to round-off and its energy bounded; the update before it (the
    gyroscopic moment explicit, ``W1 = W0 - h J^-1 W0 x J W0``) gained 1.1 % of the energy in
    these 5 s and 77 % in 20 s, and the angular momentum drifted by 12 % (outside check)."""
    r = run(scene_from_toml(SPINNING_ROD), tmp_path, progress=False)
    assert r.status == "ok", r.message
    a = r.arrays
    m = a["node_mass"] if a["node_mass"].ndim == 1 else a["node_mass"][:, 0]
    R = so3.quat_to_matrix(a["rotation_node_quaternions"].reshape(-1, 4)).reshape(
        a["rotation_node_quaternions"].shape[:2] + (3, 3))
    L = np.einsum("n,fni->fi", m, np.cross(a["positions"], a["velocities"])) + np.einsum(
        "frij,frj->fi", R, a["rotation_node_inertia"][None] * a["rotation_node_spins"])
    assert np.linalg.norm(L - L[0], axis=1).max() <= 1e-10 * np.linalg.norm(L[0])
    energy = a["kinetic_energy"] + a["elastic_energy"]
    assert np.abs(energy / energy[0] - 1.0).max() <= 1e-3
