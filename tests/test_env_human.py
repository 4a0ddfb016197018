"""render_mode="human": the real pybullet GUI on a virtual X display (Xvfb)."""

from __future__ import annotations

import shutil
import subprocess
import time
from collections.abc import Iterator

import gymnasium as gym
import numpy as np
import pytest

import smartcar_gym  # noqa: F401
from smartcar_gym.sim.bullet import pybullet

pytestmark = pytest.mark.skipif(
    shutil.which("Xvfb") is None,
    reason="the pybullet GUI needs a display: apt-get install xvfb (.ci/run does)",
)


@pytest.fixture
def display(monkeypatch) -> Iterator[str]:
    """A fresh Xvfb server; DISPLAY points at it for the test."""
    server = subprocess.Popen(
        ["Xvfb", "-displayfd", "1", "-screen", "0", "640x480x24", "-nolisten", "tcp"],
        stdout=subprocess.PIPE, stderr=subprocess.DEVNULL,
    )
    number = server.stdout.readline().decode().strip()  # Xvfb writes it once it is ready
    if not number.isdigit():
        server.kill()
        pytest.skip(f"Xvfb is installed but did not start (exit {server.wait()})")
    monkeypatch.setenv("DISPLAY", f":{number}")
    yield f":{number}"
    server.terminate()
    server.wait(timeout=10)


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
