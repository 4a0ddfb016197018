"""``smartcar-ros bringup``: the simulated smartcar as ``arbotix_driver`` presents it to ROS.

The node runs the env's own ``SmartCarRobot`` (pybullet body, emulated ``diff_controller`` and
board) in a ``Simulator``: it subscribes ``cmd_vel`` and publishes ``odom`` and the ``odom ->
base_link`` transform on ``/tf`` at the controller's rate, the wheel ``joint_states`` at the
driver's ``read_rate``, and ``/clock`` with ``/use_sim_time``. Beside what the driver publishes,
the simulator's true pose goes out on ``base_pose_ground_truth`` (as stage_ros and Gazebo's p3d
name it) with the odometry. See ``timing`` for how time runs
and ``params`` for where the configuration comes from.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from smartcar_gym.bags import messages as m
from smartcar_gym.controller import ArbotixConfig
from smartcar_gym.envs.robots.smartcar import SmartCarRobot
from smartcar_gym.ros.timing import Pacer, Schedule, Stream, period_ns
from smartcar_gym.sim.clock import NS_PER_S
from smartcar_gym.sim.engines import DEFAULT_ENGINE, make_simulator

CLOCK_RATE_HZ = 100.0  # /clock, and how often received commands are handed to the controller
LAG_REPORT_S = 5.0  # at most one "behind real time" line per this many wall seconds
LOG_EVERY_S = 2.0  # at most one line per bad cmd_vel kind per this many seconds


def twist_problem(linear_x: float, angular_z: float, config: ArbotixConfig) -> str | None:
    """Why a ``cmd_vel`` cannot be sent to the board (None if it can).

    The driver sends each wheel's speed as a 16-bit number of ticks per frame; a faster wheel
    would wrap around on the board (upstream does not check).
    """
    wheel = abs(linear_x) + abs(angular_z) * config.base_width_m / 2.0
    if wheel > config.max_target_speed_m_s:
        return (f"cmd_vel ({linear_x:g} m/s, {angular_z:g} rad/s) asks a wheel for {wheel:g} m/s; "
                f"with ticks_meter {config.ticks_meter:g} the board's 16-bit target holds at "
                f"most {config.max_target_speed_m_s:g} m/s")
    return None


class CommandInbox:
    """The latest ``cmd_vel`` from rospy's thread, handed to the controller in the sim loop."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._twist: tuple[float, float] | None = None

    def put(self, linear_x: float, angular_z: float) -> None:
        with self._lock:
            self._twist = (linear_x, angular_z)

    def take(self) -> tuple[float, float] | None:
        with self._lock:
            twist, self._twist = self._twist, None
        return twist


@dataclass(frozen=True)
class BringupOptions:
    speed: float = 1.0
    sim_time: bool = False  # /use_sim_time: publish /clock and stamp with the simulator's clock


