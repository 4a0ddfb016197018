"""Rerun recordings (``RerunRecorder``, ``smartcar-eval --rerun``) read back with Rerun's
dataframe API (``rerun.chunk.RrdReader`` and DataFusion, ``rerun-sdk[catalog]``) and checked
against the episodes that made them."""

from __future__ import annotations

import importlib.util
import socket
import urllib.request

import gymnasium as gym
import numpy as np
import pytest

import smartcar_gym  # noqa: F401  (registers the envs)
from smartcar_gym.agents.cli_eval import main as eval_main
from smartcar_gym.agents.episodes import evaluate_policy_episodes
from smartcar_gym.agents.random_policy import RandomPolicy

pytestmark = pytest.mark.skipif(importlib.util.find_spec("rerun") is None,
                                reason='rerun-sdk not installed: pip install '
                                       '"smartcar-gym[rerun]"')
needs_reader = pytest.mark.skipif(
    importlib.util.find_spec("datafusion") is None,
    reason='reading .rrd files back needs DataFusion: pip install "rerun-sdk[catalog]"')


def _store(path):
    from rerun.chunk import RrdReader

    reader = RrdReader(path)
    (recording,) = reader.recordings()
    return reader.stream(store=recording).collect()


def _column(store, entity, component, static=False):
    """The values of ``entity``'s ``component`` (``Archetype:field``), row by row in time
    (``static``: its one static value)."""
    frame = store.reader(index=None if static else "sim_time",
                         contents=f"/{entity}").to_pandas()
    column = frame[f"/{entity}:{component}"]
    if static:
        return column.iloc[0]
    return frame["sim_time"].dt.total_seconds().to_numpy(), list(column)


def _drive(env, seed, steps=None):
    """One episode with seeded random actions; what the env said at every step."""
    obs, info = env.reset(seed=seed)
    env.action_space.seed(seed)
    laser = env.unwrapped.laser  # None: the task's car carries no laser
    poses, rewards, scans = [info["pose"]], [], [None if laser is None
                                                  else laser.latest.ranges.copy()]
    done = False
    while not done:
        obs, reward, terminated, truncated, info = env.step(env.action_space.sample())
        poses.append(info["pose"])
        rewards.append(reward)
        if laser is not None:
            scans.append(env.unwrapped.laser.latest.ranges.copy())
        done = terminated or truncated or (steps is not None and len(rewards) == steps)
    return np.array(poses), np.array(rewards), scans, env.unwrapped.goal.copy()


@needs_reader
def test_recorder_writes_poses_goal_rewards_and_steps(tmp_path):
    from smartcar_gym.wrappers import RerunRecorder

    path = tmp_path / "episodes.rrd"
    env = RerunRecorder(gym.make("SmartCar-v0", max_episode_steps=60), path)
    first = _drive(env, seed=3)
    second = _drive(env, seed=4)
    assert not path.exists()  # written whole on close
    env.close()
    assert env.episodes_recorded == 2
    store = _store(path)
    for index, (poses, rewards, _, goal) in enumerate((first, second)):
        name = f"episode_{index:03d}"
        times, translations = _column(store, f"world/{name}/car", "Transform3D:translation")
        assert len(times) == len(rewards) + 1 == len(poses)  # the reset and every step
        np.testing.assert_allclose(times, 0.1 * np.arange(len(times)), atol=1e-9)  # 10 Hz
        xy = np.array([t[0][:2] for t in translations])
        np.testing.assert_allclose(xy, poses[:, :2], atol=1e-6)  # float32 in Rerun
        point = _column(store, f"world/{name}/goal", "Points3D:positions", static=True)
        np.testing.assert_allclose(point[0][:2], goal, atol=1e-6)
        _, reward_rows = _column(store, f"reward/{name}", "Scalars:scalars")
        terms = np.array([r for r in reward_rows])
        np.testing.assert_allclose(terms[1:, -1], rewards, atol=1e-12)  # the total
        np.testing.assert_allclose(terms[1:, :-1].sum(axis=1), rewards, atol=1e-9)  # its terms
        names = _column(store, f"reward/{name}", "SeriesLines:names", static=True)
        assert list(names) == ["progress", "time", "action", "success", "failure", "total"]
        _, wheels = _column(store, f"wheel_speed/{name}", "Scalars:scalars")
        assert np.array(wheels).shape == (len(poses), 4)
    urdf = _column(store, "robot_description", "TextDocument:text", static=True)
    assert "<robot" in str(urdf[0])


@needs_reader
def test_recorder_writes_the_laser_scan_and_obstacles(tmp_path):
    from smartcar_gym.wrappers import RerunRecorder

    path = tmp_path / "nav.rrd"
    env = RerunRecorder(gym.make("SmartCarNav-v0"), path)
    poses, rewards, scans, _ = _drive(env, seed=1, steps=15)
    env.close()  # an episode cut short is recorded as far as it went
    store = _store(path)
    times, points = _column(store, "world/episode_000/car/laser/scan", "Points3D:positions")
    assert len(times) == len(scans) == 16
    for ranges, cloud in zip(scans, points, strict=True):
        finite = np.sort(ranges[np.isfinite(ranges)])
        cloud = np.stack(cloud)
        assert len(cloud) == len(finite)  # one point per finite range, in the laser frame
        np.testing.assert_allclose(np.sort(np.hypot(cloud[:, 0], cloud[:, 1])), finite,
                                   rtol=1e-6)
    obstacles = env.unwrapped.obstacles
    boxes = [o for o in obstacles if o.shape == "box"]
    cylinders = [o for o in obstacles if o.shape == "cylinder"]
    if boxes:
        centers = _column(store, "world/episode_000/obstacles/boxes", "Boxes3D:centers",
                          static=True)
        np.testing.assert_allclose(np.stack(centers)[:, :2], [o.position for o in boxes],
                                   atol=1e-6)
    if cylinders:
        radii = _column(store, "world/episode_000/obstacles/cylinders", "Cylinders3D:radii",
                        static=True)
        np.testing.assert_allclose(radii, [o.size[0] / 2 for o in cylinders], rtol=1e-6)


