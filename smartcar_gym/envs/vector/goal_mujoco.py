"""SmartCarGoal-v0 on MuJoCo for N cars: SmartCar-v0's batch with the GoalEnv's dict
observations, goal-conditioned reward and ends."""

from __future__ import annotations

from typing import Any

import numpy as np

from smartcar_gym.envs.goal_env import GoalRewards, SmartCarGoalEnv
from smartcar_gym.envs.vector.mujoco import SmartCarMujocoVectorEnv


class SmartCarGoalMujocoVectorEnv(GoalRewards, SmartCarMujocoVectorEnv):
    """## Description

    ``SmartCarGoal-v0`` with ``engine="mujoco"`` for ``num_envs`` cars at once: the physics and
    controller of ``SmartCarMujocoVectorEnv`` (each car's MuJoCo world stepped in C, the cars
    split between ``num_threads`` worker threads), and SmartCarGoalEnv's observation, reward
    and ends on arrays. Per car it is ``gym.make("SmartCarGoal-v0", engine="mujoco")`` bit
    for bit (tested): the ``Dict`` observation (``observation``, ``achieved_goal``,
    ``desired_goal``, each ``(N, ...)``), the reward ``compute_reward(achieved_goal,
    desired_goal)``, terminated on reaching the goal by odometry, truncated when the odometry
    leaves the arena, the car flips or the time limit (100 steps) ends the episode, ``info``
    with SmartCar-v0's keys and ``flipped``.

    Made by ``gym.make_vec("SmartCarGoal-v0", num_envs=N, vectorization_mode=
    "vector_entry_point", engine="mujoco", **kwargs)`` with SmartCarGoalEnv's kwargs, plus
    ``autoreset_mode`` and ``num_threads``; what SmartCar-v0's MuJoCo batch cannot run
    (``randomize``, ``render_mode="human"``, ``controller_mode="sim"``, ...) falls back to
    ``SmartCarLoopVectorEnv``.

    ## Conventions

    As ``SmartCarSimVectorEnv`` (autoreset ``"NextStep"`` or ``"SameStep"``, whose
    ``info["final_obs"]`` holds each ended car's dict, car i seeded ``s + i``, ``(N, 2)``
    actions, ``render()`` tiles the first 16 cars top-down). ``compute_reward``,
    ``compute_terminated`` and ``compute_truncated`` are the single env's (goals ``(..., 2)``).
    """

    single_env = SmartCarGoalEnv
    env_id = "SmartCarGoal-v0"
    from_settings = ("observation", "_achieved", "_desired")

    def _init_from(self, s: SmartCarGoalEnv, num_threads: int) -> None:
        super()._init_from(s, num_threads)
        self.goal_task = s.goal_task
        self._achieved, self._desired = s._achieved, s._desired
        n = self.num_envs
        self._flipped = np.zeros(n, dtype=bool)
        self._truncate = np.zeros(n, dtype=bool)
        self._just_reset = np.zeros(n, dtype=bool)
        self._reset_success = np.zeros(n, dtype=bool)

    # -- the model -----------------------------------------------------------------------------
    def _reset_cars(self, mask: np.ndarray, goals: np.ndarray | None) -> None:
        """SmartCar-v0's reset, then SmartCarGoalEnv.reset's ``is_success`` and ``flipped``."""
        super()._reset_cars(mask, goals)
        achieved, desired = self._goals()
        self._reset_success[mask] = self.goal_task.is_success(achieved, desired)[mask]
        self._flipped[mask] = self.task.is_flipped(self._up_z[mask])
        self._just_reset[mask] = True

    def _advance(self, a: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """SmartCar-v0's step (its reward and ends unused, as the single env's), then the
        goal-conditioned reward and ends from the observed goals."""
        super()._advance(a)
        self._just_reset[:] = False
        achieved, desired = self._goals()
        self._flipped = self.task.is_flipped(self._up_z)
        success = self.goal_task.compute_terminated(achieved, desired, None)
        self._truncate = self.goal_task.compute_truncated(achieved, desired, None) | self._flipped
        reward = self.goal_task.compute_reward(achieved, desired, None)
        return reward, success, np.zeros(self.num_envs, dtype=bool)

    def _cut_short(self) -> np.ndarray:
        return self._truncate.copy()

    def _goals(self) -> tuple[np.ndarray, np.ndarray]:
        """Every car's observed achieved and desired goals ((N, 2) float32)."""
        columns = self._columns()
        return self._build(self._achieved, columns), self._build(self._desired, columns)

    def _columns(self) -> dict[str, Any]:
        columns = super()._columns()
        columns["achieved_goal"] = (self.base.x, self.base.y)
        columns["desired_goal"] = (self.goal[:, 0], self.goal[:, 1])
        return columns

    def _observe(self) -> dict[str, np.ndarray]:
        columns = self._columns()
        return {"observation": self._build(self.observation, columns),
                "achieved_goal": self._build(self._achieved, columns),
                "desired_goal": self._build(self._desired, columns)}

    @staticmethod
    def _car_obs(obs: dict[str, np.ndarray], i: int) -> dict[str, np.ndarray]:
        return {key: value[i].copy() for key, value in obs.items()}

    def _info_values(self, success: np.ndarray) -> dict[str, np.ndarray]:
        values = super()._info_values(success)
        # a car just reset reports its reset's is_success (the goal may start within reach)
        values["is_success"] = np.where(self._just_reset, self._reset_success, success)
        values["flipped"] = self._flipped.copy()
        return values
