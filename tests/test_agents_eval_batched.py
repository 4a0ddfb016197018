"""smartcar-eval --vectorization batched and its pass marks: the batched evaluation's records
against the sequential evaluation's, the JSON, the recordings of the first episodes, the exit
status."""

from __future__ import annotations

import importlib.util
import json

import numpy as np
import pytest

from smartcar_gym.agents import cli_eval
from smartcar_gym.agents.env_factory import EnvSetupError
from smartcar_gym.agents.episodes import (
    RECORD_TOLERANCE,
    evaluate_batched_episodes,
    evaluate_policy_episodes,
)
from smartcar_gym.envs.vector import SmartCarSimVectorEnv
from smartcar_gym.policy import Policy
from smartcar_gym.testing import FunctionModel

MUJOCO = importlib.util.find_spec("mujoco") is not None
needs_mujoco = pytest.mark.skipif(not MUJOCO, reason="engine='mujoco' needs the mujoco extra")
#: near goals and a short limit: successes and time limits in a few episodes
NEAR = {"goal_range": [0.3, 0.8], "max_episode_steps": 25}


def go_to_goal(obs: np.ndarray) -> np.ndarray:
    """A plain function of one observation: turn towards the goal, then drive to it."""
    bearing = np.arctan2(obs[15], obs[14])
    v = np.clip(2.0 * obs[14], -1, 1) * (abs(bearing) < 0.8)
    return np.array([v, np.clip(1.5 * bearing, -1, 1)], dtype=np.float32)


def steer(obs) -> np.ndarray:
    """A plain function of one observation (or of a Dict space's ``observation``)."""
    vector = obs["observation"] if isinstance(obs, dict) else obs
    return np.array([0.8, np.tanh(3.0 * vector[3])], dtype=np.float32)


def _dicts(records):
    return [r.to_dict(include_paths=True) for r in records]


@pytest.mark.parametrize(("env_id", "kwargs"), [
    ("SmartCarSim-v0", {}),  # the numpy batch
    pytest.param("SmartCar-v0", {"engine": "mujoco"}, marks=needs_mujoco),  # the MuJoCo batch
    ("SmartCar-v0", {"engine": "planar"}),  # the planar batch
    ("SmartCar-v0", {"max_episode_steps": 12}),  # pybullet: the loop of single envs
])
def test_batched_records_equal_the_sequential_ones_bit_for_bit(env_id, kwargs):
    """A policy whose actions do not depend on batching: every record (path included) of the
    batched evaluation is the sequential one's, whatever the number of cars."""
    kwargs = {**NEAR, **kwargs}
    common = dict(env_id=env_id, n_episodes=7, seed=3, env_kwargs=kwargs)
    model = FunctionModel(go_to_goal)
    want = _dicts(evaluate_policy_episodes(model, **common))
    three = _dicts(evaluate_batched_episodes(model, n_envs=3, **common))
    two = _dicts(evaluate_batched_episodes(model, n_envs=2, **common))
    assert three == want and two == want
    assert [r["seed"] for r in want] == list(range(3, 10))
    if kwargs["max_episode_steps"] > 12:
        ends = {r["success"] for r in want}
        assert ends == {True, False}, ends  # reaching goals and time limits compared


@pytest.mark.parametrize("engine", [pytest.param("mujoco", marks=needs_mujoco), "planar"])
@pytest.mark.parametrize("env_id", ["SmartCarNav-v0", "SmartCarGoal-v0"])
def test_nav_and_goal_batches_give_the_sequential_records(env_id, engine):
    """The MuJoCo and planar Nav batches (their own worlds built at each reset) and the Goal
    batches (Dict observations): the sequential evaluation's records, bit for bit."""
    common = dict(env_id=env_id, n_episodes=4, seed=1,
                  env_kwargs={"engine": engine, "max_episode_steps": 15})
    model = FunctionModel(steer)
    want = _dicts(evaluate_policy_episodes(model, **common))
    assert _dicts(evaluate_batched_episodes(model, n_envs=3, **common)) == want
    assert all(np.isfinite(r["goal"]).all() for r in want)


