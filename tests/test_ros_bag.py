"""``smartcar-eval --bag``: evaluated episodes as a ROS 1 bag or MCAP file, written without ROS.

Read back with rosbags (the ``ros`` extra) and, where Debian's ROS is installed, with
``rosbag info`` and Debian's own ``rosbag`` Python module (ROS's deserialisers).
"""

from __future__ import annotations

import importlib.util
import json
import os
import subprocess
import sys
import textwrap

import numpy as np
import pytest
import ros_needs

from smartcar_gym.agents.cli_eval import main as eval_main

pytestmark = pytest.mark.skipif(
    importlib.util.find_spec("rosbags") is None or importlib.util.find_spec("mcap") is None,
    reason='rosbags and mcap not installed: pip install "smartcar-gym[ros]"')

TOPICS = {"/odom": "nav_msgs/Odometry", "/tf": "tf2_msgs/TFMessage",
          "/joint_states": "sensor_msgs/JointState",
          "/base_pose_ground_truth": "nav_msgs/Odometry", "/cmd_vel": "geometry_msgs/Twist",
          "/move_base_simple/goal": "geometry_msgs/PoseStamped"}


@pytest.fixture(scope="module")
def evaluated(tmp_path_factory):
    folder = tmp_path_factory.mktemp("bag")
    bag, mcap, record = folder / "episodes.bag", folder / "episodes.mcap", folder / "eval.json"
    common = ["--pretrained", "--episodes", "2", "--seed", "5", "--no-progress"]
    assert eval_main([*common, "--bag", str(bag), "--json", str(record)]) == 0
    assert eval_main([*common, "--bag", str(mcap)]) == 0
    return bag, mcap, json.loads(record.read_text())


def _read_bag(path):
    from rosbags.rosbag1 import Reader

    from smartcar_gym.bags.ros1 import typestore

    store = typestore()
    with Reader(path) as reader:
        types = {c.topic: c.msgtype for c in reader.connections}
        rows = [(c.topic, t, store.deserialize_ros1(data, c.msgtype))
                for c, t, data in reader.messages()]
    return types, rows


def _episodes(rows):
    """Messages split at each goal (an episode's first message)."""
    episodes = []
    for topic, t, msg in rows:
        if topic == "/move_base_simple/goal":
            episodes.append([])
        episodes[-1].append((topic, t, msg))
    return episodes


def test_bag_holds_the_evaluated_episodes(evaluated):
    bag, _, record = evaluated
    types, rows = _read_bag(bag)
    assert types == {topic: kind.replace("/", "/msg/") for topic, kind in TOPICS.items()}
    episodes = _episodes(rows)
    assert len(episodes) == 2
    for episode, result in zip(episodes, record["episode_records"], strict=True):
        odom = [(t, msg) for topic, t, msg in episode if topic == "/odom"]
        twists = [msg for topic, _, msg in episode if topic == "/cmd_vel"]
        goal = episode[0][2].pose.position
        assert [goal.x, goal.y] == result["goal"]
        assert len(odom) == result["length"] + 1 and len(twists) == result["length"]
        stamps = [msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec for _, msg in odom]
        assert stamps == [t for t, _ in odom]  # header stamps are the bag's times
        assert np.all(np.diff(stamps) == 100_000_000)  # one controller period (0.1 s)
        last = odom[-1][1].pose.pose.position
        # the same episode as the evaluation's, to the last bit
        assert [last.x, last.y] == result["final_odom_pose"][:2]
        truth = [msg for topic, _, msg in episode if topic == "/base_pose_ground_truth"][-1]
        p = truth.pose.pose.position
        assert [p.x, p.y] == pytest.approx(result["final_pose"][:2], abs=1e-12)
        assert truth.header.frame_id == "world"
    first = rows[0][1]
    assert first == 1_000_000_000  # simulated time starts at 1 s in the bag
    gap = episodes[1][0][1] - episodes[0][-1][1]
    assert gap == 1_000_000_000


