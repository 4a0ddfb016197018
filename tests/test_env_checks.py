"""Gymnasium's and SB3's env checkers, and rendering (rgb_array headless, human needs a display)."""

from __future__ import annotations

import warnings

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env as gym_check_env
from stable_baselines3.common.env_checker import check_env as sb3_check_env

import smartcar_gym  # noqa: F401


def _blue(img: np.ndarray) -> np.ndarray:
    r, g, b = (img[..., i].astype(int) for i in range(3))
    return (b > 120) & (r < 60) & (g < 60)


def _green(img: np.ndarray) -> np.ndarray:  # goal disc, rgba (0.1, 0.8, 0.2, 0.6)
    r, g, b = (img[..., i].astype(int) for i in range(3))
    return (g > 90) & (g > r + 50) & (g > b + 50)


def _yellow(img: np.ndarray) -> np.ndarray:  # odometry trail, rviz's (221, 200, 14)
    r, g, b = (img[..., i].astype(int) for i in range(3))
    return (r > 120) & (g > 110) & (b < 60)


@pytest.mark.parametrize("mode", ["hardware", "sim"])
def test_gymnasium_and_sb3_checkers_pass_without_warnings(mode):
    env = gym.make("SmartCar-v0", controller_mode=mode)
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            gym_check_env(env.unwrapped, skip_render_check=True)
            sb3_check_env(env.unwrapped, warn=True)
        assert [f"{w.category.__name__}: {w.message}" for w in caught] == []
    finally:
        env.close()


def test_rgb_array_render_shows_car_goal_and_trail():
    env = gym.make("SmartCar-v0", render_mode="rgb_array", render_width=320, render_height=240)
    try:
        assert env.metadata["render_fps"] == 10  # the shipped controller rate
        assert env.unwrapped.metadata["render_fps"] == 10
        assert env.render_mode == "rgb_array"
        env.reset(seed=0, options={"goal": (1.5, 0.0)})
        img = env.render()
        assert isinstance(img, np.ndarray)
        assert img.shape == (240, 320, 3) and img.dtype == np.uint8
        assert img.std() > 10  # not a blank frame
        assert _blue(img).sum() > 20, "car body not visible"
        assert _green(img).sum() > 20, "goal marker not visible"
        # the trail: the car drives off its first odometry poses (hidden under it at first)
        assert _yellow(img).sum() == 0
        for _ in range(15):
            env.step(np.array([1.0, 0.0], dtype=np.float32))
        moved = env.render()
        assert _yellow(moved).sum() > 5, "odometry trail not visible"
        assert not np.array_equal(img, moved)
    finally:
        env.close()


def test_rgb_array_default_size_and_render_is_deterministic():
    env = gym.make("SmartCar-v0", render_mode="rgb_array")
    try:
        env.reset(seed=3)
        a, b = env.render(), env.render()
        assert a.shape == (360, 480, 3) and a.dtype == np.uint8
        assert np.array_equal(a, b)
    finally:
        env.close()


def test_render_without_render_mode_warns_and_returns_none():
    env = gym.make("SmartCar-v0")
    try:
        env.reset(seed=0)
        with pytest.warns(UserWarning, match="render_mode"):
            assert env.unwrapped.render() is None
    finally:
        env.close()


def test_human_render_without_display_is_a_clear_error(monkeypatch):
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    with pytest.raises(RuntimeError, match=r"DISPLAY is not set.*rgb_array"):
        gym.make("SmartCar-v0", render_mode="human")
