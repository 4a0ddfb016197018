"""SmartCar-v0 and SmartCarGoal-v0 on the planar engine for N cars, all in arrays.

The MuJoCo batches' clocks, events, controller and task arithmetic (``vector/mujoco.py``) with
the planar engine's cars (``sim.planar.batch.PlanarBatch``) in place of MuJoCo's worlds: the
per-car events, the integer ArbotiX boards (``BatchedArbotix``), observations and rewards are
those classes' own code; only where the physics is read and written differs. The Goal and Nav
batches put their MuJoCo class first (``SmartCarGoalPlanarVectorEnv(SmartCarGoalMujocoVectorEnv,
SmartCarPlanarVectorEnv)``), so that their task code runs on the planar cars.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from smartcar_gym.controller import HARDWARE
from smartcar_gym.controller.batched import BatchedArbotix
from smartcar_gym.envs.smartcar_env import SmartCarEnv
from smartcar_gym.envs.vector.goal_mujoco import SmartCarGoalMujocoVectorEnv
from smartcar_gym.envs.vector.mujoco import SmartCarMujocoVectorEnv

#: measured (4096 cars, SmartCar-v0): about 6 KiB of arrays per car; the margin covers the
#: per-car generators
BYTES_PER_CAR = 16 * 1024


def supports(kwargs: dict[str, Any]) -> str | None:
    """Why the planar batch cannot run these SmartCar-v0 kwargs (None: it can)."""
    if kwargs.get("engine") != "planar":
        return "only engine='planar' is batched in arrays here"
    if kwargs.get("randomize") is not None:
        return "randomize (domain randomisation) builds a different car per episode"
    if kwargs.get("render_mode") == "human":
        return "render_mode='human' is a GUI"
    if kwargs.get("stop_speed") is not None:
        return "stop_speed's arrival terms (SmartCarArrive-v0) are the single env's"
    if kwargs.get("controller_mode") not in (None, HARDWARE):
        return "controller_mode='sim' steps no physics (SmartCarSim-v0 is batched in numpy)"
    return None


class SmartCarPlanarVectorEnv(SmartCarMujocoVectorEnv):
    """## Description

    ``SmartCar-v0`` with ``engine="planar"`` for ``num_envs`` cars at once, in arrays. Per car
    it is ``gym.make("SmartCar-v0", engine="planar")`` bit for bit (tested): the single env's
    planar car is copied into every column of ``sim.planar.batch.PlanarBatch``; each car keeps
    its own clock and steps each interval between its own events (board PID frames, controller
    updates) in the fewest equal substeps no longer than ``max_substep_s``, through the same
    substep function as the single env (numba's loop when the ``fast`` extra is installed,
    numpy arrays otherwise: the same numbers). The ArbotiX boards and ``diff_controller`` s
    are ``controller.batched.BatchedArbotix``; observation, reward and resets are numpy over
    cars.

    Made by ``gym.make_vec("SmartCar-v0", num_envs=N, vectorization_mode="vector_entry_point",
    engine="planar", **kwargs)`` with SmartCarEnv's kwargs (``planar_params`` included), plus
    ``autoreset_mode``. ``randomize``, ``render_mode="human"``, ``stop_speed`` and
    ``controller_mode="sim"`` fall back to ``SmartCarLoopVectorEnv``.

    ## Conventions

    As ``SmartCarSimVectorEnv`` (autoreset ``"NextStep"`` or ``"SameStep"``, car i seeded
    ``s + i``, ``info`` per car with ``_key`` masks, ``(N, 2)`` actions, ``render()`` tiles the
    first 16 cars top-down).
    """

    env_id = "SmartCar-v0"

    bytes_per_car = BYTES_PER_CAR
    why_not = staticmethod(supports)
    engine = "planar"
    differential = True  # BatchedArbotix starts the encoders mid-tick, as the single env

    def _keep(self, template: SmartCarEnv) -> None:
        template.close()

    def _init_from(self, s: SmartCarEnv, num_threads: int | None) -> None:
        from smartcar_gym.sim.planar.batch import PlanarBatch

        self._take_settings(s)
        n, robot, sim = self.num_envs, s.robot, s.sim
        body = robot.body
        self.cars = PlanarBatch(body, n)
        of = body.groups.of
        self._wheel_joints = [of[j] for j in robot.wheel_joint_indices]
        self._encoder_joints = [of[j] for j in robot._encoder_idx]
        self._encoder_sign = np.array(robot._encoder_signs, dtype=np.float64)
        self._side = [0 if left else 1 for left in robot._left]
        self._share = list(robot._share)
        self._sign = list(robot._signs)
        # the order PlanarBody sums joint torques and damping into its groups
        self._held_joints = [(of[j], k) for k, j in enumerate(robot.wheel_joint_indices)
                             if j in of]
        self._damped_joints = [(of[j], robot.wheel_joint_indices.index(j))
                               for j in body._damping if j in of]
        self.max_substep_ns = sim.max_substep_ns
        wheels = len(robot.wheel_joint_indices)
        self._wheel_group = np.arange(wheels)
        self.period_ns = robot.update_period_ns
        self.base = BatchedArbotix(s.controller_config, HARDWARE, s.robot_model.wheel_radius_m,
                                   num_cars=n, encoder_phase_ticks=robot.encoder_phase_ticks)
        self._rngs: list[np.random.Generator | None] = [None] * n
        self._steps = np.zeros(n, dtype=np.int64)
        self._now = np.zeros(n, dtype=np.int64)
        self._next_update = np.zeros(n, dtype=np.int64)
        self._pose = np.zeros((n, 3))
        self._up_z = np.ones(n)
        self._wheels = np.zeros((n, wheels))
        self._wheel_speed = np.zeros((n, wheels))
        self.goal = np.zeros((n, 2))
        self._distance = np.zeros(n)
        self._prev_action = np.zeros((n, 2), dtype=np.float32)
        self._autoreset = np.zeros(n, dtype=bool)
        self._needs_reset = True

    def close_extras(self, **kwargs: Any) -> None:
        """Nothing to release: arrays only."""

    def _angles(self) -> np.ndarray:
        """The encoder wheels' forward-positive angles (N, 2), as ``encoder_angles``."""
        return self.cars.joint_angles(self._encoder_joints) * self._encoder_sign

    def _read_pose(self) -> None:
        px, py, yaw = self.cars.pose()
        self._pose[:, 0], self._pose[:, 1], self._pose[:, 2] = px, py, yaw

    def _new_worlds(self, idx: np.ndarray, goals: np.ndarray | None) -> None:
        origin = np.zeros(2)
        for i in idx:
            self.goal[i] = (goals[i] if goals is not None
                            else self.task.sample_goal(self._rng(i), origin))
        self.cars.reset(idx)

    def _motors_to_wheels(self, mask: np.ndarray) -> None:
        """Each side's motor output into its wheel groups, with ``set_motor_output``'s and
        ``PlanarBody._drive``'s arithmetic in their order."""
        cars, ng = self.cars, self.cars.ng
        drive, damping = self.base.drive_torque[mask], self.base.damping[mask]
        tau = [np.zeros(len(drive)) for _ in range(ng)]
        for (g, sign), k in self._held_joints:
            tau[g] = tau[g] + sign * (drive[:, self._side[k]] * self._share[k] * self._sign[k])
        damp = [np.zeros(len(drive)) for _ in range(ng)]
        for (g, sign), k in self._damped_joints:
            damp[g] = damp[g] + sign * sign * (damping[:, self._side[k]] * self._share[k])
        for g in range(ng):
            cars.drive[g, mask] = tau[g]
            cars.drive[ng + g, mask] = damp[g]

    def _read_wheels(self) -> None:
        self._wheels = self.cars.joint_angles(self._wheel_joints)
        self._wheel_speed = self.cars.joint_speeds(self._wheel_joints)


class SmartCarGoalPlanarVectorEnv(SmartCarGoalMujocoVectorEnv, SmartCarPlanarVectorEnv):
    """``SmartCarGoal-v0`` with ``engine="planar"`` for ``num_envs`` cars (dict observations,
    ``final_obs`` per car), per car bit for bit ``gym.make("SmartCarGoal-v0",
    engine="planar")``; otherwise as ``SmartCarPlanarVectorEnv``."""

    env_id = "SmartCarGoal-v0"
