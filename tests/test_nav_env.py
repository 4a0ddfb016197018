"""SmartCarNav-v0: observation, obstacles, collisions, layouts, laser settings, rendering."""

from __future__ import annotations

import copy
import pickle

import gymnasium as gym
import numpy as np
import pytest

import smartcar_gym  # noqa: F401
from smartcar_gym.envs.sensors.scan import scan_sectors
from smartcar_gym.envs.smartcar_env import SmartCarEnv
from smartcar_gym.envs.tasks.nav import NavTask
from smartcar_gym.model import SHIPPED_MODEL
from smartcar_gym.model.footprint import footprint_radius

AHEAD = [{"shape": "box", "position": [0.6, 0.0], "size": [0.2, 1.0]}]  # face at x = 0.5
FORWARD = np.array([1.0, 0.0], dtype=np.float32)


@pytest.fixture
def env():
    env = gym.make("SmartCarNav-v0")
    yield env
    env.close()


def test_observation_is_smartcar_v0_then_the_scan(env):
    base = SmartCarEnv()
    try:
        names = env.unwrapped.observation_names
        assert env.observation_space.shape == (57,) == (len(names),)
        assert names[:21] == base.observation_names
        assert names[21:] == tuple(f"scan_{i:02d}" for i in range(36))
        assert env.observation_space.high[-1] == 3.5 and env.observation_space.low[-1] == 0.0
    finally:
        base.close()
    obs, info = env.reset(seed=0)
    assert obs in env.observation_space and info["collision"] is False
    ranges = env.unwrapped.laser.latest.ranges
    assert np.array_equal(obs[21:], scan_sectors(ranges, 3.5, 36).astype(np.float32))
    obs, *_ = env.step(FORWARD)
    assert np.array_equal(obs[21:], scan_sectors(env.unwrapped.laser.latest.ranges, 3.5, 36)
                          .astype(np.float32))
    assert env.unwrapped.laser.latest.stamp_s == pytest.approx(0.1)


def test_docstring_table_is_the_declared_observation():
    env = gym.make("SmartCarNav-v0")
    try:
        table = env.unwrapped.observation.table()
    finally:
        env.close()
    assert type(env.unwrapped.task) is NavTask
    assert table.replace("\n", "\n    ") in NavTask.__doc__
    assert "| 21-56 | laser: nearest range in each of 36 sectors" in NavTask.__doc__


def test_drawn_obstacles_stand_where_the_layout_says_and_leave_room(env):
    radius = footprint_radius(env.unwrapped.robot_model)
    assert radius == pytest.approx(0.1506, abs=1e-3)  # the base box's half diagonal
    layouts = []
    for seed in range(5):
        env.reset(seed=seed)
        u = env.unwrapped
        layouts.append(u.obstacles)  # the single env's car's
        assert len(u.obstacles) == 8
        for i, o in enumerate(u.obstacles):
            assert o.distance(np.zeros(2)) >= radius + 0.2
            assert o.distance(u.goal) >= radius + 0.2
            body = u.sim.body(f"obstacle_{i}")
            position, _ = body.link_pose()
            assert position == pytest.approx((*o.position, 0.15))
    assert len({tuple(layout) for layout in layouts}) == 5
    env.reset(seed=3)
    assert env.unwrapped.obstacles == layouts[3]


def test_driving_into_an_obstacle_is_a_penalised_terminal_collision(env):
    env.reset(seed=0, options={"goal": (1.5, 0.5), "obstacles": AHEAD})
    u = env.unwrapped
    steps = 0
    while steps < 60:
        distance = float(u.task.distance[0])
        obs, reward, terminated, truncated, info = env.step(FORWARD)
        steps += 1
        if terminated:
            break
        assert not info["collision"]
    assert info["collision"] is True and terminated and not truncated
    assert not info["is_success"] and info["clearance"] <= 0.0
    assert 0.35 < info["pose"][0] < 0.4  # the front (x + 0.125) at the face (0.5)
    progress = 10 * (distance - info["distance"]) - 0.01 - 0.01 * 1.0
    assert reward == pytest.approx(progress - 10.0)
    assert obs[21 + 18] < 0.2  # the sector ahead sees the box
    assert 9 < steps < 21  # 0.375 m at up to 0.5 m/s


def test_proximity_penalty_follows_the_ground_truth_clearance():
    env = gym.make("SmartCarNav-v0", proximity_penalty=2.0, proximity_m=0.3)
    try:
        _, info = env.reset(seed=0, options={"goal": (1.5, 0.5), "obstacles": AHEAD})
        assert info["clearance"] == 0.3  # 0.375 m from the box: capped at proximity_m
        u, seen = env.unwrapped, []
        for _ in range(60):
            distance = float(u.task.distance[0])
            _, reward, terminated, _, info = env.step(FORWARD)
            progress = 10 * (distance - info["distance"]) - 0.02
            inside = min(1.0, max(0.0, (0.3 - info["clearance"]) / 0.3))
            assert reward == pytest.approx(progress - 2.0 * inside - 10.0 * info["collision"])
            seen.append(info["clearance"])
            if terminated:
                break
        assert info["collision"] and seen[-1] <= 0.0
        assert any(0.0 < c < 0.3 for c in seen)  # the penalty grew on the way in
    finally:
        env.close()


