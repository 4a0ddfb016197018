"""Many replays at once: recordings x candidate parameters, as one batch of planar cars.

A fit evaluates many candidate ``PlanarParams`` on every recording. ``FleetReplay`` puts each
(candidate, recording) pair in a column of the planar batched vector env's cars
(``SmartCarBatchVectorEnv`` on ``engine="planar"``: the same cars, boards, controllers and
clocks as the single env, bit for bit), gives each car
its candidate's parameters (``PlanarBody.model_with``) and its recording's start pose, and sends
each car its recording's ``cmd_vel`` once per controller period, as ``recording.replay`` does one
at a time. A differential evolution generation of 40 candidates on the fit's 11 drives is one
batch of 440 cars.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from smartcar_gym.calibration.recording import Recording
from smartcar_gym.controller import ArbotixConfig
from smartcar_gym.model import RobotModel
from smartcar_gym.sim.clock import NS_PER_S
from smartcar_gym.sim.planar.params import PlanarParams

#: the engine whose model the fit identifies (the replays run on it)
FITTED_ENGINE = "planar"


class FleetReplay:
    """Replays ``recordings`` on the planar engine for many candidate parameter sets."""

    def __init__(self, model: RobotModel, config: ArbotixConfig,
                 recordings: Sequence[Recording]) -> None:
        from smartcar_gym.envs.smartcar_env import SmartCarEnv

        self.model, self.config = model, config
        self.recordings = list(recordings)
        # the template: the robot as the env spawns it, for its contacts and actuation
        self.template = SmartCarEnv(model=model, controller_config=config, engine=FITTED_ENGINE)
        self.template.reset(seed=0)
        self.body = self.template.robot.body
        self.length = max(len(r.commands) for r in self.recordings)
        self._venv = None  # the batch, kept while the number of candidates stays the same

    def close(self) -> None:
        self.template.close()
        if self._venv is not None:
            self._venv.close()
            self._venv = None

    def _batch(self, n: int):
        from smartcar_gym.envs.vector import SmartCarBatchVectorEnv

        if self._venv is None or self._venv.num_envs != n:
            if self._venv is not None:
                self._venv.close()
            self._venv = SmartCarBatchVectorEnv("SmartCar-v0", num_envs=n, model=self.model,
                                                controller_config=self.config,
                                                engine=FITTED_ENGINE)
        return self._venv

    def run(self, candidates: Sequence[PlanarParams]
            ) -> list[list[tuple[np.ndarray, np.ndarray]]]:
        """For each candidate, each recording's replay: (true poses, odometry), each
        (T + 1, 3) for the recording's T commands, as ``recording.replay`` gives them."""
        recs, nr = self.recordings, len(self.recordings)
        n = len(candidates) * nr
        venv = self._batch(n)
        venv.reset(seed=0)
        cars = venv.cars.batch  # the PlanarBatch
        for c, params in enumerate(candidates):
            cars.set_model(np.arange(c * nr, (c + 1) * nr), self.body.model_with(params))
        starts = np.array([self.body.spawn_state(*r.truth[0]) for r in recs]).T
        cars.reset(np.arange(n), np.tile(starts, (1, len(candidates))))
        venv.base.reset(0.0, venv.cars.encoder_angles())
        venv.cars.set_drive(np.ones(n, dtype=bool), venv.base.drive_torque, venv.base.damping)
        commands = np.full((self.length, n, 2), np.nan)
        for k, r in enumerate(recs):
            commands[:len(r.commands), k::nr] = r.commands[:, None, :]
        truth = np.empty((self.length + 1, n, 3))
        odom = np.empty((self.length + 1, n, 3))
        yaw = np.array([r.truth[0, 2] for r in recs] * len(candidates))
        self._record(venv, truth, odom, 0, yaw)
        for t in range(self.length):
            sent = np.isfinite(commands[t, :, 0])
            if sent.any():
                venv.base.cmd_vel(np.nan_to_num(commands[t, :, 0]),
                                  np.nan_to_num(commands[t, :, 1]),
                                  venv.state.now_ns / NS_PER_S, sent)
            venv.clocks.run_period()
            self._record(venv, truth, odom, t + 1, yaw)
        out = []
        for c in range(len(candidates)):
            out.append([(truth[:len(r.commands) + 1, c * nr + k],
                         odom[:len(r.commands) + 1, c * nr + k]) for k, r in enumerate(recs)])
        return out

    @staticmethod
    def _record(venv, truth: np.ndarray, odom: np.ndarray, t: int, yaw: np.ndarray) -> None:
        px, py, now = venv.cars.batch.pose()
        yaw += np.remainder(now - yaw + math.pi, 2 * math.pi) - math.pi  # unwrapped
        truth[t, :, 0], truth[t, :, 1], truth[t, :, 2] = px, py, yaw
        b = venv.base
        odom[t, :, 0], odom[t, :, 1], odom[t, :, 2] = b.x, b.y, b.theta
