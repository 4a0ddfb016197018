"""``calibration.bag_source``: bags read back as the planar fit's ``Recording`` objects.

The alignment test: bags written by ``smartcar-eval --bag`` (ROS 1 ``.bag``, ``.mcap`` and a
ROS 2 folder) of short pybullet runs, read back and replayed on pybullet with the recorded
commands, retrace the recorded truth and odometry: the commands sit in the periods the
controller acted on them. The rest are small bags written here: a motion-capture topic at
another rate, a start in motion, resets, and the one-line errors.
"""

from __future__ import annotations

import importlib.util
import logging
import math

import numpy as np
import pytest

from smartcar_gym.agents.cli_eval import main as eval_main
from smartcar_gym.calibration.bag_source import BagError, read_recordings
from smartcar_gym.calibration.recording import replay
from smartcar_gym.controller.config import load_controller_config
from smartcar_gym.model import load_model

pytestmark = pytest.mark.skipif(
    importlib.util.find_spec("rosbags") is None or importlib.util.find_spec("mcap") is None,
    reason='rosbags and mcap not installed: pip install "smartcar-gym[ros]"')

NS = 1_000_000_000
RATE_HZ = 10.0
STEPS = 40  # per episode


@pytest.fixture(scope="module")
def plant():
    model, config = load_model(), load_controller_config()
    assert config.rate_hz == RATE_HZ
    return model, config


@pytest.fixture(scope="module")
def bags(tmp_path_factory):
    """Two random-action SmartCar-v0 episodes of 40 steps on pybullet, as smartcar-eval writes
    them: {format: path}."""
    folder = tmp_path_factory.mktemp("bags")
    common = ["--random", "--episodes", "2", "--seed", "3", "--no-progress", "--engine",
              "pybullet", "--env-kwargs", f"max_episode_steps={STEPS}"]
    out = {"bag": folder / "run.bag", "mcap": folder / "run.mcap", "ros2": folder / "run2"}
    for kind, path in out.items():
        extra = ["--bag-format", "ros2"] if kind == "ros2" else []
        assert eval_main([*common, "--bag", str(path), *extra]) == 0
    return out


@pytest.mark.parametrize("kind", ["bag", "mcap", "ros2"])
def test_replaying_a_bag_retraces_it(bags, plant, kind):
    path = bags[kind]
    recordings = read_recordings(path, rate_hz=RATE_HZ)
    assert [r.name for r in recordings] == [f"{path.name} episode {i}" for i in (1, 2)]
    for recording in recordings:
        assert len(recording.commands) == STEPS
        assert np.all(np.isfinite(recording.commands))  # one command in every period
        assert np.array_equal(recording.odom[0], [0.0, 0.0, 0.0])
        assert np.abs(recording.truth[-1] - recording.truth[0]).max() > 0.05
        truth, odom = replay(*plant, "pybullet", recording.commands, recording.truth[0])
        # respawned at the settled pose, the robot settles again (by ~2 um and ~1e-5 rad): the
        # replay starts that far off and keeps the offset; seen from its start, it is the run
        assert np.abs(truth - recording.truth).max() < 3e-5
        assert np.abs(_from_start(truth) - _from_start(recording.truth)).max() < 2e-6
        assert np.abs(odom - recording.odom).max() < 1e-12
        # spawned where the env spawned it (its origin), the replay is the recorded run
        truth, odom = replay(*plant, "pybullet", recording.commands, (0.0, 0.0, 0.0))
        assert np.abs(truth - recording.truth).max() < 1e-9
        assert np.abs(odom - recording.odom).max() < 1e-12
    # a period early, the same commands miss the recorded run by far more
    early = replay(*plant, "pybullet", recording.commands[1:], (0.0, 0.0, 0.0))[0]
    assert np.abs(early - recording.truth[:-1]).max() > 1e-3


def _from_start(poses):
    """Poses seen from the first: position in its frame, turn since."""
    d = poses - poses[0]
    c, s = math.cos(poses[0, 2]), math.sin(poses[0, 2])
    return np.stack([c * d[:, 0] + s * d[:, 1], -s * d[:, 0] + c * d[:, 1], d[:, 2]], axis=1)