class Bringup:
    """The node's work, given rospy (``ros``: see ``debian.import_ros``) and a spawned robot."""

    def __init__(self, ros: Any, robot: SmartCarRobot, options: BringupOptions) -> None:
        self.ros, self.rospy = ros, ros.rospy
        self.robot, self.sim = robot, robot.sim
        self.config = robot.config
        self.options = options
        self.types = m.RospyTypes(ros.rospy.Time)
        self.inbox = CommandInbox()
        rospy = self.rospy
        self.pub_odom = rospy.Publisher("odom", ros.nav_msgs.Odometry, queue_size=10)
        self.pub_tf = rospy.Publisher("/tf", ros.tf2_msgs.TFMessage, queue_size=10)
        self.pub_joints = rospy.Publisher("joint_states", ros.sensor_msgs.JointState,
                                          queue_size=10)
        self.pub_truth = rospy.Publisher(m.GROUND_TRUTH_TOPIC, ros.nav_msgs.Odometry,
                                         queue_size=10)
        self.pub_clock = (rospy.Publisher("/clock", ros.rosgraph_msgs.Clock, queue_size=10)
                          if options.sim_time else None)
        self.schedule = Schedule([
            Stream("odom", robot.update_period_ns),  # the controller's own instants
            Stream("joint_states", period_ns(self.config.read_rate_hz)),
            Stream("tick", period_ns(CLOCK_RATE_HZ)),
        ])
        rospy.Subscriber("cmd_vel", ros.geometry_msgs.Twist, self._on_cmd_vel, queue_size=10)

    # -- rospy's thread ------------------------------------------------------------------------
    def _on_cmd_vel(self, msg: Any) -> None:
        try:
            linear_x, angular_z = m.read_twist(msg)
        except m.MessageError as err:
            self.rospy.logerr_throttle(LOG_EVERY_S, f"{err}: stopping the base")
            self.inbox.put(0.0, 0.0)
            return
        problem = twist_problem(linear_x, angular_z, self.config)
        if problem:
            self.rospy.logerr_throttle(LOG_EVERY_S, f"{problem}: stopping the base")
            linear_x = angular_z = 0.0
        self.inbox.put(linear_x, angular_z)

    # -- the simulation loop -------------------------------------------------------------------
    def run(self, stop: threading.Event) -> None:
        """Until ``stop`` is set or ROS shuts down: step to each instant, wait for it, publish
        what is due."""
        rospy, sim = self.rospy, self.sim
        pacer = Pacer(self.options.speed)
        ros0_ns = 0 if self.options.sim_time else rospy.Time.now().to_nsec()
        if self.pub_clock is not None:
            self.pub_clock.publish(m.clock_message(self.types, sim.now_ns))
        pacer.start(sim.now_ns)
        last_report = -LAG_REPORT_S
        reported_falls = 0
        while not (stop.is_set() or rospy.is_shutdown()):
            now_ns = self.schedule.next_ns()
            sim.run_until(now_ns, physics=not self.robot.kinematic)
            lag = pacer.wait(now_ns)
            if pacer.falls > reported_falls and time.monotonic() - last_report > LAG_REPORT_S:
                rospy.logwarn(
                    f"behind real time: simulated time has fallen {pacer.behind_s:.2f} s behind "
                    f"the wall clock so far (latest lag {lag:.2f} s at speed "
                    f"{self.options.speed:g}); this machine cannot simulate that fast")
                last_report, reported_falls = time.monotonic(), pacer.falls
            # without /use_sim_time (speed 1) stamps follow the wall clock: start + simulated
            # time + the time lost to falling behind
            stamp = (now_ns if self.options.sim_time
                     else ros0_ns + now_ns + round(pacer.behind_s * NS_PER_S))
            self._publish(self.schedule.due(now_ns), now_ns, stamp)

    def _publish(self, due: Sequence[str], now_ns: int, stamp: int) -> None:
        if self.pub_clock is not None:  # first: no message is stamped ahead of /clock
            self.pub_clock.publish(m.clock_message(self.types, now_ns))
        if "tick" in due:
            twist = self.inbox.take()
            if twist is not None:
                self.robot.cmd_vel(*twist)
        if "odom" in due:
            odom = self.robot.odometry
            self.pub_odom.publish(m.odometry_message(self.types, odom, stamp))
            self.pub_tf.publish(m.transform_message(self.types, odom, stamp))
            body = self.robot.body
            self.pub_truth.publish(m.ground_truth_message(
                self.types, body.link_pose(), body.velocity(), stamp, odom.child_frame_id))
        if "joint_states" in due:
            self.pub_joints.publish(
                m.joint_state_message(self.types, self.robot.joint_states(), stamp))


def start_robot(model: Any, config: ArbotixConfig, mode: str,
                engine: str = DEFAULT_ENGINE) -> SmartCarRobot:
    """A fresh world of ``engine`` with the robot spawned at the origin, its controller started
    at t = 0."""
    sim = make_simulator(engine)
    try:
        robot = SmartCarRobot(sim, model, config, mode=mode)
        sim.reset()
        robot.spawn(0.0, 0.0, 0.0)
    except BaseException:
        sim.close()  # a refused robot leaves no world behind
        raise
    return robot