@pytest.mark.slow
@needs_reader
def test_evaluation_records_every_episode_unchanged(tmp_path):
    from smartcar_gym.viewers.rerun_log import RerunSink

    plain = evaluate_policy_episodes(RandomPolicy(2), "SmartCar-v0", n_episodes=3, seed=2,
                                     n_envs=2)
    sink = RerunSink(tmp_path / "eval.rrd")
    recorded = evaluate_policy_episodes(RandomPolicy(2), "SmartCar-v0", n_episodes=3, seed=2,
                                        n_envs=2, recorders=[sink])  # frames from workers
    sink.close()
    store = _store(tmp_path / "eval.rrd")
    for before, after in zip(plain, recorded, strict=True):
        assert before.to_dict() == after.to_dict()  # recording changes nothing
        name = f"episode_{after.episode:03d}"
        times, translations = _column(store, f"world/{name}/car", "Transform3D:translation")
        assert len(times) == after.length + 1
        np.testing.assert_allclose(translations[-1][0][:2], after.path[-1], atol=1e-6)
        path = _column(store, f"world/{name}/odom/path", "LineStrips3D:strips", static=True)
        np.testing.assert_allclose(np.stack(path[0])[:, :2], after.odom_path, atol=1e-6)
        _, success = _column(store, f"success/{name}", "Scalars:scalars")
        assert bool(success[-1][0]) == after.success


def test_eval_cli_writes_a_recording_and_refuses_bad_names(tmp_path, capsys):
    path = tmp_path / "random.rrd"
    assert eval_main(["--random", "--episodes", "2", "--no-progress", "--rerun",
                      str(path)]) == 0
    assert path.stat().st_size > 10_000
    assert "rerun (2 episodes)" in capsys.readouterr().out
    with pytest.raises(SystemExit) as exit_info:
        eval_main(["--random", "--episodes", "1", "--rerun", str(tmp_path / "x.mcap")])
    assert exit_info.value.code == 2
    assert "--rerun: the file must end in .rrd" in capsys.readouterr().err


def test_eval_cli_records_without_importing_pandas(tmp_path):
    """``smartcar-eval --rerun`` spares itself pyarrow's import of pandas (0.3 s); pyarrow's
    pandas features still work afterwards."""
    import subprocess
    import sys

    path = tmp_path / "random.rrd"
    code = (
        "import sys\n"
        "from smartcar_gym.agents.cli_eval import main\n"
        f"main(['--random', '--episodes', '2', '--no-progress', '--rerun', {str(path)!r}])\n"
        "print('pandas' in sys.modules)\n"
        "import pyarrow as pa\n"
        "print(pa.table({'a': [1.5]}).to_pandas()['a'].tolist())\n"
    )
    out = subprocess.run([sys.executable, "-c", code], check=True, capture_output=True,
                         text=True).stdout.splitlines()
    assert out[-2:] == ["False", "[1.5]"]
    assert path.stat().st_size > 10_000


def test_eval_cli_names_the_extra_when_rerun_is_missing(monkeypatch, capsys, tmp_path):
    monkeypatch.chdir(tmp_path)  # were the check missed, nothing is written into the tree
    import smartcar_gym.extras as extras

    real = extras.missing_modules
    monkeypatch.setattr(extras, "missing_modules",
                        lambda names: ["rerun"] if "rerun" in names else real(names))
    with pytest.raises(SystemExit) as exit_info:
        eval_main(["--random", "--episodes", "1", "--rerun", "x.rrd"])
    assert exit_info.value.code == 2
    line = capsys.readouterr().err.strip().splitlines()[-1]
    assert line.endswith('--rerun: rerun-sdk not installed; recording needs the rerun extra: '
                         'pip install "smartcar-gym[rerun]"')


def test_recorder_refuses_an_env_that_is_not_a_smartcar():
    from smartcar_gym.wrappers import RerunRecorder

    with pytest.raises(ValueError, match="needs a SmartCarEnv.*CartPoleEnv"):
        RerunRecorder(gym.make("CartPole-v1"), "x.rrd")


def _free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_serve_hosts_the_web_viewer_from_the_package():
    from smartcar_gym.viewers.rerun_log import RerunSink

    grpc_port, web_port = _free_port(), _free_port()
    sink = RerunSink(serve=True, grpc_port=grpc_port, web_port=web_port)
    try:
        assert sink.web_url.startswith(f"http://127.0.0.1:{web_port}/?url=rerun%2Bhttp")
        page = urllib.request.urlopen(f"http://localhost:{web_port}/", timeout=10).read()
        assert b"<html" in page.lower() and b"rerun" in page.lower()
    finally:
        sink.close()
