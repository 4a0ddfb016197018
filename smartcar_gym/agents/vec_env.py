"""Old path of ``smartcar_gym.agents.vec_envs`` and ``sb3_vec_env`` (``make_batched_vec_env``
and ``GymVectorVecEnv``): its names still import from here."""

from smartcar_gym.agents import moved

__getattr__ = moved("smartcar_gym.agents.vec_envs", "smartcar_gym.agents.sb3_vec_env")
