"""Evaluated episodes as a ROS 1 bag (``.bag``) or an MCAP file (``.mcap``), without ROS.

``smartcar-eval --bag FILE`` runs the evaluation's episodes (episode ``i`` with seed
``seed + i``: the same episodes, step for step) in one env through the episode runner
(``agents.bag.write_bag``), and ``BagRecorder``, a hook of the runner, writes per controller
period what the bringup node would publish: ``/odom``, ``/tf``, ``/joint_states``,
``/base_pose_ground_truth``, and the ``/cmd_vel`` sent, plus each episode's goal on
``/move_base_simple/goal``. Stamps are simulated time: episode ``i`` starts
``EPISODE_GAP_S`` after the end of episode ``i - 1``, the first at ``START_S``. Each ``/cmd_vel``
is stamped ``COMMAND_LAG_NS`` after the controller update whose odometry the policy read: the
controller acts on it at the next update (stamped at the update itself, a reader could not tell
whether it arrived before that update fired, and would shift every command by a period).

Messages are serialised by ``rosbags`` (its ROS 1 typestore, the ``ros`` extra), bags written
by its ``rosbag1.Writer``, MCAP files (ROS 1 profile) by ``mcap``. Debian's ``rosbag info`` and
``rosbag play`` read the bags.
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np

from smartcar_gym.bags import messages as m

ROS_EXTRA = 'pip install "smartcar-gym[ros]"'
SUFFIXES = (".bag", ".mcap")
START_S = 1.0  # ROS time 0 means "unset" to many tools
EPISODE_GAP_S = 1.0
COMMAND_LAG_NS = 1_000_000  # a command is sent 1 ms after the update it answers
TF_MESSAGE = "geometry_msgs/TransformStamped[] transforms"
TOPICS = {  # topic (resolved, as rosbag record writes it) -> message type
    "/odom": "nav_msgs/Odometry",
    "/tf": "tf2_msgs/TFMessage",
    "/joint_states": "sensor_msgs/JointState",
    f"/{m.GROUND_TRUTH_TOPIC}": "nav_msgs/Odometry",
    "/cmd_vel": "geometry_msgs/Twist",
    "/move_base_simple/goal": "geometry_msgs/PoseStamped",
}


def missing_library() -> str | None:
    """What is missing to write bags (None if nothing is): one line naming the extra."""
    from smartcar_gym.extras import missing_modules

    missing = missing_modules(("rosbags", "mcap"))
    if missing:
        return f"{', '.join(missing)} not installed; --bag needs the ros extra: {ROS_EXTRA}"
    return None


def typestore() -> Any:
    """rosbags' ROS 1 (Noetic) typestore with ``tf2_msgs/TFMessage`` added."""
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    store = get_typestore(Stores.ROS1_NOETIC)
    if "tf2_msgs/msg/TFMessage" not in store.types:
        store.register(get_types_from_msg(TF_MESSAGE, "tf2_msgs/msg/TFMessage"))
    return store


class EpisodeWriter:
    """Writes messages to a ``.bag`` or ``.mcap`` file, one connection (channel) per topic."""

    def __init__(self, path: Path, store: Any) -> None:
        self.path, self.store = path, store
        self.count = 0
        self._channels: dict[str, Any] = {}
        if path.suffix == ".bag":
            from rosbags.rosbag1 import Writer

            self._bag = Writer(path)
            self._bag.open()
            self._stream = None
        else:
            from mcap.writer import Writer

            self._bag = None
            self._stream = open(path, "wb")  # noqa: SIM115 (closed by close())
            self._mcap = Writer(self._stream)
            self._mcap.start(profile="ros1", library="smartcar_gym")
            self._schemas: dict[str, int] = {}

    def write(self, topic: str, msg: Any, time_ns: int) -> None:
        msgtype = TOPICS[topic]
        full = msgtype.replace("/", "/msg/")
        data = self.store.serialize_ros1(msg, full)
        if self._bag is not None:
            if topic not in self._channels:
                self._channels[topic] = self._bag.add_connection(topic, full,
                                                                 typestore=self.store)
            self._bag.write(self._channels[topic], time_ns, data)
        else:
            if topic not in self._channels:
                if msgtype not in self._schemas:
                    definition = self.store.generate_msgdef(full, ros_version=1)[0]
                    self._schemas[msgtype] = self._mcap.register_schema(
                        msgtype, "ros1msg", definition.encode())
                self._channels[topic] = self._mcap.register_channel(
                    topic, "ros1", self._schemas[msgtype])
            self._mcap.add_message(self._channels[topic], log_time=time_ns, data=bytes(data),
                                   publish_time=time_ns, sequence=self.count)
        self.count += 1

    def close(self) -> None:
        if self._bag is not None:
            self._bag.close()
        else:
            self._mcap.finish()
            self._stream.close()


