"""``Recording`` objects from a robot's bag: what the planar fit needs from a real drive.

``read_recordings`` reads a ROS 1 bag (``.bag``), an MCAP file (``.mcap``: ROS 1 messages, as
``smartcar-eval --bag FILE.mcap`` writes, or ROS 2 CDR messages) or a ROS 2 bag folder
(``metadata.yaml`` with its ``.mcap`` or ``.db3``), with ``rosbags`` and ``mcap`` (the ``ros``
extra). Three topics are read:

* the ground truth (``truth_topic``): ``nav_msgs/Odometry`` (``/base_pose_ground_truth``, as
  Gazebo's p3d and stage publish it), or a motion-capture topic of ``geometry_msgs/PoseStamped``,
  ``PoseWithCovarianceStamped`` or ``TransformStamped`` (``/vrpn_client_node/robot/pose``); the
  planar pose x, y and the yaw of its quaternion, at its header stamp;
* the commands (``cmd_topic``): ``geometry_msgs/Twist`` or ``TwistStamped``, ``linear.x`` and
  ``angular.z``, at the time the bag received them;
* the controller's odometry (``odom_topic``, ``nav_msgs/Odometry``; ``None``: not read), at its
  header stamp. The ArbotiX driver publishes it at each controller update, so its stamps give
  the instants at which the controller fired.

Resampling onto the controller's periods: the controller fires every ``1 / rate_hz`` s, at
``t_k = t_0 + k / rate_hz`` with ``t_0`` the first ``odom`` stamp of the episode at which the
truth is known (without odometry: the first truth stamp). Period k runs from ``t_k`` (included)
to ``t_k+1``: ``commands[k]`` is the last twist the bag received in it (NaN if none), which the
controller acts on at ``t_k+1``. A command received exactly at an update instant counts as
received just after that update fired (as the envs send it; ``smartcar-eval --bag`` stamps it
``bag.COMMAND_LAG_NS`` later anyway). ``truth[k]`` and ``odom[k]`` are the poses at ``t_k``,
linearly interpolated (x, y and the unwrapped yaw) between the two messages around it: a message
stamped at ``t_k`` is taken as it is, and a motion-capture topic at another rate, or with a
dropped message, is interpolated in between. The yaw is unwrapped along each episode and starts
in [-pi, pi]; the odometry is re-based to start at (0, 0, 0), as a controller started with the
recording would publish it (theta unwrapped, as the driver's own is never wrapped).

Episodes: the truth is split where its stamps leave a gap longer than ``gap_s`` (between the
episodes of ``smartcar-eval --bag``: 1 s) or run back by as much (a simulation restarted), and
where it jumps (a reset: it moved faster than ``JUMP_SPEED_M_S`` or turned faster than
``JUMP_RATE_RAD_S``); odometry and commands go with the episode during whose truth the bag
received them. Each episode becomes one ``Recording`` that starts with the robot at rest, as a
replay spawns it: at the first update after which the truth stays still for a period (within
``REST_M`` and ``REST_RAD``; a command acts only at the update after it arrived, so a robot at
rest does not move in the period that follows) and before which no non-zero command arrived for
``TIMEOUT_S`` (the driver's timeout: its PID holds no target). The part before it is dropped,
and then the recording's name says from when it starts (``"x.bag episode 2 from 3.2 s"``; the
module's logger says it too). An episode that never comes to rest, or in which the robot never
moves, is left out.

Commands and poses must share a clock: the bag's receive times and the header stamps (both
simulated time in Gazebo with ``use_sim_time``; wall-clock time on a robot with its recorder).
The truth must be the pose of ``base_link`` (a motion-capture body defined elsewhere on the robot
adds a lever arm to every turn).
"""

from __future__ import annotations

import logging
import math
import os
from bisect import bisect_left
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from smartcar_gym.calibration.recording import Recording

log = logging.getLogger(__name__)

ROS_EXTRA = 'pip install "smartcar-gym[ros]"'
NS_PER_S = 1_000_000_000
GAP_S = 0.5  # a longer gap in the truth's stamps ends an episode
JUMP_SPEED_M_S = 3.0  # faster than this (6x the smartcar's top speed) the truth jumped: a reset
JUMP_RATE_RAD_S = 12.0  # likewise for the yaw (6x its top turn rate)
JUMP_FLOOR_M, JUMP_FLOOR_RAD = 0.01, 0.05  # allowed on top (noise between close samples)
REST_M, REST_RAD = 0.002, 0.01  # at most this much motion over the period after the start
TIMEOUT_S = 1.0  # arbotix_driver's default timeout: an older command no longer drives
MOVED_M, MOVED_RAD = 0.01, 0.05  # an episode whose truth never gets this far has no motion
SUFFIXES = (".bag", ".mcap")

