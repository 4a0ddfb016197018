"""Regression gate: the shipped PPO policy still drives SmartCar-v0 to its goals.

If a change to the model, controller or env breaks this test, retrain and re-export the policy
with ``smartcar-train`` and the shipped defaults (the pybullet run: docs/results.md), then
``python -m smartcar_gym.agents.export runs/ppo_SmartCar-v0_s0``.
"""

import pytest
import shipped_policies as shipped

from smartcar_gym.agents.models import PRETRAINED_MODEL

NAME = "default"
FOLDER = shipped.folder(NAME)
MIN_SUCCESS_RATE = 0.9


def test_shipped_policy_is_in_the_package():
    """The policy is part of the package (``smartcar-eval --pretrained``): missing is a failure."""
    for name in (PRETRAINED_MODEL, "provenance.json"):
        assert (FOLDER / name).is_file(), (
            f"smartcar_gym/pretrained/{name} is missing: retrain and re-export (docs/results.md)")


def test_shipped_policy_is_small_and_documented():
    assert (FOLDER / PRETRAINED_MODEL).stat().st_size < 1_000_000
    provenance = shipped.provenance(NAME)
    for key in ("algo", "env", "command", "seed", "timesteps", "wall_time_s", "evaluation"):
        assert provenance.get(key) is not None, key
    assert provenance["evaluation"]["success_rate"] >= MIN_SUCCESS_RATE


@pytest.mark.slow
def test_shipped_policy_reaches_its_goals():
    summary, records = shipped.evaluate_shipped(
        NAME, n_episodes=64, n_envs=4, env_kwargs=shipped.provenance(NAME).get("env_kwargs"))
    failures = [(r.seed, round(r.final_distance_m, 3)) for r in records if not r.success]
    assert summary["success_rate"] >= MIN_SUCCESS_RATE, (
        f"shipped policy: {summary['success_rate']:.1%} success over 64 episodes "
        f"(< {MIN_SUCCESS_RATE:.0%}); failed (seed, final distance m): {failures}. "
        "Retrain with smartcar-train (docs/results.md) if the env, model or controller changed."
    )
