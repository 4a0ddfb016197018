"""Vector envs: many cars per process through Gymnasium's vector API.

``gym.make_vec(env_id, num_envs=N, vectorization_mode="vector_entry_point", **kwargs)`` calls
the id's entry point (``entries``), ``make_vector_env``: SmartCarSim-v0 (kinematic, no
engine) is batched in numpy arrays (``SmartCarSimVectorEnv``); any id on an engine with a car
batch (MuJoCo: worlds stepped in C; planar: arrays; any engine registered with ``car_batch``)
is ``SmartCarBatchVectorEnv``, one class running the id's task over all its cars; the
pybullet ids, and the options only a single env's world has (the GUI, ...), step N single
envs in a loop (``SmartCarLoopVectorEnv``). All follow the same conventions (docs/vector.md).
"""

from __future__ import annotations

from smartcar_gym.envs.vector.batched import SmartCarBatchVectorEnv
from smartcar_gym.envs.vector.common import CannotBatch
from smartcar_gym.envs.vector.kinematic import SmartCarSimVectorEnv
from smartcar_gym.envs.vector.loop import SmartCarLoopVectorEnv
from smartcar_gym.envs.vector.make import make_vector_env

__all__ = ["CannotBatch", "SmartCarBatchVectorEnv", "SmartCarLoopVectorEnv",
           "SmartCarSimVectorEnv", "make_vector_env"]
