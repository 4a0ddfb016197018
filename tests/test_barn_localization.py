"""Localization on the known map (``SmartCarBARN-v0(localize=True)``): the scan matcher puts a
drifted odometry pose back where the scan says it is, the env's waypoint follows the pose on
the map, and its batch is its single env bit for bit (DWA from that pose, batched as single:
``tests/test_bench_barn_batched.py``)."""

from __future__ import annotations

import contextlib
import math

import gymnasium as gym
import numpy as np
import pytest

import smartcar_gym  # noqa: F401
from smartcar_gym.envs.vector import SmartCarBatchVectorEnv
from smartcar_gym.navigation import localization
from smartcar_gym.navigation.localization import COMPILED, IDENTITY, ScanMatcher, compose
from tests.test_vector_batched import rollout
from tests.test_vector_randomize import assert_same

RADIUS = 0.03
ORIGIN = np.array([0.05, 0.0])  # the laser, in base_link


def scan_of(centres: np.ndarray, pose: tuple[float, float, float],
            angles: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Exact ranges (inf: no hit) from a laser at ``ORIGIN`` on a car at ``pose``, and the
    beams' directions in base_link."""
    directions = np.stack([np.cos(angles), np.sin(angles)], axis=1)
    c, s = math.cos(pose[2]), math.sin(pose[2])
    o = np.array([pose[0] + c * ORIGIN[0] - s * ORIGIN[1], pose[1] + s * ORIGIN[0] + c * ORIGIN[1]])
    world = directions @ np.array([[c, s], [-s, c]])
    ranges = np.full(len(angles), np.inf)
    for centre in centres:  # the nearer root of |o + t u - centre| = r
        f = o - centre
        b = world @ f
        disc = b * b - (f @ f - RADIUS * RADIUS)
        t = -b - np.sqrt(np.maximum(disc, 0.0))
        ranges = np.where((disc > 0) & (t > 0), np.minimum(ranges, t), ranges)
    return ranges, directions


@pytest.fixture
def field() -> np.ndarray:
    rng = np.random.default_rng(7)
    return rng.uniform([0.3, -1.2], [2.5, 1.2], (40, 2))


def test_the_matcher_brings_a_drifted_odometry_onto_the_map(field):
    """The car truly at (0, 0.02, 0.03 rad); its odometry 2 cm and 2 degrees off. From the
    identity, one scan matched in 8 steps puts the odometry pose on the truth within 1e-9 m
    and rad (the hits lie exactly on the outlines); half a degree off, 4 steps do."""
    angles = np.linspace(-math.pi, math.pi, 360, endpoint=False)
    truth = (0.0, 0.02, 0.03)
    odom = compose(truth, (0.015, -0.013, math.radians(2.0)))  # drifted
    ranges, directions = scan_of(field, truth, angles)
    assert math.hypot(odom[0] - truth[0], odom[1] - truth[1]) > 0.015  # it is off
    for off, steps in (((0.015, -0.013, math.radians(2.0)), 8), ((0.005, 0.0, 0.009), 4)):
        odom = compose(truth, off)
        correction = ScanMatcher(field, RADIUS, steps=steps).correct(IDENTITY, odom, ranges,
                                                                     ORIGIN, directions)
        on_map = compose(correction, odom)
        assert math.hypot(on_map[0] - truth[0], on_map[1] - truth[1]) < 1e-9
        assert abs(on_map[2] - truth[2]) < 1e-9
    # two steps (a scan's default) leave part of a 2-degree error
    odom = compose(truth, (0.015, -0.013, math.radians(2.0)))
    on_map = compose(ScanMatcher(field, RADIUS).correct(IDENTITY, odom, ranges, ORIGIN,
                                                        directions), odom)
    assert 1e-4 < math.hypot(on_map[0] - truth[0], on_map[1] - truth[1]) < 0.005


def test_too_few_hits_or_hits_off_the_map_keep_the_correction(field):
    angles = np.linspace(-0.1, 0.1, 5)
    matcher = ScanMatcher(field, RADIUS)
    start = (0.001, 0.0, 0.0)
    ranges, directions = scan_of(field, IDENTITY, angles)
    assert matcher.correct(start, IDENTITY, ranges, ORIGIN, directions) == start
    far = np.full(360, 1.0)  # a wall where the map has nothing
    _, directions = scan_of(field, IDENTITY, np.linspace(-math.pi, math.pi, 360))
    assert matcher.correct(start, IDENTITY, far, ORIGIN, directions) == start
    with pytest.raises(ValueError, match="no cylinders"):
        ScanMatcher(np.zeros((0, 2)), RADIUS)


def drifted_scans(rng: np.random.Generator, centres: np.ndarray, count: int):
    """``count`` (correction, odometry pose, ranges, directions): scans of random true poses
    amid ``centres``, with a random correction a few cm and degrees off, some beams lost."""
    angles = np.linspace(-math.pi, math.pi, 360, endpoint=False)
    for _ in range(count):
        truth = (rng.uniform(0.8, 2.0), rng.uniform(-0.6, 0.6), rng.uniform(-math.pi, math.pi))
        ranges, directions = scan_of(centres, truth, angles)
        ranges[rng.random(360) < 0.1] = np.inf
        correction = (rng.normal(0, 0.02), rng.normal(0, 0.02), rng.normal(0, 0.03))
        odom = compose((-correction[0], -correction[1], 0.0), truth)  # roughly un-corrected
        yield correction, odom, ranges, directions


@pytest.mark.skipif(not COMPILED, reason="numba (the fast extra) is off or not installed")
def test_the_compiled_matcher_is_numpys_bit_for_bit(field):
    """Cylinders of two radii, some overlapping; 60 drifted scans, all beams and every third
    (``max_beams=120``), 1 to 3 Gauss-Newton steps: the same correction to the last bit, and
    scans with too few hits keep the correction on both."""
    rng = np.random.default_rng(11)
    centres = np.vstack([field, field[:8] + 0.02])  # overlapping pairs
    radii = np.where(np.arange(len(centres)) % 3 == 0, 0.05, RADIUS)
    moved = 0
    for max_beams, steps in ((360, 2), (120, 1), (360, 3)):
        numpy_way = ScanMatcher(centres, radii, steps=steps, max_beams=max_beams,
                                compiled=False)
        compiled = ScanMatcher(centres, radii, steps=steps, max_beams=max_beams, compiled=True)
        for correction, odom, ranges, directions in drifted_scans(rng, centres, 20):
            want = numpy_way.correct(correction, odom, ranges, ORIGIN, directions)
            assert compiled.correct(correction, odom, ranges, ORIGIN, directions) == want
            moved += want != correction
        few = np.full(360, np.inf)
        few[:30:2] = 0.5  # 15 hits: fewer than MIN_HITS
        assert compiled.correct((0.01, 0.0, 0.0), IDENTITY, few, ORIGIN, directions) == (
            numpy_way.correct((0.01, 0.0, 0.0), IDENTITY, few, ORIGIN, directions))
    assert moved >= 50


def test_every_outline_near_a_hit_is_among_its_cells_candidates(field):
    """The grid that finds a hit's nearest outline: for 20,000 points about the map, every
    cylinder whose outline is within the gate (inside or out) is listed in the point's cell,
    so the nearest outline found is the nearest of all."""
    rng = np.random.default_rng(5)
    centres = np.vstack([field, field[:8] + 0.02])
    radii = np.where(np.arange(len(centres)) % 3 == 0, 0.05, RADIUS)
    matcher = ScanMatcher(centres, radii, compiled=False)
    points = centres[rng.integers(len(centres), size=20000)] + rng.normal(0, 0.05, (20000, 2))
    cell = np.floor((points - matcher._low) / localization.CELL_M).astype(int)
    rows = cell[:, 0] * matcher._shape[1] + cell[:, 1]
    gap = np.hypot(points[:, None, 0] - centres[:, 0], points[:, None, 1] - centres[:, 1]) - radii
    near = gap < matcher.gate_m
    assert near.any(axis=1).mean() > 0.3  # plenty of points near an outline
    for k in np.flatnonzero(near.any(axis=1)):
        listed = set(matcher._table[rows[k]].tolist())
        assert set(np.flatnonzero(near[k]).tolist()) <= listed
    assert (matcher._table[-1] == -1).all()  # the row of points off the map lists none


def test_max_beams_takes_evenly_spaced_beams(field):
    """``max_beams`` as amcl's laser_max_beams: 120 of 360 beams is every third, from the
    first; the correction is the full matcher's on those beams."""
    rng = np.random.default_rng(2)
    (correction, odom, ranges, directions), = drifted_scans(rng, field, 1)
    third = ScanMatcher(field, RADIUS, max_beams=120).correct(correction, odom, ranges, ORIGIN,
                                                              directions)
    assert third == ScanMatcher(field, RADIUS).correct(correction, odom, ranges[::3], ORIGIN,
                                                       directions[::3])
    assert third != ScanMatcher(field, RADIUS).correct(correction, odom, ranges, ORIGIN,
                                                       directions)


def test_bad_matcher_arguments_are_refused(field, monkeypatch):
    with pytest.raises(ValueError, match="max_beams must be at least 1, got 0"):
        ScanMatcher(field, RADIUS, max_beams=0)
    with pytest.raises(ValueError, match="radii positive"):
        ScanMatcher(field, 0.0)
    with pytest.raises(ValueError, match="centres must be finite"):
        ScanMatcher(np.array([[np.nan, 0.0]]), RADIUS)
    monkeypatch.setattr(localization, "COMPILED", False)
    with pytest.raises(RuntimeError, match=r"needs numba: pip install \"smartcar-gym\[fast\]\""):
        ScanMatcher(field, RADIUS, compiled=True)


def test_the_env_waypoint_follows_the_pose_on_the_map():
    """A car whose odometry drifts (track 1.1, encoders off scale): with localize its pose on
    the map stays within a millimetre of the truth, odometry's goes centimetres off; without,
    the pose on the map is the odometry's."""
    drift = {"track": 1.1, "left_encoder_scale": 0.97}
    errors = {}
    for localize in (False, True):
        env = gym.make("SmartCarBARN-v0", engine="planar", randomize=drift, localize=localize)
        u = env.unwrapped
        env.reset(seed=0, options={"world": 0})
        for _ in range(40):
            _, _, _, _, info = env.step(np.array([0.6, 0.4]))
        pose, odom = info["pose"], u.robot.odometry
        errors[localize] = math.hypot(u.map_pose[0] - pose[0], u.map_pose[1] - pose[1])
        if not localize:
            assert u.map_pose == (odom.x, odom.y, odom.theta) and u.correction == IDENTITY
        env.close()
    assert errors[False] > 0.03 and errors[True] < 1e-3


def test_bad_localize_arguments_are_refused():
    with pytest.raises(ValueError, match="localize must be True or False, got 'yes'"):
        gym.make("SmartCarBARN-v0", engine="planar", localize="yes")
    with pytest.raises(ValueError, match=r"laser's rate_hz \(5\) must be the controller's \(10\)"):
        gym.make("SmartCarBARN-v0", engine="planar", localize=True, laser={"rate_hz": 5.0})


@contextlib.contextmanager
def batch_beside_single(steps: int, **kwargs):
    """8 cars of SmartCarBARN-v0 with ``kwargs``, their scans matched on two threads (4 cars
    each), and 8 single envs, rolled out alike for ``steps`` steps, each step the same
    (``assert_same``); yields both (closed after) for the caller's checks."""
    batched = gym.make_vec("SmartCarBARN-v0", num_envs=8, num_threads=2,
                           vectorization_mode="vector_entry_point", autoreset_mode="SameStep",
                           **kwargs)
    single = gym.make_vec("SmartCarBARN-v0", num_envs=8, vectorization_mode="sync",
                          vector_kwargs={"autoreset_mode": gym.vector.AutoresetMode.SAME_STEP},
                          **kwargs)
    assert isinstance(batched, SmartCarBatchVectorEnv)
    try:
        got, want = rollout(batched, steps, 5), rollout(single, steps, 5)
        for k, (g, w) in enumerate(zip(got, want, strict=True)):
            assert_same(g, w, f"step {k}")
        yield batched.unwrapped, single.envs
    finally:
        batched.close()
        single.close()


def test_the_localized_batch_equals_n_single_envs_bit_for_bit():
    """8 cars, their scans matched on two threads (4 cars each), as 8 single envs."""
    with batch_beside_single(50, engine="planar", localize=True, randomize="odometry",
                             max_episode_steps=24) as (u, envs):
        for i, env in enumerate(envs):
            assert u.corrections[i] == env.unwrapped.correction != IDENTITY
            assert tuple(u.map_poses[i]) == env.unwrapped.map_pose
