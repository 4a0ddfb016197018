"""The planar engine's shipped fits against the engines they were fitted to, on the fidelity
table's maneuvers, within the gates MuJoCo meets against pybullet (docs/planar.md; the full
table: benchmarks/engine_fidelity.py)."""

from __future__ import annotations

import importlib.util

import pytest

from smartcar_gym.calibration.engines_compared import (
    coast_down,
    odometry_error,
    spin_rate,
    steady_speed,
    umbmark,
)

#: maneuver, relative tolerance against the fitted engine (the issue's gates)
GATES = [
    *((steady_speed(v), 0.05) for v in (0.2, 0.3, 0.5)),
    *((steady_speed(v), 0.15) for v in (0.05, 0.1)),
    *((spin_rate(w), 0.15) for w in (0.5, 1.0, 2.0)),
    (coast_down(0.3), 0.10),
    (umbmark(1), 0.15), (umbmark(-1), 0.15),
]
ENGINES = ["pybullet", pytest.param("mujoco", marks=pytest.mark.skipif(
    importlib.util.find_spec("mujoco") is None, reason="engine='mujoco' needs the mujoco extra"))]


@pytest.mark.parametrize("engine", ENGINES)
@pytest.mark.parametrize("maneuver,tolerance", GATES, ids=[m.name for m, _ in GATES])
def test_the_shipped_fit_drives_like_its_engine(engine, maneuver, tolerance, shipped_model,
                                                shipped_config):
    reference = maneuver.measure(shipped_model, shipped_config, engine)
    value = maneuver.measure(shipped_model, shipped_config, "planar", planar_params=engine)
    assert value == pytest.approx(reference, rel=tolerance)


@pytest.mark.parametrize("engine", ENGINES)
def test_odometry_drifts_as_on_its_engine(engine, shipped_model, shipped_config):
    reference = odometry_error().measure(shipped_model, shipped_config, engine)
    value = odometry_error().measure(shipped_model, shipped_config, "planar",
                                     planar_params=engine)
    assert value == pytest.approx(reference, abs=0.03)


#: the casterbot's gates: the squares are left out (below)
CASTERBOT_GATES = [(m, tol) for m, tol in GATES if not m.name.startswith("UMBmark")]


def drives_like_pybullet(model, config, params) -> None:
    """The planar car with ``params`` within ``CASTERBOT_GATES`` and the odometry gate of the
    robot on pybullet."""
    for maneuver, tolerance in CASTERBOT_GATES:
        reference = maneuver.measure(model, config, "pybullet")
        value = maneuver.measure(model, config, "planar", planar_params=params)
        assert value == pytest.approx(reference, rel=tolerance), maneuver.name
    reference = odometry_error().measure(model, config, "pybullet")
    value = odometry_error().measure(model, config, "planar", planar_params=params)
    assert value == pytest.approx(reference, abs=0.03)


@pytest.mark.slow
def test_a_users_robot_is_identified_inside_the_gates() -> None:
    """The casterbot fixture (two wheels and a sliding caster ball), fitted from the fit's own
    drives on pybullet (``smartcar-calibrate --fit planar --model ...``, seed 0), drives like
    pybullet's casterbot within the speed, spin, coast-down and odometry gates (docs/planar.md,
    "A user's robot"). Its UMBmark square is not gated: it ends 0.11-0.22 m from the start on
    pybullet itself as the side goes from 0.98 to 1.02 m (a small difference of large moves;
    the 1 m square's value is a draw from that spread: seeds 0, 1 and 2 of the fit give +9,
    +41 and +30 %)."""
    from pathlib import Path

    from smartcar_gym.calibration.planar_fit import fit
    from smartcar_gym.calibration.recording import record
    from smartcar_gym.controller import load_controller_config
    from smartcar_gym.model import load_model

    fixture = Path(__file__).parent / "fixtures" / "casterbot_description"
    model = load_model(str(fixture / "urdf" / "casterbot.urdf.xacro"))
    config = load_controller_config(str(fixture / "config" / "casterbot_arbotix.yaml"))
    params = fit(model, config, record(model, config, "pybullet")).params
    drives_like_pybullet(model, config, params)


def reversal_turn(engine: str, **kwargs) -> float:
    """True over odometry yaw while reversing out of a fast left arc (SmartCar-v0 actions
    ``(1, 1)`` for 1.2 s, then ``(-0.9, 0.7)`` for 0.9 s): the wheels brake through zero with
    the turn held, and their spin momentum loads the front wheels (docs/planar.md)."""
    import gymnasium as gym
    import numpy as np

    env = gym.make("SmartCar-v0", engine=engine, goal_range=(2.3, 2.4), arena_size=20.0,
                   max_episode_steps=1000, **kwargs)
    try:
        env.reset(seed=0)
        for _ in range(12):
            info = env.step(np.array([1.0, 1.0], dtype=np.float32))[4]
        start = info["pose"][2], info["odom_pose"][2]
        for _ in range(9):
            info = env.step(np.array([-0.9, 0.7], dtype=np.float32))[4]
    finally:
        env.close()
    turned = [(after - before + np.pi) % (2 * np.pi) - np.pi
              for before, after in zip(start, (info["pose"][2], info["odom_pose"][2]),
                                       strict=True)]
    return float(turned[0] / turned[1])