def test_random_episodes_in_the_bag_are_the_scored_ones(tmp_path):
    """``--random``: the bag replays the episodes scored (each episode's actions seeded by the
    episode), with 1 car or 3: their final odometry poses are the evaluation's."""
    for n_envs in ("1", "3"):
        bag, record = tmp_path / f"random{n_envs}.bag", tmp_path / f"random{n_envs}.json"
        assert eval_main(["--random", "--episodes", "3", "--seed", "2", "--engine", "planar",
                          "--vectorization", "batched", "--n-envs", n_envs, "--env-kwargs",
                          "max_episode_steps=15", "--no-progress", "--bag", str(bag),
                          "--json", str(record)]) == 0
        _, rows = _read_bag(bag)
        results = json.loads(record.read_text())["episode_records"]
        for episode, result in zip(_episodes(rows), results, strict=True):
            last = [msg for topic, _, msg in episode if topic == "/odom"][-1].pose.pose.position
            assert [last.x, last.y] == result["final_odom_pose"][:2]


def test_mcap_holds_the_same_messages(evaluated):
    bag, mcap, _ = evaluated
    from mcap.reader import make_reader

    _, rows = _read_bag(bag)
    with open(mcap, "rb") as stream:
        reader = make_reader(stream)
        assert reader.get_header().profile == "ros1"
        summary = reader.get_summary()
        schemas = {s.name for s in summary.schemas.values()}
        messages = [(channel.topic, message.log_time, message.data)
                    for _, channel, message in reader.iter_messages(log_time_order=False)]
    assert schemas == set(TOPICS.values())
    assert [(topic, t) for topic, t, _ in messages] == [(topic, t) for topic, t, _ in rows]


@ros_needs.needs("rosbag", ros_needs.DEBIAN_ROSBAG)
def test_debian_rosbag_info_and_rosbag_read_the_bag(evaluated):
    bag, _, record = evaluated
    info = subprocess.run(["rosbag", "info", str(bag)], capture_output=True, text=True,
                          timeout=60)
    assert info.returncode == 0, info.stderr
    n_odom = sum(r["length"] + 1 for r in record["episode_records"])
    assert f"/odom                     {n_odom} msgs    : nav_msgs/Odometry" in info.stdout
    for md5 in ("nav_msgs/Odometry         [cd5e73d190d741a2f92e81eda573aca7]",
                "tf2_msgs/TFMessage        [94810edda583a504dfda3829e70d7eec]",
                "geometry_msgs/PoseStamped [d3812c3cbc69362b77dc0b19b345f8f5]"):
        assert md5 in info.stdout  # ROS's own message definitions
    # Debian's Python reads every message with ROS's generated classes
    script = textwrap.dedent(f"""
        import collections, rosbag
        counts = collections.Counter()
        with rosbag.Bag({str(bag)!r}) as bag:
            for topic, msg, t in bag.read_messages():
                counts[topic] += 1
                if topic == "/odom":
                    last = msg.pose.pose.position
        print(dict(counts), last.x, last.y)
    """)
    debian = subprocess.run(["/usr/bin/python3", "-c", script], capture_output=True, text=True,
                            timeout=60, env={k: v for k, v in os.environ.items()
                                             if k not in ("PYTHONPATH", "VIRTUAL_ENV")})
    assert debian.returncode == 0, debian.stderr
    final = record["episode_records"][-1]["final_odom_pose"][:2]
    assert debian.stdout.split("}")[1].split() == [repr(final[0]), repr(final[1])]
    assert f"'/odom': {n_odom}" in debian.stdout


def test_bad_bag_arguments_are_one_line(tmp_path, capsys):
    with pytest.raises(SystemExit) as exit_info:
        eval_main(["--pretrained", "--episodes", "1", "--bag", str(tmp_path / "x.db3")])
    assert exit_info.value.code == 2
    assert "--bag: the file must end in .bag or .mcap, got" in capsys.readouterr().err
    (tmp_path / "dir.bag").mkdir()
    with pytest.raises(SystemExit):
        eval_main(["--pretrained", "--episodes", "1", "--bag", str(tmp_path / "dir.bag")])
    assert "dir.bag is a directory" in capsys.readouterr().err


def test_without_the_ros_extra_bag_says_which_extra():
    code = textwrap.dedent("""
        import sys
        class Blocker:
            def find_spec(self, name, path=None, target=None):
                if name.partition(".")[0] in ("rosbags", "mcap"):
                    raise ModuleNotFoundError(name)
        sys.meta_path.insert(0, Blocker())
        from smartcar_gym.agents.cli_eval import main
        main(["--pretrained", "--episodes", "1", "--bag", "x.bag"])
    """)
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                            timeout=120)
    assert result.returncode == 2
    assert result.stderr.strip().splitlines()[-1] == (
        'smartcar-eval: error: --bag: rosbags, mcap not installed; --bag needs the ros extra: '
        'pip install "smartcar-gym[ros]"')