def test_a_bag_and_an_mcap_file_give_the_same_recordings(bags):
    for a, b in zip(read_recordings(bags["bag"], rate_hz=RATE_HZ),
                    read_recordings(bags["mcap"], rate_hz=RATE_HZ), strict=True):
        for key in ("commands", "truth", "odom"):
            np.testing.assert_array_equal(getattr(a, key), getattr(b, key))


# -- bags written here -------------------------------------------------------------------------
class Bag:
    """A ROS 1 bag of hand-made messages (rosbags' writer, the ROS 1 messages of ``bags.ros1``)."""

    def __init__(self) -> None:
        from smartcar_gym.bags import messages as m
        from smartcar_gym.bags.ros1 import typestore

        self.m, self.store = m, typestore()
        self.types = m.RosbagsTypes(self.store)
        self.rows: list[tuple[str, str, object, int]] = []

    def pose(self, topic, kind, t_ns, x, y, yaw, received=None):
        types, m = self.types, self.m
        q = (0.0, 0.0, math.sin(yaw / 2), math.cos(yaw / 2))
        header = m.header(types, t_ns, "world")
        if kind == "nav_msgs/Odometry":
            pose = types("geometry_msgs/PoseWithCovariance", pose=m._pose(types, x, y, q),
                         covariance=np.zeros(36))
            msg = types(kind, header=header, child_frame_id="base_link", pose=pose,
                        twist=types("geometry_msgs/TwistWithCovariance",
                                    twist=m.twist_message(types, 0.0, 0.0),
                                    covariance=np.zeros(36)))
        elif kind == "geometry_msgs/PoseStamped":
            msg = types(kind, header=header, pose=m._pose(types, x, y, q))
        else:
            msg = types(kind, header=header, child_frame_id="robot",
                        transform=types("geometry_msgs/Transform",
                                        translation=m._vector(types, x, y, 0.0),
                                        rotation=m._quaternion(types, q)))
        self.rows.append((topic, kind, msg, t_ns if received is None else received))

    def twist(self, t_ns, v, w, topic="/cmd_vel"):
        self.rows.append((topic, "geometry_msgs/Twist", self.m.twist_message(self.types, v, w),
                          t_ns))

    def write(self, path):
        from rosbags.rosbag1 import Writer

        with Writer(path) as writer:
            connections = {}
            for topic, kind, msg, t in sorted(self.rows, key=lambda row: row[3]):
                full = kind.replace("/", "/msg/")
                if topic not in connections:
                    connections[topic] = writer.add_connection(topic, full, typestore=self.store)
                writer.write(connections[topic], t, self.store.serialize_ros1(msg, full))
        return path


KINK = 0.5 + 1 / 240  # when the arc starts: on a 120 Hz sample (t = i / 120 - 3 / 240)


def arc(t):
    """Still until ``KINK``, then 0.3 m/s and 0.8 rad/s from (1, 2) heading 3.0 rad (its yaw
    passes pi after 0.18 s)."""
    s = max(t - KINK, 0.0)
    yaw = 3.0 + 0.8 * s
    radius = 0.3 / 0.8
    return (1.0 + radius * (math.sin(yaw) - math.sin(3.0)),
            2.0 - radius * (math.cos(yaw) - math.cos(3.0)), yaw)


