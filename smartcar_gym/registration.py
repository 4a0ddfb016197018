"""Registration of the smartcar environments with Gymnasium (idempotent)."""

from __future__ import annotations

from gymnasium.envs.registration import register, registry

ENTRY_POINT = "smartcar_gym.envs.smartcar_env:SmartCarEnv"
MAX_EPISODE_STEPS = 200
# Mean return of a policy that reaches the goal reliably (see README, "Training").
REWARD_THRESHOLD = 15.0

ENV_IDS = ("SmartCar-v0", "SmartCarSim-v0")


def register_envs() -> None:
    """Register SmartCar-v0 (hardware controller) and SmartCarSim-v0 (the driver's sim mode)."""
    kwargs = {"SmartCar-v0": {}, "SmartCarSim-v0": {"controller_mode": "sim"}}
    for env_id in ENV_IDS:
        if env_id in registry:
            continue
        register(
            id=env_id,
            entry_point=ENTRY_POINT,
            max_episode_steps=MAX_EPISODE_STEPS,
            reward_threshold=REWARD_THRESHOLD,
            kwargs=kwargs[env_id],
        )
