"""render_mode="human" on MuJoCo: MuJoCo's own viewer on a virtual X display (Xvfb), and
Gymnasium's ``check_env`` with its render check on every physics id and both engines."""

from __future__ import annotations

import warnings

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

pytest.importorskip("smartcar_gym.sim.mujoco", reason="engine='mujoco' needs the mujoco extra")

import smartcar_gym  # noqa: E402, F401
from smartcar_gym.sim.mujoco import window  # noqa: E402
from tests.xvfb import needs_xvfb  # noqa: E402

PHYSICS_IDS = ("SmartCar-v0", "SmartCarNav-v0", "SmartCarGoal-v0", "SmartCarArrive-v0")
FORWARD = np.array([1.0, 0.0], dtype=np.float32)


@pytest.fixture
def viewer_display(display) -> str:
    """The virtual display, once it has shown it can hold an OpenGL window (skip otherwise)."""
    try:
        window.start_glfw()
    except RuntimeError as exc:
        pytest.skip(f"no OpenGL window on Xvfb here: {exc}")
    window.stop_glfw()
    return display


@needs_xvfb
def test_human_mode_shows_the_world_in_mujocos_viewer(viewer_display):
    env = gym.make("SmartCar-v0", engine="mujoco", render_mode="human")
    env.reset(seed=0)
    for _ in range(10):
        env.step(FORWARD)
    sim = env.unwrapped.sim
    shown = sim.window
    assert shown.is_open and shown.model is sim.model  # this world, compiled
    assert env.render() is None  # human mode draws in the window and returns nothing
    # the camera looks at the midpoint between the car and the goal, as pybullet's GUI's
    pose, goal = env.unwrapped.robot.pose(), env.unwrapped.goal
    np.testing.assert_allclose(shown.camera.lookat[:2], [(pose.x + goal[0]) / 2,
                                                        (pose.y + goal[1]) / 2])
    assert shown.camera.elevation == -60.0 and shown.camera.azimuth == 90.0
    assert pose.x > 0.2  # it drove forward with the window open
    assert shown.scene.ngeom == sum(len(m.parts) for m in sim._markers) > 0  # goal, trail
    env.reset(seed=1)  # a new world: the viewer is handed its model
    assert shown.is_open and shown.model is sim.model
    env.close()
    assert not shown.is_open and sim.window is None


@needs_xvfb
@pytest.mark.parametrize("engine", ["mujoco", "pybullet"])
@pytest.mark.parametrize("env_id", PHYSICS_IDS)
def test_check_env_with_its_render_check_passes(viewer_display, env_id, engine):
    """``check_env`` makes the env in every mode ``metadata["render_modes"]`` lists."""
    env = gym.make(env_id, engine=engine)
    assert "human" in env.metadata["render_modes"]
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # check_env's warnings are failures here
        check_env(env.unwrapped)
    env.close()


def test_human_mode_without_a_display_is_one_line(monkeypatch):
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    with pytest.raises(RuntimeError, match=r"^render_mode='human' opens MuJoCo's viewer, which "
                                           r"needs a display \(DISPLAY is not set\)"):
        gym.make("SmartCar-v0", engine="mujoco", render_mode="human")


def test_without_a_viewer_the_metadata_lists_only_rgb_array(monkeypatch):
    """Where MuJoCo's viewer cannot open at all (macOS outside mjpython, no GLFW), the env
    lists only the mode it has, and asking for the other says why."""
    monkeypatch.setattr(window, "unavailable", lambda: "on macOS it needs mjpython")
    env = gym.make("SmartCar-v0", engine="mujoco")
    assert list(env.metadata["render_modes"]) == ["rgb_array"]
    env.close()
    with pytest.raises(ValueError, match=r"^render_mode='human' is not available with "
                                         r"engine='mujoco' here: on macOS it needs mjpython"):
        gym.make("SmartCar-v0", engine="mujoco", render_mode="human")
    pybullet = gym.make("SmartCar-v0")
    assert list(pybullet.metadata["render_modes"]) == ["human", "rgb_array"]
    pybullet.close()
