"""SmartCarBARN-v0: the worlds on every engine, the protocol's outcomes and scores, the waypoint."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import smartcar_gym  # noqa: F401
from smartcar_gym.bench.dwa import DWADriver
from smartcar_gym.envs.tasks.barn import BarnTask, barn_score
from smartcar_gym.envs.tasks.barn.protocol import SHIPPED_CAR_WIDTH_M
from smartcar_gym.envs.vector.view import CarView
from smartcar_gym.model.footprint import car_width
from smartcar_gym.navigation.path_trackers import COMPILED as PATHS_COMPILED
from smartcar_gym.navigation.path_trackers import PathTrackers
from smartcar_gym.navigation.paths import PathTracker, to_base_frame
from smartcar_gym.worlds.barn import TRAIN_WORLDS, load_worlds, to_car_frame

SCALE = 0.18 / 0.43


@pytest.fixture(scope="module")
def env():
    env = gym.make("SmartCarBARN-v0", engine="mujoco")
    yield env
    env.close()


def test_the_world_is_scaled_to_the_cars_width_and_the_protocol_with_it(env):
    u = env.unwrapped
    assert type(u.task) is BarnTask
    assert car_width(u.robot_model) == pytest.approx(SHIPPED_CAR_WIDTH_M)
    assert u.protocol.scale == pytest.approx(SCALE)
    obs, info = env.reset(seed=0, options={"world": 6})
    assert obs.shape == (59,) and obs in env.observation_space
    assert u.observation_names[-2:] == ("waypoint_x_base", "waypoint_y_base")
    world = load_worlds().world(6)
    obstacles = u.obstacles  # the single env's car's
    assert len(obstacles) == len(world.centres)
    assert obstacles[0].size == pytest.approx((2 * 0.075 * SCALE,))
    assert np.allclose([o.position for o in obstacles], to_car_frame(world.centres, SCALE))
    assert u.task.world.index == u.world_index[0] == 6
    assert np.allclose(u.goal, [10 * SCALE, 0.0])
    assert u.task.goal_tolerance_m == pytest.approx(SCALE)
    assert u.timeout_steps == 1675 and gym.spec("SmartCarBARN-v0").max_episode_steps is None
    assert info["world"] == 6 and info["outcome"] is None and info["score"] == 0.0
    assert info["optimal_time_s"] == pytest.approx(world.path_length_m * SCALE / 0.5)


def test_the_global_path_goes_from_start_to_goal_clear_of_the_inflated_cylinders(env):
    env.reset(seed=0, options={"world": 150})
    u = env.unwrapped
    path = u.global_path
    assert np.linalg.norm(path[0]) < 0.02 and np.linalg.norm(path[-1] - u.goal) < 0.02
    centres = np.array([o.position for o in u.obstacles])
    clear = np.linalg.norm(path[:, None] - centres[None], axis=-1) - 0.075 * SCALE
    assert clear.min() >= 0.09 - 1e-9  # half the car's width


def test_the_waypoint_is_the_path_a_lookahead_ahead_in_the_base_frame(env):
    obs, _ = env.reset(seed=0, options={"world": 0})
    u = env.unwrapped
    path = u.global_path
    arc = np.concatenate([[0], np.cumsum(np.linalg.norm(np.diff(path, axis=0), axis=1))])
    expected = [np.interp(0.5, arc, path[:, 0]), np.interp(0.5, arc, path[:, 1])]
    assert np.allclose(obs[-2:], expected, atol=1e-5)  # odometry at the origin, facing +x


def test_reset_draws_training_worlds_unless_one_is_given(env):
    drawn = {env.reset(seed=s)[1]["world"] for s in range(8)}
    assert drawn <= set(TRAIN_WORLDS) and len(drawn) > 1
    assert env.reset(seed=3)[1]["world"] == env.reset(seed=3)[1]["world"]


@pytest.mark.parametrize(("options", "message"), [
    ({"world": 300}, r"^BARN world 300 is out of range: the worlds are 0 to 299 \("),
    ({"world": -1}, r"^BARN world -1 is out of range"),
    ({"goal": (1, 0)}, r"^unknown reset option\(s\) \['goal'\]; SmartCarBARN-v0 takes 'world'"),
])
def test_bad_reset_options_are_one_line(env, options, message):
    with pytest.raises(ValueError, match=message):
        env.reset(options=options)


def test_what_the_protocol_sets_is_refused_as_a_kwarg():
    with pytest.raises(TypeError, match="SmartCarBARN-v0 takes no goal_range, obstacles: the "
                                        "BARN protocol sets"):
        gym.make("SmartCarBARN-v0", goal_range=(1, 2), obstacles=3)


def test_a_missing_world_file_is_one_line(tmp_path):
    with pytest.raises(ValueError, match=f"^BARN world file {tmp_path / 'x.npz'}: no such file$"):
        gym.make("SmartCarBARN-v0", world_file=tmp_path / "x.npz")


def test_driving_straight_ends_in_a_collision_that_scores_nothing(env):
    env.reset(seed=0, options={"world": 0})
    for _ in range(200):
        _, _, terminated, truncated, info = env.step(np.array([1.0, 0.0]))
        if terminated or truncated:
            break
    assert terminated and not truncated and info["collision"]
    assert info["outcome"] == "collision" and info["score"] == 0.0 == info["score_025"]
    assert info["run_time_s"] > 0


def test_standing_still_times_out(env):
    env.reset(seed=0, options={"world": 0})
    task = env.unwrapped.task
    limit, task.timeout_steps = task.timeout_steps, 5
    try:
        ends = [env.step(np.zeros(2))[2:] for _ in range(5)]
    finally:
        task.timeout_steps = limit
    assert [t for _, t, _ in ends] == [False] * 4 + [True]
    assert [i["outcome"] for _, _, i in ends] == [None] * 4 + ["timeout"]
    assert ends[-1][2]["run_time_s"] == 0.0  # it never moved


def test_a_success_scores_as_the_challenge(env):
    driver = DWADriver()
    env.reset(seed=0, options={"world": 0})
    cars = CarView([env])
    driver.reset(cars)
    for _ in range(1000):
        _, _, terminated, truncated, info = env.step(driver.act(cars)[0])
        if terminated or truncated:
            break
    assert info["outcome"] == "success" and info["is_success"]
    at, ot = info["run_time_s"], info["optimal_time_s"]
    assert 10 * SCALE / 0.5 < at < 4 * ot  # at most the car's top speed; DWA at a quarter
    assert info["score"] == pytest.approx(barn_score(True, at, ot)) and info["score"] > 0.25
    assert info["score_025"] == pytest.approx(ot / max(at, 4 * ot))


@pytest.mark.parametrize("engine", ["pybullet", "planar"])
def test_every_engine_builds_the_world_and_its_laser_sees_the_cylinders(engine):
    env = gym.make("SmartCarBARN-v0", engine=engine)
    try:
        env.reset(seed=0, options={"world": 0})
        ranges = env.unwrapped.laser.latest.ranges
        # the corridor's walls of touching cylinders, 1.0 m to the left and 0.8 m to the right:
        # the nearest returns within 15 degrees of either side
        beams = env.unwrapped.laser_config.angles
        left = ranges[np.abs(beams - np.pi / 2) < np.radians(15)].min()
        right = ranges[np.abs(beams + np.pi / 2) < np.radians(15)].min()
        walls = to_car_frame(load_worlds().world(0).centres, SCALE)[:, 1]
        assert left == pytest.approx(walls.max() - 0.075 * SCALE, abs=0.01)
        assert right == pytest.approx(-walls.min() - 0.075 * SCALE, abs=0.01)
        _, _, terminated, _, info = env.step(np.array([0.5, 0.0]))
        assert not terminated and not info["collision"] and info["clearance"] > 0.1
    finally:
        env.close()


def test_pybullets_pillars_scan_as_its_cylinders(monkeypatch):
    """On pybullet BARN's cylinders collide as capsules (pillars: rays 2.6x faster); the laser
    sees their sides as it sees pybullet's cylinders (within Bullet's convex-cast tolerance,
    < 2 mm) and, as those, within 2 mm of the planar engine's exact cast on 9 beams in 10."""

    def scan(engine: str) -> np.ndarray:
        env = gym.make("SmartCarBARN-v0", engine=engine)
        try:
            env.reset(seed=0, options={"world": 12})
            return env.unwrapped.laser.latest.ranges.copy()
        finally:
            env.close()

    pillars, exact = scan("pybullet"), scan("planar")
    monkeypatch.setattr(BarnTask, "pillars", False)
    cylinders = scan("pybullet")
    both = np.isfinite(pillars) & np.isfinite(cylinders)
    assert both.sum() > 300 and np.array_equal(both, np.isfinite(pillars))
    assert np.abs(pillars[both] - cylinders[both]).max() < 0.002
    assert not np.array_equal(pillars, cylinders)  # another shape
    hit = both & np.isfinite(exact)
    assert np.percentile(np.abs(pillars[hit] - exact[hit]), 90) < 0.002


