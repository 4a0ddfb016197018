"""``smartcar-eval --bag DIR --bag-format ros2``: rosbag2 folders written without ROS 2, read
back with rosbags and with ``mcap`` + ``mcap-ros2-support`` (a decoder of its own), and
checked against the episodes that made them."""

from __future__ import annotations

import importlib.util

import numpy as np
import pytest

from smartcar_gym.agents.cli_eval import main as eval_main
from smartcar_gym.agents.episodes import evaluate_policy_episodes
from smartcar_gym.agents.random_policy import RandomPolicy

pytestmark = pytest.mark.skipif(importlib.util.find_spec("rosbags") is None,
                                reason='rosbags not installed: pip install "smartcar-gym[ros]"')
NS = 1_000_000_000


@pytest.fixture(scope="module")
def nav_bag(tmp_path_factory):
    """Two SmartCarNav-v0 episodes (random actions, at most 30 steps each): the
    bag and the episodes as captured."""
    from smartcar_gym.bags.ros2 import Ros2BagSink

    path = tmp_path_factory.mktemp("ros2") / "nav"
    episodes = []
    sink = Ros2BagSink(path)
    records = evaluate_policy_episodes(RandomPolicy(7), "SmartCarNav-v0", n_episodes=2, seed=7,
                                       env_kwargs={"max_episode_steps": 30},
                                       recorders=[sink, episodes.append])
    sink.close()
    return path, episodes, records


def _read(path):
    from rosbags.rosbag2 import Reader

    from smartcar_gym.bags.ros2 import typestore

    store = typestore()
    with Reader(path) as reader:
        connections = {c.topic: c for c in reader.connections}
        rows = [(c.topic, t, store.deserialize_cdr(data, c.msgtype))
                for c, t, data in reader.messages()]
    return connections, rows


def _stamp(msg):
    return msg.header.stamp.sec * NS + msg.header.stamp.nanosec


def test_topics_counts_and_latched_description(nav_bag):
    path, episodes, records = nav_bag
    connections, rows = _read(path)
    frames = sum(len(e.frames) for e in episodes)
    steps = sum(e.steps for e in episodes)
    assert [r.length for r in records] == [e.steps for e in episodes]
    expected = {"/robot_description": 1, "/tf_static": 2, "/goal_pose": 2, "/odom": frames,
                "/tf": frames, "/joint_states": frames, "/base_pose_ground_truth": frames,
                "/scan": frames, "/cmd_vel": steps}
    assert {t: c.msgcount for t, c in connections.items()} == expected
    assert connections["/scan"].msgtype == "sensor_msgs/msg/LaserScan"
    assert connections["/tf"].msgtype == "tf2_msgs/msg/TFMessage"
    from rosbags.interfaces import QosDurability

    (qos,) = connections["/robot_description"].ext.offered_qos_profiles
    assert qos.durability == QosDurability.TRANSIENT_LOCAL  # latched, as rsp publishes it
    description = next(m for t, _, m in rows if t == "/robot_description")
    assert description.data == episodes[0].scene.urdf and "<robot" in description.data


def test_stamps_and_values_follow_the_episodes(nav_bag):
    path, episodes, _ = nav_bag
    _, rows = _read(path)
    odom = [(t, m) for topic, t, m in rows if topic == "/odom"]
    scans = [m for topic, _, m in rows if topic == "/scan"]
    commands = [m for topic, _, m in rows if topic == "/cmd_vel"]
    frames = [f for e in episodes for f in e.frames]
    start_2 = 1 * NS + episodes[0].frames[-1].time_ns + 1 * NS  # START_S, EPISODE_GAP_S
    expected = ([1 * NS + f.time_ns for f in episodes[0].frames]
                + [start_2 + f.time_ns for f in episodes[1].frames])
    assert [t for t, _ in odom] == expected == [_stamp(m) for _, m in odom]
    for (_, msg), frame in zip(odom, frames, strict=True):
        assert msg.header.frame_id == "odom" and msg.child_frame_id == "base_link"
        assert msg.pose.pose.position.x == frame.odometry.x
        assert msg.pose.pose.position.y == frame.odometry.y
        assert msg.twist.twist.linear.x == frame.odometry.v
    for msg, frame in zip(scans, frames, strict=True):
        np.testing.assert_array_equal(msg.ranges, frame.scan.ranges)
        assert msg.header.frame_id == "laser" and len(msg.ranges) == 360
    sent = [f.command for e in episodes for f in e.frames[1:]]
    assert [(c.linear.x, c.angular.z) for c in commands] == sent
    truth = [m for topic, _, m in rows if topic == "/base_pose_ground_truth"]
    assert [m.pose.pose.position.x for m in truth] == [f.position[0] for f in frames]
    goals = [m for topic, _, m in rows if topic == "/goal_pose"]
    assert [(g.pose.position.x, g.pose.position.y) for g in goals] == [e.scene.goal
                                                                       for e in episodes]


