"""close() frees the pybullet client; make/step/close cycles leak neither clients nor memory;
an env collected unclosed leaves no folder and says nothing."""

from __future__ import annotations

import contextlib
import copy
import ctypes
import gc
import os
import sys
import warnings
import weakref

import gymnasium as gym
import numpy as np
import pytest

import smartcar_gym  # noqa: F401
from smartcar_gym.sim.pybullet.bullet import pybullet

CYCLES = 100  # a window; two are measured
WARM_UP = 10
# A client left connected holds about 30 MB (the world, the model, the render buffers): one
# leaked client, or ~50 kB of Python objects per cycle, fails this.
MAX_GROWTH_MB = 5.0


def _rss_mb() -> float:
    """Resident set size, after giving freed memory back to the OS (less allocator noise)."""
    gc.collect()
    with contextlib.suppress(OSError, AttributeError):  # glibc only
        ctypes.CDLL(None).malloc_trim(0)
    with open("/proc/self/statm") as stream:
        resident_pages = int(stream.read().split()[1])
    return resident_pages * os.sysconf("SC_PAGE_SIZE") / 2**20


def _connected(cid: int) -> bool:
    return bool(pybullet.isConnected(physicsClientId=cid))


@pytest.mark.parametrize("render_mode", [None, "rgb_array"])
def test_close_disconnects_and_is_idempotent(render_mode):
    env = gym.make("SmartCar-v0", render_mode=render_mode)
    env.reset(seed=0)
    env.step(np.zeros(2, dtype=np.float32))
    cid = env.unwrapped.sim.client._client
    assert _connected(cid)
    env.close()
    assert env.unwrapped.sim is None
    assert not _connected(cid)
    env.close()  # a second close is a no-op
    env.unwrapped.close()


def test_close_before_reset_and_without_make():
    from smartcar_gym.envs.smartcar_env import SmartCarEnv

    env = SmartCarEnv(controller_mode="sim")
    cid = env.sim.client._client
    env.close()
    env.close()
    assert not _connected(cid)


def _cycle(seed: int) -> int:
    env = gym.make("SmartCar-v0")
    env.reset(seed=seed)
    env.step(np.array([1.0, 0.5], dtype=np.float32))
    env.step(np.array([-0.5, -1.0], dtype=np.float32))
    cid = env.unwrapped.sim.client._client
    env.close()
    return cid


def test_make_step_close_cycles_leak_no_client_and_little_memory():
    """A leak grows every window of cycles; the heap may grow once (by up to ~20 MB under
    pytest-xdist, depending on what the process ran before), so the smaller of two windows
    is what is held."""
    before = {i for i in range(64) if _connected(i)}  # other tests' live clients, if any
    for i in range(WARM_UP):
        assert not _connected(_cycle(i))
    growth = []
    for window in range(2):
        start = _rss_mb()
        for i in range(CYCLES):
            cid = _cycle(WARM_UP + window * CYCLES + i)
            assert not _connected(cid), f"cycle {i}: client {cid} still connected after close()"
        growth.append(_rss_mb() - start)
    assert {i for i in range(64) if _connected(i)} == before
    print(f"RSS growth over two windows of {CYCLES} make/reset/2 steps/close cycles: "
          f"{growth[0]:.2f}, {growth[1]:.2f} MB")
    assert min(growth) < MAX_GROWTH_MB, f"RSS grew by {growth} MB over each {CYCLES} cycles"


def test_resets_do_not_grow_memory():
    """pybullet's file cache kept every spawned URDF (a new temporary path each reset).

    A leak grows every window of resets; the heap may grow once (by ~2 MB, depending on
    what the process did before), so the smaller of two windows is what is held.
    """
    env = gym.make("SmartCar-v0")
    env.reset(seed=0)
    for _ in range(100):
        env.reset()
    growth = []
    for _ in range(2):
        before = _rss_mb()
        for _ in range(600):
            env.reset()
        growth.append(_rss_mb() - before)
    env.close()
    assert min(growth) < 1.5, (
        f"{growth} MB more after each 600 resets (3.5 MB with the file cache)")


@pytest.mark.parametrize("engine", ["pybullet", "mujoco", "planar"])
@pytest.mark.parametrize("how", ["dropped", "a copy"])
def test_a_simulator_collected_unclosed_removes_its_folder_without_a_warning(engine, how,
                                                                            monkeypatch):
    """An env that nobody closes (an env copy, or one a test or a user dropped): its
    simulator's scratch folder goes when the collector takes it, without the ResourceWarning
    that once fell into whatever warning check was running then (issue 42, item 14)."""
    if engine == "mujoco":
        pytest.importorskip("smartcar_gym.sim.mujoco", reason="needs the mujoco extra")
    original = gym.make("SmartCar-v0", engine=engine)
    env = copy.deepcopy(original) if how == "a copy" else original
    env.reset(seed=0)
    sim = weakref.ref(env.unwrapped.sim)
    folder = env.unwrapped.sim.scratch_dir
    assert folder.is_dir() and any(folder.iterdir())  # the robot's URDF
    unraised: list = []
    monkeypatch.setattr(sys, "unraisablehook", unraised.append)  # errors in finalizers
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        del env
        if how == "a copy":
            original.close()
        del original
        gc.collect()
    assert sim() is None  # collected, not closed
    assert [f"{u.exc_type.__name__}: {u.exc_value}" for u in unraised] == []
    assert not folder.exists()


def test_a_robot_refused_by_gym_make_leaves_no_world_open(monkeypatch):
    """The planar engine refuses a car that would tip over while the env is made: the world
    the env had opened is closed on the way out, not left to the collector."""
    from smartcar_gym.envs import world

    made = []
    real = world.make_simulator

    def recording(*args, **kwargs):
        made.append(real(*args, **kwargs))
        return made[-1]

    monkeypatch.setattr(world, "make_simulator", recording)
    with pytest.raises(ValueError, match="tip over"):
        gym.make("SmartCar-v0", engine="planar", planar_params={"load_shift_x": 0.5})
    assert len(made) == 2  # the env's world and the scratch world of the spawn check
    assert not any(sim.connected for sim in made)
