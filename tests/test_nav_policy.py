"""The SmartCarNav-v0 policy shipped in the package (SAC, sac.yaml's entry)."""

from __future__ import annotations

import json

import pytest
import shipped_policies as shipped

from smartcar_gym.agents import cli_eval
from smartcar_gym.agents.models import PRETRAINED_MODEL

NAME = "nav"
FOLDER = shipped.folder(NAME)
MIN_SUCCESS = 0.8  # measured: docs/tasks.md (100 episodes); 32 episodes vary by about 5 points


def test_the_nav_policy_is_shipped_with_its_provenance():
    for name in (PRETRAINED_MODEL, "vecnormalize.pkl", "provenance.json"):
        assert (FOLDER / name).is_file(), name
    assert (FOLDER / PRETRAINED_MODEL).stat().st_size < 1_500_000  # SAC keeps its critics
    provenance = shipped.provenance(NAME)
    assert (provenance["algo"], provenance["env"]) == ("sac", "SmartCarNav-v0")
    assert provenance["evaluation"]["command"].startswith("smartcar-eval --pretrained nav")
    assert provenance["evaluation"]["episodes"] == 100
    assert provenance["evaluation"]["success_rate"] >= 0.85


def test_smartcar_eval_pretrained_nav_runs_on_its_env(tmp_path):
    out = tmp_path / "eval.json"
    code = cli_eval.main(["--pretrained", "nav", "--episodes", "2", "--no-progress",
                          "--json", str(out)])
    assert code == 0
    data = json.loads(out.read_text())
    assert (data["model"], data["env"]) == (f"pretrained:nav/{PRETRAINED_MODEL}",
                                            "SmartCarNav-v0")
    assert data["normalizer"].endswith("pretrained/nav/vecnormalize.pkl")


@pytest.mark.slow
def test_the_nav_policy_reaches_goals_among_obstacles():
    summary, _ = shipped.evaluate_shipped(NAME, n_episodes=32, n_envs=2)
    assert summary["success_rate"] >= MIN_SUCCESS
