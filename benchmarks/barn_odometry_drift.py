"""How far each engine's odometry drifts on the BARN policy's commands (docs/barn.md,
"Odometry drift"; the ``randomize="odometry"`` preset's ranges were chosen with it, on the
first shipped policy's commands: docs/history.md).

    python benchmarks/barn_odometry_drift.py        # about a minute; deterministic

The shipped known-map BARN policy (``barn-known``) drives the 50 test worlds once on the planar
engine; its commands are then replayed open-loop, world by world, on an empty floor
(SmartCarNav-v0 with one far-away pillar, the same controller) on each engine, and with the
randomisation presets on the planar engine (the draw of sequence i seeded i). Printed per row:
how far the odometry ends from the true pose (m, mean and largest of the 50 sequences), the
heading error at the end (degrees, mean of its size) and the heading error's change per step
(degrees, rms).
"""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np

import smartcar_gym  # noqa: F401  (registers the envs)
from smartcar_gym.policy import Policy
from smartcar_gym.worlds.barn import TEST_WORLDS

#: an empty floor: one pillar 35 m away (SmartCarNav-v0 needs an obstacle layout)
FLOOR = dict(obstacle_layout=[{"shape": "cylinder", "position": [25.0, 25.0], "size": [0.1]}],
             goal_range=(20.0, 20.0), arena_size=60.0, max_episode_steps=10_000)
ROWS = {
    "pybullet": {"engine": "pybullet"},
    "MuJoCo": {"engine": "mujoco"},
    "planar": {"engine": "planar"},
    'planar, randomize="odometry"': {"engine": "planar", "randomize": "odometry"},
    'planar, randomize="default"': {"engine": "planar", "randomize": "default"},
}


def policy_commands() -> list[list[np.ndarray]]:
    """The shipped known-map BARN policy's actions on the 50 test worlds, planar engine."""
    policy = Policy.load("barn-known")
    kwargs = {k: v for k, v in policy.env_kwargs.items()
              if k not in ("max_episode_steps", "engine", "planar_params")}
    env = gym.make("SmartCarBARN-v0", engine="planar", **kwargs)
    commands = []
    try:
        for world in TEST_WORLDS:
            obs, info = env.reset(options={"world": world})
            actions = []
            while not info.get("outcome"):
                action = policy.act(obs)
                actions.append(action)
                obs, _, _, _, info = env.step(action)
            commands.append(actions)
    finally:
        env.close()
    return commands


def replay(commands: list[list[np.ndarray]], kwargs: dict) -> tuple[float, ...]:
    """Odometry error at each sequence's end (m), its largest, the end heading error's mean
    size (deg) and the per-step heading error change's rms (deg)."""
    env = gym.make("SmartCarNav-v0", **FLOOR, **kwargs)
    ends, headings, steps = [], [], []
    try:
        for i, actions in enumerate(commands):
            env.reset(seed=i)
            before = 0.0
            for action in actions:
                _, _, _, _, info = env.step(action)
                error = math.remainder(info["odom_pose"][2] - info["pose"][2], 2 * math.pi)
                steps.append(error - before)
                before = error
            ends.append(info["odom_error"])
            headings.append(abs(math.degrees(before)))
    finally:
        env.close()
    return (float(np.mean(ends)), float(np.max(ends)), float(np.mean(headings)),
            math.degrees(float(np.sqrt(np.mean(np.square(steps))))))


def main() -> None:
    commands = policy_commands()
    print(f"the shipped BARN policy's commands on the {len(commands)} test worlds "
          f"({sum(map(len, commands))} steps), replayed on an empty floor\n")
    print("| engine | odometry error at the end, mean (m) | largest (m) | heading error at the "
          "end, mean (deg) | heading error per step, rms (deg) |")
    print("|---|---|---|---|---|")
    for name, kwargs in ROWS.items():
        mean, largest, heading, step = replay(commands, kwargs)
        print(f"| {name} | {mean:.3f} | {largest:.3f} | {heading:.2f} | {step:.3f} |")


if __name__ == "__main__":
    main()