TRUTH_TYPES = {  # message type -> the stamped pose in it (position, orientation)
    "nav_msgs/Odometry": lambda m: (m.pose.pose.position, m.pose.pose.orientation),
    "geometry_msgs/PoseStamped": lambda m: (m.pose.position, m.pose.orientation),
    "geometry_msgs/PoseWithCovarianceStamped": lambda m: (m.pose.pose.position,
                                                          m.pose.pose.orientation),
    "geometry_msgs/TransformStamped": lambda m: (m.transform.translation, m.transform.rotation),
}
COMMAND_TYPES = {
    "geometry_msgs/Twist": lambda m: m,
    "geometry_msgs/TwistStamped": lambda m: m.twist,
}
ODOM_TYPES = {"nav_msgs/Odometry": TRUTH_TYPES["nav_msgs/Odometry"]}


class BagError(ValueError):
    """A bag that cannot give recordings; one line naming the file and what is wrong."""


def missing_library() -> str | None:
    """What is missing to read bags (None if nothing is): one line naming the extra."""
    from smartcar_gym.extras import missing_modules

    missing = missing_modules(("rosbags", "mcap"))
    if missing:
        return f"{', '.join(missing)} not installed; reading bags needs the ros extra: {ROS_EXTRA}"
    return None


def read_recordings(path: str | os.PathLike, truth_topic: str = "/base_pose_ground_truth",
                    cmd_topic: str = "/cmd_vel", odom_topic: str | None = "/odom", *,
                    rate_hz: float, gap_s: float = GAP_S) -> list[Recording]:
    """The episodes of the bag at ``path`` as ``Recording`` objects (see the module's text),
    for a controller running at ``rate_hz`` (the ArbotiX YAML's ``rate``). ``BagError``: the
    file cannot be read, lacks a topic, has a topic of an unexpected type, is empty, or holds
    no motion from rest."""
    path = Path(path)
    if not (math.isfinite(rate_hz) and rate_hz > 0):
        raise ValueError(f"rate_hz must be a positive number, got {rate_hz!r}")
    for key, topic in (("truth_topic", truth_topic), ("cmd_topic", cmd_topic),
                       ("odom_topic", odom_topic)):
        if topic is not None and not (isinstance(topic, str) and topic.strip()):
            none = " (None: no odometry)" if key == "odom_topic" else ""
            raise BagError(f"{path}: {key} {topic!r} is not a topic name{none}")
    if not path.exists():
        raise BagError(f"{path}: no such file or folder")
    if not path.is_dir() and path.suffix not in SUFFIXES:
        raise BagError(f"{path}: not a bag (a .bag or .mcap file, or a ROS 2 bag folder)")
    problem = missing_library()  # after the path: a wrong name is said whatever is installed
    if problem:
        raise BagError(problem)
    wanted = [(truth_topic, TRUTH_TYPES), (cmd_topic, COMMAND_TYPES)]
    if odom_topic is not None:
        wanted.append((odom_topic, ODOM_TYPES))
    truth, commands, *odom_rows = _read(path, wanted)
    odom = odom_rows[0] if odom_rows else None
    period_ns = round(NS_PER_S / rate_hz)
    if odom is not None:
        _check_clocks(path, truth, odom, truth_topic, odom_topic)
    truth_in, odom_in, commands_in = _spans(truth), _spans(odom or []), _spans(commands)
    out, restless = [], 0
    for index, (start, end) in enumerate(_episodes(truth, round(gap_s * NS_PER_S))):
        grid = _Grid.of(truth_in(start, end), None if odom is None else odom_in(start, end),
                        period_ns, path, odom_topic)
        if grid is None or not grid.moved():
            continue
        name = f"{path.name} episode {index + 1}"
        recording = grid.recording(name, rate_hz, commands_in(start, end))
        if recording is None:
            log.info("%s: left out: the robot is never at rest before it moves on %s", name,
                     truth_topic)
            restless += 1
            continue
        out.append(recording)
    if not out:
        if restless:
            raise BagError(f"{path}: the robot is never at rest on {truth_topic} (still for a "
                           f"controller period, no command for {TIMEOUT_S:g} s before) before "
                           "it moves, so no recording can start from rest")
        raise BagError(f"{path}: no motion: the robot never moves on {truth_topic} (by "
                       f"{MOVED_M * 100:g} cm or {MOVED_RAD:g} rad) in {len(truth)} poses")
    return out