def test_pybullets_pillars_are_static_rigid_bodies_and_run_as_fixed_multibodies(monkeypatch):
    """pybullet makes BARN's pillars static rigid bodies (maximal coordinates), which its
    multibody solver leaves out of each step, instead of fixed-base multibodies. Upright
    capsules, they stand where they stood to the bit, so a run into a pillar (scans,
    clearances, the collision) is the same bit for bit either way (a pillar 1 nm off fails)."""
    import pybullet
    create = pybullet.createMultiBody

    def run(maximal: bool | None) -> tuple[list, list[bool]]:
        made: list[bool] = []

        def recorded(*args, **kwargs):
            if kwargs.get("baseMass") == 0.0 and "useMaximalCoordinates" in kwargs:
                if maximal is not None:
                    kwargs["useMaximalCoordinates"] = maximal
                made.append(kwargs["useMaximalCoordinates"])
            return create(*args, **kwargs)

        monkeypatch.setattr(pybullet, "createMultiBody", recorded)
        return _drive_into_a_pillar(), made

    rigid, made = run(None)
    multibodies, forced = run(False)
    assert len(made) > 200 and all(made) and not any(forced)
    _assert_the_same_collision(rigid, multibodies)


def _drive_into_a_pillar(after_each_step=None) -> list:
    """pybullet BARN world 12, noisy laser, seed 3: the reset and the steps of a drive
    into a pillar (``after_each_step()`` called after each)."""
    env = gym.make("SmartCarBARN-v0", laser={"noise_std_m": 0.01})
    try:
        steps = [env.reset(seed=3, options={"world": 12})]
        for _ in range(40):
            steps.append(env.step(np.array([1.0, 0.1], dtype=np.float32)))
            if after_each_step is not None:
                after_each_step()
            if steps[-1][2]:
                break
    finally:
        env.close()
    return steps


