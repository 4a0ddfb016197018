"""Turns on each engine: the two tables of docs/planar.md about turning.

    python benchmarks/planar_turns.py          # about 5 s; deterministic

Arcs ("Where the weight rests"): each row holds one ``cmd_vel`` (as a SmartCar-v0 action) for
3 s from rest and reports the true turn rate over the last 1.5 s, forward and in reverse. The
planar columns are the shipped pybullet fit and the same fit with ``load_shift_x`` 0 (the
static loads balanced about the URDF's centre of mass).

A slow turn after a run ("The slip speed has a floor"): 2 s at 0.35 m/s, then 0.1 m/s and
0.6 rad/s; the true turn (rad) over the next 0.8 s, on the engines and on the shipped fit with
its slip speed replaced (the tyres' creep below breakaway grows with it).
"""

from __future__ import annotations

import dataclasses

import gymnasium as gym
import numpy as np

import smartcar_gym  # noqa: F401  (registers the envs)
from smartcar_gym.sim.planar.params import resolve

#: SmartCar-v0 actions: linear.x = 0.5 a[0] m/s, angular.z = 2 a[1] rad/s
ACTIONS = ((1.0, 1.0), (-1.0, -1.0), (0.5, 1.0), (-0.5, -1.0))
STEPS, WINDOW = 30, 15  # 3 s of 0.1 s steps; the rate over the last 1.5 s
RUN, TURN = (0.7, 0.0), (0.2, 0.3)  # 0.35 m/s; then 0.1 m/s and 0.6 rad/s


def turn_rate(env: gym.Env, action: tuple[float, float]) -> float:
    env.reset(seed=0)
    yaw = []
    for _ in range(STEPS):
        info = env.step(np.array(action, dtype=np.float32))[4]
        yaw.append(info["pose"][2])
    yaw = np.unwrap(yaw)
    return float((yaw[-1] - yaw[-1 - WINDOW]) / (WINDOW * 0.1))


def turn_after_run(env: gym.Env) -> float:
    env.reset(seed=0)
    for _ in range(20):
        info = env.step(np.array(RUN, dtype=np.float32))[4]
    start = info["pose"][2]
    for _ in range(8):
        info = env.step(np.array(TURN, dtype=np.float32))[4]
    return float((info["pose"][2] - start + np.pi) % (2 * np.pi) - np.pi)


def on_each(columns: dict[str, dict], measure) -> dict[str, object]:
    """``measure(env)`` on a fresh SmartCar-v0 (a far goal, a wide arena) per column."""
    out = {}
    for name, kwargs in columns.items():
        env = gym.make("SmartCar-v0", goal_range=(2.3, 2.4), arena_size=20.0,
                       max_episode_steps=1000, **kwargs)
        out[name] = measure(env)
        env.close()
    return out


def main() -> None:
    fit = resolve("pybullet")
    columns = {
        "pybullet": {"engine": "pybullet"},
        "planar, shift 0": {"engine": "planar",
                            "planar_params": dataclasses.replace(fit, load_shift_x=0.0)},
        f"planar, shipped fit (shift {fit.load_shift_x * 1000:.1f} mm)":
            {"engine": "planar", "planar_params": fit},
        "MuJoCo": {"engine": "mujoco"},
    }
    rates = on_each(columns, lambda env: [turn_rate(env, a) for a in ACTIONS])
    print("| cmd_vel (linear.x m/s, angular.z rad/s) | " + " | ".join(columns) + " |")
    print("|---" + "|---:" * len(columns) + "|")
    for i, (a, w) in enumerate(ACTIONS):
        cells = " | ".join(f"{abs(rates[name][i]):.3f}" for name in columns)
        print(f"| ({0.5 * a:g}, {2 * w:g}) | {cells} |")
    print()
    onset = {"pybullet": {"engine": "pybullet"}, "MuJoCo": {"engine": "mujoco"}}
    for slip in (fit.slip_speed, 0.005):
        onset[f"planar, slip speed {slip * 1000:.1f} mm/s"] = {
            "engine": "planar", "planar_params": dataclasses.replace(fit, slip_speed=slip)}
    turns = on_each(onset, turn_after_run)
    print("| a slow turn after a run | " + " | ".join(onset) + " |")
    print("|---" + "|---:" * len(onset) + "|")
    print("| true turn in 0.8 s (rad) | " + " | ".join(f"{t:.3f}" for t in turns.values())
          + " |")


if __name__ == "__main__":
    main()
