"""A task as a plug-in: parking, stop inside a box around the goal at a given heading.

Through the public API only (``smartcar_gym.envs.tasks``): ``ParkTask`` is SmartCar-v0's
reaching task (``ReachTask``) with a heading drawn per episode and a different success: the
car's base_link inside a box around the goal (``box``: half its length and width, along and
across the heading), its yaw within ``heading_tolerance`` of the heading and the car at rest
by odometry. It is written once over the cars' public state (``CarState``), so the single env
and the batched envs run the same code. ``register_task`` makes the id ``SmartCarPark-v0``;
then Gymnasium's ``check_env`` runs on it with every registered engine that is installed, and
a batched vector env (``gym.make_vec(..., vectorization_mode="vector_entry_point")``) steps it
on planar and on MuJoCo. Prints ``ok``.

    python examples/task_plugin.py

docs/tasks.md ("Writing a task") explains each part.
"""

from __future__ import annotations

import math
import warnings
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium.utils.env_checker import check_env

import smartcar_gym  # noqa: F401 (registers the env ids)
from smartcar_gym.envs.observation import Entry, Observation
from smartcar_gym.envs.tasks.reach import OBSERVATION_ORDER, ReachTask
from smartcar_gym.envs.tasks.registry import EnvId, register_task, task_names
from smartcar_gym.envs.vector import SmartCarBatchVectorEnv
from smartcar_gym.sim.engines import available, engine_names

ENV_ID = "SmartCarPark-v0"
REST_SPEED_M_S = 0.02  # at rest: the odometry's speed under this (m/s) ...
REST_TURN_RAD_S = 0.1  # ... and its turn rate under this (rad/s)


