"""SmartCarBARN-v0 with ``map_mode="laser"``: no map, the global path planned on each car's
own laser costmap and planned again as it fills (the batch against its single envs is in
tests/test_vector_barn.py)."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import smartcar_gym  # noqa: F401
from smartcar_gym.navigation.costmap import INSCRIBED

SCALE = 0.18 / 0.43


@pytest.fixture(scope="module")
def laser_env():
    env = gym.make("SmartCarBARN-v0", engine="planar", map_mode="laser")
    yield env
    env.close()


def _cells(u, points):
    ix, iy, inside = u.costmaps.world_to_cell(np.asarray(points, dtype=float))
    assert inside.all()
    return ix, iy


def test_the_first_scan_marks_only_what_the_laser_reaches(laser_env):
    laser_env.reset(seed=0, options={"world": 0})
    u = laser_env.unwrapped
    lethal = u.costmaps.lethal(0)
    assert lethal.any()
    iy, ix = np.nonzero(lethal)
    marks = u.costmaps.cell_to_world(ix, iy)
    laser_xy = u.mount[:2, 3]  # base_link at the origin, heading +x
    reach = u.costmap_config.obstacle_range + u.costmap_config.resolution
    assert np.hypot(*(marks - laser_xy).T).max() <= reach
    # the cylinders beyond the laser's reach are not on the costmap: nothing of them is known
    centres = np.array([o.position for o in u.obstacles])
    far = centres[np.hypot(*(centres - laser_xy).T) > reach + 0.2]
    assert len(far) > 100
    fx, fy = _cells(u, far)
    assert not lethal[fy, fx].any()


def test_the_path_avoids_what_was_seen_and_is_planned_again_as_the_car_drives(laser_env):
    laser_env.reset(seed=0, options={"world": 0})
    u = laser_env.unwrapped
    first = u.global_path.copy()
    assert np.allclose(first[-1], u.goal, atol=u.costmap_config.resolution)
    marked = int(u.costmaps.lethal(0).sum())
    for _ in range(5):
        laser_env.step(np.array([0.3, 0.0], dtype=np.float32))
    px, py = _cells(u, u.global_path)
    assert (u.costmaps.costs(0)[py[1:], px[1:]] < INSCRIBED).all()
    assert int(u.costmaps.lethal(0).sum()) > marked  # the costmap filled as the car moved
    assert not np.array_equal(u.global_path, first)  # and the path was planned again


def test_the_known_map_stays_the_default():
    env = gym.make("SmartCarBARN-v0", engine="planar")
    try:
        env.reset(seed=0, options={"world": 0})
        assert env.unwrapped.map_mode == "known" and env.unwrapped.costmaps is None
    finally:
        env.close()


@pytest.mark.parametrize(("kwargs", "message"), [
    ({"map_mode": "slam"}, "map_mode must be one of 'known', 'laser', got 'slam'"),
    ({"map_mode": "laser", "localize": True, "laser": {"rate_hz": 5.0}},
     "localize=True matches each scan with the odometry of its instant: the laser's rate_hz "
     "(5) must be the controller's (10)"),
])
def test_a_map_mode_it_cannot_run_is_one_line(kwargs, message):
    with pytest.raises(ValueError) as err:
        gym.make("SmartCarBARN-v0", engine="planar", **kwargs)
    assert str(err.value).startswith(message) and "\n" not in str(err.value)


def test_the_path_progress_reward_is_the_known_paths_in_either_map_mode():
    """progress='path' on the laser map: the reward is the known map's path progress (the
    simulator's truth, a training signal), the same to the bit as on the known map for the
    same actions; only the waypoint in the observation differs."""
    envs = [gym.make("SmartCarBARN-v0", engine="planar", map_mode=mode, progress="path")
            for mode in ("known", "laser")]
    try:
        for env in envs:
            env.reset(seed=0, options={"world": 6})
        rng = np.random.default_rng(0)
        waypoints_differ = False
        for _ in range(30):
            action = rng.uniform([0.2, -0.5], [1.0, 0.5]).astype(np.float32)
            (obs_k, r_k, *_), (obs_l, r_l, *_) = (env.step(action) for env in envs)
            assert r_k == r_l
            waypoints_differ |= not np.array_equal(obs_k[-2:], obs_l[-2:])
        assert waypoints_differ and envs[1].unwrapped.costmaps is not None
        assert np.all(np.asarray(envs[1].unwrapped.task.terms["path"]) != 0.0)
    finally:
        for env in envs:
            env.close()


def test_dwa_follows_each_new_plan_of_the_laser_costmap(laser_env):
    """Mapless DWA: the driver restarts its path tracker on each path the task plans again,
    as move_base hands navfn's plans to its local planner."""
    from smartcar_gym.bench.dwa import DWADriver
    from smartcar_gym.envs.vector.view import CarView

    laser_env.reset(seed=0, options={"world": 6})
    u = laser_env.unwrapped
    driver, cars = DWADriver(), CarView([laser_env])
    driver.reset(cars)
    plans = set()
    for _ in range(25):
        action = driver.act(cars)[0]
        assert driver.following[0] is u.global_path  # the newest plan
        plans.add(id(u.global_path))
        _, _, terminated, truncated, info = laser_env.step(action)
        assert not (terminated or truncated)
    assert len(plans) > 1 and info["pose"][0] > 0.1  # planned again as it drove on


