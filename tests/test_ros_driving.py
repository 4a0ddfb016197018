"""The policy node's decisions (``GoalDriver``, no ROS): it drives only on good, fresh data.

A goal in another frame, a malformed message, stale or missing odometry or joint states, a car
outside the trained arena: a zero twist and one log line saying why (repeated lines are not
logged again); no goal: nothing is published at all.
"""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest

from smartcar_gym.bags import messages as m
from smartcar_gym.controller import Odometry
from smartcar_gym.envs.policy_settings import policy_settings
from smartcar_gym.envs.robots.smartcar import JointStates
from smartcar_gym.ros.driving import STOP, GoalDriver

S = m.NS_PER_S
WHEELS = ("left_front_wheel_joint", "left_back_wheel_joint", "right_front_wheel_joint",
          "right_back_wheel_joint")


class Types:
    def __call__(self, msg_type: str, /, **fields):
        return SimpleNamespace(**fields)

    def time(self, ns: int):
        return SimpleNamespace(secs=ns // S, nsecs=ns % S)


T = Types()


@pytest.fixture(scope="module")
def settings():
    return policy_settings("SmartCar-v0")


def odometry(x=0.0, y=0.0, theta=0.0, stamp_ns=0, frame="odom"):
    return m.odometry_message(T, Odometry(0.0, frame, "base_link", x, y, theta, 0.0, 0.0),
                              stamp_ns)


def joints(stamp_ns=0, names=WHEELS, position=(0.0, 0.1, 0.2, 0.3)):
    return m.joint_state_message(
        T, JointStates(tuple(names), np.array(position), np.ones(len(position)),
                       np.zeros(len(position))), stamp_ns)


def goal(x=1.0, y=0.5, frame="odom"):
    return m.goal_message(T, (x, y), 0, frame)


def driver(settings, action=(0.5, -0.25), stop_on="odometry"):
    seen = []

    def act(obs):
        seen.append(obs)
        return np.array(action, dtype=np.float32)

    d = GoalDriver(settings, act, stale_after_s=0.5, stop_on=stop_on)
    d.seen = seen
    return d


def ready(d, now=1 * S, **odom):
    d.on_odometry(odometry(stamp_ns=now, **odom))
    d.on_joint_states(joints(stamp_ns=now))
    return now


def test_no_goal_publishes_nothing(settings):
    d = driver(settings)
    assert d.step(ready(d)).twist is None
    assert d.watchdog(5 * S).twist is None and not d.seen


def test_drives_with_the_policys_action_scaled_as_the_env(settings):
    d = driver(settings, action=(2.0, -0.25))  # clipped to 1 as SmartCarEnv.step clips
    assert d.on_goal(goal()).log == ("info", "new goal (1, 0.5) in frame odom")
    command = d.step(ready(d))
    assert command.twist == (1.0 * settings.max_linear, -0.25 * settings.max_angular)
    assert command.log is None
    assert d.previous_action.tolist() == [1.0, -0.25]  # the next observation's
    names = settings.observation.names
    assert d.seen[-1][names.index("goal_x_odom")] == pytest.approx(1.0)


def test_rviz_slash_frames_count_as_the_same_frame(settings):
    d = driver(settings)
    d.on_goal(goal(frame="/odom"))  # urdf.rviz has Fixed Frame /odom
    assert d.step(ready(d)).twist != STOP


def test_goal_in_another_frame_is_dropped_with_a_stop(settings):
    d = driver(settings)
    d.on_goal(goal(frame="map"))
    command = d.step(ready(d))
    assert command.twist == STOP
    level, text = command.log
    assert level == "error" and "'map'" in text and "'odom'" in text and "Fixed Frame" in text
    assert d.goal is None and not d.seen
    assert d.step(ready(d, now=2 * S)).twist is None  # dropped: nothing more


@pytest.mark.parametrize("bad, expected", [
    (lambda: goal(x=math.nan), "goal refused: goal has non-finite values (x=nan)"),
    (lambda: goal(x=3.0), "goal refused: (3, 0.5) lies outside the arena the policy was "
                          "trained in (|x|, |y| <= 2.5 m around the odometry origin)"),
])
def test_bad_goals_are_refused_with_a_stop(settings, bad, expected):
    d = driver(settings)
    command = d.on_goal(bad())
    assert command == type(command)(STOP, ("error", expected))
    assert d.goal is None


def test_stale_odometry_stops_the_car_and_says_so_once(settings):
    d = driver(settings)
    d.on_goal(goal())
    ready(d, now=1 * S)
    assert d.step(1 * S).twist not in (None, STOP)
    first = d.watchdog(int(1.6 * S))  # 0.6 s without odometry, stale after 0.5 s
    assert first.twist == STOP
    assert first.log == ("error", "odometry is stale (0.60 s old, more than 0.5 s): stopping")
    again = d.watchdog(2 * S)
    assert again.twist == STOP and again.log is None  # said once
    assert d.watchdog(int(1.4 * S)).twist is None  # fresh enough: the odometry decides
    ready(d, now=3 * S)  # fresh data: driving again
    assert d.step(3 * S).twist not in (None, STOP)
    assert d.watchdog(int(3.6 * S)).log is not None  # a new stale spell is said again


def test_stale_joint_states_stop_the_car(settings):
    d = driver(settings)
    d.on_goal(goal())
    d.on_odometry(odometry(stamp_ns=2 * S))
    d.on_joint_states(joints(stamp_ns=1 * S))
    command = d.step(2 * S)
    assert command.twist == STOP and "joint_states is stale (1.00 s old" in command.log[1]


@pytest.mark.parametrize("message, expected", [
    (lambda: odometry(x=math.inf), "odometry has non-finite values (x=inf): stopping"),
    (lambda: _scaled_quaternion(odometry(), 2.0),
     "odometry orientation is not a unit quaternion (|q| = 2): stopping"),
])
def test_malformed_odometry_stops_the_car(settings, message, expected):
    d = driver(settings)
    d.on_goal(goal())
    ready(d)
    d.on_odometry(message())
    command = d.step(1 * S)
    assert command.twist == STOP and command.log == ("error", expected)


def _scaled_quaternion(msg, factor):
    q = msg.pose.pose.orientation
    q.z, q.w = q.z * factor, q.w * factor
    return msg


@pytest.mark.parametrize("message, expected", [
    (lambda: joints(names=WHEELS[:3], position=(0.0, 0.1, 0.2)),
     "joint_states has no right_back_wheel_joint (it names left_front_wheel_joint, "
     "left_back_wheel_joint, right_front_wheel_joint): stopping"),
    (lambda: _short(joints()), "joint_states names 4 joints but has 3 positions and 4 "
                               "velocities: stopping"),
])
def test_malformed_joint_states_stop_the_car(settings, message, expected):
    d = driver(settings)
    d.on_goal(goal())
    d.on_odometry(odometry(stamp_ns=1 * S))
    d.on_joint_states(message())
    command = d.step(1 * S)
    assert command.twist == STOP and command.log == ("error", expected)


def _short(msg):
    msg.position = msg.position[:3]
    return msg


def test_joint_states_are_read_by_name_in_the_envs_wheel_order(settings):
    d = driver(settings)
    d.on_goal(goal())
    d.on_odometry(odometry(stamp_ns=1 * S))
    shuffled = (WHEELS[3], WHEELS[0], WHEELS[2], WHEELS[1])
    d.on_joint_states(joints(stamp_ns=1 * S, names=shuffled, position=(3.0, 0.0, 2.0, 1.0)))
    d.step(1 * S)
    names = settings.observation.names
    obs = d.seen[-1]
    assert [obs[names.index(f"{w}.position")] for w in WHEELS] == [0.0, 1.0, 2.0, 3.0]


def test_no_data_yet_waits_stopped(settings):
    d = driver(settings)
    d.on_goal(goal())
    command = d.step(0)
    assert command.twist == STOP
    assert command.log == ("warn", "no odometry received yet: waiting, stopped")


def test_stops_when_odometry_reaches_the_goal(settings):
    d = driver(settings)
    d.on_goal(goal(1.0, 0.5))
    command = d.step(ready(d, x=0.95, y=0.45))  # 0.071 m < 0.1 m (the env's goal_tolerance)
    assert command.twist == STOP
    assert command.log == ("info", "goal (1, 0.5) reached: odometry says 0.071 m away")
    assert d.goal is None and d.step(2 * S).twist is None
    d.on_goal(goal(-1.0, 0.0))  # a new goal starts again, from a zero previous action
    assert d.previous_action.tolist() == [0.0, 0.0]
    assert d.step(ready(d, now=3 * S, x=0.95, y=0.45)).twist not in (None, STOP)


def test_ground_truth_stop_needs_fresh_ground_truth(settings):
    d = driver(settings, stop_on="ground_truth")
    d.on_goal(goal(1.0, 0.5))
    now = ready(d, x=0.95, y=0.45)  # odometry says reached: not what counts here
    command = d.step(now)
    assert command.twist == STOP and command.log == (
        "warn", "no base_pose_ground_truth received yet: waiting, stopped")
    d.on_ground_truth(odometry(x=0.7, y=0.2, stamp_ns=now, frame="world"))
    assert d.step(now).twist not in (None, STOP)
    d.on_ground_truth(odometry(x=1.0, y=0.45, stamp_ns=now, frame="world"))
    command = d.step(now)
    assert command.twist == STOP and command.log == (
        "info", "goal (1, 0.5) reached: ground truth 0.050 m away (odometry says 0.071 m)")


def test_a_car_outside_the_trained_arena_is_stopped(settings):
    d = driver(settings)
    d.on_goal(goal(2.0, 0.0))
    command = d.step(ready(d, x=2.6))
    assert command.twist == STOP and "outside the arena the policy was trained in" in \
        command.log[1]


def test_a_non_finite_action_stops_the_car(settings):
    d = driver(settings, action=(math.nan, 0.0))
    d.on_goal(goal())
    command = d.step(ready(d))
    assert command.twist == STOP and command.log == (
        "error", "the policy gave the action [nan, 0.0] (expected 2 finite numbers): stopping")


def test_stop_on_is_checked(settings):
    with pytest.raises(ValueError, match="stop_on must be one of"):
        GoalDriver(settings, lambda obs: obs, 0.5, stop_on="odom")


def test_a_goal_sent_from_where_the_car_stands_is_an_episode_from_the_origin(settings):
    """The car at (1, 1) facing +y by odometry, a goal 1 m ahead of it at (1, 2): the policy
    sees what the env shows at reset with a goal at (1, 0)."""
    d = driver(settings)
    d.on_goal(goal(x=1.0, y=2.0))
    d.step(ready(d, x=1.0, y=1.0, theta=math.pi / 2))
    seen = dict(zip(settings.observation.names, d.seen[-1], strict=True))
    for name, value in [("odom_x", 0.0), ("odom_y", 0.0), ("odom_cos_yaw", 1.0),
                        ("odom_sin_yaw", 0.0), ("goal_x_base", 1.0), ("goal_y_base", 0.0),
                        ("goal_distance", 1.0), ("goal_x_odom", 1.0), ("goal_y_odom", 0.0)]:
        assert seen[name] == pytest.approx(value, abs=1e-6), name
    # the car moved 0.5 m ahead: half way there, in the frame of the goal's episode
    d.step(ready(d, now=2 * S, x=1.0, y=1.5, theta=math.pi / 2))
    seen = dict(zip(settings.observation.names, d.seen[-1], strict=True))
    assert (seen["odom_x"], seen["goal_x_base"]) == pytest.approx((0.5, 0.5), abs=1e-6)
    d.on_goal(goal(x=0.0, y=1.5))  # a new goal: a new origin, where the car stands now
    d.step(ready(d, now=3 * S, x=1.0, y=1.5, theta=math.pi / 2))
    seen = dict(zip(settings.observation.names, d.seen[-1], strict=True))
    assert (seen["odom_x"], seen["goal_x_odom"], seen["goal_y_odom"]) == pytest.approx(
        (0.0, 0.0, 1.0), abs=1e-6)  # 1 m to the left


def test_a_policy_trained_to_stop_is_done_only_at_rest():
    d = driver(policy_settings("SmartCarArrive-v0"))
    d.on_goal(goal(x=1.0, y=0.5))
    moving = m.odometry_message(T, Odometry(0.0, "odom", "base_link", 0.95, 0.5, 0.0, 0.05,
                                            0.0), 1 * S)
    d.on_odometry(moving)
    d.on_joint_states(joints(stamp_ns=1 * S))
    assert d.step(1 * S).twist not in (None, STOP) and d.goal is not None  # 0.05 m/s: driving
    command = d.step(ready(d, now=2 * S, x=0.95, y=0.5))  # at rest, 0.05 m away
    assert command.twist == STOP and d.goal is None
    assert command.log == ("info", "goal (1, 0.5) reached: odometry says 0.050 m away, "
                                   "0.000 m/s")
