"""render_mode="human": the real pybullet GUI on a virtual X display (Xvfb)."""

from __future__ import annotations

import time

import gymnasium as gym
import numpy as np

import smartcar_gym  # noqa: F401
from smartcar_gym.sim.pybullet.bullet import pybullet
from tests.xvfb import needs_xvfb

pytestmark = needs_xvfb


def test_human_mode_shows_the_car_and_goal_and_closes_quietly(display, capfd):
    env = gym.make("SmartCar-v0", render_mode="human")
    env.reset(seed=0)
    for _ in range(10):
        env.step(np.array([1.0, 0.0], dtype=np.float32))
    unwrapped = env.unwrapped
    client = unwrapped.sim.client
    # every step renders: the GUI camera looks at the midpoint between the car and the goal
    assert env.render() is None  # human mode draws in the window and returns nothing
    pose, goal = unwrapped.robot.pose(), unwrapped.goal
    wanted = np.array([(pose.x + goal[0]) / 2, (pose.y + goal[1]) / 2])
    deadline = time.monotonic() + 5.0
    while True:  # the GUI thread applies camera moves asynchronously: give it a moment
        target = np.array(client.getDebugVisualizerCamera()[11][:2])
        if np.allclose(target, wanted, atol=1e-4) or time.monotonic() > deadline:
            break
        time.sleep(0.05)
    np.testing.assert_allclose(target, wanted, atol=1e-4)
    assert pose.x > 0.2  # it drove forward in the GUI world (0.26 m: 1 s at 0.5 m/s from rest)
    assert unwrapped.markers is not None  # goal and odometry trail are drawn
    cid = client._client
    env.close()
    assert not pybullet.isConnected(physicsClientId=cid)
    printed = capfd.readouterr()
    # pybullet's GUI reports its threads' shutdown on the C-level stdout: silenced
    assert "stopping threads" not in printed.out + printed.err