# -- reading -----------------------------------------------------------------------------------
@dataclass(frozen=True)
class _Row:
    received: int  # the bag's time (ns)
    stamp: int  # the header's stamp (ns); the bag's time for a message without a header
    value: tuple[float, float, float]  # x, y, yaw (a pose) or linear.x, angular.z, 0 (a twist)


def _read(path: Path, wanted: list[tuple[str, dict[str, Any]]]) -> list[list[_Row]]:
    """The rows of each ``wanted`` topic (with the message types it may have), in the order
    the bag received them; BagError for a missing topic or an unexpected type."""
    rows: dict[str, list[_Row]] = {topic: [] for topic, _ in wanted}
    with _messages(path) as (topics, messages):
        if not topics:
            raise BagError(f"{path} is empty: no topics")
        for topic, accepted in wanted:
            if topic not in topics:
                raise BagError(f"{path} has no {topic}; topics: {', '.join(sorted(topics))}")
            if topics[topic] not in accepted:
                raise BagError(f"{path}: {topic} is {topics[topic]}, not "
                               f"{' or '.join(accepted)}")
        kinds = dict(wanted)
        for topic, received, msg in messages(set(kinds)):
            rows[topic].append(_row(kinds[topic][topics[topic]], msg, received,
                                    kinds[topic] is COMMAND_TYPES))
    for topic, got in rows.items():
        if not got:
            raise BagError(f"{path} has no messages on {topic}")
    return [rows[topic] for topic, _ in wanted]


def _row(get: Any, msg: Any, received: int, twist: bool) -> _Row:
    if twist:
        t = get(msg)
        v, w = float(t.linear.x), float(t.angular.z)
        if not (math.isfinite(v) and math.isfinite(w)):
            v = w = math.nan  # not a command a driver acts on
        return _Row(received, received, (v, w, 0.0))
    p, q = get(msg)
    stamp = msg.header.stamp
    stamp_ns = int(stamp.sec) * NS_PER_S + int(stamp.nanosec)
    yaw = math.atan2(2.0 * (q.w * q.z + q.x * q.y), 1.0 - 2.0 * (q.y * q.y + q.z * q.z))
    return _Row(received, stamp_ns or received,  # stamp 0: unset, take the bag's time
                (float(p.x), float(p.y), yaw))