@needs_mujoco
def test_sb3_policy_batched_matches_the_sequential_evaluation_within_tolerance():
    """The shipped MuJoCo policy: batched matrix products round differently (about 1e-7 in
    the actions); the episodes end alike, the figures agree within RECORD_TOLERANCE."""
    policy = Policy.load("mujoco")
    common = dict(env_id=policy.env_id, n_episodes=6, seed=0,
                  env_kwargs={**policy.env_kwargs, "max_episode_steps": 60})
    want = evaluate_policy_episodes(policy, **common)
    got = evaluate_batched_episodes(policy, n_envs=4, **common)
    assert sum(r.success for r in want) >= 4
    for g, w in zip(got, want, strict=True):
        assert (g.episode, g.seed, g.goal, g.success, g.length) == (w.episode, w.seed, w.goal,
                                                                    w.success, w.length)
        assert g.episode_return == pytest.approx(w.episode_return, abs=RECORD_TOLERANCE)
        assert g.final_distance_m == pytest.approx(w.final_distance_m, abs=RECORD_TOLERANCE)
        np.testing.assert_allclose(g.path, w.path, atol=RECORD_TOLERANCE)


def test_a_vector_env_without_partial_resets_is_one_line(monkeypatch):
    """An env that resets every car when asked for some would run the wrong seeds: refused."""
    def everyone(self, options):
        options = {k: v for k, v in (options or {}).items() if k != "reset_mask"} or None
        return options, np.ones(self.num_envs, dtype=bool)

    monkeypatch.setattr(SmartCarSimVectorEnv, "_reset_mask", everyone)
    with pytest.raises(EnvSetupError, match=r"^SmartCarSim-v0's vector env "
                       r"\(SmartCarSimVectorEnv\) cannot reset single cars .* it reset cars "
                       r"\[0, 1\], not \[0\], which --vectorization batched needs$"):
        evaluate_batched_episodes(FunctionModel(go_to_goal), "SmartCarSim-v0", n_episodes=3,
                                  n_envs=2, env_kwargs=NEAR)


@needs_mujoco
def test_cli_batched_json_and_plot_match_the_sequential_evaluation(tmp_path, capsys):
    common = ["--pretrained", "mujoco", "--episodes", "4", "--seed", "2", "--no-progress",
              "--env-kwargs", "max_episode_steps=50"]
    batched, plain = tmp_path / "batched.json", tmp_path / "plain.json"
    assert cli_eval.main([*common, "--vectorization", "batched", "--n-envs", "3", "--json",
                          str(batched), "--plot", str(tmp_path / "paths.png")]) == 0
    assert cli_eval.main([*common, "--json", str(plain)]) == 0
    got, want = json.loads(batched.read_text()), json.loads(plain.read_text())
    assert (got["vectorization"], got["n_envs"], want["vectorization"], want["n_envs"]) == (
        "batched", 3, "subproc", 1)
    assert got["marks"] == want["marks"] == [] and got["passed"] is True
    assert got["recorded_episodes"] is None  # nothing recorded
    assert got["success_rate"] == want["success_rate"]
    for g, w in zip(got["episode_records"], want["episode_records"], strict=True):
        assert {k: g[k] for k in ("episode", "seed", "success", "length", "goal")} == \
            {k: w[k] for k in ("episode", "seed", "success", "length", "goal")}
        assert g["final_distance_m"] == pytest.approx(w["final_distance_m"],
                                                      abs=RECORD_TOLERANCE)
    assert (tmp_path / "paths.png").read_bytes()[:4] == b"\x89PNG"


def test_cli_pass_marks_missed_exit_1_with_one_line_each(tmp_path, capsys):
    out = tmp_path / "eval.json"
    argv = ["--random", "--env", "SmartCarSim-v0", "--episodes", "3", "--no-progress",
            "--vectorization", "batched", "--env-kwargs", "max_episode_steps=10",
            "--fail-under", "50", "--max-final-distance", "0.05", "--json", str(out)]
    assert cli_eval.main(argv) == 1
    data = json.loads(out.read_text())
    lines = [line for line in capsys.readouterr().err.splitlines() if "pass mark" in line]
    distance = data["mean_final_distance_m"]
    assert lines == [
        "smartcar-eval: pass mark missed: success rate 0.0% is under --fail-under 50% "
        "(3 episodes)",
        f"smartcar-eval: pass mark missed: mean final distance {distance:.3f} m is over "
        "--max-final-distance 0.05 m (3 episodes)"]
    assert data["passed"] is False
    assert [(m["option"], m["figure"], m["mark"], m["value"], m["held"]) for m in data["marks"]] \
        == [("--fail-under", "success_rate_pct", 50.0, 0.0, False),
            ("--max-final-distance", "mean_final_distance_m", 0.05, distance, False)]


