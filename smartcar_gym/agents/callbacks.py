"""Training callbacks: atomic checkpoints, evaluation by success rate, a progress bar.

Files are written atomically (a temporary file in the same folder, then ``os.replace``), so a
run killed at any moment leaves either the previous file or the new one, never half a file.
A model ``<stem>.zip`` keeps its ``VecNormalize`` statistics in ``<stem>_vecnormalize.pkl``
(``model.zip`` in ``vecnormalize.pkl``).
"""

from __future__ import annotations

import contextlib
import json
import os
import pickle
import re
import signal
import sys
import tempfile
import threading
import time
from collections.abc import Iterator
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np
from stable_baselines3.common.base_class import BaseAlgorithm
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.evaluation import evaluate_policy
from stable_baselines3.common.vec_env import VecEnv, sync_envs_normalization

CHECKPOINT_RE = re.compile(r"^ckpt_(\d+)_steps\.zip$")


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike) -> Iterator[Path]:
    """A temporary path next to ``path`` (same suffix) that replaces ``path`` once written.

    If the body raises (or the process dies), ``path`` is left as it was.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.stem}.", suffix=path.suffix)
    os.close(fd)
    try:
        yield Path(tmp)
        with open(tmp, "rb+") as f:
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        raise


def atomic_write_bytes(path: str | os.PathLike, data: bytes) -> None:
    """Write ``data`` to ``path`` atomically."""
    with atomic_path(path) as tmp:
        tmp.write_bytes(data)


def atomic_write_text(path: str | os.PathLike, text: str) -> None:
    """Write ``text`` to ``path`` atomically."""
    atomic_write_bytes(path, text.encode())


def vecnormalize_path_for(model_path: str | os.PathLike) -> Path:
    """Where a saved model's VecNormalize statistics go (``vecnormalize.pkl`` for model.zip)."""
    model_path = Path(model_path)
    stem = model_path.name.removesuffix(".zip")
    name = "vecnormalize.pkl" if stem == "model" else f"{stem}_vecnormalize.pkl"
    return model_path.with_name(name)


def save_model_atomic(model: BaseAlgorithm, path: str | os.PathLike) -> Path:
    """Save ``model`` (and its VecNormalize statistics, if any) atomically; returns the zip path.

    Both files are written to temporary files first, then renamed: the statistics, then the
    zip. So a new zip (a checkpoint) always has its statistics beside it. When an existing pair
    is replaced (``model.zip``, ``best_model.zip``), a kill in the few milliseconds between the
    two renames leaves the new statistics beside the old model; nothing is ever half-written.
    """
    path = Path(path)
    vec_normalize = model.get_vec_normalize_env()
    with contextlib.ExitStack() as stack:  # exits (renames) in reverse order: statistics first
        tmp_zip = stack.enter_context(atomic_path(path))
        if vec_normalize is not None:
            tmp_stats = stack.enter_context(atomic_path(vecnormalize_path_for(path)))
            tmp_stats.write_bytes(pickle.dumps(vec_normalize))
        model.save(tmp_zip)
    return path


def checkpoint_path(run_dir: str | os.PathLike, num_timesteps: int) -> Path:
    """``<run_dir>/checkpoints/ckpt_<steps>_steps.zip``."""
    return Path(run_dir) / "checkpoints" / f"ckpt_{num_timesteps}_steps.zip"


def checkpoint_steps(path: str | os.PathLike) -> int:
    """The step count of a checkpoint from its name ``ckpt_<steps>_steps.zip``."""
    match = CHECKPOINT_RE.match(Path(path).name)
    if match is None:
        raise ValueError(f"{path} is not named like a checkpoint (ckpt_<steps>_steps.zip)")
    return int(match.group(1))


def replay_buffer_path_for(checkpoint: str | os.PathLike) -> Path:
    """The replay buffer saved with a checkpoint: ``ckpt_<steps>_steps_replay_buffer.pkl``."""
    checkpoint = Path(checkpoint)
    return checkpoint.with_name(checkpoint.name.removesuffix(".zip") + "_replay_buffer.pkl")


def find_latest_checkpoint(run_dir: str | os.PathLike, normalize: bool) -> Path | None:
    """The checkpoint with the most steps (with its VecNormalize file if ``normalize``)."""
    folder = Path(run_dir) / "checkpoints"
    found = []
    for path in folder.glob("ckpt_*_steps.zip") if folder.is_dir() else []:
        match = CHECKPOINT_RE.match(path.name)
        if match and (not normalize or vecnormalize_path_for(path).exists()):
            found.append((int(match.group(1)), path))
    return max(found)[1] if found else None


