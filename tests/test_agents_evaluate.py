"""smartcar-eval and evaluate_policy_episodes on SmartCar-v0: files, seeding, determinism."""

import json
import math
import re
import shutil

import gymnasium as gym
import imageio.v3 as iio
import numpy as np
import pytest

from smartcar_gym.agents import cli_eval, cli_train
from smartcar_gym.agents.episodes import evaluate_policy_episodes
from smartcar_gym.agents.export import export_run
from smartcar_gym.agents.models import find_run_config, find_vecnormalize, load_model
from smartcar_gym.agents.plots import plot_trajectories
from smartcar_gym.agents.records import EpisodeRecord, summarize
from smartcar_gym.agents.video import record_video

SHORT = {"max_episode_steps": 30}


@pytest.fixture(scope="module")
def tiny_run(tmp_path_factory):
    """A PPO model trained for 128 steps (one env in-process, no evaluation)."""
    run_dir = tmp_path_factory.mktemp("eval") / "tiny"
    argv = ["--n-envs", "1", "--timesteps", "128", "--run-dir", str(run_dir), "--eval-freq",
            "0", "--no-progress", "--env-kwargs", "max_episode_steps=30", "--hyperparams",
            "n_steps=64", "batch_size=64", "n_epochs=1", "policy_kwargs=dict(net_arch=[8])"]
    assert cli_train.main(argv) == 0
    return run_dir


class GoToGoal:
    """A scripted policy: turn towards the goal seen in the observation, then drive to it."""

    def predict(self, obs, deterministic=True):
        obs = np.atleast_2d(obs)
        bearing = np.arctan2(obs[:, 15], obs[:, 14])
        v = np.clip(2.0 * obs[:, 14], -1, 1) * (np.abs(bearing) < 0.8)
        return np.stack([v, np.clip(1.5 * bearing, -1, 1)], axis=1).astype(np.float32), None


@pytest.mark.slow
def test_eval_cli_prints_and_writes_json_gif_and_plot(tiny_run, tmp_path, capsys):
    out = tmp_path / "out"
    argv = ["--model", str(tiny_run / "model.zip"), "--episodes", "3", "--n-envs", "2",
            "--seed", "7", "--json", str(out / "eval.json"), "--video", str(out / "run.gif"),
            "--video-episodes", "1", "--plot", str(out / "paths.png"), "--no-progress",
            "--env-kwargs", "render_width=64", "render_height=48"]
    assert cli_eval.main(argv) == 0
    printed = capsys.readouterr().out
    for text in ("success rate", "mean return", "mean time to goal", "mean final distance",
                 "odometry error", "seeds 7..9"):
        assert text in printed

    data = json.loads((out / "eval.json").read_text())
    assert (data["algo"], data["env"], data["episodes"], data["n_envs"]) == ("ppo", "SmartCar-v0",
                                                                            3, 2)
    # the run's env kwargs are used, extended by --env-kwargs
    assert data["env_kwargs"] == {"max_episode_steps": 30, "render_width": 64,
                                  "render_height": 48}
    assert data["normalizer"] == str(tiny_run / "vecnormalize.pkl")
    assert data["normalizer_source"].endswith(f"(that of the smartcar-train run {tiny_run})")
    assert data["warnings"] == []
    for key in ("success_rate", "mean_return", "mean_time_to_goal_s", "mean_final_distance_m",
                "mean_final_odom_error_m"):
        assert key in data
    records = data["episode_records"]
    assert [r["episode"] for r in records] == [0, 1, 2]
    assert [r["seed"] for r in records] == [7, 8, 9]
    assert all(r["length"] <= 30 and r["final_distance_m"] >= 0 for r in records)

    # one frame per step plus the reset frame and a short pause (Pillow merges identical ones)
    n_frames = int(re.search(r"video \((\d+) frames\)", printed).group(1))
    assert n_frames >= records[0]["length"] + 1
    frames = iio.imread(out / "run.gif", index=None)
    assert frames.ndim == 4 and frames.shape[1:] == (48, 64, 3)
    assert (out / "paths.png").read_bytes()[:4] == b"\x89PNG"


