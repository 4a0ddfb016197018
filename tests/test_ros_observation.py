"""The policy node's observation from ROS messages is the env's, bit for bit, on the same state.

An episode of SmartCar-v0 is driven by ``GoalDriver`` (the node's decisions) with the shipped
policy: at every step the env's state is written as the messages the bringup node publishes,
read back by the driver, and the observation it builds is compared with the env's own. Messages
are made as plain namespaces and, with rosbags installed, also sent through ROS 1 serialisation.
"""

from __future__ import annotations

import importlib.util
from types import SimpleNamespace

import gymnasium as gym
import numpy as np
import pytest

from smartcar_gym.bags import messages as m
from smartcar_gym.envs.policy_settings import policy_settings
from smartcar_gym.envs.state import CarState
from smartcar_gym.policy import Policy
from smartcar_gym.ros.driving import GoalDriver

HAS_ROSBAGS = importlib.util.find_spec("rosbags") is not None


class NamespaceTypes:
    """Messages as plain namespaces (what the readers need: attribute access)."""

    def __call__(self, msg_type: str, /, **fields):
        return SimpleNamespace(**fields)

    def time(self, ns: int):
        return SimpleNamespace(secs=ns // m.NS_PER_S, nsecs=ns % m.NS_PER_S)


class WireTypes:
    """rosbags' ROS 1 messages, serialised and deserialised as on the wire."""

    def __init__(self) -> None:
        from smartcar_gym.bags.ros1 import typestore

        self.store = typestore()
        self.types = m.RosbagsTypes(self.store)

    def __call__(self, msg_type: str, /, **fields):
        return self.types(msg_type, **fields)

    def time(self, ns: int):
        return self.types.time(ns)

    def wire(self, msg, msg_type: str):
        full = msg_type.replace("/", "/msg/")
        return self.store.deserialize_ros1(self.store.serialize_ros1(msg, full), full)


@pytest.fixture(scope="module")
def policy():
    return Policy.load("default")


@pytest.mark.parametrize("backend", [
    "namespace",
    pytest.param("wire", marks=pytest.mark.skipif(not HAS_ROSBAGS,
                                                  reason="rosbags (the ros extra) not installed")),
])
def test_node_observation_equals_the_envs_bit_for_bit(policy, backend):
    types = NamespaceTypes() if backend == "namespace" else WireTypes()
    wire = getattr(types, "wire", lambda msg, _: msg)
    raw = []

    def act(obs):
        raw.append(policy.act(obs))
        return raw[-1]

    driver = GoalDriver(policy.settings, act, stale_after_s=0.5,
                        stop_on="ground_truth")
    env = gym.make("SmartCar-v0")
    base = env.unwrapped
    sent = []
    cmd_vel = base.robot.cmd_vel
    base.robot.cmd_vel = lambda v, w: (sent.append((v, w)), cmd_vel(v, w))[1]

    def publish():
        """What the bringup node publishes at a controller update, as the driver gets it."""
        t, robot = base.sim.now_ns, base.robot
        driver.on_odometry(wire(m.odometry_message(types, robot.odometry, t),
                                "nav_msgs/Odometry"))
        driver.on_joint_states(wire(m.joint_state_message(types, robot.joint_states(), t),
                                    "sensor_msgs/JointState"))
        truth = m.ground_truth_message(types, robot.body.link_pose(), robot.body.velocity(),
                                       t, "base_link")
        driver.on_ground_truth(wire(truth, "nav_msgs/Odometry"))
        return t

    try:
        obs, _ = env.reset(seed=3)
        driver.on_goal(wire(m.goal_message(types, base.goal, publish(), "odom"),
                            "geometry_msgs/PoseStamped"))
        steps = 0
        while True:
            command = driver.step(base.sim.now_ns)
            if driver.goal is None:  # reached (ground truth: the env's success)
                break
            assert driver.last_observation.dtype == obs.dtype == np.float32
            assert driver.last_observation.tobytes() == obs.tobytes(), steps
            obs, _, terminated, truncated, info = env.step(raw[-1])
            assert sent[-1] == command.twist  # the env's cmd_vel is the node's twist
            publish()
            steps += 1
            assert not truncated
        assert terminated and info["is_success"] and steps > 20
        assert command.twist == (0.0, 0.0) and "reached" in command.log[1]
    finally:
        env.close()


def test_theta_through_a_quaternion_keeps_the_float32_observation():
    """The env reads odometry's unwrapped theta; the node only sees a quaternion. The task
    builds both observations from a one-car state (``CarState``) that differs only there."""
    settings = policy_settings("SmartCar-v0")
    task = settings.task
    rng = np.random.default_rng(0)
    types = NamespaceTypes()

    def observe(odometry):
        state = CarState.zeros(1, len(settings.wheel_joints))
        state.odometry[0] = (odometry.x, odometry.y, odometry.theta, odometry.v,
                             odometry.omega)
        state.wheel_position[0] = [0.1, 0.2, 0.3, 0.4]
        state.wheel_velocity[0] = [1.0, 2.0, 3.0, 4.0]
        state.goal[0] = [0.5, -0.7]
        state.previous_action[0] = [0.1, -0.2]
        return task.observe(SimpleNamespace(state=state, threads=1,
                                            values=lambda array: array))[0]

    for _ in range(2000):
        theta = rng.uniform(-30, 30)
        odom = m.Odometry(0.0, "odom", "base_link", *rng.uniform(-2, 2, 2), theta,
                          *rng.uniform(-1, 1, 2))
        reading = m.read_odometry(m.odometry_message(types, odom, 0))
        assert abs(reading.theta) <= np.pi  # the quaternion's angle, wrapped
        env_obs, node_obs = observe(odom), observe(reading)
        assert env_obs.dtype == node_obs.dtype == np.float32
        assert env_obs.tobytes() == node_obs.tobytes(), theta