@pytest.mark.parametrize(("name", "trained", "other"), [("barn-known", "known", "laser"),
                                                       ("barn", "laser", "known")])
def test_a_policy_of_one_map_mode_is_refused_in_the_other_in_one_line(name, trained, other,
                                                                      capsys):
    pytest.importorskip("stable_baselines3", reason="the shipped policy needs the train extra")
    from smartcar_gym.agents.policies import Policy, PolicyError
    from smartcar_gym.bench import cli as bench_cli

    expected = (f"the policy was trained with map_mode={trained!r} (its waypoint from that "
                f"map's path) and cannot run with map_mode={other!r}: pass a policy trained "
                "for it")
    with pytest.raises(PolicyError) as err:
        Policy.load(name, env_kwargs={"map_mode": other})
    assert str(err.value) == expected
    assert Policy.load(name, env_kwargs={"map_mode": trained}).env_kwargs["map_mode"] == trained
    with pytest.raises(SystemExit) as exit_:
        bench_cli.main(["barn", "--pretrained", name, "--worlds", "0", "--engine", "planar",
                        "--env-kwargs", f"map_mode={other}"])
    assert exit_.value.code == 2
    last = capsys.readouterr().err.strip().splitlines()[-1]
    assert last == f"smartcar-bench barn: error: {expected}"


def test_the_costmap_keyword_changes_the_laser_costmaps_fields_and_only_those():
    """``costmap={...}``: the named fields replace the challenge's scaled ones, the others stay."""
    changes = {"obstacle_range": 3.0, "raytrace_range": 3.5, "inscribed_radius": 0.125,
               "inflation_radius": 0.25}
    envs = [gym.make("SmartCarBARN-v0", engine="planar", map_mode="laser", **kwargs)
            for kwargs in ({}, {"costmap": changes})]
    try:
        challenge, changed = (env.unwrapped.costmap_config for env in envs)
        assert challenge.obstacle_range == pytest.approx(2.5 * SCALE)
        assert challenge.inflation_radius == pytest.approx(0.30 * SCALE)
        assert {name: getattr(changed, name) for name in changes} == changes
        assert (changed.resolution, changed.size, changed.cost_scaling_factor) == (
            challenge.resolution, challenge.size, challenge.cost_scaling_factor)
        envs[1].reset(seed=0, options={"world": 6})
        assert envs[1].unwrapped.costmaps.config == changed
    finally:
        for env in envs:
            env.close()


@pytest.mark.parametrize(("kwargs", "message"), [
    ({"map_mode": "laser", "costmap": {"range": 3.0}},
     "costmap: unknown field(s) ['range']; CostmapConfig has resolution, size, obstacle_range"),
    ({"map_mode": "laser", "costmap": {"inflation_radius": -1}},
     "costmap inflation_radius must be a positive number, got -1"),
    ({"map_mode": "laser", "costmap": {"inscribed_radius": 0.3}},
     "costmap inscribed_radius 0.3 m must not exceed inflation_radius"),
    ({"costmap": {"obstacle_range": 3.0}},
     "costmap changes the laser costmap's fields: map_mode='known' has none"),
    ({"map_mode": "laser", "costmap": [3.0]}, "costmap must be a dict of CostmapConfig fields"),
])
def test_a_bad_costmap_keyword_is_one_line(kwargs, message):
    with pytest.raises((ValueError, TypeError)) as err:
        gym.make("SmartCarBARN-v0", engine="planar", **kwargs)
    assert str(err.value).startswith(message) and "\n" not in str(err.value)


def test_planner_frequency_0_keeps_the_path_until_a_new_mark_blocks_it():
    """The env's ``planner_frequency=0`` plans again only when a new mark blocks the path (the
    default: every step); refused on the known map and below 0 in one line."""
    counts = []
    for kwargs in ({}, {"planner_frequency": 0}):
        env = gym.make("SmartCarBARN-v0", engine="planar", map_mode="laser", **kwargs)
        try:
            env.reset(seed=0, options={"world": 6})
            u, changes = env.unwrapped, 0
            for _ in range(40):
                before = u.global_path
                env.step(np.array([0.6, 0.0], np.float32))
                changes += u.global_path is not before
            counts.append(changes)
        finally:
            env.close()
    assert counts[0] >= 30 and 1 <= counts[1] < counts[0] // 3, counts
    for kwargs, message in (({"planner_frequency": 0}, "planner_frequency is the laser map's"),
                            ({"planner_frequency": -1, "map_mode": "laser"},
                             "planner_frequency must be a rate >= 0 Hz")):
        with pytest.raises(ValueError) as err:
            gym.make("SmartCarBARN-v0", engine="planar", **kwargs)
        assert str(err.value).startswith(message) and "\n" not in str(err.value)