class CheckpointCallback(BaseCallback):
    """Save ``checkpoints/ckpt_<steps>_steps.zip`` every ``save_freq`` environment steps.

    ``save_replay_buffer`` keeps the replay buffer of SAC/TD3 with the latest checkpoint only,
    in ``ckpt_<steps>_steps_replay_buffer.pkl`` (large: it holds the whole buffer). It is
    written before the checkpoint's zip, so a checkpoint that exists has its buffer.
    """

    def __init__(self, run_dir: str | os.PathLike, save_freq: int,
                 save_replay_buffer: bool = False) -> None:
        super().__init__()
        self.run_dir = Path(run_dir)
        self.save_freq = int(save_freq)
        self.save_replay_buffer = save_replay_buffer
        self._next = 0
        self.last_path: Path | None = None

    def _init_callback(self) -> None:
        self.num_timesteps = self.model.num_timesteps  # not yet set by BaseCallback here
        if self.save_freq > 0:
            self._next = (self.num_timesteps // self.save_freq + 1) * self.save_freq

    def _on_step(self) -> bool:
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
        save_model_atomic(model, path)
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
    """

    def __init__(
        self,
        eval_env: VecEnv,
        eval_dir: str | os.PathLike,
        best_model_path: str | os.PathLike | None,
        eval_freq: int,
        n_eval_episodes: int = 20,
        eval_seed: int = 10_000,
        deterministic: bool = True,
        eval_start: int = 0,
    ) -> None:
        super().__init__()
        self.eval_env = eval_env
        self.eval_dir = Path(eval_dir)
        self.best_model_path = None if best_model_path is None else Path(best_model_path)
        self.eval_freq = int(eval_freq)
        self.n_eval_episodes = int(n_eval_episodes)
        self.eval_seed = int(eval_seed)
        self.eval_start = int(eval_start)
        self.deterministic = deterministic
        self.history: list[tuple[EvalResult, list[float], list[int], list[bool], list[float]]] = []
        self.best_score: tuple[float, float] | None = None
        self.last_result: EvalResult | None = None
        self._next = 0
        self._episode_success: list[bool] = []
        self._episode_distance: list[float] = []

    @property
    def npz_path(self) -> Path:
        """``<eval_dir>/evaluations.npz``."""
        return self.eval_dir / "evaluations.npz"

    @property
    def best_json_path(self) -> Path | None:
        """Scores of the best model, beside it."""
        return None if self.best_model_path is None else self.best_model_path.with_suffix(".json")

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
            returns = data["results"][i].tolist()
            lengths = data["ep_lengths"][i].tolist()
            successes = data["successes"][i].astype(bool).tolist()
            distances = data["final_distances"][i].tolist()
            self.history.append((
                _summarise(int(steps), returns, lengths, successes, distances),
                returns, lengths, successes, distances,
            ))
        if self.history:
            self.last_result = self.history[-1][0]
        if self.best_json_path is not None and self.best_json_path.exists():
            best = json.loads(self.best_json_path.read_text())
            self.best_score = (best["success_rate"], best["mean_reward"])

    def _on_step(self) -> bool:
        if self.eval_freq > 0 and self.num_timesteps >= self._next:
            self.evaluate()
            self._next = self._next_after(self.num_timesteps)
        return True

    def _collect(self, locals_: dict[str, Any], globals_: dict[str, Any]) -> None:
        if locals_["done"]:
            info = locals_["info"]
            self._episode_success.append(bool(info.get("is_success", False)))
            self._episode_distance.append(float(info.get("distance", np.nan)))

    def evaluate(self) -> EvalResult:
        """Run the evaluation episodes now, log and save them, update the best model."""
        if self.model.get_vec_normalize_env() is not None:
            sync_envs_normalization(self.training_env, self.eval_env)
        self.eval_env.seed(self.eval_seed)  # the same goals at every evaluation
        self._episode_success, self._episode_distance = [], []
        returns, lengths = evaluate_policy(
            self.model, self.eval_env, n_eval_episodes=self.n_eval_episodes,
            deterministic=self.deterministic, return_episode_rewards=True,
            callback=self._collect, warn=False,
        )
        result = _summarise(
            self.num_timesteps, list(returns), list(lengths), self._episode_success,
            self._episode_distance,
        )
        self.history.append(
            (result, list(returns), list(lengths), self._episode_success, self._episode_distance)
        )
        self.last_result = result
        self._save_history()
        for key in ("success_rate", "mean_reward", "mean_final_distance", "mean_ep_length"):
            self.logger.record(f"eval/{key}", getattr(result, key))
        self.logger.record("time/total_timesteps", self.num_timesteps, exclude="tensorboard")
        self.logger.dump(self.num_timesteps)
        score = (result.success_rate, result.mean_reward)
        is_best = self.best_score is None or score > self.best_score
        if self.best_model_path is not None and is_best:
            self.best_score = score
            save_model_atomic(self.model, self.best_model_path)
            atomic_write_text(self.best_json_path, json.dumps(asdict(result), indent=2) + "\n")
        return result

    def _save_history(self) -> None:
        def stack(i: int, dtype: type) -> np.ndarray:
            rows = [h[i] for h in self.history]
            width = max(len(r) for r in rows)
            fill = False if dtype is bool else np.nan
            return np.array([list(r) + [fill] * (width - len(r)) for r in rows], dtype=dtype)

        with atomic_path(self.npz_path) as tmp:
            np.savez(
                tmp,
                timesteps=np.array([h[0].timesteps for h in self.history], dtype=np.int64),
                results=stack(1, float), ep_lengths=stack(2, float), successes=stack(3, bool),
                final_distances=stack(4, float),
            )


def _summarise(steps: int, returns: list[float], lengths: list[int], successes: list[bool],
               distances: list[float]) -> EvalResult:
    return EvalResult(
        timesteps=int(steps),
        success_rate=float(np.mean(successes)) if successes else float("nan"),
        mean_reward=float(np.mean(returns)), std_reward=float(np.std(returns)),
        mean_final_distance=float(np.nanmean(distances)) if distances else float("nan"),
        mean_ep_length=float(np.mean(lengths)),
    )


class ProgressBarCallback(BaseCallback):
    """A tqdm bar over environment steps showing steps/s and the latest success rates."""

    def __init__(self, total_timesteps: int, eval_callback: SuccessEvalCallback | None = None,
                 refresh_s: float = 0.5) -> None:
        super().__init__()
        self.total_timesteps = int(total_timesteps)
        self.eval_callback = eval_callback
        self.refresh_s = refresh_s
        self.bar = None
        self._shown = 0
        self._last_refresh = 0.0

    def _on_training_start(self) -> None:
        from tqdm.auto import tqdm

        self._shown = self.num_timesteps
        self.bar = tqdm(
            total=self.total_timesteps, initial=self.num_timesteps, unit="step",
            unit_scale=True, dynamic_ncols=True, smoothing=0.05, desc="training",
        )

    def _on_step(self) -> bool:
        if self.bar is None:
            return True
        self.bar.update(self.num_timesteps - self._shown)
        self._shown = self.num_timesteps
        now = time.monotonic()
        if now - self._last_refresh >= self.refresh_s:
            self._last_refresh = now
            postfix = {}
            buffer = getattr(self.model, "ep_success_buffer", None)
            if buffer:
                postfix["train_success"] = f"{np.mean(buffer):.0%}"
            last = None if self.eval_callback is None else self.eval_callback.last_result
            if last is not None:
                postfix["eval_success"] = f"{last.success_rate:.0%}"
            self.bar.set_postfix(postfix, refresh=False)
        return True

    def _on_training_end(self) -> None:
        self.close()

    def close(self) -> None:
        """Close the bar (also after an interrupted run)."""
        if self.bar is not None:
            self.bar.close()
            self.bar = None


class StopOnSigint(BaseCallback):
    """While active (``with``), the first Ctrl-C (SIGINT) or SIGTERM makes training stop
    cleanly at the next step; ``signum`` records which.

    A KeyboardInterrupt in the middle of a ``SubprocVecEnv`` exchange would leave its pipes out
    of step, so the signal only sets ``requested`` and ``_on_step`` returns False; SB3 then
    ends ``learn()``. A second signal raises KeyboardInterrupt (stop at once).
    """

    SIGNALS = (signal.SIGINT, signal.SIGTERM)

    def __init__(self) -> None:
        super().__init__()
        self.requested = False
        self.signum: int | None = None
        self._previous: dict[int, Any] = {}

    def __enter__(self) -> StopOnSigint:
        if threading.current_thread() is threading.main_thread():
            self._previous = {s: signal.signal(s, self._handle) for s in self.SIGNALS}
        return self

    def __exit__(self, *exc: object) -> None:
        for signum, previous in self._previous.items():
            signal.signal(signum, previous)
        self._previous = {}

    def _handle(self, signum: int, frame: Any) -> None:
        if self.requested:
            raise KeyboardInterrupt
        self.requested, self.signum = True, signum
        name = "Ctrl-C" if signum == signal.SIGINT else signal.Signals(signum).name
        print(f"\n{name}: stopping after this step and saving a checkpoint "
              f"({name} again to stop at once)", file=sys.stderr)

    def _on_step(self) -> bool:
        return not self.requested


def close_vec_env(venv: VecEnv, force: bool = False) -> None:
    """Close a VecEnv; with ``force`` (after an abrupt interrupt) do not wait for pending
    worker replies and kill workers that are still alive."""
    base = venv
    while hasattr(base, "venv"):
        base = base.venv
    if force and hasattr(base, "waiting"):
        base.waiting = False  # the replies of an interrupted step may never come
    try:
        venv.close()
    except (EOFError, OSError):
        pass
    for process in getattr(base, "processes", []):
        if process.is_alive():
            process.kill()  # workers ignore SIGTERM (see env_factory.make_env)
            process.join(timeout=5)