def test_tf_tree_links_world_odom_base_and_urdf_links(nav_bag):
    path, episodes, _ = nav_bag
    _, rows = _read(path)
    static = next(m for topic, _, m in rows if topic == "/tf_static")
    edges = {(t.header.frame_id, t.child_frame_id) for t in static.transforms}
    assert ("world", "odom") in edges and ("base_link", "laser") in edges
    first_tf = next(m for topic, _, m in rows if topic == "/tf")
    moving = {t.child_frame_id: t for t in first_tf.transforms}
    assert moving["base_link"].header.frame_id == "odom"
    wheels = set(episodes[0].scene.wheel_joints)
    assert {w.replace("_joint", "") for w in wheels} <= set(moving)
    for transform in first_tf.transforms:
        q = transform.transform.rotation
        assert abs(q.x**2 + q.y**2 + q.z**2 + q.w**2 - 1.0) < 1e-12


@pytest.mark.skipif(importlib.util.find_spec("mcap_ros2") is None,
                    reason="mcap-ros2-support not installed")
def test_mcap_ros2_support_decodes_the_bag(nav_bag):
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory

    path, episodes, _ = nav_bag
    (file,) = path.glob("*.mcap")
    assert file.name == "nav.mcap"
    counts: dict[str, int] = {}
    odom_x = []
    with open(file, "rb") as stream:
        reader = make_reader(stream, decoder_factories=[DecoderFactory()])
        for schema, channel, message, msg in reader.iter_decoded_messages():
            counts[channel.topic] = counts.get(channel.topic, 0) + 1
            assert channel.message_encoding == "cdr" and schema.encoding == "ros2msg"
            if channel.topic == "/odom":
                odom_x.append(msg.pose.pose.position.x)
                assert message.log_time == msg.header.stamp.sec * NS + msg.header.stamp.nanosec
            if channel.topic == "/joint_states" and counts[channel.topic] == 5:
                frame = episodes[0].frames[4]
                assert list(msg.name) == list(frame.joints.name)
                np.testing.assert_array_equal(msg.velocity, frame.joints.velocity)
    assert odom_x == [f.odometry.x for e in episodes for f in e.frames]
    assert counts["/scan"] == counts["/odom"] == sum(len(e.frames) for e in episodes)


def test_cli_writes_mcap_and_sqlite3_bags_and_refuses_an_existing_folder(tmp_path, capsys):
    from rosbags.rosbag2 import Reader

    common = ["--random", "--env", "SmartCarSim-v0", "--episodes", "2", "--no-progress",
              "--bag-format", "ros2"]
    for storage, suffix in (("mcap", ".mcap"), ("sqlite3", ".db3")):
        path = tmp_path / storage
        assert eval_main([*common, "--bag", str(path), "--bag-storage", storage]) == 0
        assert [p.suffix for p in path.iterdir() if p.name != "metadata.yaml"] == [suffix]
        with Reader(path) as reader:
            counts = {c.topic: c.msgcount for c in reader.connections}
        assert counts["/cmd_vel"] == 2 * 200 and counts["/odom"] == 2 * 201
        assert "/scan" not in counts  # SmartCarSim-v0 has no laser
    assert not list(tmp_path.glob(".*partial"))
    with pytest.raises(SystemExit) as exit_info:
        eval_main([*common, "--bag", str(tmp_path / "mcap")])
    assert exit_info.value.code == 2
    assert "exists; a ROS 2 bag is a new folder" in capsys.readouterr().err


