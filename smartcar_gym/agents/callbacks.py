"""Training callbacks: atomic checkpoints and evaluation by success rate (the progress bar and
Ctrl-C: ``run_control``).

The files are written atomically (``atomic_files``; those functions and the checkpoint names
of ``runs`` can also be imported from here). The evaluations' episodes are run by
``episodes.run_sb3_episodes`` and summarised by ``records.summarize``.
"""

from __future__ import annotations

import json
import os
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.vec_env import VecEnv, sync_envs_normalization

from smartcar_gym.agents.atomic_files import (
    atomic_path,
    atomic_write_bytes,
    atomic_write_text,
    file_mode,
    move_model_atomic,
    remove_model,
    save_model_atomic,
)
from smartcar_gym.agents.episodes import run_sb3_episodes
from smartcar_gym.agents.eval_worker import EvalWorker, Records, normalization_stats
from smartcar_gym.agents.models import vecnormalize_path_for
from smartcar_gym.agents.records import EpisodeRecord, summarize
from smartcar_gym.agents.runs import (
    CHECKPOINT_RE,
    checkpoint_info_path_for,
    checkpoint_path,
    checkpoint_steps,
    find_latest_checkpoint,
    replay_buffer_path_for,
)
from smartcar_gym.agents.vec_envs import close_vec_env

__all__ = [  # with the file functions of atomic_files and runs, imported from here before
    "CHECKPOINT_RE", "CheckpointCallback", "EvalResult", "SuccessEvalCallback", "atomic_path",
    "atomic_write_bytes", "atomic_write_text", "checkpoint_info_path_for", "checkpoint_path",
    "checkpoint_steps", "close_vec_env", "file_mode", "find_latest_checkpoint",
    "replay_buffer_path_for", "save_model_atomic", "vecnormalize_path_for",
]