def test_cli_pass_marks_held_exit_0_in_either_vectorization(tmp_path, capsys):
    for vectorization in ("subproc", "batched"):
        out = tmp_path / f"{vectorization}.json"
        argv = ["--random", "--env", "SmartCarSim-v0", "--episodes", "2", "--no-progress",
                "--vectorization", vectorization, "--env-kwargs", "max_episode_steps=5",
                "--fail-under", "0", "--max-final-distance", "50", "--json", str(out)]
        assert cli_eval.main(argv) == 0
        data = json.loads(out.read_text())
        assert data["passed"] is True and [m["held"] for m in data["marks"]] == [True, True]
        err = capsys.readouterr().err
        assert "pass mark held: success rate 0.0% is not under --fail-under 0%" in err


@pytest.mark.parametrize(("argv", "line"), [
    (["--fail-under", "101"], "argument --fail-under: expected a percentage from 0 to 100, "
                              "got '101'"),
    (["--fail-under", "x"], "argument --fail-under: expected a percentage from 0 to 100, "
                            "got 'x'"),
    (["--max-final-distance", "0"], "argument --max-final-distance: expected a distance in "
                                    "metres > 0, got '0'"),
    (["--max-final-distance", "nan"], "argument --max-final-distance: expected a distance in "
                                      "metres > 0, got 'nan'"),
    (["--record-episodes", "2"], "--record-episodes: only with --vectorization batched"),
    (["--vectorization", "batched", "--n-envs", "0"], "argument --n-envs: expected a "
                                                      "positive integer"),
])
def test_bad_batched_and_mark_arguments_are_one_line(argv, line, capsys):
    with pytest.raises(SystemExit) as exit_info:
        cli_eval.main(["--random", "--episodes", "1", *argv])
    assert exit_info.value.code == 2
    assert line in capsys.readouterr().err.strip().splitlines()[-1]


@pytest.mark.skipif(importlib.util.find_spec("rosbags") is None,
                    reason='rosbags not installed: pip install "smartcar-gym[ros]"')
def test_cli_batched_bag_records_the_first_episodes(tmp_path, capsys):
    from tests.test_ros_bag import _episodes, _read_bag

    bag, out = tmp_path / "first.bag", tmp_path / "eval.json"
    argv = ["--random", "--episodes", "3", "--no-progress", "--vectorization", "batched",
            "--record-episodes", "2", "--env-kwargs", "max_episode_steps=6", "--bag", str(bag),
            "--json", str(out)]
    assert cli_eval.main(argv) == 0
    data = json.loads(out.read_text())
    assert data["recorded_episodes"] == 2 and data["episodes"] == 3
    episodes = _episodes(_read_bag(bag)[1])
    assert len(episodes) == 2
    for episode, record in zip(episodes, data["episode_records"], strict=False):
        goal = episode[0][2].pose.position
        assert [goal.x, goal.y] == record["goal"]  # the same seeds' episodes


@pytest.mark.skipif(importlib.util.find_spec("rerun") is None,
                    reason='rerun-sdk not installed: pip install "smartcar-gym[rerun]"')
def test_cli_batched_rerun_records_the_first_episodes(tmp_path, capsys):
    path = tmp_path / "first.rrd"
    assert cli_eval.main(["--random", "--env", "SmartCarSim-v0", "--episodes", "3",
                          "--no-progress", "--vectorization", "batched", "--record-episodes",
                          "1", "--env-kwargs", "max_episode_steps=5", "--rerun",
                          str(path)]) == 0
    assert "rerun (1 episode)" in capsys.readouterr().out
    assert path.stat().st_size > 10_000
