"""The simulated laser: LaserConfig, the scan's sectors, the scanner in a world, the laser link."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest

from smartcar_gym import load_model
from smartcar_gym.envs.robots import SmartCarRobot, drive
from smartcar_gym.envs.sensors.laser import SimulatedLaser, mount_from_model, mount_from_pose
from smartcar_gym.envs.sensors.scan import (
    MAX_BEAMS,
    LaserConfig,
    scan_entry,
    scan_sectors,
    sector_names,
)
from smartcar_gym.envs.state import SCAN, SCAN_TIME, CarState
from smartcar_gym.envs.tasks.base import CarSettings
from smartcar_gym.envs.tasks.nav import NavTask
from smartcar_gym.sim.obstacles import add_obstacle
from smartcar_gym.sim.rays import MAX_RAYS

# -- LaserConfig -------------------------------------------------------------------------------


def test_default_config_is_a_360_beam_one_degree_scan():
    config = LaserConfig()
    assert config.beams == 360
    angles = config.angles
    assert angles[0] == -math.pi
    assert angles[180] == pytest.approx(0.0, abs=1e-12)  # beam 180 looks straight ahead
    assert angles[-1] == pytest.approx(math.pi - math.radians(1))
    assert np.allclose(np.diff(angles), math.radians(1))
    assert (config.range_min, config.range_max, config.rate_hz) == (0.12, 3.5, 10.0)


def test_beam_count_follows_ros_rule():
    # (angle_max - angle_min) / angle_increment + 1, the last beam at or before angle_max
    assert LaserConfig(angle_min=-1.0, angle_max=1.0, angle_increment=0.5).beams == 5
    assert LaserConfig(angle_min=-1.0, angle_max=1.2, angle_increment=0.5).beams == 5
    assert LaserConfig(angle_min=0.0, angle_max=0.0, angle_increment=0.1).beams == 1


@pytest.mark.parametrize("kwargs, match", [
    ({"angle_min": 1.0, "angle_max": 0.0}, "angle_max"),
    ({"angle_min": -4.0, "angle_max": 4.0}, "one turn"),
    ({"angle_min": float("nan")}, "angle_min"),
    ({"angle_increment": 0.0}, "angle_increment"),
    ({"range_min": 3.5}, "range_min"),
    ({"range_min": -0.1}, "range_min"),
    ({"range_max": float("inf")}, "range_max"),
    ({"rate_hz": 0}, "rate_hz"),
    ({"rate_hz": 1e6}, r"laser rate_hz must be at most 100 \(planar lidars scan at 5-40 Hz\)"),
    ({"angle_increment": 1e-9}, r"gives 6.27e\+09 beams over its angles: at most 4096"),
    ({"noise_std_m": -0.01}, "noise_std_m"),
    ({"noise_std_m": float("inf")}, "noise_std_m"),
])
def test_bad_config_is_refused_naming_the_field(kwargs, match):
    with pytest.raises(ValueError, match=match):
        LaserConfig(**kwargs)


# -- sectors (what the observation holds) ------------------------------------------------------


def test_sectors_take_the_nearest_range_with_inf_as_range_max_and_minus_inf_as_zero():
    ranges = np.array([1.0, np.inf, -np.inf, 2.0, 3.0, np.inf], dtype=np.float32)
    assert scan_sectors(ranges, 3.5, 3).tolist() == [1.0, 0.0, 3.0]
    assert scan_sectors(ranges, 3.5, 6).tolist() == [1.0, 3.5, 0.0, 2.0, 3.0, 3.5]
    assert scan_sectors(ranges, 3.5, 1).tolist() == [0.0]


def test_uneven_sectors_differ_by_at_most_one_beam():
    ranges = np.arange(1.0, 6.0)  # 5 beams, 2 sectors: beams 0-1 and 2-4
    assert scan_sectors(ranges, 10.0, 2).tolist() == [1.0, 3.0]
    assert scan_sectors(np.arange(1.0, 8.0), 10.0, 3).tolist() == [1.0, 3.0, 5.0]


def test_sector_count_outside_the_beams_is_refused():
    with pytest.raises(ValueError, match="1 to 5 sectors"):
        scan_sectors(np.ones(5), 3.5, 6)
    with pytest.raises(ValueError, match="scan_sectors"):
        scan_entry(LaserConfig(), 361)
    with pytest.raises(ValueError, match="scan_sectors"):
        scan_entry(LaserConfig(), 0)


def test_scan_entry_names_and_reads_the_sectors(laser_model, shipped_config):
    entry = scan_entry(LaserConfig(), 36)
    assert entry.names == sector_names(36) and entry.names[0] == "scan_00"
    assert (entry.low, entry.high) == (0.0, 3.5)
    # the nav task reads its cars' latest scans into the entry's columns
    task = NavTask()
    task.bind(CarSettings(laser_model, shipped_config, "hardware", 0.5, 2.0, "sphere",
                          "pybullet"))
    task.attach(2)
    cars = SimpleNamespace(state=CarState.zeros(2, 4, {SCAN: ((360,), np.float32),
                                                       SCAN_TIME: ((), np.int64)}),
                           values=lambda array: array)
    ranges = cars.state.readings[SCAN]
    ranges[:] = np.inf
    ranges[0, 185] = 0.5  # 5 degrees left of ahead: sector 18
    ranges[1, 0] = -np.inf  # closer than range_min, behind: sector 0
    obs = task.observe(cars)
    start = task.observation().names.index("scan_00")
    values = obs[:, start:]
    assert values.shape == (2, 36) and obs.shape == (2, start + 36)
    assert values[0, 18] == 0.5 and np.count_nonzero(values[0] == 3.5) == 35
    assert values[1, 0] == 0.0 and np.count_nonzero(values[1] == 3.5) == 35
    # a new scan (a new time) is read again, the same one is not
    ranges[0, 185] = 1.0
    assert task.observe(cars)[0, start + 18] == 0.5
    cars.state.readings[SCAN_TIME][0] = 100
    assert task.observe(cars)[0, start + 18] == 1.0


# -- the scanner in a world --------------------------------------------------------------------


@pytest.fixture(scope="module")
def laser_model():
    return load_model(mappings={"laser": "true"})


@pytest.fixture
def robot(sim, laser_model, shipped_config):
    robot = SmartCarRobot(sim, laser_model, shipped_config, mode="hardware")
    robot.spawn()
    return robot


def test_ranges_to_a_box_and_a_cylinder_match_the_geometry(sim, robot, laser_model):
    add_obstacle(sim, "box", "box", (0.2, 0.6), (1.0, 0.0))  # front face at x = 0.9
    add_obstacle(sim, "cyl", "cylinder", (0.4,), (0.0, -1.5))  # surface at y = -1.3
    laser = SimulatedLaser(LaserConfig(), mount_from_model(laser_model))
    laser.attach(robot.body)
    scan = laser.latest
    pose = robot.pose()
    # the laser is 0.1 m above base_link, which sits (settled) at the origin
    assert scan.ranges[180] == pytest.approx(0.9 - pose.x, abs=2e-3)  # ahead
    assert scan.ranges[90] == pytest.approx(1.3 + pose.y, abs=2e-3)  # -90 deg: right
    assert np.isinf(scan.ranges[0]) and scan.ranges[0] > 0  # behind: nothing within 3.5 m
    # 10 degrees off ahead the beam still meets the box face, 0.9 / cos(10 deg) away
    assert scan.ranges[190] == pytest.approx((0.9 - pose.x) / math.cos(math.radians(10)),
                                             abs=3e-3)
    assert scan.ranges.dtype == np.float32 and scan.ranges.shape == (360,)
    assert (scan.frame_id, scan.time_increment, scan.scan_time) == ("laser", 0.0, 0.1)
    assert scan.angle_max == pytest.approx(math.pi - math.radians(1))
    hits = laser.hit_points
    assert len(hits) == np.isfinite(scan.ranges).sum()
    assert np.allclose(hits[:, 2], 0.1, atol=1e-3)


def test_closer_than_range_min_is_minus_inf(sim, robot, laser_model):
    add_obstacle(sim, "box", "box", (0.2, 0.6), (0.5, 0.0))  # 0.4 m ahead
    laser = SimulatedLaser(LaserConfig(range_min=0.5), mount_from_model(laser_model))
    laser.attach(robot.body)
    assert laser.latest.ranges[180] == -np.inf
    assert np.isposinf(laser.latest.ranges[0])


def test_the_robot_is_invisible_to_its_own_laser(sim, robot):
    # mounted behind the car at the height of its base and head: the beams ahead cross them
    add_obstacle(sim, "box", "box", (0.2, 2.0), (-1.0, 0.0))  # behind the car
    laser = SimulatedLaser(LaserConfig(), mount_from_pose((-0.2, 0.0, 0.07, 0.0)))
    laser.attach(robot.body)
    ranges = laser.latest.ranges
    assert ranges[0] == pytest.approx(0.7 + robot.pose().x, abs=2e-3)  # behind: the obstacle
    assert np.isposinf(ranges[170:191]).all()  # ahead: the base and the head are not seen


def test_mount_yaw_turns_the_beams(sim, robot):
    add_obstacle(sim, "box", "box", (0.2, 0.6), (1.0, 0.0))
    laser = SimulatedLaser(LaserConfig(), mount_from_pose((0.0, 0.0, 0.1, math.pi / 2)))
    laser.attach(robot.body)
    # the laser frame looks left: the box ahead of the car is at -90 degrees (beam 90)
    assert laser.latest.ranges[90] == pytest.approx(0.9 - robot.pose().x, abs=2e-3)
    assert np.isposinf(laser.latest.ranges[180])


def test_one_ray_batch_per_scan_at_the_scan_rate(sim, robot, laser_model):
    calls = []
    original = sim.client.rayTestBatch
    sim.client.rayTestBatch = lambda *a, **k: calls.append(len(a[0])) or original(*a, **k)
    laser = SimulatedLaser(LaserConfig(rate_hz=4.0), mount_from_model(laser_model))
    laser.attach(robot.body)
    stamps = [laser.latest.stamp_s]
    for _ in range(10):  # 1 s of 0.1 s controller periods
        drive(robot, 0.0, 0.0, 1)
        if laser.latest.stamp_s != stamps[-1]:
            stamps.append(laser.latest.stamp_s)
    assert stamps == [0.0, 0.25, 0.5, 0.75, 1.0]
    assert calls == [360] * 5  # one batch of every beam per scan


def test_noise_is_gaussian_seeded_and_only_on_returns(sim, robot, laser_model):
    add_obstacle(sim, "wall", "box", (0.2, 20.0), (1.0, 0.0))
    config = LaserConfig(angle_min=-0.5, angle_max=0.5, angle_increment=0.001,
                         noise_std_m=0.01)
    mount = mount_from_model(laser_model)
    clean = SimulatedLaser(LaserConfig(angle_min=-0.5, angle_max=0.5, angle_increment=0.001),
                           mount)
    clean.attach(robot.body)
    scans = []
    for seed in (7, 7, 8):
        noisy = SimulatedLaser(config, mount)
        noisy.attach(robot.body, np.random.default_rng(seed))
        scans.append(noisy.latest.ranges)
    error = scans[0].astype(float) - clean.latest.ranges
    assert len(error) == 1001 and abs(error.mean()) < 0.002
    assert error.std() == pytest.approx(0.01, rel=0.1)
    assert np.array_equal(scans[0], scans[1]) and not np.array_equal(scans[0], scans[2])
    with pytest.raises(ValueError, match="random generator"):
        SimulatedLaser(config, mount).attach(robot.body)


def test_a_laser_has_at_most_max_beams_so_a_scan_is_one_batch_of_rays():
    assert MAX_BEAMS < MAX_RAYS
    assert LaserConfig(angle_min=0.0, angle_max=1.0, angle_increment=1.0 / 4095).beams == 4096
    with pytest.raises(ValueError, match="gives 4.1e\\+03 beams over its angles: at most 4096"):
        LaserConfig(angle_min=0.0, angle_max=1.0, angle_increment=1.0 / 4096)


# -- mounts and the laser link -----------------------------------------------------------------


def test_shipped_laser_link_is_fixed_0_1_m_above_base_link(laser_model):
    assert "laser" in laser_model.links
    joint = laser_model.joints["laser_joint"]
    assert (joint.type, joint.parent, joint.child) == ("fixed", "base_link", "laser")
    assert np.allclose(mount_from_model(laser_model), mount_from_pose((0, 0, 0.1, 0)))
    assert laser_model.links["laser"].mass == pytest.approx(0.1)
    assert [w.joint for w in laser_model.wheels] == [w.joint for w in load_model().wheels]
    assert laser_model.defects == ()


def test_the_laser_argument_defaults_to_the_unchanged_car(shipped_model):
    assert "laser" not in shipped_model.links
    assert mount_from_model(shipped_model) is None
    assert load_model(mappings={"laser": "false"}).urdf == shipped_model.urdf


def test_a_laser_on_a_moving_joint_is_refused(tmp_path, shipped_model):
    urdf = shipped_model.urdf.replace(
        "</robot>",
        '<link name="laser"/><joint name="spin" type="continuous"><parent link="base_link"/>'
        '<child link="laser"/><axis xyz="0 0 1"/></joint></robot>')
    path = tmp_path / "spinning.urdf"
    path.write_text(urdf)
    with pytest.raises(ValueError, match="continuous joint 'spin'"):
        mount_from_model(load_model(path))


@pytest.mark.parametrize("pose", [(0, 0, 0.1), "abcd", (0, 0, float("nan"), 0)])
def test_bad_mount_pose_is_refused(pose):
    with pytest.raises(ValueError, match="laser_mount"):
        mount_from_pose(pose)
