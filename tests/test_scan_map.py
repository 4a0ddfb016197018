"""Localization without a map (``navigation.scan_map.ScanMaps``, ``SmartCarBARN-v0(map_mode=
"laser", localize=True)``): each scan matched to the map the car's earlier scans made puts a
drifted odometry back, numpy and numba give the same numbers, the env's observation and
costmap follow the pose on that map, and its batch is its single envs bit for bit."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest

import smartcar_gym  # noqa: F401
from smartcar_gym.navigation import localization
from smartcar_gym.navigation.costmap import CostmapConfig
from smartcar_gym.navigation.localization import COMPILED, compose
from smartcar_gym.navigation.scan_map import LEVELS, ScanMaps
from tests.test_barn_localization import batch_beside_single, scan_of

GRID = CostmapConfig.challenge(0.18 / 0.43)  # the shipped car's laser costmap: 2.09 cm cells
ANGLES = np.linspace(-math.pi, math.pi, 360, endpoint=False)
ZERO = np.zeros((1, 3))


@pytest.fixture
def field() -> np.ndarray:
    rng = np.random.default_rng(7)
    return rng.uniform([0.3, -1.2], [2.5, 1.2], (40, 2))


def first_map(field: np.ndarray, compiled: bool = False, **kwargs) -> tuple[ScanMaps, tuple]:
    """One car's map made from its first scan at the origin, and the beams' geometry."""
    maps = ScanMaps(GRID, 1, compiled=compiled, **kwargs)
    ranges, directions = scan_of(field, (0.0, 0.0, 0.0), ANGLES)
    beams = (localization.beam_geometry(ANGLES, np.eye(4))[0] + [0.05, 0.0], directions)
    maps.correct([0], ZERO, ZERO, ranges[None], *beams)
    return maps, beams


def test_the_first_scan_is_kept_where_the_odometry_puts_it(field):
    """An empty map: no correction, and each return kept in its cell (the first one there)
    within 1/255 of a cell of where it is."""
    maps, (origin, directions) = first_map(field)
    ranges, _ = scan_of(field, (0.0, 0.0, 0.0), ANGLES)
    hits = origin + ranges[np.isfinite(ranges), None] * directions[np.isfinite(ranges)]
    kept = maps.points(0)
    assert 50 < len(kept) < len(hits)  # several returns share a cell: the first is kept
    gap = np.hypot(*(kept[:, None, :] - hits[None, :, :]).transpose(2, 0, 1)).min(axis=1)
    assert gap.max() <= GRID.resolution / LEVELS  # each kept point is a return, quantized


@pytest.mark.parametrize("compiled", [False, pytest.param(True, marks=pytest.mark.skipif(
    not COMPILED, reason="needs the fast extra (numba)"))])
def test_a_drifted_odometry_is_put_back_onto_the_map(field, compiled):
    """The car drives 10 cm on and turns 2 degrees; its odometry says 2 cm, 1.5 cm and 3
    degrees otherwise. Matched to the first scan's map, the pose is the truth within 2 mm and
    0.4 degrees (measured: 1.2 mm, 0.31 degrees, the same after 3 steps or 12: the map is
    one return per 2.09 cm cell on 3 cm cylinders, and a line through two of them is a chord
    of the arc the new scan sees), where the odometry is 2.5 cm and 3 degrees off."""
    maps, beams = first_map(field, compiled)
    truth = (0.10, 0.01, math.radians(2.0))
    odom = compose(truth, (0.02, -0.015, math.radians(3.0)))
    ranges, _ = scan_of(field, truth, ANGLES)
    correction = maps.correct([0], ZERO, np.array([odom]), ranges[None], *beams)[0]
    pose = compose(tuple(correction), odom)
    assert math.hypot(odom[0] - truth[0], odom[1] - truth[1]) > 0.0249
    assert math.hypot(pose[0] - truth[0], pose[1] - truth[1]) < 2e-3
    assert abs(pose[2] - truth[2]) < math.radians(0.4)


def test_too_few_pairs_or_too_far_keep_the_correction(field):
    """Fewer pairs than ``min_pairs`` (a map of one scan, a scan of its few nearest returns),
    or every return further than the gate from the map (the odometry 20 cm off): the
    correction stays as it was."""
    maps, beams = first_map(field)
    start = np.array([[0.01, -0.02, 0.03]])
    ranges, _ = scan_of(field, (0.0, 0.0, 0.0), ANGLES)
    few = np.where(ranges < np.sort(ranges)[10], ranges, np.inf)
    assert np.array_equal(maps.correct([0], start, ZERO, few[None], *beams), start)
    far, _ = scan_of(field, (0.0, 0.0, 0.0), ANGLES)
    out = maps.correct([0], ZERO, np.array([[0.2, 0.2, 0.0]]), far[None], *beams)
    assert np.array_equal(out, ZERO)


@pytest.mark.skipif(not COMPILED, reason="needs the fast extra (numba)")
def test_the_compiled_maps_are_numpys_bit_for_bit(field):
    """Eight cars, 12 noisy scans each along drives with drifting odometry: numba's loops
    (on one thread, and on two: four cars each) give numpy's corrections and maps to the
    bit."""
    rng = np.random.default_rng(3)
    beams = (np.array([0.05, 0.0]), scan_of(field, (0.0, 0.0, 0.0), ANGLES)[1])
    runs = {}
    for name, compiled, threads in (("numpy", False, 1), ("numba", True, 1),
                                    ("numba x2", True, 2)):
        maps = ScanMaps(GRID, 10, compiled=compiled)
        cars = np.array([4, 0, 2, 9, 7, 1, 5, 3])
        corrections = np.zeros((8, 3))
        out = []
        rng = np.random.default_rng(3)
        for step in range(12):
            truth = [(0.03 * step, 0.01 * k, 0.01 * step * (k - 3)) for k in range(8)]
            odoms = np.array([compose(t, (0.002 * step, -0.001 * step, 0.003 * step))
                              for t in truth])
            ranges = np.stack([scan_of(field, t, ANGLES)[0] for t in truth])
            ranges = ranges + rng.normal(0.0, 0.01, ranges.shape)
            corrections = maps.correct(cars, corrections, odoms, ranges, *beams,
                                       threads=threads)
            out.append(corrections.copy())
        runs[name] = (np.array(out), maps._offsets.copy())
    for name in ("numba", "numba x2"):
        assert np.array_equal(runs[name][0], runs["numpy"][0]), name
        assert np.array_equal(runs[name][1], runs["numpy"][1]), name
    assert np.abs(runs["numpy"][0][-1]).max() > 0.005  # the corrections did move


def test_bad_scan_map_arguments_are_refused(field, monkeypatch):
    with pytest.raises(ValueError, match="scan map cars: 1000 maps of 800 x 800 cells are more"):
        ScanMaps(GRID, 1000)
    with pytest.raises(ValueError, match="scan map gate_m must be a positive number, got 0.0"):
        ScanMaps(GRID, 1, gate_m=0.0)
    maps = ScanMaps(GRID, 2, compiled=False)
    with pytest.raises(IndexError, match=r"scan map cars must be in \[0, 2\), got \[2\]"):
        maps.reset([2])
    with pytest.raises(ValueError, match=r"scan map cars must be distinct, got \[1, 1\]"):
        maps.correct([1, 1], np.zeros((2, 3)), np.zeros((2, 3)), np.ones((2, 4)),
                     np.zeros(2), np.ones((4, 2)))
    monkeypatch.setattr("smartcar_gym.navigation.scan_map.COMPILED", False)
    with pytest.raises(RuntimeError, match=r"needs numba: pip install \"smartcar-gym\[fast\]\""):
        ScanMaps(GRID, 1, compiled=True)


def drive(localize: bool, steps: int = 40):
    """A mapless car whose odometry drifts (track 1.1, encoders off scale) driven in world 0;
    the env after ``steps``, its last observation and info."""
    env = gym.make("SmartCarBARN-v0", engine="planar", map_mode="laser", localize=localize,
                   randomize={"track": 1.1, "left_encoder_scale": 0.97})
    env.reset(seed=0, options={"world": 0})
    for _ in range(steps):
        obs, _, terminated, truncated, info = env.step(np.array([0.6, 0.4]))
        assert not (terminated or truncated)
    return env, obs, info


def test_the_mapless_env_follows_the_pose_on_its_own_map():
    """With ``localize`` the pose on the map stays within 5 mm of the truth where the
    odometry's goes 8 cm off; the observation's pose and goal entries are that pose's, the
    costmap is marked there; without it all of them are the odometry's."""
    errors = {}
    for localize in (False, True):
        env, obs, info = drive(localize)
        u = env.unwrapped
        pose, odom = info["pose"], info["odom_pose"]
        errors[localize] = math.hypot(u.map_pose[0] - pose[0], u.map_pose[1] - pose[1])
        seen = odom if not localize else np.array(u.map_pose)
        goal = u.goal - seen[:2]
        c, s = math.cos(seen[2]), math.sin(seen[2])
        names = u.task.observation().names
        values = dict(zip(names, obs, strict=True))
        assert values["odom_x"] == np.float32(seen[0]) and values["odom_y"] == np.float32(seen[1])
        assert values["goal_x_base"] == pytest.approx(c * goal[0] + s * goal[1], abs=1e-6)
        assert values["goal_distance"] == pytest.approx(math.hypot(*goal), abs=1e-6)
        assert (u.correction == (0.0, 0.0, 0.0)) != localize
        env.close()
    assert errors[False] > 0.05 and errors[True] < 0.005


def test_the_mapless_localized_batch_equals_n_single_envs_bit_for_bit():
    """8 cars, their scans matched on two threads, as 8 single envs: observations, rewards,
    infos, corrections, costmaps."""
    with batch_beside_single(40, engine="planar", map_mode="laser", localize=True,
                             randomize="odometry", max_episode_steps=24,
                             laser={"noise_std_m": 0.01}) as (u, envs):
        for i, env in enumerate(envs):
            assert u.corrections[i] == env.unwrapped.correction != (0.0, 0.0, 0.0)
            assert np.array_equal(u.costmaps.costs(i), env.unwrapped.costmaps.costs(0))
