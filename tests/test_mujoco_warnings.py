"""MuJoCo's warnings go through the facade: an unstable world is one warning naming the car's
state, and nothing is ever written into the working folder (MuJoCo's MUJOCO_LOG.TXT)."""

from __future__ import annotations

import os
import subprocess
import sys

import gymnasium as gym
import numpy as np
import pytest

pytest.importorskip("smartcar_gym.sim.mujoco", reason="engine='mujoco' needs the mujoco extra")

import smartcar_gym  # noqa: E402, F401
from smartcar_gym.sim.mujoco.mjlog import MujocoWarning  # noqa: E402

STOP = np.zeros(2, dtype=np.float32)


def test_an_unstable_single_env_is_one_warning_and_no_file(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    env = gym.make("SmartCar-v0", engine="mujoco")
    env.reset(seed=0)
    env.step(STOP)
    env.unwrapped.sim.data.qvel[0] = 1e30  # a blow-up, as a stiff contact or a bad model makes
    with pytest.warns(MujocoWarning) as caught:
        env.step(STOP)
    env.close()
    (line,) = [str(w.message) for w in caught]
    assert "\n" not in line
    assert line.startswith("MuJoCo's simulation became unstable at t=0.2000 s (Nan, Inf or huge "
                           "value in QVEL at DOF 0) and MuJoCo reset that world")
    assert "smartcar at x=" in line and "vx=1e+30" in line
    assert os.listdir(tmp_path) == []


def test_an_unstable_car_of_a_batch_is_named(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    envs = gym.make_vec("SmartCar-v0", num_envs=3, vectorization_mode="vector_entry_point",
                        engine="mujoco")
    envs.reset(seed=0)
    envs.unwrapped.cars.batch.datas[1].qvel[0] = 1e30
    with pytest.warns(MujocoWarning, match=r"^SmartCar-v0 \(mujoco\): MuJoCo's simulation became "
                                           r"unstable .*; car 1 at x=.* vx=1e\+30") as caught:
        envs.step(np.zeros((3, 2)))
    envs.close()
    assert len(caught) == 1
    assert os.listdir(tmp_path) == []


def test_mujoco_stepped_outside_the_facade_warns_in_python_too(tmp_path):
    """Once the facade is imported, a world of someone else's in the same process warns as
    Python does, not into its working folder."""
    script = (
        "import warnings, mujoco\n"
        "import smartcar_gym.sim.mujoco.simulator\n"
        "m = mujoco.MjModel.from_xml_string('<mujoco><worldbody><body><freejoint/>"
        "<geom size=\".1\"/></body></worldbody></mujoco>')\n"
        "d = mujoco.MjData(m)\n"
        "d.qvel[0] = float('nan')\n"
        "with warnings.catch_warnings(record=True) as w:\n"
        "    warnings.simplefilter('always')\n"
        "    mujoco.mj_step(m, d)\n"
        "print([(x.category.__name__, str(x.message)) for x in w])\n"
    )
    done = subprocess.run([sys.executable, "-c", script], cwd=tmp_path, capture_output=True,
                          text=True, timeout=120, check=True)
    assert "('MujocoWarning', 'MuJoCo: Nan, Inf or huge value in QVEL at DOF 0." in done.stdout
    assert os.listdir(tmp_path) == []
