"""The learning curve's episodes after resumes: the episodes that a resumed run repeats (played
after the checkpoint it went back to) are counted once."""

import json

import pytest
import yaml

from smartcar_gym.agents.plots import load_training_episodes, plot_learning_curve

EPISODE = 32  # steps per episode in these runs: both envs finish one every 32 steps


def _monitor(run_dir, segment, rank, n_episodes, t0=0.0):
    """A Monitor file of ``n_episodes`` episodes of 32 steps, one every 3.2 s from ``t0``."""
    path = run_dir / "monitor" / f"seg{segment}_{rank}.monitor.csv"
    path.parent.mkdir(parents=True, exist_ok=True)
    rows = [f"{segment + 0.01 * i},{EPISODE},{3.2 * (i + 1) + 0.01 * rank},0.0"
            for i in range(n_episodes)]
    path.write_text(json.dumps({"t_start": t0, "env_id": "SmartCar-v0"}) + "\n"
                    "r,l,t,is_success\n" + "".join(row + "\n" for row in rows))


def _config(run_dir, resumes):
    (run_dir / "config.yaml").write_text(yaml.safe_dump({"algo": "ppo", "resumes": resumes}))


def _resume(from_timesteps, kept=None):
    record = {"from_checkpoint": f"checkpoints/ckpt_{from_timesteps}_steps.zip",
              "from_timesteps": from_timesteps}
    if kept is not None:
        record["kept_episodes"] = {"segment": kept[0], "per_env": kept[1]}
    return record


@pytest.mark.parametrize("kept", [(0, [4, 4]), None])  # None: a resume of an older version
def test_a_run_killed_after_its_checkpoint_is_counted_once(kept, tmp_path):
    """Checkpoint at 256 steps (4 episodes per env), killed at 384 (6 per env), resumed from
    256 up to 512."""
    _monitor(tmp_path, 0, 0, 6)
    _monitor(tmp_path, 0, 1, 6)
    _monitor(tmp_path, 1, 0, 4, t0=100.0)
    _monitor(tmp_path, 1, 1, 4, t0=100.0)
    _config(tmp_path, [_resume(256, kept)])
    episodes = load_training_episodes(tmp_path)
    assert episodes["steps"].tolist() == list(range(EPISODE, 512 + 1, EPISODE))
    # the first 8 episodes are the first run's, up to the checkpoint; then the resumed run's
    assert episodes["r"].round(2).tolist() == [0.0, 0.0, 0.01, 0.01, 0.02, 0.02, 0.03, 0.03,
                                               1.0, 1.0, 1.01, 1.01, 1.02, 1.02, 1.03, 1.03]
    assert (tmp_path / "monitor" / "seg0_0.monitor.csv").read_text().count("\n") == 8  # kept


def test_a_resume_that_died_before_its_first_checkpoint_is_left_out(tmp_path):
    """Checkpoint at 256 (4 per env), killed at 384; resumed from 256 and killed at 320
    before a checkpoint; resumed from 256 again up to 512."""
    for rank in (0, 1):
        _monitor(tmp_path, 0, rank, 6)
        _monitor(tmp_path, 1, rank, 1, t0=100.0)
        _monitor(tmp_path, 2, rank, 4, t0=200.0)
    _config(tmp_path, [_resume(256, (0, [4, 4])), _resume(256, (0, [4, 4]))])
    episodes = load_training_episodes(tmp_path)
    assert episodes["steps"].tolist() == list(range(EPISODE, 512 + 1, EPISODE))
    assert sorted(set(episodes["r"].round(0))) == [0.0, 2.0]  # nothing from segment 1
    assert plot_learning_curve(tmp_path).read_bytes()[:4] == b"\x89PNG"


def test_uneven_envs_keep_exactly_the_episodes_before_the_checkpoint(tmp_path):
    _monitor(tmp_path, 0, 0, 5)
    _monitor(tmp_path, 0, 1, 3)
    _monitor(tmp_path, 1, 0, 2, t0=100.0)
    _monitor(tmp_path, 1, 1, 2, t0=100.0)
    _config(tmp_path, [_resume(192, (0, [4, 2]))])
    episodes = load_training_episodes(tmp_path)
    assert len(episodes) == 4 + 2 + 2 + 2
    assert episodes["steps"].tolist()[:6] == list(range(EPISODE, 192 + 1, EPISODE))