def _assert_the_same_collision(first: list, second: list) -> None:
    """Two ``_drive_into_a_pillar`` runs ending in the collision, the same bit for bit."""
    assert first[-1][4]["outcome"] == "collision" and first[-1][4]["clearance"] < 0
    assert len(first) == len(second)
    for a, b in zip(first, second, strict=True):
        assert np.array_equal(a[0], b[0])
        if len(a) == 5:
            assert a[1:4] == b[1:4]
            assert a[4]["clearance"] == b[4]["clearance"]
            assert a[4]["outcome"] == b[4]["outcome"]


def test_the_path_progress_reward_is_the_distance_gone_along_the_path():
    rewards, poses = {}, {}
    for progress in ("goal", "path"):
        env = gym.make("SmartCarBARN-v0", engine="planar", progress=progress)
        try:
            env.reset(seed=0, options={"world": 6})
            total = 0.0
            for _ in range(12):
                _, reward, _, _, info = env.step(np.array([0.6, 0.3]))
                total += reward
            rewards[progress], poses[progress] = total, info["pose"][:2]
            path = env.unwrapped.global_path
        finally:
            env.close()
    assert np.array_equal(poses["goal"], poses["path"])  # the same drive
    arc = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(path, axis=0).T))])
    nearest = np.argmin(np.hypot(*(path - poses["path"]).T))
    to_go = arc[-1] - arc[nearest] + np.hypot(*(path[nearest] - poses["path"]))
    gone = arc[-1] + np.hypot(*path[0]) - to_go  # the path starts in the start's grid cell
    costs = 12 * 0.01 + 12 * 0.01 * (0.6 ** 2 + 0.3 ** 2)  # time and action, 12 steps
    assert rewards["path"] == pytest.approx(10.0 * gone - costs, abs=0.02)
    goal = to_car_frame(np.array([[-2.0, 13.0]]), SCALE)[0]  # GOAL_XY in the car's frame
    closer = np.hypot(*goal) - np.hypot(*(goal - poses["goal"]))
    assert rewards["goal"] == pytest.approx(10.0 * closer - costs, abs=0.02)
    with pytest.raises(ValueError, match="progress must be one of goal, path"):
        gym.make("SmartCarBARN-v0", engine="planar", progress="straight")


@pytest.mark.parametrize("compiled", [False, pytest.param(True, marks=pytest.mark.skipif(
    not PATHS_COMPILED, reason="numba (the fast extra) is off or not installed"))])
