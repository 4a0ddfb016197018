"""The policy shipped as --pretrained mujoco (PPO trained with engine="mujoco", the shipped
settings), and sim-to-sim transfer both ways (docs/engines.md)."""

from __future__ import annotations

import json

import pytest
import shipped_policies as shipped

pytest.importorskip("smartcar_gym.sim.mujoco", reason="engine='mujoco' needs the mujoco extra")

from smartcar_gym.agents import cli_eval  # noqa: E402
from smartcar_gym.agents.models import PRETRAINED_MODEL  # noqa: E402

NAME = "mujoco"
FOLDER = shipped.folder(NAME)
MIN_SUCCESS = 0.9  # measured over 100 episodes: 94 % on MuJoCo, 97 % on pybullet


def test_the_mujoco_policy_is_shipped_with_its_provenance():
    for name in (PRETRAINED_MODEL, "vecnormalize.pkl", "provenance.json"):
        assert (FOLDER / name).is_file(), name
    provenance = shipped.provenance(NAME)
    assert provenance["env_kwargs"] == {"engine": "mujoco"}
    assert "engine=mujoco" in provenance["command"]
    assert provenance["evaluation"]["command"].startswith("smartcar-eval --pretrained mujoco")
    assert provenance["evaluation"]["success_rate"] >= MIN_SUCCESS
    assert provenance["transfer"]["engine"] == "pybullet"
    assert provenance["transfer"]["success_rate"] >= MIN_SUCCESS


def test_smartcar_eval_pretrained_mujoco_engine_pybullet_loads_its_own_files(tmp_path):
    out = tmp_path / "eval.json"
    assert cli_eval.main(["--pretrained", "mujoco", "--engine", "pybullet", "--episodes", "1",
                          "--no-progress", "--json", str(out)]) == 0
    data = json.loads(out.read_text())
    assert data["model"] == f"pretrained:mujoco/{PRETRAINED_MODEL}"
    assert data["env_kwargs"] == {"engine": "pybullet"}  # --engine over the provenance's
    assert data["normalizer"].endswith("pretrained/mujoco/vecnormalize.pkl")


@pytest.mark.slow
@pytest.mark.parametrize("name,engine", [("mujoco", "pybullet"), ("default", "mujoco")])
def test_policies_transfer_between_engines(name, engine):
    summary, _ = shipped.evaluate_shipped(name, n_episodes=32, n_envs=2,
                                          env_kwargs={"engine": engine})
    assert summary["success_rate"] >= MIN_SUCCESS