@contextmanager
def episode_writer(path: str | os.PathLike) -> Iterator[EpisodeWriter]:
    """An ``EpisodeWriter`` whose file appears at ``path`` only once it is complete."""
    path = Path(path)
    if path.suffix not in SUFFIXES:
        raise ValueError(f"bag file must end in .bag or .mcap, got {path.name!r}")
    path.parent.mkdir(parents=True, exist_ok=True)
    partial = path.with_name(f".{path.stem}.partial{path.suffix}")
    partial.unlink(missing_ok=True)
    writer = EpisodeWriter(partial, typestore())
    try:
        yield writer
        writer.close()
        os.replace(partial, path)
    except BaseException:
        with _quiet():
            writer.close()
        partial.unlink(missing_ok=True)
        raise


@contextmanager
def _quiet() -> Iterator[None]:
    try:
        yield
    except Exception:  # closing a half-written file after the real error: keep that one
        pass


def _state(writer: EpisodeWriter, types: m.RosbagsTypes, env: Any, time_ns: int) -> None:
    """What the bringup node publishes at a controller update, stamped ``time_ns``."""
    robot = env.robot
    odom = robot.odometry
    writer.write("/odom", m.odometry_message(types, odom, time_ns), time_ns)
    writer.write("/tf", m.transform_message(types, odom, time_ns), time_ns)
    writer.write("/joint_states", m.joint_state_message(types, robot.joint_states(), time_ns),
                 time_ns)
    truth = m.ground_truth_message(types, robot.body.link_pose(), robot.body.velocity(),
                                   time_ns, odom.child_frame_id)
    writer.write(f"/{m.GROUND_TRUTH_TOPIC}", truth, time_ns)


class BagRecorder:
    """A hook of the episode runner (``agents.runner.Hooks``: ``begin``, ``step``, ``end``)
    that writes a single env's episodes to ``writer``: each episode's goal and the state at
    its reset, then per step the ``/cmd_vel`` sent and the state after it; the next episode
    starts ``EPISODE_GAP_S`` after one ends. The env must be in this process (a vector env of
    one single env: ``envs.envs[0]``)."""

    def __init__(self, writer: EpisodeWriter) -> None:
        self.writer = writer
        self.types = m.RosbagsTypes(writer.store)
        self.offset_ns = round(START_S * m.NS_PER_S)
        self._env: Any = None

    def begin(self, envs: Any, cars: Any, jobs: Any, obs: Any, info: Any) -> None:
        base = envs.envs[0].unwrapped
        if not all(hasattr(base, name) for name in ("robot", "sim", "goal", "max_linear")):
            raise ValueError(f"--bag records SmartCarEnv episodes; the env is a "
                             f"{type(base).__name__}")
        self._env = base
        self._scale = np.array([base.max_linear, base.max_angular])
        frame = base.robot.odometry.frame_id
        self.writer.write("/move_base_simple/goal",
                          m.goal_message(self.types, base.goal, self.offset_ns, frame),
                          self.offset_ns)
        _state(self.writer, self.types, base, self.offset_ns)

    def step(self, cars: Any, actions: np.ndarray, obs: Any, reward: Any, terminated: Any,
             truncated: Any, info: Any) -> None:
        base = self._env
        linear, angular = (np.clip(np.asarray(actions[0], dtype=np.float64), -1.0, 1.0)
                           * self._scale)
        now_ns = base.sim.now_ns
        sent_ns = self.offset_ns + now_ns - base.robot.update_period_ns + COMMAND_LAG_NS
        self.writer.write("/cmd_vel", m.twist_message(self.types, linear, angular), sent_ns)
        _state(self.writer, self.types, base, self.offset_ns + now_ns)

    def end(self, car: int, job: Any, info: Any) -> None:
        self.offset_ns += self._env.sim.now_ns + round(EPISODE_GAP_S * m.NS_PER_S)
