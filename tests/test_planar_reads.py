"""What the planar batch reads for the envs (poses, joints, encoders): numba's loops give the
bits of the single body's Python floats and of the numpy arrays."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest

from smartcar_gym.envs.robots.smartcar import pose_from
from smartcar_gym.sim.planar import batch as planar_batch
from smartcar_gym.sim.planar import dynamics, layout
from smartcar_gym.sim.planar.batch import PlanarBatch
from smartcar_gym.sim.planar.body import yaw_quaternion

needs_numba = pytest.mark.skipif(not dynamics.COMPILED,
                                 reason="numba (the fast extra) is not installed")


@pytest.fixture(scope="module")
def body():
    env = gym.make("SmartCar-v0", engine="planar")
    env.reset(seed=0)
    yield env.unwrapped.robot.body
    env.close()


def headings(n: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Random unit (cos, sin) pairs, the quaternion's branch points and signed zeros first."""
    th = rng.uniform(-math.pi, math.pi, n)
    c, s = np.cos(th), np.sin(th)
    edges = [(1.0, 0.0), (1.0, -0.0), (-1.0, 0.0), (-1.0, -0.0), (0.0, 1.0), (0.0, -1.0),
             (-0.5, math.sqrt(0.75)), (-0.5, -math.sqrt(0.75)),
             (np.nextafter(-0.5, 0.0), math.sqrt(0.75)),
             (np.nextafter(-0.5, -1.0), -math.sqrt(0.75))]
    for k, (ck, sk) in enumerate(edges):
        c[k], s[k] = ck, sk
    return c, s


@pytest.mark.parametrize("compiled", [True, False])
def test_each_cars_pose_is_the_bodys_link_pose_read_as_the_single_env_reads_it(
        body, monkeypatch, compiled: bool) -> None:
    if compiled and not dynamics.COMPILED:
        pytest.skip("numba (the fast extra) is not installed")
    monkeypatch.setattr(dynamics, "COMPILED", compiled)
    rng = np.random.default_rng(3)
    n = 2000
    batch = PlanarBatch(body, n)
    c, s = headings(n, rng)
    batch.state[layout.X] = rng.normal(0.0, 5.0, n)
    batch.state[layout.Y] = rng.normal(0.0, 5.0, n)
    batch.state[layout.COS], batch.state[layout.SIN] = c, s
    batch.com_x[:] = rng.normal(0.0, 0.05, n)
    batch.com_y[:] = rng.normal(0.0, 0.05, n)
    px, py, yaw = batch.pose()
    for i in range(n):
        ci, si = float(c[i]), float(s[i])
        cx, cy = float(batch.com_x[i]), float(batch.com_y[i])
        x, y = float(batch.state[layout.X, i]), float(batch.state[layout.Y, i])
        # PlanarBody.link_pose, then SmartCarRobot.pose's pose_from
        position = (x - (ci * cx - si * cy), y - (si * cx + ci * cy), 0.0)
        expected = pose_from(position, yaw_quaternion(ci, si))
        assert (px[i], py[i]) == (expected.x, expected.y)
        assert np.float64(yaw[i]).tobytes() == np.float64(expected.yaw).tobytes(), (ci, si)
    # and the yaw is the heading's
    assert np.allclose(np.cos(yaw), c, atol=1e-12) and np.allclose(np.sin(yaw), s, atol=1e-12)


@needs_numba
def test_joints_and_encoders_numba_and_numpy_agree(body, monkeypatch) -> None:
    """Joint angles and speeds by group and sign, the encoders' signs after: numba's loop and
    numpy's arrays, the same bits (signs of 1 and -1 and other scales)."""
    rng = np.random.default_rng(4)
    batch = PlanarBatch(body, 37)
    batch.state[:] = rng.normal(0.0, 3.0, batch.state.shape)
    joints = [(0, 1.0), (1, -1.0), (0, -1.0), (1, 0.5)]
    scale = (1.0, -1.0, 0.3, -2.5)
    fast = [batch.joint_angles(joints), batch.joint_speeds(joints),
            batch.joint_angles(joints, scale), batch.joint_angles(joints[:2], scale[:2])]
    monkeypatch.setattr(dynamics, "COMPILED", False)
    slow = [batch.joint_angles(joints), batch.joint_speeds(joints),
            batch.joint_angles(joints, scale), batch.joint_angles(joints[:2], scale[:2])]
    for a, b in zip(fast, slow, strict=True):
        assert a.tobytes() == b.tobytes()
    speed = layout.speed_row(batch.ng)
    assert fast[1][5, 1] == -batch.state[speed + 1, 5]
    assert fast[2][7, 3] == (0.5 * batch.state[layout.ANGLE + 1, 7]) * -2.5


def test_the_compiled_pose_is_left_out_where_numba_uses_svml() -> None:
    """Intel's SVML may round atan2 otherwise: then the batch's pose is numpy's and Python's."""
    numba = pytest.importorskip("numba")
    if not dynamics.COMPILED:
        pytest.skip("numba (the fast extra) is not installed")
    assert (planar_batch._poses is None) == bool(numba.config.USING_SVML)
