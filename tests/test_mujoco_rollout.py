"""Seeded MuJoCo rollouts pinned to what they were when recorded (before any speed work).

Speed work on engine="mujoco" must not change its physics: the shipped ``--pretrained mujoco``
policy and the fidelity table of docs/engines.md were made with it. Each case steps 60 seeded
random actions (episode resets included) and hashes every observation, reward and ground-truth
pose; the final pose is pinned too. The hashes are bit for bit, so they are checked where they
were recorded (MuJoCo 4.0.0 on x86_64: another build may round differently); the poses, to 1 um
and 1 urad, everywhere (a physics setting that changed them would move them far more).
"""

from __future__ import annotations

import hashlib
import platform

import gymnasium as gym
import numpy as np
import pytest

pytest.importorskip("smartcar_gym.sim.mujoco", reason="engine='mujoco' needs the mujoco extra")
import mujoco  # noqa: E402  (after smartcar_gym.sim.mujoco has chosen MUJOCO_GL)

import smartcar_gym  # noqa: E402, F401

STEPS = 60
RECORDED_ON = ("4.0.0", "x86_64")  # mujoco.__version__, platform.machine()
#: env id, seed -> (sha256 of the rollout, final ground-truth pose (x m, y m, yaw rad))
PINNED = {
    ("SmartCar-v0", 3): (
        "aa37b520c81335c022bc42d10ee3d7de9b94c15dbe1a0104e42fe9d8107ce874",
        (0.098824478425154, -0.0002328083394263844, -0.004458201188183692)),
    ("SmartCarNav-v0", 4): (
        "0c7c7b9789b51cf15c4428ca9b0a6adfdf7b5ba669f513d566b8dba435c9d38c",
        (0.20839459077891614, -0.026971815949385275, 0.2237552160797089)),
    ("SmartCarGoal-v0", 5): (
        "c3b9286e7a8a7bf4de70314154dd45b542b5dc7d767360fc89d39a68d00bf00d",
        (0.05585592725408054, 0.012877307992787052, 0.2408795268548398)),
}


def rollout(env_id: str, seed: int) -> tuple[str, list[float]]:
    """The rollout's sha256 and its final pose."""
    env = gym.make(env_id, engine="mujoco")
    digest = hashlib.sha256()

    def feed(obs) -> None:
        for value in ([obs[k] for k in sorted(obs)] if isinstance(obs, dict) else [obs]):
            digest.update(np.asarray(value, dtype=np.float64).tobytes())

    try:
        obs, _ = env.reset(seed=seed)
        feed(obs)
        rng = np.random.default_rng(seed)
        for _ in range(STEPS):
            obs, reward, terminated, truncated, info = env.step(
                rng.uniform(-1, 1, 2).astype(np.float32))
            feed(obs)
            digest.update(np.float64(reward).tobytes())
            digest.update(info["pose"].tobytes())
            if terminated or truncated:
                obs, _ = env.reset()
                feed(obs)
    finally:
        env.close()
    return digest.hexdigest(), info["pose"].tolist()


@pytest.mark.parametrize("env_id,seed", list(PINNED))
def test_a_seeded_mujoco_rollout_is_what_it_was(env_id, seed):
    sha, pose = rollout(env_id, seed)
    pinned_sha, pinned_pose = PINNED[(env_id, seed)]
    assert pose == pytest.approx(pinned_pose, abs=1e-6)
    if (mujoco.__version__, platform.machine()) != RECORDED_ON:
        pytest.skip(f"the hash was recorded with MuJoCo {RECORDED_ON[0]} on {RECORDED_ON[1]}")
    assert sha == pinned_sha