def test_mp4_video(tiny_run, tmp_path):
    model = load_model(tiny_run / "model.zip", "ppo")
    n = record_video(model, tmp_path / "run.mp4", n_episodes=1, seed=0,
                     env_kwargs={**SHORT, "render_width": 64, "render_height": 48},
                     vecnormalize_path=tiny_run / "vecnormalize.pkl")
    assert n > 1
    assert iio.improps(tmp_path / "run.mp4", plugin="pyav" if _has_av() else None).shape[0] >= 1


def _has_av():
    try:
        import av  # noqa: F401
    except ImportError:
        return False
    return True


@pytest.mark.slow
def test_same_seed_same_records_whatever_the_number_of_envs(tiny_run):
    model = load_model(tiny_run / "model.zip", "ppo")
    kwargs = dict(n_episodes=5, seed=11, env_kwargs=SHORT,
                  vecnormalize_path=tiny_run / "vecnormalize.pkl")
    one = [r.to_dict(include_paths=True) for r in evaluate_policy_episodes(model, **kwargs)]
    again = [r.to_dict(include_paths=True) for r in evaluate_policy_episodes(model, **kwargs)]
    two = [r.to_dict(include_paths=True)
           for r in evaluate_policy_episodes(model, n_envs=2, **kwargs)]
    assert one == again == two
    assert [r["seed"] for r in one] == [11, 12, 13, 14, 15]
    assert len({tuple(r["goal"]) for r in one}) == 5
    other = evaluate_policy_episodes(model, **{**kwargs, "seed": 12, "n_episodes": 1})
    assert other[0].to_dict(include_paths=True) == {**one[1], "episode": 0}


@pytest.mark.slow
def test_scripted_policy_episodes_end_at_the_goal_or_the_time_limit():
    records = evaluate_policy_episodes(GoToGoal(), n_episodes=6, n_envs=3, seed=3,
                                       env_kwargs={"goal_range": [0.3, 0.5]})
    assert len(records) == 6
    for r in records:
        assert len(r.path) == len(r.odom_path) == r.length + 1
        assert np.allclose(r.path[0], 0.0, atol=1e-3) and np.allclose(r.odom_path[0], 0.0)
        assert 0.3 <= math.hypot(*r.goal) <= 0.5
        assert r.final_distance_m == pytest.approx(math.dist(r.path[-1], r.goal), abs=1e-6)
        assert r.final_odom_error_m == pytest.approx(math.dist(r.path[-1], r.odom_path[-1]),
                                                     abs=1e-6)
        if r.success:
            assert r.final_distance_m < 0.1 and r.time_to_goal_s == pytest.approx(0.1 * r.length)
        else:
            assert r.length == 200 and r.time_to_goal_s is None


def _record(i, success, length):
    path = np.array([[0.0, 0.0], [0.5, 0.1], [1.0, 0.0 if success else 0.3]])
    return EpisodeRecord(
        episode=i, seed=i, success=success, episode_return=10.0 * success, length=length,
        time_to_goal_s=0.1 * length if success else None,
        final_distance_m=0.05 if success else 0.3, final_odom_error_m=0.02, goal=(1.0, 0.0),
        path=path, odom_path=path * 1.05,
    )


def test_summary_and_trajectory_plot(tmp_path):
    records = [_record(0, True, 20), _record(1, False, 200), _record(2, True, 40)]
    summary = summarize(records)
    assert summary["success_rate"] == pytest.approx(2 / 3)
    assert summary["mean_time_to_goal_s"] == pytest.approx(3.0)  # successes only
    assert summary["mean_final_distance_m"] == pytest.approx((0.05 + 0.3 + 0.05) / 3)
    assert summary["mean_return"] == pytest.approx(20 / 3)
    assert summarize([_record(0, False, 200)])["mean_time_to_goal_s"] is None
    assert json.loads(json.dumps(records[1].to_dict()))["final_pose"] == [1.0, 0.3]
    out = plot_trajectories(records * 7, tmp_path / "paths.png")  # capped at 16 panels
    assert out.read_bytes()[:4] == b"\x89PNG"


@pytest.mark.parametrize("n", [1, 2, 4, 16])
def test_trajectory_plot_has_room_for_its_title_and_legend(n, tmp_path):
    """One 3-inch panel (270 px) could show neither the six-entry legend nor a long title."""
    title = "policy.zip on SmartCar-v0: 100% success over 100 episodes (first 16 shown)"
    out = plot_trajectories([_record(i, i % 2 == 0, 20) for i in range(n)],
                            tmp_path / "paths.png", title=title)
    height, width = iio.imread(out).shape[:2]
    assert width >= 450 and height >= 300