@pytest.mark.parametrize("kind", ["geometry_msgs/PoseStamped", "geometry_msgs/TransformStamped"])
def test_motion_capture_at_another_rate_is_interpolated(tmp_path, kind):
    bag, start = Bag(), 5 * NS
    mocap = "/vrpn_client_node/robot/pose"
    for i in range(int(3.0 * 120)):  # 120 Hz, half a sample off the updates, from before the
        t = round(i * NS / 120) - round(NS * 5 / 240)  # first one; received 2 ms later
        bag.pose(mocap, kind, start + t, *arc(t / NS), received=start + t + 2_000_000)
    odom0 = (0.5, -0.2, 1.0)  # the controller started earlier: its odometry is somewhere
    for k in range(29):
        x, y, yaw = arc(k / RATE_HZ)
        c, s = math.cos(odom0[2]), math.sin(odom0[2])
        dx, dy = x - arc(0)[0], y - arc(0)[1]
        bag.pose("/odom", "nav_msgs/Odometry", start + k * NS // 10, odom0[0] + c * dx - s * dy,
                 odom0[1] + s * dx + c * dy, odom0[2] + yaw - 3.0)
    sent = {}
    for k in range(4, 25):
        if k == 7:
            continue  # nothing published: NaN
        sent[k] = (0.3, 0.8 if k != 9 else -0.5)
        bag.twist(start + k * NS // 10 + 30_000_000, 9.0, 9.0)  # replaced by the next
        bag.twist(start + k * NS // 10 + 60_000_000, *sent[k])
    bag.twist(start + 25 * NS // 10, 0.1, 0.0)  # at the update itself: the period after it
    path = bag.write(tmp_path / "mocap.bag")
    (recording,) = read_recordings(path, truth_topic=mocap, rate_hz=RATE_HZ)
    assert recording.name == "mocap.bag episode 1" and recording.rate_hz == RATE_HZ
    assert len(recording.commands) == 28
    for k, row in enumerate(recording.commands):
        expected = sent.get(k, (0.1, 0.0) if k == 25 else (math.nan, math.nan))
        np.testing.assert_array_equal(row, expected)
    expected = np.array([arc(k / RATE_HZ) for k in range(29)])
    assert recording.truth[-1, 2] > math.pi  # unwrapped
    assert np.abs(recording.truth - expected).max() < 1e-5  # chords of 2.5 mm on a 37 cm arc
    # re-based: from (0, 0, 0); written turned by odom0 from the truth's motion, it is that
    assert np.abs(recording.odom - (expected - expected[0])).max() < 1e-12


def _episode(bag, start, duration, still_until, speed=0.2, stop_at=None, t0=0):
    """Ground truth and odometry at 10 Hz, straight along x at ``speed`` from ``still_until``
    s (until ``stop_at``), commands sent 10 ms after each update while moving."""
    stop_at = duration if stop_at is None else stop_at
    for k in range(round(duration * RATE_HZ) + 1):
        t = k / RATE_HZ
        x = t0 + speed * (min(max(t, still_until), stop_at) - still_until)
        bag.pose("/base_pose_ground_truth", "nav_msgs/Odometry", start + k * NS // 10, x, 0.0,
                 0.0)
        bag.pose("/odom", "nav_msgs/Odometry", start + k * NS // 10, x, 0.0, 0.0)
        if still_until - 0.1 <= t < stop_at - 0.1:
            bag.twist(start + k * NS // 10 + 10_000_000, speed, 0.0)


def test_a_start_in_motion_is_dropped_until_rest(tmp_path, caplog):
    bag = Bag()
    # moving from the start until 1 s, commanded until 0.81 s; still until 2.6 s; moving again
    _episode(bag, NS, 4.0, still_until=-1.0, stop_at=1.0)
    for k in range(25, 40):
        bag.twist(NS + k * NS // 10 + 10_000_000, 0.1, 0.0)
    rows = [r for r in bag.rows if r[0] != "/base_pose_ground_truth"]
    bag.rows = rows
    for k in range(41):
        t = k / RATE_HZ
        x = 0.2 * (min(t, 1.0) + 1.0) + 0.1 * max(t - 2.6, 0.0)
        bag.pose("/base_pose_ground_truth", "nav_msgs/Odometry", NS + k * NS // 10, x, 0.0, 0.0)
    path = bag.write(tmp_path / "moving.bag")
    with caplog.at_level(logging.INFO, logger="smartcar_gym.calibration.bag_source"):
        (recording,) = read_recordings(path, rate_hz=RATE_HZ)
    # still from 1 s, but the last command (0.2 m/s) arrived at 0.81 s: at rest from 1.9 s
    # (the driver's 1 s timeout)
    assert recording.name == "moving.bag episode 1 from 1.9 s"
    assert "the first 1.9 s dropped" in caplog.text
    assert len(recording.commands) == 21
    assert recording.truth[0, 0] == pytest.approx(0.4)
    assert np.isnan(recording.commands[:6]).all() and recording.commands[6, 0] == 0.1


def test_gaps_and_jumps_split_episodes(tmp_path):
    bag = Bag()
    _episode(bag, NS, 2.0, still_until=0.3)  # ends at x = 0.34
    _episode(bag, 4 * NS, 2.0, still_until=0.5)  # a 1 s gap before it
    # reset to x = -1 one period later: a jump, no gap
    _episode(bag, 6 * NS + NS // 10, 2.0, still_until=0.2, t0=-1.0)
    path = bag.write(tmp_path / "three.bag")
    recordings = read_recordings(path, rate_hz=RATE_HZ)
    assert [len(r.commands) for r in recordings] == [20, 20, 20]
    assert [r.truth[-1, 0] for r in recordings] == pytest.approx([0.34, 0.3, -0.64])
    assert [r.truth[0, 0] for r in recordings] == [0.0, 0.0, -1.0]
    first = recordings[0].commands
    assert np.isnan(first[:2]).all() and np.array_equal(first[2], [0.2, 0.0])


# -- errors ------------------------------------------------------------------------------------
@pytest.fixture
def drive_bag(tmp_path):
    bag = Bag()
    _episode(bag, NS, 2.0, still_until=0.3)
    return bag.write(tmp_path / "drive.bag")


def test_a_missing_topic_is_named_with_the_bag_topics(drive_bag):
    with pytest.raises(BagError) as error:
        read_recordings(drive_bag, truth_topic="/vrpn_client_node/robot/pose", rate_hz=RATE_HZ)
    assert str(error.value) == (f"{drive_bag} has no /vrpn_client_node/robot/pose; topics: "
                                "/base_pose_ground_truth, /cmd_vel, /odom")
    with pytest.raises(BagError, match=r"has no /cmd; topics: "):
        read_recordings(drive_bag, cmd_topic="/cmd", rate_hz=RATE_HZ)
    recordings = read_recordings(drive_bag, odom_topic=None, rate_hz=RATE_HZ)
    assert recordings[0].odom is None and len(recordings[0].commands) == 20


def test_an_empty_topic_name_is_refused_in_one_line(drive_bag):
    """``odom_topic=""`` said "has no ; topics: ..."; None is the way to read no odometry."""
    for key in ("truth_topic", "cmd_topic", "odom_topic"):
        with pytest.raises(BagError, match=rf"drive.bag: {key} '' is not a topic name"):
            read_recordings(drive_bag, **{key: ""}, rate_hz=RATE_HZ)


def test_a_topic_of_another_type_is_refused(drive_bag):
    with pytest.raises(BagError) as error:
        read_recordings(drive_bag, truth_topic="/cmd_vel", rate_hz=RATE_HZ)
    assert str(error.value) == (
        f"{drive_bag}: /cmd_vel is geometry_msgs/Twist, not nav_msgs/Odometry or "
        "geometry_msgs/PoseStamped or geometry_msgs/PoseWithCovarianceStamped or "
        "geometry_msgs/TransformStamped")
    with pytest.raises(BagError, match=r"/odom is nav_msgs/Odometry, not geometry_msgs/Twist"):
        read_recordings(drive_bag, cmd_topic="/odom", rate_hz=RATE_HZ)


def test_a_wrong_rate_or_clock_is_refused(drive_bag, tmp_path):
    with pytest.raises(BagError, match=r"/odom comes every 100 ms, but the controller's rate "
                                       r"20 Hz fires every 50 ms: is rate_hz right\?"):
        read_recordings(drive_bag, rate_hz=20.0)
    bag = Bag()
    _episode(bag, NS, 2.0, still_until=0.3)
    for topic, _, msg, _ in bag.rows:
        if topic == "/odom":  # stamped with another clock
            msg.header.stamp.sec += 1000
    with pytest.raises(BagError, match=r"the stamps of /odom \(1001 s on\) never fall among "
                                       r"those of /base_pose_ground_truth \(1 to 3 s\)"):
        read_recordings(bag.write(tmp_path / "clocks.bag"), rate_hz=RATE_HZ)


@pytest.mark.parametrize("kind", ["mcap", "ros2"])
def test_errors_name_the_topics_of_any_format(bags, kind):
    with pytest.raises(BagError) as error:
        read_recordings(bags[kind], truth_topic="/mocap", rate_hz=RATE_HZ)
    assert str(error.value).startswith(f"{bags[kind]} has no /mocap; topics: ")
    assert "/base_pose_ground_truth, /cmd_vel" in str(error.value)
    with pytest.raises(BagError, match=r"/tf is tf2_msgs/TFMessage, not nav_msgs/Odometry or"):
        read_recordings(bags[kind], truth_topic="/tf", rate_hz=RATE_HZ)


def test_empty_still_and_unreadable_bags(tmp_path):
    empty = Bag().write(tmp_path / "empty.bag")
    with pytest.raises(BagError, match=r"empty\.bag is empty: no topics$"):
        read_recordings(empty, rate_hz=RATE_HZ)
    bag = Bag()
    _episode(bag, NS, 2.0, still_until=5.0)
    bag.twist(NS + NS // 2, 0.0, 0.0)
    with pytest.raises(BagError, match=r"still\.bag: no motion: the robot never moves on "
                                       r"/base_pose_ground_truth"):
        read_recordings(bag.write(tmp_path / "still.bag"), rate_hz=RATE_HZ)
    bag = Bag()
    _episode(bag, NS, 2.0, still_until=0.0)
    bag.rows = [r for r in bag.rows if r[0] != "/cmd_vel"]
    bag.twist(NS // 2, 0.0, 0.0, topic="/other")
    with pytest.raises(BagError, match=r"has no /cmd_vel; topics: /base_pose_ground_truth, "
                                       r"/odom, /other$"):
        read_recordings(bag.write(tmp_path / "nocmd.bag"), rate_hz=RATE_HZ)
    junk = tmp_path / "junk.bag"
    junk.write_bytes(b"not a bag")
    with pytest.raises(BagError, match=r"junk\.bag: cannot be read as a bag: "):
        read_recordings(junk, rate_hz=RATE_HZ)
    with pytest.raises(BagError, match=r"nothing\.bag: no such file or folder"):
        read_recordings(tmp_path / "nothing.bag", rate_hz=RATE_HZ)
    (tmp_path / "x.txt").write_text("")
    with pytest.raises(BagError, match=r"not a bag \(a \.bag or \.mcap file, or a ROS 2 bag"):
        read_recordings(tmp_path / "x.txt", rate_hz=RATE_HZ)


def test_without_the_ros_extra_one_line_names_it(monkeypatch, drive_bag):
    import smartcar_gym.extras

    monkeypatch.setattr(smartcar_gym.extras, "missing_modules", lambda names: ["rosbags"])
    with pytest.raises(BagError) as error:
        read_recordings(drive_bag, rate_hz=RATE_HZ)
    assert str(error.value) == ('rosbags not installed; reading bags needs the ros extra: '
                                'pip install "smartcar-gym[ros]"')


def test_a_missing_bag_is_named_before_the_missing_extra(monkeypatch, tmp_path):
    """`smartcar-calibrate --fit planar --bag typo.bag` without the ros extra: the file's name
    first (the extra would not help)."""
    import smartcar_gym.extras

    monkeypatch.setattr(smartcar_gym.extras, "missing_modules", lambda names: ["rosbags"])
    with pytest.raises(BagError, match=r"typo\.bag: no such file or folder"):
        read_recordings(tmp_path / "typo.bag", rate_hz=RATE_HZ)