def test_the_batched_path_trackers_are_path_trackers_bit_for_bit(compiled):
    """Robots on paths of different lengths (one of a single point, one with a repeated
    point), driven along noisy ways: waypoints (odom and base frame), distances to go and
    path windows are each robot's ``PathTracker``'s, step by step."""
    rng = np.random.default_rng(4)
    paths = [np.cumsum(rng.uniform(0.0, 0.05, (m, 2)), axis=0) for m in (40, 7, 120)]
    paths.append(np.array([[0.3, 0.2]]))
    paths.append(np.array([[0.0, 0.0], [0.1, 0.0], [0.1, 0.0], [0.2, 0.1]]))
    n = len(paths)
    trackers = PathTrackers(n, 0.12, 0.5, compiled=compiled)
    alone = [PathTracker(p, 0.12, 0.5) for p in paths]
    to_go_alone = [PathTracker(p, 0.0, 0.5) for p in paths]
    to_go_trackers = PathTrackers(n, 0.0, 0.5, compiled=compiled)
    for i, path in enumerate(paths):
        trackers.start(i, path)
        to_go_trackers.start(i, path)
    for step in range(30):
        slots = [0, 2, 3, 4] if step % 2 else list(range(n))
        xy = np.array([paths[i][min(step, len(paths[i]) - 1)] for i in slots])
        xy += rng.normal(0, 0.01, xy.shape)
        poses = np.column_stack([xy, rng.uniform(-3, 3, len(slots))])
        got = trackers.waypoints_in_base(slots, poses)
        for k, i in enumerate(slots):
            x, y, theta = poses[k]
            assert tuple(got[k]) == to_base_frame(alone[i].waypoint(xy[k]), x, y, theta)
            assert trackers.index(i) == alone[i].index
        assert np.array_equal(to_go_trackers.to_go(slots, xy),
                              [to_go_alone[i].to_go(p)
                               for i, p in zip(slots, xy, strict=True)])
        cos, sin = np.cos(poses[:, 2]), np.sin(poses[:, 2])
        windows = trackers.windows(slots, poses, cos, sin, 0.05, 0.2, 1e3)
        for k, i in enumerate(slots):
            t = alone[i]
            lo = int(np.searchsorted(t.arc, t.arc[t.index] - 0.05))
            hi = max(int(np.searchsorted(t.arc, t.arc[t.index] + 0.2, side="right")), lo + 1)
            d = t.path[lo:hi] - poses[k, :2]
            expected = np.stack([cos[k] * d[:, 0] + sin[k] * d[:, 1],
                                 -sin[k] * d[:, 0] + cos[k] * d[:, 1]], -1)
            assert np.array_equal(windows[k, :hi - lo], expected)
            assert (windows[k, hi - lo:] == 1e3).all()
    assert trackers.index(2) > 20  # it followed the long path
    with pytest.raises(ValueError, match="robot 1 has no path"):
        PathTrackers(2, 0.1, compiled=compiled).waypoints([1], np.zeros((1, 2)))


def test_a_pybullet_world_nothing_draws_has_no_visual_shapes_and_the_same_rollout():
    """render_mode None: the pillars are collision shapes only (a reset 300 visual shapes
    cheaper: pybullet reports the collision capsule as the visual), with a render mode they
    are drawn as cylinders. The runs are the same bit for bit."""
    import pybullet
    ways = {}
    for mode in (None, "rgb_array"):
        env = gym.make("SmartCarBARN-v0", render_mode=mode)
        try:
            obs, _ = env.reset(seed=3, options={"world": 6})
            u = env.unwrapped
            pillar = u.obstacle_bodies[0].uid
            drawn_as = u.sim.client.getVisualShapeData(pillar)[0][2]
            assert drawn_as == (pybullet.GEOM_CAPSULE if mode is None else pybullet.GEOM_CYLINDER)
            assert u.sim.draws == (mode is not None)
            steps = [obs]
            for _ in range(15):
                steps.append(env.step(np.array([1.0, 0.3], dtype=np.float32))[0])
            ways[mode] = np.array(steps)
        finally:
            env.close()
    assert np.array_equal(ways[None], ways["rgb_array"])


def test_pybullets_pillars_sleep_after_their_first_step_and_run_as_awake(monkeypatch):
    """pybullet puts BARN's pillars to sleep, every one by the end of the first step (Bullet
    then stops computing their boxes at every step): a run into a pillar (scans, clearances,
    the collision) is the same bit for bit as with the pillars awake. Why after a step and not
    at their creation: ``test_laser_rays.py``."""
    import pybullet

    from smartcar_gym.sim.pybullet.simulator import Simulator

    change = pybullet.changeDynamics
    asleep: list[int] = []

    def recorded(*args, **kwargs):
        if kwargs.get("activationState") == pybullet.ACTIVATION_STATE_SLEEP:
            asleep.append(args[0])
        return change(*args, **kwargs)

    monkeypatch.setattr(pybullet, "changeDynamics", recorded)
    after_first: list[int] = []
    sleeping = _drive_into_a_pillar(lambda: after_first.append(len(asleep)))
    pillars = after_first[0]
    monkeypatch.setattr(Simulator, "_sleep_pillars", lambda self: None)
    awake = _drive_into_a_pillar()
    assert pillars > 200 and len(asleep) == pillars and len(set(asleep)) == pillars
    _assert_the_same_collision(sleeping, awake)