def test_a_model_for_another_observation_shape_is_refused():
    class OldModel:
        observation_space = gym.spaces.Box(-1, 1, (7,))

    with pytest.raises(ValueError, match=r"expects observations of shape \(7,\).*retrain"):
        evaluate_policy_episodes(OldModel(), n_episodes=1)


def test_model_files_are_found_next_to_the_model(tiny_run):
    assert find_vecnormalize(tiny_run / "model.zip") == tiny_run / "vecnormalize.pkl"
    [checkpoint] = (tiny_run / "checkpoints").glob("ckpt_*_steps.zip")
    assert find_vecnormalize(checkpoint).name == checkpoint.stem + "_vecnormalize.pkl"
    assert find_run_config(checkpoint)["algo"] == "ppo"


@pytest.mark.slow
def test_export_packages_a_run_that_smartcar_eval_can_load(tiny_run, tmp_path, capsys):
    provenance = export_run(tiny_run, tmp_path / "pretrained", episodes=2)
    names = sorted(p.name for p in (tmp_path / "pretrained").iterdir())
    assert names == ["policy.zip", "provenance.json", "vecnormalize.pkl"]
    assert (tmp_path / "pretrained" / "policy.zip").stat().st_size < 1_000_000
    for key in ("command", "seed", "timesteps", "wall_time_s", "evaluation"):
        assert provenance[key] is not None
    assert provenance["evaluation"]["episodes"] == 2
    assert 0.0 <= provenance["evaluation"]["success_rate"] <= 1.0
    assert provenance["selected_by_eval"] is None  # model.zip: the last one, not a selection
    # algo and env kwargs come from provenance.json beside the model
    argv = ["--model", str(tmp_path / "pretrained" / "policy.zip"), "--episodes", "1",
            "--no-progress", "--json", str(tmp_path / "e.json")]
    assert cli_eval.main(argv) == 0
    data = json.loads((tmp_path / "e.json").read_text())
    assert data["algo"] == "ppo" and data["env_kwargs"] == SHORT


def test_random_baseline_is_seeded_and_writes_a_short_gif(tmp_path, capsys):
    out = []
    for _ in range(2):
        path = tmp_path / "random.json"
        assert cli_eval.main(["--random", "--episodes", "2", "--seed", "5", "--no-progress",
                     "--json", str(path), "--env-kwargs", "max_episode_steps=20"]) == 0
        out.append(json.loads(path.read_text()))
    assert out[0]["algo"] == "random" and out[0]["success_rate"] == 0.0
    returns = [[r["episode_return"] for r in o["episode_records"]] for o in out]
    assert returns[0] == returns[1]  # the same seed, the same random actions
    assert [r["length"] for r in out[0]["episode_records"]] == [20, 20]
    gif = tmp_path / "random.gif"
    assert cli_eval.main(["--random", "--episodes", "1", "--no-progress", "--video", str(gif),
                 "--video-episodes", "1", "--env-kwargs", "max_episode_steps=10",
                 "render_width=160", "render_height=120"]) == 0
    frames = iio.imread(gif)  # pillow merges repeated frames, so count only a few
    assert frames.shape[1:] == (120, 160, 3) and frames.shape[0] >= 5
    assert "random-policy" in capsys.readouterr().out


def test_export_of_the_best_model_records_the_evaluation_that_selected_it(tiny_run, tmp_path):
    run_dir = tmp_path / "run"
    shutil.copytree(tiny_run, run_dir)
    shutil.copyfile(run_dir / "model.zip", run_dir / "best_model.zip")
    shutil.copyfile(run_dir / "vecnormalize.pkl", run_dir / "best_model_vecnormalize.pkl")
    selected = {"timesteps": 96, "success_rate": 0.5, "mean_reward": 1.25}
    (run_dir / "best_model.json").write_text(json.dumps(selected))
    provenance = export_run(run_dir, tmp_path / "pretrained", "best_model.zip", episodes=1)
    assert provenance["selected_by_eval"] == selected
    assert provenance["source"] == "run/best_model.zip"