@pytest.mark.parametrize("engine", ENGINES)
def test_a_reversal_out_of_a_turn_turns_as_on_its_engine(engine) -> None:
    """pybullet turns 0.86 of its odometry's turn here, MuJoCo 0.75: pybullet's rotor inertia
    sits on the wheel link and its momentum loads the front wheels as they brake, MuJoCo's
    armature has none. Each fit follows its engine (the model without the spin moment: 0.75
    on both)."""
    reference = reversal_turn(engine)
    assert reversal_turn("planar", planar_params=engine) == pytest.approx(reference, abs=0.03)


@pytest.mark.slow
def test_a_robot_balanced_on_its_axle_is_identified_inside_the_gates() -> None:
    """The axlebot fixture (two wheels, a rear caster, the centre of mass 1.4 mm behind the
    axle: the caster carries under 2 % of the weight), fitted from pybullet's drives in 5
    generations from neutral values, its load shift inside what its contacts allow, drives
    like pybullet's axlebot within the casterbot's gates (its UMBmark square is left out for
    the same reason: a small difference of large moves)."""
    from pathlib import Path

    from smartcar_gym.calibration.planar_fit import fit
    from smartcar_gym.calibration.recording import record
    from smartcar_gym.controller import load_controller_config
    from smartcar_gym.model import load_model

    fixture = Path(__file__).parent / "fixtures" / "axlebot_description"
    model = load_model(str(fixture / "urdf" / "axlebot.urdf.xacro"))
    config = load_controller_config(str(fixture / "config" / "axlebot_arbotix.yaml"))
    params = fit(model, config, record(model, config, "pybullet"), generations=5).params
    assert -0.0737 <= params.load_shift_x <= 0.00137  # ahead of it the caster would pull
    drives_like_pybullet(model, config, params)


def alternation(engine: str, steps: int = 2000, **kwargs) -> tuple[float, float]:
    """Full forward, full reverse, alternating every step (SmartCar-v0 actions ``(+-1, 0)``,
    200 s): the car's end x (m) and the path it drove (m)."""
    import gymnasium as gym
    import numpy as np

    env = gym.make("SmartCar-v0", engine=engine, max_episode_steps=steps + 1, arena_size=100.0,
                   **kwargs)
    try:
        env.reset(seed=0)
        path, before = 0.0, np.zeros(2)
        for t in range(steps):
            info = env.step(np.array([1.0 - 2.0 * (t % 2), 0.0], dtype=np.float32))[4]
            path += float(np.hypot(*(info["pose"][:2] - before)))
            before = np.array(info["pose"][:2])
    finally:
        env.close()
    return float(info["pose"][0]), path


#: how far the planar car's end may lie from its engine's after ``alternation`` (m)
ALTERNATION_GATE_M = 0.2


@pytest.mark.parametrize("engine", ENGINES)
def test_alternating_full_forward_and_reverse_creeps_as_little_as_on_its_engine(engine):
    """Issue 42 item 12: the planar car creeps under +1/-1 alternation (pybullet fit -0.12 m
    after 2000 steps, the built-in defaults +0.19 m; pybullet +0.003 m, MuJoCo's fit +0.012 m).
    The wheels never leave the gearbox's dead band: each step's command is undone by the next
    before the ramped target gets far, and the car drives about 0.5 m in 200 s, back and forth
    in steps of a few tenths of a millimetre (odometry agrees: the wheels creep, not the
    tyres). Which way each cycle's creep goes is settled by the integer board PID's limit
    cycle against the regularised Coulomb friction (``gearbox_friction_scale``,
    ``stiction_speed``, ``rolling_resistance``): a staircase of those values (the pybullet fit
    with gearbox friction 0.98, 0.99, 0.992, 1.0 ends +0.16, +0.02, -0.12, +0.01 m; stiction
    0.005, 0.02, 0.05, 0.2 rad/s ends +0.016, +0.011, -0.12, +0.013 m), not a bias of the
    model, so the fit cannot aim at it. The gate holds because the creep is bounded by the
    little the car moves at all: under 0.2 m in 200 s (1 mm/s against the commanded 0.5 m/s),
    within a path of at most 1 m on either engine."""
    reference, reference_path = alternation(engine)
    value, path = alternation("planar", planar_params=engine)
    assert reference_path < 1.0 and path < 1.0
    assert abs(value - reference) <= ALTERNATION_GATE_M