def test_cli_names_the_extra_when_rosbags_is_missing(monkeypatch, capsys, tmp_path):
    monkeypatch.chdir(tmp_path)  # were the check missed, nothing is written into the tree
    import smartcar_gym.extras as extras

    real = extras.missing_modules
    monkeypatch.setattr(extras, "missing_modules",
                        lambda names: ["rosbags"] if "rosbags" in names else real(names))
    with pytest.raises(SystemExit) as exit_info:
        eval_main(["--random", "--episodes", "1", "--bag", "b", "--bag-format", "ros2"])
    assert exit_info.value.code == 2
    assert capsys.readouterr().err.strip().splitlines()[-1].endswith(
        '--bag: rosbags not installed; --bag needs the ros extra: pip install '
        '"smartcar-gym[ros]"')


def test_packed_cdr_is_byte_for_byte_what_rosbags_serialises(nav_bag):
    from smartcar_gym.bags import cdr
    from smartcar_gym.bags import messages as m
    from smartcar_gym.bags.ros2 import Ros2Types, typestore

    store = typestore()
    types = Ros2Types(store)
    _, episodes, _ = nav_bag
    frame = episodes[1].frames[7]
    stamp = 12_345_678_901
    odom = frame.odometry

    def serialised(msg, msgtype):
        return bytes(store.serialize_cdr(msg, msgtype))

    assert cdr.OdometryEncoder("odom", "base_link")(
        stamp, (odom.x, odom.y, 0.0), odom.quaternion, (odom.v, 0.0, 0.0),
        (0.0, 0.0, odom.omega)) == serialised(m.odometry_message(types, odom, stamp),
                                             "nav_msgs/msg/Odometry")
    assert cdr.TwistEncoder()(*frame.command) == serialised(
        m.twist_message(types, *frame.command), "geometry_msgs/msg/Twist")
    joints = frame.joints
    assert cdr.JointStateEncoder(joints.name)(
        stamp, joints.position.tolist(), joints.velocity.tolist(),
        joints.effort.tolist()) == serialised(m.joint_state_message(types, joints, stamp),
                                              "sensor_msgs/msg/JointState")
    tf = m.transform_message(types, odom, stamp)
    assert cdr.TransformsEncoder([("odom", "base_link")])(
        stamp, [((odom.x, odom.y, 0.0), odom.quaternion)]) == serialised(
        tf, "tf2_msgs/msg/TFMessage")
    scan = frame.scan
    expected = types("sensor_msgs/LaserScan", header=m.header(types, stamp, "laser"),
                     angle_min=scan.angle_min, angle_max=scan.angle_max,
                     angle_increment=scan.angle_increment,
                     time_increment=scan.time_increment, scan_time=scan.scan_time,
                     range_min=scan.range_min, range_max=scan.range_max, ranges=scan.ranges,
                     intensities=np.zeros(0, dtype=np.float32))
    assert cdr.LaserScanEncoder("laser")(
        stamp, scan.angle_min, scan.angle_max, scan.angle_increment, scan.time_increment,
        scan.scan_time, scan.range_min, scan.range_max, scan.ranges) == serialised(
        expected, "sensor_msgs/msg/LaserScan")


def test_close_is_idempotent_after_close_or_discard(nav_bag, tmp_path):
    """As ``RerunProcessSink.close``: a second ``close``, or ``close`` after ``discard``, does
    nothing (it raised rosbags' bare AssertionError)."""
    from smartcar_gym.bags.ros2 import Ros2BagSink

    _, episodes, _ = nav_bag
    kept = Ros2BagSink(tmp_path / "kept")
    kept.write(episodes[0])
    kept.close()
    kept.close()
    connections, rows = _read(tmp_path / "kept")
    assert {c.topic for c in connections.values()} >= {"/odom", "/tf"} and rows
    dropped = Ros2BagSink(tmp_path / "dropped")
    dropped.write(episodes[0])
    dropped.discard()
    dropped.close()
    dropped.discard()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["kept"]  # no bag, no scratch
