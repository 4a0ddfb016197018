"""rgb_array rendering on MuJoCo: headless (EGL or OSMesa), with the goal and odometry arrows;
one line saying what to install where it cannot render."""

from __future__ import annotations

import ctypes.util
import json
import os
import subprocess
import sys

import numpy as np
import pytest

pytest.importorskip("smartcar_gym.sim.mujoco", reason="engine='mujoco' needs the mujoco extra")

RENDER = """
import json, sys, numpy as np, gymnasium as gym, smartcar_gym
env = gym.make("SmartCar-v0", engine="mujoco", render_mode="rgb_array",
               render_width=320, render_height=240)
env.reset(seed=4)
first = env.render()
for _ in range(20):
    env.step(np.array([0.8, 0.5], dtype=np.float32))
image = env.render()
env.close()
green = (image[..., 1] > 150) & (image[..., 0] < 100) & (image[..., 2] < 100)  # the goal
yellow = (image[..., 0] > 150) & (image[..., 1] > 130) & (image[..., 2] < 90)  # the arrows
print(json.dumps({"shape": list(image.shape), "dtype": str(image.dtype),
                  "std": float(image.std()), "green": int(green.sum()),
                  "yellow": int(yellow.sum()), "yellow_first": int(
                      ((first[..., 0] > 150) & (first[..., 1] > 130) & (first[..., 2] < 90)).sum()),
                  "gl": __import__("os").environ.get("MUJOCO_GL")}))
"""
BACKENDS = [b for b, lib in (("egl", "EGL"), ("osmesa", "OSMesa")) if ctypes.util.find_library(lib)]


def _render(backend: str | None) -> dict:
    env = {k: v for k, v in os.environ.items()
           if k not in ("MUJOCO_GL", "PYOPENGL_PLATFORM", "DISPLAY")}  # as a fresh shell
    if backend is not None:
        env["MUJOCO_GL"] = backend
    done = subprocess.run([sys.executable, "-c", RENDER], capture_output=True, text=True,
                          env=env, timeout=120)
    assert done.returncode == 0, done.stderr[-2000:]
    return json.loads(done.stdout.strip().splitlines()[-1])


@pytest.mark.skipif(not BACKENDS, reason="neither EGL nor OSMesa is installed (apt-get install "
                                         "libegl1 libgl1-mesa-dri libosmesa6)")
def test_headless_render_picks_a_backend_and_draws_goal_and_odometry_arrows():
    result = _render(None)  # no MUJOCO_GL, no display: the package picks one
    assert result["gl"] in BACKENDS
    assert result["shape"] == [240, 320, 3] and result["dtype"] == "uint8"
    assert result["std"] > 10  # a picture, not a blank
    assert result["green"] > 20  # the goal disc
    assert result["yellow"] > result["yellow_first"]  # the odometry trail grew


@pytest.mark.slow
@pytest.mark.skipif("osmesa" not in BACKENDS, reason="OSMesa is not installed "
                                                    "(apt-get install libosmesa6)")
def test_software_rendering_through_osmesa_works_too():
    assert _render("osmesa")["green"] > 20


def test_a_machine_that_cannot_render_gets_one_line_naming_what_to_install(monkeypatch):
    import gymnasium as gym
    import mujoco

    import smartcar_gym  # noqa: F401

    def no_gl(*args, **kwargs):
        raise mujoco.FatalError("gladLoadGL error")

    monkeypatch.setattr(mujoco, "Renderer", no_gl)
    env = gym.make("SmartCar-v0", engine="mujoco", render_mode="rgb_array")
    env.reset(seed=0)
    with pytest.raises(RuntimeError, match="apt-get install libosmesa6") as error:
        env.render()
    assert "\n" not in str(error.value) and "MUJOCO_GL" in str(error.value)
    env.close()


def test_rendering_does_not_change_the_dynamics():
    import gymnasium as gym

    poses = []
    for mode in (None, "rgb_array"):
        env = gym.make("SmartCar-v0", engine="mujoco", render_mode=mode, render_width=64,
                       render_height=48)
        env.reset(seed=2)
        for _ in range(10):
            _, _, _, _, info = env.step(np.array([0.5, 0.5], dtype=np.float32))
            if mode is not None and BACKENDS:
                assert env.render().shape == (48, 64, 3)
        poses.append(info["pose"])
        env.close()
    assert np.array_equal(poses[0], poses[1])
