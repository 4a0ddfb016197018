"""``smartcar-ros policy``: a trained policy as a ROS node that drives to rviz's 2D Nav Goal.

Subscribes ``odom``, ``joint_states`` and ``/move_base_simple/goal`` (and, to stop on the
simulator's ground truth, ``base_pose_ground_truth``) and publishes ``cmd_vel``.
A decision is made when odometry arrives (at the controller's rate, as the env steps), with
the joint states of the same instant when they come within ``JOINT_WAIT_S``; between
odometry messages a watchdog (at the controller's rate of wall-clock time) stops the car when
odometry goes stale. The decisions themselves are ``driving.GoalDriver``'s.
"""

from __future__ import annotations

import threading
import time
from typing import Any

from smartcar_gym.bags import messages as m
from smartcar_gym.ros.driving import Command, GoalDriver

#: the state topics (odometry, joint states, ground truth) keep only their newest message: a
#: node that falls behind (a loaded machine, a fast ``--speed``) decides on the present instead
#: of working through a backlog of odometry that is stale by the time it is read (which stops
#: the car at every decision, for as long as the backlog lasts)
STATE_QUEUE = 1
JOINT_WAIT_S = 0.02  # wall seconds to wait for the joint states stamped with the odometry
LISTEN_TIMEOUT_S = 60.0  # wall seconds to wait for the master to list the goal subscription
GOAL_TOPIC = "/move_base_simple/goal"


class PolicyNode:
    """The rospy side of ``GoalDriver`` (``ros``: see ``debian.import_ros``)."""

    def __init__(self, ros: Any, driver: GoalDriver) -> None:
        self.rospy = rospy = ros.rospy
        self.driver = driver
        self.types = m.RospyTypes(rospy.Time)
        self._lock = threading.Condition()
        self.pub = rospy.Publisher("cmd_vel", ros.geometry_msgs.Twist, queue_size=10)
        rospy.Subscriber("joint_states", ros.sensor_msgs.JointState, self._on_joint_states,
                         queue_size=STATE_QUEUE)
        rospy.Subscriber("odom", ros.nav_msgs.Odometry, self._on_odometry,
                         queue_size=STATE_QUEUE)
        if driver.stop_on == "ground_truth":
            rospy.Subscriber(m.GROUND_TRUTH_TOPIC, ros.nav_msgs.Odometry, self._on_ground_truth,
                             queue_size=STATE_QUEUE)
        self.goal_topic = rospy.resolve_name(GOAL_TOPIC)
        rospy.Subscriber(self.goal_topic, ros.geometry_msgs.PoseStamped, self._on_goal,
                         queue_size=10)

    def announce_listening(self, stop: threading.Event,
                           timeout_s: float = LISTEN_TIMEOUT_S) -> bool:
        """Log one line once the master lists this node as a subscriber of the goal topic.

        rospy registers a subscription from a thread of its own, and a goal published before
        that is not received (rviz's 2D Nav Goal is not latched): the line says from when on
        a goal counts. On a loaded machine the node takes seconds to get there (loading the
        policy, then registering). A warning instead if the master has not listed it after
        ``timeout_s``; nothing once ``stop`` is set."""
        import rosgraph

        rospy, me = self.rospy, self.rospy.get_name()
        master = rosgraph.Master(me)
        deadline = time.monotonic() + timeout_s
        while not (stop.is_set() or rospy.is_shutdown()):
            try:
                _, subscribers, _ = master.getSystemState()
            except (OSError, rosgraph.MasterException):
                subscribers = []
            if any(topic == self.goal_topic and me in nodes for topic, nodes in subscribers):
                rospy.loginfo(f"listening for goals on {self.goal_topic} (a goal sent before "
                              "this line was not received: send it again)")
                return True
            if time.monotonic() > deadline:
                break
            stop.wait(0.05)
        if stop.is_set() or rospy.is_shutdown():
            return False
        rospy.logwarn(f"the master does not list {me} as a subscriber of {self.goal_topic} "
                      f"after {timeout_s:g} s: goals may not arrive")
        return False

    def _now_ns(self) -> int:
        return self.rospy.Time.now().to_nsec()

    def _send(self, command: Command) -> None:
        if command.log is not None:
            level, text = command.log
            {"info": self.rospy.loginfo, "warn": self.rospy.logwarn,
             "error": self.rospy.logerr}[level](text)
        if command.twist is not None:
            self.pub.publish(m.twist_message(self.types, *command.twist))

    def _on_goal(self, msg: Any) -> None:
        with self._lock:
            self._send(self.driver.on_goal(msg))

    def _on_joint_states(self, msg: Any) -> None:
        with self._lock:
            self.driver.on_joint_states(msg)
            self._lock.notify_all()

    def _on_ground_truth(self, msg: Any) -> None:
        with self._lock:
            self.driver.on_ground_truth(msg)

    def _on_odometry(self, msg: Any) -> None:
        with self._lock:
            self.driver.on_odometry(msg)
            odom = self.driver.odometry
            if odom is not None:  # the joint states of the same instant, if they come soon
                self._lock.wait_for(lambda: self.driver.wheels is not None
                                    and self.driver.wheels.stamp_ns >= odom.stamp_ns,
                                    timeout=JOINT_WAIT_S)
            self._send(self.driver.step(self._now_ns()))

    def spin(self, stop: threading.Event) -> None:
        """The watchdog, at the controller's rate of wall-clock time (so that it runs when ROS
        time stands still), until ``stop`` is set or ROS shuts down."""
        period = 1.0 / self.driver.settings.rate_hz
        while not (stop.wait(period) or self.rospy.is_shutdown()):
            with self._lock:
                self._send(self.driver.watchdog(self._now_ns()))
