"""render_mode="human" on MuJoCo: MuJoCo's own viewer on a virtual X display (Xvfb), and
Gymnasium's ``check_env`` with its render check on every physics id and both engines."""

from __future__ import annotations

import os
import subprocess
import sys

import gymnasium as gym
import numpy as np
import pytest

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


# Gymnasium's check_env with its render check (skip_render_check=False), as Gymnasium's own
# test_env_api_with_render_check runs it: the checked env (rendered once) stays open while
# check_env makes, renders and closes an env in every listed mode, the human window included.
CHECK_EVERY_MODE = """
import sys, warnings
import gymnasium as gym
from gymnasium.utils.env_checker import check_env
import smartcar_gym

env_id, engine, *outer = sys.argv[1:]
first = gym.make(env_id, engine=engine)
print("listed", *first.metadata["render_modes"])
first.close()
for mode in outer:
    env = gym.make(env_id, engine=engine, render_mode=None if mode == "None" else mode)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # check_env's warnings are failures here
        check_env(env.unwrapped)
    env.close()
    print("checked", mode)
"""

# issue 42, item 15: under a display MuJoCo's offscreen renderer draws in a hidden GLFW window;
# closing the last human window once ended GLFW (glfw.terminate), that hidden window with it,
# and closing the rgb_array env then crashed the process (SIGSEGV)
OUTLIVES_A_WINDOW = """
import gymnasium as gym
import smartcar_gym

def make(mode):
    env = gym.make("SmartCar-v0", engine="mujoco", render_mode=mode)
    env.reset(seed=0)
    env.render()
    return env

a = make("rgb_array")
make("human").close()
make("rgb_array").close()
print("std", a.render().std())
a.close()
print("closed")
"""


def _child(code: str, display: str, *args: str) -> subprocess.CompletedProcess:
    """``code`` in a fresh interpreter on ``display``: a crash fails one test, not the run."""
    env = {k: v for k, v in os.environ.items()
           if k not in ("MUJOCO_GL", "PYOPENGL_PLATFORM", "WAYLAND_DISPLAY")}  # GLFW, as a desktop
    env["DISPLAY"] = display
    done = subprocess.run([sys.executable, "-X", "faulthandler", "-c", code, *args],
                          capture_output=True, text=True, env=env, timeout=600)
    how = "killed by a signal" if done.returncode < 0 else "an error"
    assert done.returncode == 0, f"exit {done.returncode} ({how}): {done.stderr[-3000:]}"
    return done


@needs_xvfb
@pytest.mark.parametrize("engine", ["mujoco", "pybullet"])
@pytest.mark.parametrize("env_id", PHYSICS_IDS)
def test_check_env_with_its_render_check_passes_in_every_mode(viewer_display, env_id, engine):
    """``check_env`` makes an env in every mode ``metadata["render_modes"]`` lists (a human
    window, an rgb_array renderer) while the env it checks, made without a render mode and
    then in rgb_array mode and rendered, stays open. The checked env is not made "human":
    check_env's own human env would be a second window beside it, which pybullet refuses
    (one GUI per process) and MuJoCo's viewer threads do not survive reliably."""
    outer = ["None", "rgb_array"]
    done = _child(CHECK_EVERY_MODE, viewer_display, env_id, engine, *outer)
    said = [line for line in done.stdout.splitlines()
            if line.startswith(("listed", "checked"))]  # not pybullet's own lines
    assert said == ["listed human rgb_array", *(f"checked {mode}" for mode in outer)], said


@needs_xvfb
def test_an_rgb_array_env_outlives_a_closed_human_window(viewer_display):
    done = _child(OUTLIVES_A_WINDOW, viewer_display)
    std, closed = done.stdout.strip().splitlines()[-2:]
    assert float(std.split()[1]) > 10 and closed == "closed", done.stdout  # not a blank frame


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