def test_collisions_are_seen_in_sim_mode_too():
    env = gym.make("SmartCarNav-v0", controller_mode="sim", obstacle_layout=AHEAD)
    try:
        env.reset(seed=0, options={"goal": (1.5, 0.5)})
        for _ in range(60):
            _, _, terminated, _, info = env.step(FORWARD)
            if terminated:
                break
        assert info["collision"] and 0.36 < info["pose"][0] < 0.43
    finally:
        env.close()


def test_a_fixed_layout_redraws_goals_that_are_too_close(tmp_path):
    wall = [{"shape": "box", "position": [0.0, 1.5], "size": [6.0, 1.4]}]  # covers y 0.8-2.2
    path = tmp_path / "wall.yaml"
    path.write_text("- {shape: box, position: [0.0, 1.5], size: [6.0, 1.4]}\n")
    env = gym.make("SmartCarNav-v0", obstacle_layout=path)
    try:
        for seed in range(20):
            env.reset(seed=seed)
            u = env.unwrapped
            assert [o.to_dict() for o in u.obstacles] == [
                {"shape": "box", "position": [0.0, 1.5], "size": [6.0, 1.4], "yaw": 0.0}]
            assert u.goal[1] < 0.8 - 0.35  # the wall's near side minus the keep-out distance
        env.reset(seed=0, options={"obstacles": []})  # this episode only
        assert env.unwrapped.obstacles == ()
        env.reset(seed=0)
        assert len(env.unwrapped.obstacles) == 1
        with pytest.raises(ValueError, match="inside an obstacle"):
            env.reset(options={"goal": (0.0, 1.5)})
        with pytest.raises(ValueError, match="inside an obstacle"):
            env.reset(options={"goal": (0.0, 1.0), "obstacles": wall})
    finally:
        env.close()


@pytest.mark.parametrize("options, error, match", [
    ({"obstacles": [{"shape": "box", "position": [0.1, 0.0], "size": [0.2, 0.2]}]},
     ValueError, r"options\['obstacles'\]\[0\].*overlaps the car at the start"),
    ({"obstacles": "nowhere.yaml"}, FileNotFoundError, "no such file"),
    ({"obstacles": {"shape": "box"}}, ValueError, "must be a list of obstacles"),
    ({"walls": []}, ValueError, r"SmartCarNav-v0 takes 'goal', 'obstacles'"),
])
def test_bad_reset_options_keep_the_running_world(env, options, error, match):
    env.reset(seed=0)
    before = env.unwrapped.obstacles
    bodies = list(env.unwrapped.obstacle_bodies)
    with pytest.raises(error, match=match):
        env.reset(seed=1, options=options)
    assert env.unwrapped.obstacles == before  # nothing was torn down
    assert env.unwrapped.obstacle_bodies == bodies
    env.step(FORWARD)


@pytest.mark.parametrize("kwargs, error, match", [
    ({"laser": {"range": 3}}, ValueError, r"laser: unknown field\(s\) \['range'\]"),
    ({"laser": {"range_min": 5.0}}, ValueError, "range_min"),
    ({"laser": 3}, TypeError, "laser must be a dict"),
    ({"scan_sectors": 400}, ValueError, "scan_sectors must be at most 360"),
    ({"obstacles": -1}, ValueError, "obstacles must be"),
    ({"obstacles": 60}, RuntimeError, "could not place 60 obstacles"),
    ({"obstacle_size": (0.3,)}, ValueError, "obstacle_size"),
    ({"obstacle_clearance": -1}, ValueError, "obstacle_clearance"),
    ({"collision_penalty": -1}, ValueError, "collision_penalty"),
    ({"obstacle_layout": [{"shape": "box", "position": [0, 0], "size": [1, 1]}]}, ValueError,
     r"obstacle_layout\[0\].*overlaps the car"),
    ({"model_args": "laser:=true"}, TypeError, "model_args"),
    ({"laser_mount": (0, 0)}, ValueError, "laser_mount"),
])
def test_bad_arguments_are_refused(kwargs, error, match):
    with pytest.raises(error, match=match):
        gym.make("SmartCarNav-v0", **kwargs)


