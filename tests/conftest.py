"""Shared fixtures: the shipped model and controller config, a robot in a DIRECT world, and a
virtual display (Xvfb) for the windows."""

from __future__ import annotations

import signal
from collections.abc import Iterator

import gymnasium
import pytest

from smartcar_gym.controller import ArbotixConfig, load_controller_config
from smartcar_gym.envs.robots import SmartCarRobot
from smartcar_gym.model import RobotModel, load_model
from smartcar_gym.sim.pybullet.simulator import Simulator


@pytest.fixture
def display(monkeypatch) -> Iterator[str]:
    """A fresh Xvfb server (``tests.xvfb``); DISPLAY points at it for the test."""
    from tests import xvfb

    with xvfb.start() as name:
        monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
        monkeypatch.setenv("DISPLAY", name)
        yield name


@pytest.fixture(scope="session")
def shipped_model() -> RobotModel:
    return load_model()


@pytest.fixture(scope="session")
def shipped_config() -> ArbotixConfig:
    return load_controller_config()


@pytest.fixture
def sim() -> Iterator[Simulator]:
    world = Simulator()  # the env's default stepping: 10 ms substeps between events
    yield world
    world.close()


@pytest.fixture
def hardware_robot(sim, shipped_model, shipped_config) -> SmartCarRobot:
    robot = SmartCarRobot(sim, shipped_model, shipped_config, mode="hardware")
    robot.spawn()
    return robot


@pytest.fixture
def hard_timeout():
    """``hard_timeout(seconds)``: fail (instead of hanging) if the test runs longer (Ray tests)."""
    def arm(seconds: int) -> None:
        def fire(signum, frame):
            raise TimeoutError(f"still running after {seconds} s: Ray is waiting for something")

        signal.signal(signal.SIGALRM, fire)
        signal.alarm(seconds)

    yield arm
    signal.alarm(0)
    signal.signal(signal.SIGALRM, signal.SIG_DFL)


@pytest.fixture(autouse=True)
def _gymnasium_time_limit_untouched() -> Iterator[None]:
    """Fail the test that leaves gymnasium's ``TimeLimit`` replaced for the tests after it
    (importing rl_zoo3 does: its ``gym_patches`` change when a terminated episode counts as
    truncated, which the vector envs' equality tests compare)."""
    yield
    patched = gymnasium.wrappers.TimeLimit
    assert patched.__module__.startswith("gymnasium."), (
        f"gymnasium.wrappers.TimeLimit was replaced by {patched.__module__}.{patched.__name__} "
        "(import rl_zoo3 only in a subprocess)")
