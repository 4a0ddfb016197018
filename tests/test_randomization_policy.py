"""The robust policy shipped beside the default one: trained with randomize="default"."""

from __future__ import annotations

import json

import pytest
import shipped_policies as shipped

from smartcar_gym.agents import cli_eval
from smartcar_gym.agents.models import PRETRAINED_MODEL

NAME = "robust"
FOLDER = shipped.folder(NAME)
MIN_NOMINAL_SUCCESS = 0.9  # measured: 96 % over 100 episodes (docs/sim2real.md)


def test_the_robust_policy_is_shipped_with_its_provenance():
    for name in (PRETRAINED_MODEL, "vecnormalize.pkl", "provenance.json"):
        assert (FOLDER / name).is_file(), name
    provenance = shipped.provenance(NAME)
    assert provenance["env_kwargs"] == {"randomize": "default"}
    assert "--env-kwargs randomize=default" in provenance["command"]
    assert provenance["evaluation"]["command"].startswith("smartcar-eval --pretrained robust")


def test_smartcar_eval_pretrained_robust_loads_its_own_files(tmp_path, capsys):
    out = tmp_path / "eval.json"
    code = cli_eval.main(["--pretrained", "robust", "--episodes", "2", "--no-progress",
                          "--env-kwargs", "randomize=null", "--json", str(out)])
    assert code == 0
    data = json.loads(out.read_text())
    assert data["model"] == f"pretrained:robust/{PRETRAINED_MODEL}"
    assert data["env_kwargs"] == {"randomize": None}
    assert data["normalizer"].endswith("pretrained/robust/vecnormalize.pkl")


@pytest.mark.slow
def test_the_robust_policy_reaches_nominal_goals():
    summary, _ = shipped.evaluate_shipped(NAME, n_episodes=32, n_envs=2)
    assert summary["success_rate"] >= MIN_NOMINAL_SUCCESS
