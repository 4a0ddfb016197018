"""Users' own robots drive straight at the default stepping (issue 23, item 5).

Two fixtures of our own, neither of them the smartcar: ``casterbot`` (two 35 mm drive wheels and
a 20 g caster ball, 1.3 kg: differential drive) and ``heavybot`` (four 50 mm wheels of 0.3 kg
under a 6 kg box: skid steer), each with its own ArbotiX YAML. Driven straight at 0.2 m/s, a
lopsided start used to turn the casterbot by one PWM count for good (1.2 cm/m sideways at
10 ms, 2.2 cm/m at 5 ms, 1.2 cm/m at 2 ms); docs/stepping.md, "Driving straight".
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from smartcar_gym.calibration.maneuvers import random_commands, run
from smartcar_gym.controller import WheelEncoder, load_controller_config
from smartcar_gym.envs.robots import SmartCarRobot
from smartcar_gym.envs.smartcar_env import SmartCarEnv
from smartcar_gym.model import RobotModel, load_model
from smartcar_gym.sim.clock import DEFAULT_MAX_SUBSTEP_S
from smartcar_gym.sim.pybullet.simulator import Simulator

FIXTURES = Path(__file__).resolve().parent / "fixtures"
CASTERBOT = (FIXTURES / "casterbot_description/urdf/casterbot.urdf.xacro",
             FIXTURES / "casterbot_description/config/casterbot_arbotix.yaml")
HEAVYBOT = (FIXTURES / "heavybot_description/urdf/heavybot.urdf.xacro",
            FIXTURES / "heavybot_description/config/heavybot_arbotix.yaml")
SPEED = 0.2  # m/s of cmd_vel
DRIFT_PER_M = 0.005  # the bound: under 0.5 cm sideways per metre


def drive_straight(model: Path, config: Path, **kwargs: object) -> tuple[float, float, SmartCarEnv]:
    """cmd_vel (0.2, 0) for 5 s in SmartCar-v0; (forward, sideways) m over the last 3 s,
    measured in the heading the robot had after the first 2 s (the issue's drive)."""
    env = SmartCarEnv(model=model, controller_config=config, **kwargs)
    env.reset(seed=0, options={"goal": (0.0, 2.0)})  # abeam: never reached driving along x
    action = np.array([SPEED / env.max_linear, 0.0])
    for _ in range(20):
        *_, info = env.step(action)
    x0, y0, yaw0 = info["pose"]
    for _ in range(30):
        _, _, terminated, _, info = env.step(action)
        assert not terminated
    dx, dy = info["pose"][0] - x0, info["pose"][1] - y0
    forward = dx * math.cos(yaw0) + dy * math.sin(yaw0)
    sideways = -dx * math.sin(yaw0) + dy * math.cos(yaw0)
    env.close()
    return forward, sideways, env


def test_drive_kind_from_the_wheels(shipped_model):
    assert shipped_model.drive_kind == "skid"
    assert load_model(CASTERBOT[0]).drive_kind == "differential"
    assert load_model(HEAVYBOT[0]).drive_kind == "skid"


@pytest.mark.parametrize("robot", [CASTERBOT, HEAVYBOT], ids=["casterbot", "heavybot"])
def test_user_robots_drive_straight_at_the_default(robot):
    forward, sideways, env = drive_straight(*robot)
    assert env.max_substep_s == DEFAULT_MAX_SUBSTEP_S
    # 0.6 m commanded; the firmware's PID rests anywhere in its +-4 ticks/frame dead band
    assert forward == pytest.approx(SPEED * 3.0, rel=0.07)
    assert abs(sideways) / forward < DRIFT_PER_M


@pytest.mark.parametrize("robot", [CASTERBOT, HEAVYBOT], ids=["casterbot", "heavybot"])
def test_user_robots_drive_straight_on_mujoco(robot):
    pytest.importorskip("smartcar_gym.sim.mujoco", reason="engine='mujoco' needs the mujoco extra")
    forward, sideways, env = drive_straight(*robot, engine="mujoco")
    # the caster ball drags more on MuJoCo's elliptic cones (0.49 m for pybullet's 0.59 m)
    assert forward == pytest.approx(SPEED * 3.0, rel=0.2)
    assert abs(sideways) / forward < DRIFT_PER_M


def test_casterbot_drifts_without_the_guards(monkeypatch):
    """The issue's failure, reproduced: taken for a skid base (no guards), the casterbot turns."""
    monkeypatch.setattr(RobotModel, "drive_kind", property(lambda self: "skid"))
    forward, sideways, _ = drive_straight(*CASTERBOT)
    assert abs(sideways) / forward > 2 * DRIFT_PER_M  # 1.2 cm/m


def test_the_smartcar_steps_as_before():
    env = SmartCarEnv()
    env.reset(seed=0)
    assert env.max_substep_s == DEFAULT_MAX_SUBSTEP_S
    assert not env.sim.contacts_converged
    assert env.robot.encoder_phase_ticks == 0.0
    env.close()


def test_a_differential_robot_gets_the_guards_and_an_explicit_substep_wins():
    env = SmartCarEnv(model=CASTERBOT[0], controller_config=CASTERBOT[1], max_substep_s=0.004)
    env.reset(seed=0)
    assert env.sim.contacts_converged
    assert env.robot.encoder_phase_ticks == 0.5
    env.step(np.array([0.4, 0.0]))
    assert env.sim.max_substep_s == 0.004
    assert env.sim.time_step_s <= 0.004
    env.close()


def lopsidedness_ticks() -> float:
    """Open loop: the casterbot's wheels under equal torques for 0.5 s at 10 ms substeps (no
    cmd_vel, so the board never drives them); how far apart they rolled, in encoder ticks."""
    model = load_model(CASTERBOT[0])
    config = load_controller_config(CASTERBOT[1])
    sim = Simulator()
    robot = SmartCarRobot(sim, model, config)
    robot.spawn()
    start = robot.body.joint_angles(robot.wheel_joint_indices)
    robot.body.hold_torques(robot.wheel_joint_indices, [0.1, 0.1], key="motors")
    sim.run_for(0.5)
    end = robot.body.joint_angles(robot.wheel_joint_indices)
    sim.close()
    left, right = ((e - s) * model.wheel_radius_m * config.ticks_meter
                   for s, e in zip(start, end, strict=True))
    assert left > 20  # it rolled (25 ticks)
    return abs(left - right)


def test_converged_contacts_keep_the_sides_equal(monkeypatch):
    assert lopsidedness_ticks() < 1e-3  # 1.1e-4 tick
    monkeypatch.setattr(Simulator, "converge_contacts", lambda self: None)
    assert lopsidedness_ticks() > 0.1  # 10 solver iterations: 0.35 tick


def test_the_encoder_starts_on_an_edge_or_mid_tick():
    encoder = WheelEncoder(0.035, 8000)  # 280 ticks per radian
    encoder.reset(1.0)
    assert encoder.count(1.0) == 0
    assert encoder.count(1.0 - 1e-12) == -1  # the least creep back counts
    encoder.reset(1.0, 0.5)
    assert encoder.count(1.0 - 1e-12) == 0
    assert encoder.count(1.0 - 0.49 / 280) == 0
    assert encoder.count(1.0 - 0.51 / 280) == -1
    assert encoder.count(1.0 + 0.49 / 280) == 0
    assert encoder.count(1.0 + 0.51 / 280) == 1
    with pytest.raises(ValueError, match=r"phase_ticks must be in \[0, 1\), got 1.0"):
        encoder.reset(0.0, 1.0)


def test_reset_restores_the_default_solver(shipped_model, shipped_config):
    """A world that held a differential robot steps the smartcar exactly as a fresh one."""

    def rollout(sim: Simulator) -> list[tuple[float, ...]]:
        robot = SmartCarRobot(sim, shipped_model, shipped_config)
        robot.spawn()
        samples = run(robot, random_commands(3.0, 10.0, seed=1))
        return [(s.x, s.y, s.yaw, s.odom_x, s.odom_y) for s in samples]

    fresh = Simulator()
    used = Simulator()
    SmartCarRobot(used, load_model(CASTERBOT[0]), load_controller_config(CASTERBOT[1])).spawn()
    assert used.contacts_converged
    used.reset()
    assert not used.contacts_converged
    assert rollout(used) == rollout(fresh)
    fresh.close()
    used.close()