class ParkTask(ReachTask):
    """## Description

    Park: drive to a goal 0.5-1.5 m away and stop there inside a box, facing a given heading.

    ## Observation Space

    SmartCar-v0's 21 values, then the heading to park at, as the cosine and sine of its angle
    from the odometry's heading.

    ## Rewards

    SmartCar-v0's progress, time and action terms, ``+10`` on parking, ``-10`` on flipping
    over or leaving the arena.

    ## Episode End

    Terminated when parked (inside the box, within the heading tolerance, at rest by
    odometry) or on a failure; ``info["in_box"]`` says which cars are parked in the box (the
    state's ``parked`` is another thing: cars not simulated until a reset).

    ## Arguments

    SmartCar-v0's, and ``box`` (half length, half width, m: (0.15, 0.1)) and
    ``heading_tolerance`` (rad: 0.3). ``reset(options={"heading": rad})`` sets the heading.
    """

    option_keys = ("goal", "heading")

    def __init__(self, box: tuple[float, float] = (0.15, 0.1), heading_tolerance: float = 0.3,
                 goal_range: tuple[float, float] = (0.5, 1.5), arena_size: float = 5.0) -> None:
        super().__init__(goal_range=goal_range, goal_tolerance=max(box), arena_size=arena_size)
        if not (len(box) == 2 and all(b > 0 for b in box)):
            raise ValueError(f"box must be (half length, half width) > 0 m, got {box!r}")
        if not 0 < heading_tolerance < math.pi:
            raise ValueError(f"heading_tolerance must be in (0, pi) rad, got "
                             f"{heading_tolerance!r}")
        self.box = (float(box[0]), float(box[1]))
        self.heading_tolerance = float(heading_tolerance)

    # -- the observation: SmartCar-v0's, then the heading to park at ---------------------------
    def declare(self) -> Observation:
        heading = Entry("park_heading", ("park_cos", "park_sin"), -1.0, 1.0, "",
                        "the heading to park at, from the odometry's heading (cos, sin)")
        return self.compose((*OBSERVATION_ORDER, "park_heading"), [heading])

    def columns(self, cars: Any) -> dict[str, Any]:
        columns = super().columns(cars)
        turn = self.heading - cars.state.odometry[:, 2]
        columns["park_heading"] = (np.cos(turn), np.sin(turn))
        return columns

    # -- the cars ------------------------------------------------------------------------------
    def attach(self, num: int) -> None:
        super().attach(num)
        #: each car's heading to park at (rad), and whether it is parked in the box
        self.heading = np.zeros(num)
        self.in_box = np.zeros(num, dtype=bool)

    def check_option(self, key: str, value: Any, vector: bool) -> list[Any]:
        if key != "heading":
            return super().check_option(key, value, vector)
        if not (isinstance(value, int | float) and math.isfinite(value)):
            raise ValueError(f"options['heading'] must be a finite angle (rad), got {value!r}")
        return [float(value)] * self.num

    def start(self, cars: Any, idx: np.ndarray, options: list[dict[str, Any]]) -> None:
        """The goal (SmartCar-v0's), then the heading: given, or drawn with the car's
        generator."""
        super().start(cars, idx, options)
        for i in idx.tolist():
            given = options[i].get("heading")
            self.heading[i] = (given if given is not None
                               else cars.rng(i).uniform(-math.pi, math.pi))

    def begin(self, cars: Any, idx: np.ndarray) -> None:
        super().begin(cars, idx)
        self.in_box[idx] = False

    def score(self, cars: Any, action: np.ndarray) -> tuple[np.ndarray, ...]:
        """Reaching's reward, with success replaced by parking."""
        reward, reached, failure = super().score(cars, action)
        state = cars.state
        c, s = np.cos(self.heading), np.sin(self.heading)
        dx, dy = state.pose[:, 0] - state.goal[:, 0], state.pose[:, 1] - state.goal[:, 1]
        along, across = np.abs(c * dx + s * dy), np.abs(-s * dx + c * dy)
        error = np.abs(np.remainder(state.pose[:, 2] - self.heading + np.pi, 2 * np.pi) - np.pi)
        rest = ((np.abs(state.odometry[:, 3]) < REST_SPEED_M_S)
                & (np.abs(state.odometry[:, 4]) < REST_TURN_RAD_S))
        self.in_box = ((along < self.box[0]) & (across < self.box[1])
                       & (error < self.heading_tolerance) & rest)
        bonus = self.success_bonus * (self.in_box.astype(float) - reached.astype(float))
        return reward + bonus, self.in_box.copy(), failure

    def info(self, cars: Any, success: np.ndarray) -> dict[str, np.ndarray]:
        return {**super().info(cars, success), "in_box": self.in_box.copy()}


def register() -> None:
    """``park`` and its id ``SmartCarPark-v0`` (30 s), once."""
    if "park" not in task_names():
        register_task("park", ParkTask, {ENV_ID: EnvId(300)}, "stop in a box at a heading")


def check(engine: str) -> None:
    """``check_env`` on the id with ``engine`` (its other render modes left out: "human"
    needs a display), then a picture."""
    env = gym.make(ENV_ID, engine=engine, render_mode="rgb_array")
    try:
        check_env(env.unwrapped, skip_render_check=True)
        env.reset(seed=0, options={"goal": (1.0, 0.0), "heading": 0.5})
        assert env.render().shape == (360, 480, 3)
    finally:
        env.close()


def step_batched(engine: str, steps: int = 5) -> None:
    """A few steps of 4 cars of the id in one batched env of ``engine``."""
    envs = gym.make_vec(ENV_ID, num_envs=4, vectorization_mode="vector_entry_point",
                        engine=engine)
    try:
        assert isinstance(envs.unwrapped, SmartCarBatchVectorEnv), type(envs.unwrapped)
        envs.reset(seed=0)
        for _ in range(steps):
            _, _, _, _, info = envs.step(np.stack([envs.single_action_space.sample()
                                                   for _ in range(4)]))
            assert info["in_box"].shape == (4,)
    finally:
        envs.close()


def main() -> None:
    register()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)  # check_env's notes on the spaces
        for engine in engine_names():
            if available(engine):
                check(engine)
    for engine in ("planar", "mujoco"):
        if available(engine):
            step_batched(engine)
    print("ok")


if __name__ == "__main__":
    main()
