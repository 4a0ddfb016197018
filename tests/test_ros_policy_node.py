"""The policy node's subscriptions under a backlog (rospy's own framing, no master).

A node that falls behind its odometry (a loaded machine, bringup at a fast ``--speed``) finds
several messages waiting when it reads the socket. rospy hands the callback the last
``queue_size`` of them: the node's state topics keep one, so it decides once, on the newest
odometry, and drives. Kept ten, it worked through odometry stale by the time it read it and
stopped the car at each (tests/test_ros_live.py's nav-goal run stalled so, behind by 30 ms a
decision). rospy runs in a child process: importing it here would put Debian's folder on the
test process's ``sys.path``.
"""

from __future__ import annotations

import json
import subprocess
import sys

import pytest
import ros_needs

pytestmark = ros_needs.needs(ros_needs.ROSPY)

SCRIPT = r"""
import io, json, struct
from types import SimpleNamespace

import numpy as np

from smartcar_gym.bags import messages as m
from smartcar_gym.controller import Odometry
from smartcar_gym.envs.policy_settings import policy_settings
from smartcar_gym.envs.robots.smartcar import JointStates
from smartcar_gym.ros.debian import import_ros
from smartcar_gym.ros.driving import GoalDriver
from smartcar_gym.ros.policy import GOAL_TOPIC, PolicyNode

ros = import_ros()
from rospy.msg import deserialize_messages  # noqa: E402 (after import_ros finds rospy)

NOW_NS = 1_000_000_000


class Time(ros.rospy.Time):
    @classmethod
    def now(cls):
        return cls(0, NOW_NS)


subscribed, sent, logged = {}, [], []


class Publisher:
    def __init__(self, topic, data_class, queue_size=None):
        pass

    def publish(self, msg):
        sent.append([msg.linear.x, msg.angular.z])


def subscriber(topic, data_class, callback, queue_size=None):
    subscribed[topic] = (data_class, callback, queue_size)


fake = SimpleNamespace(**vars(ros))
fake.rospy = SimpleNamespace(
    Publisher=Publisher, Subscriber=subscriber, resolve_name=lambda name: name, Time=Time,
    loginfo=logged.append, logwarn=logged.append, logerr=logged.append)
settings = policy_settings("SmartCar-v0")
driver = GoalDriver(settings, lambda obs: np.array([0.5, 0.0], np.float32), stale_after_s=0.5)
PolicyNode(fake, driver)
types = m.RospyTypes(Time)


def read(topic, messages):
    # one read of the socket: TCPROS frames (a 4-byte length each), then rospy's receive loop
    data_class, callback, queue_size = subscribed[topic]
    buff = io.BytesIO()
    for msg in messages:
        body = io.BytesIO()
        msg.serialize(body)
        buff.write(struct.pack("<I", len(body.getvalue())) + body.getvalue())
    kept = []
    deserialize_messages(buff, kept, data_class, queue_size=queue_size)
    for msg in kept:
        callback(msg)


stamps = [NOW_NS * i // 10 for i in range(1, 11)]  # 0.1 ... 1.0 s; ROS time is 1.0 s
wheels = len(settings.wheel_joints)
read(GOAL_TOPIC, [m.goal_message(types, (1.0, 0.5), 0, "odom")])
read("joint_states", [m.joint_state_message(types, JointStates(
    settings.wheel_joints, np.zeros(wheels), np.zeros(wheels), np.zeros(wheels)), s)
    for s in stamps])
read("odom", [m.odometry_message(types, Odometry(0.0, "odom", "base_link", 0.0, 0.0, 0.0, 0.0,
                                                 0.0), s) for s in stamps])
print(json.dumps({"sent": sent, "logged": logged, "max_linear": settings.max_linear,
                  "queues": {topic: q for topic, (_, _, q) in subscribed.items()}}))
"""


@pytest.fixture(scope="module")
def backlog() -> dict:
    result = subprocess.run([sys.executable, "-c", SCRIPT], capture_output=True, text=True,
                            timeout=120)
    assert result.returncode == 0, result.stderr[-3000:]
    return json.loads(result.stdout.strip().splitlines()[-1])


def test_a_backlog_of_odometry_gives_one_decision_on_the_newest(backlog):
    # ten odometry messages 0.1-1.0 s old (the limit: 0.5 s): one decision, on the one
    # stamped now, and it drives; no stop, no "stale" line
    assert backlog["sent"] == [[0.5 * backlog["max_linear"], 0.0]], backlog
    assert backlog["logged"] == ["new goal (1, 0.5) in frame odom"], backlog


def test_state_topics_keep_one_message_and_goals_ten(backlog):
    assert backlog["queues"] == {"joint_states": 1, "odom": 1, "/move_base_simple/goal": 10}