class CheckpointCallback(BaseCallback):
    """Save ``checkpoints/ckpt_<steps>_steps.zip`` every ``save_freq`` environment steps.

    ``save_replay_buffer`` keeps the replay buffer of SAC/TD3 with the latest checkpoint only,
    in ``ckpt_<steps>_steps_replay_buffer.pkl`` (large: it holds the whole buffer). It is
    written before the checkpoint's zip, so a checkpoint that exists has its buffer.

    ``ckpt_<steps>_steps.json`` (also written before the zip) records the run ``segment`` and
    how many episodes each env had finished in it: the rows of ``monitor/seg<segment>_<i>``
    that came before the checkpoint. A run resumed from the checkpoint repeats the episodes
    after them, so the learning curve leaves those out.
    """

    def __init__(self, run_dir: str | os.PathLike, save_freq: int,
                 save_replay_buffer: bool = False, segment: int = 0) -> None:
        super().__init__()
        self.run_dir = Path(run_dir)
        self.save_freq = int(save_freq)
        self.save_replay_buffer = save_replay_buffer
        self.segment = int(segment)
        self.episodes: np.ndarray | None = None  # finished episodes per env, this segment
        self._next = 0
        self.last_path: Path | None = None

    def _init_callback(self) -> None:
        self.num_timesteps = self.model.num_timesteps  # not yet set by BaseCallback here
        if self.episodes is None:
            self.episodes = np.zeros(self.model.n_envs, dtype=np.int64)
        if self.save_freq > 0:
            self._next = (self.num_timesteps // self.save_freq + 1) * self.save_freq

    def _on_step(self) -> bool:
        dones = self.locals.get("dones")
        if dones is not None and self.episodes is not None:
            self.episodes += np.asarray(dones, dtype=bool)  # a Monitor row each
        if self.save_freq > 0 and self.num_timesteps >= self._next:
            self.save()
            self._next = (self.num_timesteps // self.save_freq + 1) * self.save_freq
        return True

    def save(self) -> Path:
        """Write a checkpoint at the model's current step count now."""
        model = self.model
        path = checkpoint_path(self.run_dir, model.num_timesteps)
        buffer = replay_buffer_path_for(path)
        keep_buffer = self.save_replay_buffer and getattr(model, "replay_buffer", None) is not None
        if keep_buffer:
            with atomic_path(buffer) as tmp:
                model.save_replay_buffer(tmp)
        episodes = [] if self.episodes is None else self.episodes.tolist()
        info = checkpoint_info_path_for(path)
        atomic_write_text(info, json.dumps({"segment": self.segment,
                                            "monitor_episodes": episodes}) + "\n")
        try:
            save_model_atomic(model, path)
        except BaseException:
            if not path.exists():  # no checkpoint: nothing to describe
                info.unlink(missing_ok=True)
            raise
        if keep_buffer:
            for old in path.parent.glob("*replay_buffer.pkl"):
                if old != buffer:
                    old.unlink(missing_ok=True)
        self.last_path = path
        return path


@dataclass
class EvalResult:
    """One evaluation: its step count, success rate and mean return / final distance / length."""

    timesteps: int
    success_rate: float
    mean_reward: float
    std_reward: float
    mean_final_distance: float
    mean_ep_length: float


class SuccessEvalCallback(BaseCallback):
    """Evaluate every ``eval_freq`` steps on the same seeded episodes; keep the best model.

    Evaluations run at the multiples of ``eval_freq`` from ``eval_start`` steps on.

    Logs ``eval/success_rate``, ``eval/mean_final_distance`` (m), ``eval/mean_reward`` and
    ``eval/mean_ep_length``; appends to ``<eval_dir>/evaluations.npz`` (zoo's arrays
    ``timesteps, results, ep_lengths, successes`` plus ``final_distances``). The best model (by
    success rate, then mean return) is saved to ``best_model_path`` with its statistics, and its
    scores to ``best_model.json``. The eval env's normalisation statistics are synced from the
    training env before each evaluation (frozen, raw rewards).

    ``eval_env`` may be an ``EvalWorker`` (``eval_async``): each evaluation is then sent to it
    with a snapshot of the model (``<eval_dir>/pending_<steps>.zip``) and training goes on; its
    result is recorded, as above, at the first step after it comes, or in ``drain()``.
    """

    def __init__(
        self,
        eval_env: VecEnv | EvalWorker,
        eval_dir: str | os.PathLike,
        best_model_path: str | os.PathLike | None,
        eval_freq: int,
        n_eval_episodes: int = 20,
        eval_seed: int = 10_000,
        deterministic: bool = True,
        eval_start: int = 0,
    ) -> None:
        super().__init__()
        self.worker = eval_env if isinstance(eval_env, EvalWorker) else None
        self.eval_env = None if self.worker is not None else eval_env
        self.eval_dir = Path(eval_dir)
        self.best_model_path = None if best_model_path is None else Path(best_model_path)
        self.eval_freq = int(eval_freq)
        self.n_eval_episodes = int(n_eval_episodes)
        self.eval_seed = int(eval_seed)
        self.eval_start = int(eval_start)
        self.deterministic = deterministic
        self.history: list[tuple[EvalResult, list[EpisodeRecord]]] = []
        self.best_score: tuple[float, float] | None = None
        self.last_result: EvalResult | None = None
        self._next = 0

    @property
    def npz_path(self) -> Path:
        """``<eval_dir>/evaluations.npz``."""
        return self.eval_dir / "evaluations.npz"

    @property
    def best_json_path(self) -> Path | None:
        """Scores of the best model, beside it."""
        return None if self.best_model_path is None else self.best_model_path.with_suffix(".json")

    def snapshot_path(self, steps: int) -> Path:
        """Where an asynchronous evaluation keeps its model until its result comes."""
        return self.eval_dir / f"pending_{int(steps)}.zip"

    def _init_callback(self) -> None:
        self.num_timesteps = self.model.num_timesteps  # not yet set by BaseCallback here
        self.eval_dir.mkdir(parents=True, exist_ok=True)
        self._restore()
        if self.eval_freq > 0:
            self._next = self._next_after(self.num_timesteps)

    def _next_after(self, steps: int) -> int:
        """The first multiple of ``eval_freq`` after ``steps`` and at or after ``eval_start``."""
        first = -(-self.eval_start // self.eval_freq) * self.eval_freq
        return max((steps // self.eval_freq + 1) * self.eval_freq, first)

    def _restore(self) -> None:
        """On resume: keep earlier evaluations up to the current step and the best score."""
        if self.history or not self.npz_path.exists():
            return
        data = np.load(self.npz_path)
        for i, steps in enumerate(data["timesteps"]):
            if steps > self.num_timesteps:
                continue
            columns = zip(data["results"][i].tolist(), data["ep_lengths"][i].tolist(),
                          data["successes"][i].astype(bool).tolist(),
                          data["final_distances"][i].tolist(), strict=True)
            records = [EpisodeRecord(episode=j, seed=None, success=success, episode_return=ret,
                                     length=length, time_to_goal_s=None,
                                     final_distance_m=distance, final_odom_error_m=np.nan,
                                     goal=(np.nan, np.nan))
                       for j, (ret, length, success, distance) in enumerate(columns)]
            self.history.append((_summarise(int(steps), records), records))
        if self.history:
            self.last_result = self.history[-1][0]
        if self.best_json_path is not None and self.best_json_path.exists():
            best = json.loads(self.best_json_path.read_text())
            self.best_score = (best["success_rate"], best["mean_reward"])

    def _on_step(self) -> bool:
        if self.worker is not None:
            for steps, records in self.worker.results():
                self._record(steps, records)
        if self.eval_freq > 0 and self.num_timesteps >= self._next:
            self.evaluate()
            self._next = self._next_after(self.num_timesteps)
        return True

    def evaluate(self) -> EvalResult | None:
        """Run the evaluation episodes now, log and save them, update the best model.

        With an ``EvalWorker``: send them to it and return None (``drain`` waits for them)."""
        if self.worker is not None:
            if self.best_model_path is not None:
                save_model_atomic(self.model, self.snapshot_path(self.num_timesteps))
            self.worker.submit(self.num_timesteps, self.model.policy,
                               normalization_stats(self.training_env), self.n_eval_episodes,
                               self.eval_seed, self.deterministic)
            return None
        if self.model.get_vec_normalize_env() is not None:
            sync_envs_normalization(self.training_env, self.eval_env)
        records = run_sb3_episodes(self.model, self.eval_env, self.n_eval_episodes,
                                   self.eval_seed, self.deterministic)
        return self._record(self.num_timesteps, records)

    def drain(self) -> None:
        """Wait for the evaluations sent to the ``EvalWorker`` and record them (no worker:
        nothing to wait for)."""
        if self.worker is not None:
            for steps, records in self.worker.wait():
                self._record(steps, records)

    def discard_pending(self) -> None:
        """Remove the snapshots of evaluations whose results will not come (a stopped run)."""
        for path in self.eval_dir.glob("pending_*.zip"):
            remove_model(path)

    def _record(self, steps: int, records: Records) -> EvalResult:
        """Log and save one evaluation's records; keep its model if it is the best."""
        records = list(records)
        result = _summarise(steps, records)
        self.history.append((result, records))
        self.last_result = result
        self._save_history()
        for key in ("success_rate", "mean_reward", "mean_final_distance", "mean_ep_length"):
            self.logger.record(f"eval/{key}", getattr(result, key))
        self.logger.record("time/total_timesteps", steps, exclude="tensorboard")
        self.logger.dump(steps)
        score = (result.success_rate, result.mean_reward)
        is_best = self.best_score is None or score > self.best_score
        snapshot = None if self.worker is None else self.snapshot_path(steps)
        if self.best_model_path is not None and is_best:
            self.best_score = score
            if snapshot is None:
                save_model_atomic(self.model, self.best_model_path)
            else:
                move_model_atomic(snapshot, self.best_model_path)
            atomic_write_text(self.best_json_path, json.dumps(asdict(result), indent=2) + "\n")
        elif snapshot is not None:
            remove_model(snapshot)
        return result

    def _save_history(self) -> None:
        def stack(field: str, dtype: type) -> np.ndarray:
            rows = [[getattr(r, field) for r in records] for _, records in self.history]
            width = max(len(r) for r in rows)
            fill = False if dtype is bool else np.nan
            return np.array([r + [fill] * (width - len(r)) for r in rows], dtype=dtype)

        with atomic_path(self.npz_path) as tmp:
            np.savez(
                tmp,
                timesteps=np.array([h[0].timesteps for h in self.history], dtype=np.int64),
                results=stack("episode_return", float), ep_lengths=stack("length", float),
                successes=stack("success", bool),
                final_distances=stack("final_distance_m", float),
            )


def _summarise(steps: int, records: list[EpisodeRecord]) -> EvalResult:
    """One evaluation's ``EvalResult``: ``records.summarize``'s figures, under zoo's names."""
    summary = summarize(records)
    return EvalResult(
        timesteps=int(steps), success_rate=summary["success_rate"],
        mean_reward=summary["mean_return"], std_reward=summary["std_return"],
        mean_final_distance=summary["mean_final_distance_m"],
        mean_ep_length=summary["mean_length"],
    )