def test_a_model_without_laser_link_needs_a_mount():
    with pytest.raises(ValueError, match="no 'laser' link: pass laser_mount"):
        gym.make("SmartCarNav-v0", model_args={"laser": "false"})
    env = gym.make("SmartCarNav-v0", model_args={"laser": "false"},
                   laser_mount=(0.05, 0.0, 0.1, 0.0), scan_sectors=8,
                   laser={"angle_min": -1.0, "angle_max": 1.0, "angle_increment": 0.01})
    try:
        assert "laser" not in env.unwrapped.robot_model.links
        obs, _ = env.reset(seed=0, options={"obstacles": AHEAD, "goal": (-1.0, 0.0)})
        assert obs.shape == (29,)
        assert env.unwrapped.laser.latest.ranges.shape == (201,)
        assert obs[-4] == pytest.approx(0.45 - env.unwrapped.robot.pose().x, abs=3e-3)
    finally:
        env.close()


def test_a_model_path_is_expanded_with_model_args():
    env = gym.make("SmartCarNav-v0", model=SHIPPED_MODEL, model_args={"laser": "true"})
    try:
        assert "laser" in env.unwrapped.robot_model.links
        assert np.allclose(env.unwrapped.mount[:3, 3], [0.0, 0.0, 0.1])
    finally:
        env.close()
    with pytest.raises(ValueError, match="no 'laser' link"):
        gym.make("SmartCarNav-v0", model=str(SHIPPED_MODEL))  # a path: no xacro arguments


def test_noisy_scans_are_seeded():
    env = gym.make("SmartCarNav-v0", laser={"noise_std_m": 0.02})
    try:
        first = env.reset(seed=5)[0]
        again = env.reset(seed=5)[0]
        other_noise = env.reset(seed=5, options={"goal": env.unwrapped.goal})[0]
        assert np.array_equal(first, again)
        assert np.array_equal(first[:21], other_noise[:21])
        ranges = env.unwrapped.laser.latest.ranges
        assert np.isfinite(ranges).any()
    finally:
        env.close()


def test_rgb_array_shows_obstacles_and_laser_hits():
    env = gym.make("SmartCarNav-v0", render_mode="rgb_array", render_width=320,
                   render_height=240)
    try:
        # a wall left of the car: the face the laser hits faces the camera (which looks +y)
        wall = [{"shape": "box", "position": [0.5, 0.6], "size": [1.0, 0.2]}]
        env.reset(seed=0, options={"goal": (1.5, 0.0), "obstacles": wall})
        img = env.render()
        assert img.shape == (240, 320, 3) and img.dtype == np.uint8
        r, g, b = (img[..., i].astype(int) for i in range(3))
        red = (r > 150) & (g < 60) & (b < 60)  # hit points
        grey = (abs(r - g) < 12) & (abs(g - b) < 20) & (r > 60) & (r < 170)  # the box
        assert red.sum() > 20 and grey.sum() > 200
        assert np.array_equal(img, env.render())
    finally:
        env.close()


def test_copies_get_their_own_world(env):
    env.reset(seed=2)
    for clone in (copy.deepcopy(env.unwrapped), pickle.loads(pickle.dumps(env.unwrapped))):
        try:
            obs, _ = clone.reset(seed=2)
            assert np.array_equal(obs, env.reset(seed=2)[0])
            assert clone.sim is not env.unwrapped.sim
        finally:
            clone.close()


def test_nav_runs_the_calibrated_yaml_which_differs_from_the_tutorials_in_base_width_only():
    import dataclasses

    from smartcar_gym.controller import load_controller_config
    from smartcar_gym.controller.config_yaml import calibrated_config_path, default_config_path

    calibrated = load_controller_config(calibrated_config_path())
    tutorial = load_controller_config(default_config_path())
    assert (calibrated.base_width_m, tutorial.base_width_m) == (0.33, 0.26)
    assert dataclasses.replace(calibrated, base_width_m=0.26, source=tutorial.source) == tutorial
    env = gym.make("SmartCarNav-v0", obstacles=0)
    try:
        assert env.unwrapped.controller_config == calibrated
    finally:
        env.close()
    env = gym.make("SmartCarNav-v0", obstacles=0, controller_config=default_config_path())
    try:
        assert env.unwrapped.controller_config.base_width_m == 0.26
    finally:
        env.close()


@pytest.mark.parametrize("engine", ["pybullet", "planar", "mujoco"])
def test_an_empty_arena_scans_nothing_on_every_engine(engine):
    """obstacles=0: every beam reads +inf (nothing within range_max), on the planar engine
    too (its cast once failed on an empty list of bodies)."""
    env = gym.make("SmartCarNav-v0", obstacles=0, engine=engine)
    try:
        env.reset(seed=0)
        env.step(np.zeros(2, dtype=np.float32))
        assert np.isposinf(env.unwrapped.laser.latest.ranges).all()
    finally:
        env.close()