class _messages:  # noqa: N801 (a context manager used as a function)
    """``with _messages(path) as (topics, messages)``: the topics (-> type, without ``/msg/``)
    and ``messages(topics)``, an iterator of (topic, bag time ns, message) in time order."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self._close: Any = None

    def __enter__(self) -> tuple[dict[str, str], Any]:
        try:
            if self.path.suffix == ".mcap" and _mcap_profile(self.path) == "ros1":
                return self._ros1_mcap()
            return self._rosbags()
        except BagError:
            raise
        except Exception as err:  # noqa: BLE001 (the readers' many errors: one line each)
            raise BagError(f"{self.path}: cannot be read as a bag: {err}") from err

    def __exit__(self, *exc: Any) -> None:
        if self._close is not None:
            self._close()

    def _rosbags(self) -> tuple[dict[str, str], Any]:
        from rosbags.highlevel import AnyReader
        from rosbags.typesys import Stores, get_typestore

        reader = AnyReader([self.path], default_typestore=get_typestore(Stores.ROS2_JAZZY))
        reader.open()
        self._close = reader.close
        topics = {c.topic: _bare(c.msgtype) for c in reader.connections}

        def messages(wanted: set[str]) -> Iterator[tuple[str, int, Any]]:
            connections = [c for c in reader.connections if c.topic in wanted]
            for connection, time_ns, data in reader.messages(connections=connections):
                yield connection.topic, time_ns, reader.deserialize(data, connection.msgtype)

        return topics, messages

    def _ros1_mcap(self) -> tuple[dict[str, str], Any]:
        """An MCAP file of ROS 1 messages (rosbags reads only ROS 2 ones): ``mcap``'s reader,
        rosbags' ROS 1 deserialiser with the types the file's schemas define."""
        from mcap.reader import make_reader
        from rosbags.typesys import Stores, get_types_from_msg, get_typestore

        stream = open(self.path, "rb")  # noqa: SIM115 (closed by __exit__)
        self._close = stream.close
        reader = make_reader(stream)
        summary = reader.get_summary()
        if summary is None:
            raise BagError(f"{self.path}: an MCAP file without a summary (unfinished?)")
        topics = {c.topic: _bare(summary.schemas[c.schema_id].name)
                  for c in summary.channels.values() if c.schema_id in summary.schemas}
        store = get_typestore(Stores.EMPTY)

        def messages(wanted: set[str]) -> Iterator[tuple[str, int, Any]]:
            registered: set[str] = set()
            for schema, channel, message in reader.iter_messages(topics=sorted(wanted)):
                full = _full(schema.name)
                if full not in registered:
                    store.register(get_types_from_msg(schema.data.decode(), full))
                    registered.add(full)
                yield channel.topic, message.log_time, store.deserialize_ros1(message.data, full)

        return topics, messages


def _mcap_profile(path: Path) -> str:
    from mcap.reader import make_reader

    with open(path, "rb") as stream:
        return make_reader(stream).get_header().profile


def _bare(msgtype: str) -> str:
    """``nav_msgs/msg/Odometry`` -> ``nav_msgs/Odometry``."""
    return msgtype.replace("/msg/", "/")


def _full(msgtype: str) -> str:
    """``nav_msgs/Odometry`` -> ``nav_msgs/msg/Odometry``."""
    return msgtype if "/msg/" in msgtype else msgtype.replace("/", "/msg/", 1)


# -- episodes and the controller's grid --------------------------------------------------------
def _spans(rows: list[_Row]) -> Any:
    """``span(start, end)``: the rows (in the bag's order) received in [start, end)."""
    times = [r.received for r in rows]
    return lambda start, end: rows[bisect_left(times, start):bisect_left(times, end)]


def _check_clocks(path: Path, truth: list[_Row], odom: list[_Row], truth_topic: str,
                  odom_topic: str) -> None:
    """BagError if the odometry's stamps never fall among the truth's (another clock)."""
    first, last = min(r.stamp for r in truth), max(r.stamp for r in truth)
    if not any(first <= r.stamp <= last for r in odom):
        raise BagError(f"{path}: the stamps of {odom_topic} ({odom[0].stamp / NS_PER_S:.9g} s "
                       f"on) never fall among those of {truth_topic} ({first / NS_PER_S:.9g} "
                       f"to {last / NS_PER_S:.9g} s): stamped on another clock?")


def _episodes(truth: list[_Row], gap_ns: int) -> list[tuple[int, int]]:
    """The bag-time spans [start, end) of the episodes: the truth split at gaps in its stamps,
    at stamps running backwards and at jumps (see the module's text)."""
    starts = [truth[0].received]
    for a, b in zip(truth, truth[1:], strict=False):
        dt = (b.stamp - a.stamp) / NS_PER_S
        moved = math.hypot(b.value[0] - a.value[0], b.value[1] - a.value[1])
        turned = abs(math.remainder(b.value[2] - a.value[2], 2 * math.pi))
        jumped = (moved > JUMP_FLOOR_M + JUMP_SPEED_M_S * max(dt, 0.0)
                  or turned > JUMP_FLOOR_RAD + JUMP_RATE_RAD_S * max(dt, 0.0))
        if abs(b.stamp - a.stamp) > gap_ns or jumped:
            starts.append(b.received)
    ends = starts[1:] + [truth[-1].received + 1]
    return list(zip(starts, ends, strict=True))


def _poses(rows: list[_Row]) -> tuple[np.ndarray, np.ndarray]:
    """Stamps (ns, increasing: messages received out of order are sorted, a repeated stamp
    keeps its first message) and (N, 3) poses, yaw unwrapped."""
    stamps = np.array([r.stamp for r in rows], dtype=np.int64)
    order = np.argsort(stamps, kind="stable")
    stamps = stamps[order]
    keep = np.concatenate([[True], np.diff(stamps) > 0])
    poses = np.array([r.value for r in rows], dtype=float)[order][keep]
    poses[:, 2] = np.unwrap(poses[:, 2])
    return stamps[keep], poses


def _sample(stamps: np.ndarray, poses: np.ndarray, at: np.ndarray) -> np.ndarray:
    """``poses`` linearly interpolated at the instants ``at`` (ns, within ``stamps``)."""
    t0 = stamps[0]
    x, xp = (at - t0).astype(float), (stamps - t0).astype(float)  # exact: relative ns
    return np.stack([np.interp(x, xp, poses[:, i]) for i in range(3)], axis=1)


@dataclass
class _Grid:
    """One episode on the controller's updates: ``at`` (ns), truth and odometry there."""

    at: np.ndarray
    truth: np.ndarray
    odom: np.ndarray | None

    @classmethod
    def of(cls, truth: list[_Row], odom: list[_Row] | None, period_ns: int, path: Path,
           odom_topic: str | None) -> _Grid | None:
        """The updates at which the truth (and the odometry) are known; None if under two."""
        if len(truth) < 2:
            return None
        stamps, poses = _poses(truth)
        first, last = stamps[0], stamps[-1]
        odom_poses = None
        if odom is not None:
            odom_stamps, odom_poses = _poses(odom) if odom else (np.empty(0, np.int64), None)
            covered = odom_stamps[(odom_stamps >= first) & (odom_stamps <= last)]
            if len(covered) < 2:
                return None
            spacing = float(np.median(np.diff(covered)))
            if abs(spacing - period_ns) > 0.05 * period_ns:
                raise BagError(f"{path}: {odom_topic} comes every {spacing / 1e6:.4g} ms, but "
                               f"the controller's rate {NS_PER_S / period_ns:g} Hz fires every "
                               f"{period_ns / 1e6:.4g} ms: is rate_hz right?")
            first, last = covered[0], min(last, odom_stamps[-1])
        n = int((last - first) // period_ns)
        if n < 1:
            return None
        at = first + period_ns * np.arange(n + 1, dtype=np.int64)
        return cls(at, _sample(stamps, poses, at),
                   None if odom is None else _sample(odom_stamps, odom_poses, at))

    def moved(self) -> bool:
        """Whether the truth ever gets ``MOVED_M`` or ``MOVED_RAD`` away from its start."""
        d = self.truth - self.truth[0]
        return bool(np.any(np.hypot(d[:, 0], d[:, 1]) >= MOVED_M)
                    or np.any(np.abs(d[:, 2]) >= MOVED_RAD))

    def recording(self, name: str, rate_hz: float, commands: list[_Row]) -> Recording | None:
        """From the first update at rest on; None if there is none or no motion after it."""
        at, n = self.at, len(self.at) - 1
        period = at[1] - at[0]
        twists = np.full((n, 2), np.nan)
        received = np.array([c.received for c in commands], dtype=np.int64)
        values = np.array([c.value[:2] for c in commands], dtype=float).reshape(-1, 2)
        k = (received - at[0]) // period
        for i in np.flatnonzero((k >= 0) & (k < n)):
            twists[k[i]] = values[i]  # the last one received in the period
        driving = np.any(values != 0.0, axis=1) & np.all(np.isfinite(values), axis=1)
        step = np.diff(self.truth, axis=0)
        still = (np.hypot(step[:, 0], step[:, 1]) <= REST_M) & (np.abs(step[:, 2]) <= REST_RAD)
        timeout = round(TIMEOUT_S * NS_PER_S)
        start = None
        for s in np.flatnonzero(still):
            if not np.any(driving & (received < at[s]) & (received >= at[s] - timeout)):
                start = int(s)
                break
        if start is None:
            return None
        truth = self.truth[start:].copy()
        truth[:, 2] -= truth[0, 2] - math.remainder(truth[0, 2], 2 * math.pi)
        grid = _Grid(at[start:], truth, None if self.odom is None else _rebased(self.odom[start:]))
        if not grid.moved():
            return None
        if start:
            log.info("%s: the first %.3g s dropped: the robot was not at rest", name,
                     start / rate_hz)
            name = f"{name} from {start / rate_hz:.3g} s"
        return Recording(name, rate_hz, twists[start:], grid.truth, grid.odom)


def _rebased(odom: np.ndarray) -> np.ndarray:
    """Odometry as seen from its first pose: starting at (0, 0, 0)."""
    x0, y0, th0 = odom[0]
    c, s = math.cos(th0), math.sin(th0)
    dx, dy = odom[:, 0] - x0, odom[:, 1] - y0
    return np.stack([c * dx + s * dy, -s * dx + c * dy, odom[:, 2] - th0], axis=1)
