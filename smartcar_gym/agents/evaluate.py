"""Evaluate a trained policy on seeded episodes: metrics, JSON, video and trajectory plot.

``evaluate_policy_episodes`` is the reusable part (tests and the CI regression gate call it);
``main`` is ``smartcar-eval``::

    smartcar-eval --pretrained --episodes 100 --n-envs 4 --video smartcar.gif --plot paths.png
    smartcar-eval --model runs/ppo_SmartCar-v0_s0/model.zip --json results.json

Episode ``i`` is reset with seed ``seed + i`` in whichever worker runs it, and actions are
computed one observation at a time, so the per-episode results do not depend on ``n_envs``.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import math
import os
import pickle
import sys
import zipfile
from collections.abc import Iterator, Sequence
from dataclasses import asdict, dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import yaml

from smartcar_gym.agents.env_factory import EnvSetupError, check_env, make_env
from smartcar_gym.agents.hyperparams import (
    ALGOS,
    key_value_arg,
    output_path_error,
    positive_int_arg,
)

DEFAULT_ENV_ID = "SmartCar-v0"
PRETRAINED_MODEL = "ppo_smartcar.zip"


@dataclass
class EpisodeRecord:
    """One evaluation episode. Positions are ground-truth (``path``) or odometry, in metres."""

    episode: int
    seed: int
    success: bool
    episode_return: float
    length: int
    time_to_goal_s: float | None
    final_distance_m: float
    final_odom_error_m: float
    goal: tuple[float, float]
    path: np.ndarray = field(repr=False)
    odom_path: np.ndarray = field(repr=False)

    def to_dict(self, include_paths: bool = False) -> dict[str, Any]:
        """JSON-ready fields (paths as lists of [x, y] only if ``include_paths``)."""
        data = asdict(self)
        data["goal"] = [float(g) for g in self.goal]
        data["final_pose"] = np.asarray(self.path)[-1].tolist()
        data["final_odom_pose"] = np.asarray(self.odom_path)[-1].tolist()
        for key in ("path", "odom_path"):
            data[key] = np.asarray(data[key]).tolist() if include_paths else None
            if not include_paths:
                del data[key]
        return data


def summarize(records: Sequence[EpisodeRecord]) -> dict[str, float | int | None]:
    """Success rate, mean return, mean time to goal (s, successes only), distances (m)."""
    if not records:
        raise ValueError("no episodes to summarize")
    times = [r.time_to_goal_s for r in records if r.success]
    returns = np.array([r.episode_return for r in records])
    return {
        "episodes": len(records),
        "success_rate": float(np.mean([r.success for r in records])),
        "mean_return": float(returns.mean()),
        "std_return": float(returns.std()),
        "mean_time_to_goal_s": float(np.mean(times)) if times else None,
        "mean_final_distance_m": float(np.mean([r.final_distance_m for r in records])),
        "mean_final_odom_error_m": float(np.mean([r.final_odom_error_m for r in records])),
        "mean_length": float(np.mean([r.length for r in records])),
    }


class ObsNormalizer:
    """Applies saved ``VecNormalize`` observation statistics (frozen) to raw observations."""

    def __init__(self, vecnormalize_path: str | os.PathLike) -> None:
        with open(vecnormalize_path, "rb") as f:
            self.vec_normalize = pickle.load(f)

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        return self.vec_normalize.normalize_obs(obs)


def _vector_env(env_id: str, n_envs: int, env_kwargs: dict[str, Any]) -> gym.vector.VectorEnv:
    fns = [_EnvFn(env_id, env_kwargs) for _ in range(n_envs)]
    mode = gym.vector.AutoresetMode.DISABLED
    if n_envs == 1:
        return gym.vector.SyncVectorEnv(fns, autoreset_mode=mode)
    return gym.vector.AsyncVectorEnv(fns, autoreset_mode=mode, context="forkserver")


@dataclass
class _EnvFn:
    """A picklable env constructor for AsyncVectorEnv workers."""

    env_id: str
    env_kwargs: dict[str, Any]

    def __call__(self) -> gym.Env:
        return make_env(self.env_id, self.env_kwargs)


class RandomPolicy:
    """Uniform random actions in [-1, 1]^2, seeded: a baseline (and the README's GIF)."""

    observation_space = None

    def __init__(self, seed: int = 0) -> None:
        self.action_space = gym.spaces.Box(-1.0, 1.0, (2,), dtype=np.float32)
        self.action_space.seed(seed)

    def predict(self, obs: np.ndarray, deterministic: bool = True) -> tuple[np.ndarray, None]:
        """One sampled action per observation in the batch."""
        batch = np.asarray(obs).reshape(-1, np.asarray(obs).shape[-1])
        return np.stack([self.action_space.sample() for _ in batch]), None


def _predict(model: Any, obs: np.ndarray, normalizer: ObsNormalizer | None,
             deterministic: bool) -> np.ndarray:
    """The action for one observation (a batch of one, so results do not depend on batching)."""
    batch = obs[None].astype(np.float32)
    if normalizer is not None:
        batch = normalizer(batch)
    action, _ = model.predict(batch, deterministic=deterministic)
    return np.asarray(action, dtype=np.float32).reshape(-1)


def evaluate_policy_episodes(
    model: Any,
    env_id: str = DEFAULT_ENV_ID,
    n_episodes: int = 100,
    n_envs: int = 1,
    seed: int = 0,
    env_kwargs: dict[str, Any] | None = None,
    deterministic: bool = True,
    vecnormalize_path: str | os.PathLike | None = None,
    progress: bool = False,
) -> list[EpisodeRecord]:
    """Run ``n_episodes`` complete episodes over ``n_envs`` envs; episode i uses seed seed+i.

    ``model`` is anything with SB3's ``predict(obs, deterministic=...)``; observations are
    normalised with the ``VecNormalize`` statistics at ``vecnormalize_path`` if given. Envs
    run in worker processes when ``n_envs > 1`` (so call it under ``if __name__ ==
    "__main__":`` in a script). Records are returned in episode order. Sampled actions
    (``deterministic=False``) are reproducible for the same ``seed`` and ``n_envs``.
    """
    if n_episodes < 1 or n_envs < 1:
        raise ValueError(f"n_episodes and n_envs must be >= 1, got {n_episodes}, {n_envs}")
    normalizer = ObsNormalizer(vecnormalize_path) if vecnormalize_path is not None else None
    if not deterministic and hasattr(model, "set_random_seed"):
        model.set_random_seed(seed)
    n_slots = min(n_envs, n_episodes)
    envs = _vector_env(env_id, n_slots, dict(env_kwargs or {}))
    try:
        _check_spaces(model, envs.single_observation_space, env_id)
    except ObservationShapeError:
        envs.close()
        raise
    step_s = 1.0 / float(envs.metadata.get("render_fps") or 10)
    records: list[EpisodeRecord] = []
    bar = None
    if progress:
        from tqdm.auto import tqdm

        bar = tqdm(total=n_episodes, unit="episode", desc="evaluating", dynamic_ncols=True)
    try:
        episode_of = list(range(n_slots))
        obs, info = envs.reset(seed=[seed + i for i in range(n_slots)])
        goals = _goals(envs, range(n_slots))
        tracks = [_Track(i, seed + i, goals[i], info, i) for i in range(n_slots)]
        next_episode = n_slots
        while any(e is not None for e in episode_of):
            actions = np.zeros((n_slots, *envs.single_action_space.shape), dtype=np.float32)
            for slot, episode in enumerate(episode_of):
                if episode is not None:
                    actions[slot] = _predict(model, obs[slot], normalizer, deterministic)
            obs, reward, terminated, truncated, info = envs.step(actions)
            reset_mask = np.zeros(n_slots, dtype=bool)
            for slot, episode in enumerate(episode_of):
                if episode is None:
                    continue
                track = tracks[slot]
                track.add(float(reward[slot]), info, slot)
                if terminated[slot] or truncated[slot]:
                    records.append(track.record(step_s))
                    if bar is not None:
                        bar.update(1)
                    if next_episode < n_episodes:
                        episode_of[slot] = next_episode
                        next_episode += 1
                        reset_mask[slot] = True
                    else:
                        episode_of[slot] = None
            if reset_mask.any():
                seeds = [seed + episode_of[s] if m else None for s, m in enumerate(reset_mask)]
                new_obs, new_info = envs.reset(seed=seeds, options={"reset_mask": reset_mask})
                slots = np.flatnonzero(reset_mask)
                goals = _goals(envs, slots)
                for slot in slots:
                    obs[slot] = new_obs[slot]
                    tracks[slot] = _Track(
                        episode_of[slot], seed + episode_of[slot], goals[slot], new_info, slot
                    )
    finally:
        if bar is not None:
            bar.close()
        envs.close()
    return sorted(records, key=lambda r: r.episode)


class ObservationShapeError(ValueError):
    """The model was trained on observations of another shape than the env's."""


def _check_spaces(model: Any, space: gym.spaces.Space, env_id: str) -> None:
    """A clear error when the model was trained on observations of another shape."""
    expected = getattr(getattr(model, "observation_space", None), "shape", None)
    if expected is not None and tuple(expected) != tuple(space.shape):
        raise ObservationShapeError(
            f"the model expects observations of shape {tuple(expected)} but {env_id} gives "
            f"{tuple(space.shape)}: the env changed since the model was trained; retrain it "
            "(see the README, 'Training')"
        )


def _goals(envs: gym.vector.VectorEnv, slots: Any) -> dict[int, tuple[float, float]]:
    """The goal (x, y) of the given sub-envs (NaN if the env does not expose ``goal``)."""
    try:
        goals = envs.get_attr("goal")
    except AttributeError:
        return {int(s): (math.nan, math.nan) for s in slots}
    return {int(s): tuple(float(v) for v in np.asarray(goals[int(s)])[:2]) for s in slots}


class _Track:
    """Accumulates one episode of one sub-env."""

    def __init__(self, episode: int, seed: int, goal: tuple[float, float],
                 reset_info: dict[str, Any], slot: int) -> None:
        self.episode, self.seed, self.goal = episode, seed, goal
        self.ret, self.length = 0.0, 0
        self.path = [np.asarray(reset_info["pose"][slot][:2], dtype=float)]
        self.odom = [np.asarray(reset_info["odom_pose"][slot][:2], dtype=float)]
        self.last: dict[str, Any] = {}

    def add(self, reward: float, info: dict[str, Any], slot: int) -> None:
        self.ret += reward
        self.length += 1
        self.path.append(np.asarray(info["pose"][slot][:2], dtype=float))
        self.odom.append(np.asarray(info["odom_pose"][slot][:2], dtype=float))
        self.last = {k: info[k][slot] for k in ("is_success", "distance", "odom_error")}

    def record(self, step_s: float) -> EpisodeRecord:
        success = bool(self.last["is_success"])
        return EpisodeRecord(
            episode=self.episode, seed=self.seed, success=success,
            episode_return=self.ret, length=self.length,
            time_to_goal_s=self.length * step_s if success else None,
            final_distance_m=float(self.last["distance"]),
            final_odom_error_m=float(self.last["odom_error"]),
            goal=self.goal, path=np.array(self.path), odom_path=np.array(self.odom),
        )


def record_video(
    model: Any,
    out_path: str | os.PathLike,
    env_id: str = DEFAULT_ENV_ID,
    n_episodes: int = 3,
    seed: int = 0,
    env_kwargs: dict[str, Any] | None = None,
    deterministic: bool = True,
    vecnormalize_path: str | os.PathLike | None = None,
) -> int:
    """Render episodes 0..n-1 (seeds seed+i, as in the evaluation) to a .gif or .mp4.

    Returns the number of frames written (mp4 through ``imageio-ffmpeg``, a dependency).
    """
    import imageio.v3 as iio

    out_path = Path(out_path)
    suffix = out_path.suffix.lower()
    if suffix not in (".gif", ".mp4"):
        raise ValueError(f"video file must end in .gif or .mp4, got {out_path.name!r}")
    normalizer = ObsNormalizer(vecnormalize_path) if vecnormalize_path is not None else None
    env = make_env(env_id, {**(env_kwargs or {}), "render_mode": "rgb_array"})
    fps = float(env.metadata.get("render_fps") or 10)
    frames = []
    try:
        for i in range(n_episodes):
            obs, _ = env.reset(seed=seed + i)
            frames.append(env.render())
            done = False
            while not done:
                action = _predict(model, obs, normalizer, deterministic)
                obs, _, terminated, truncated, _ = env.step(action)
                frames.append(env.render())
                done = terminated or truncated
            frames.extend([frames[-1]] * int(fps // 2))  # a short pause between episodes
    finally:
        env.close()
    # even sizes for yuv420p video
    frames = [np.ascontiguousarray(f[: f.shape[0] // 2 * 2, : f.shape[1] // 2 * 2, :3])
              for f in frames]
    out_path.parent.mkdir(parents=True, exist_ok=True)
    if suffix == ".gif":
        iio.imwrite(out_path, np.stack(frames), plugin="pillow", duration=1000.0 / fps, loop=0)
    else:
        import imageio.v2 as iio2

        iio2.mimsave(out_path, frames, format="FFMPEG", fps=fps, macro_block_size=2)
    return len(frames)


# -- loading models ---------------------------------------------------------------------------
def find_run_config(model_path: str | os.PathLike) -> dict[str, Any] | None:
    """What is known of a model's training: the run's ``config.yaml`` (in the model's folder or
    the one above, for checkpoints) or an exported policy's ``provenance.json`` beside it.

    Both have ``algo``, ``env`` and ``env_kwargs``.
    """
    model_path = Path(model_path).resolve()
    for folder in (model_path.parent, model_path.parent.parent):
        path = folder / "config.yaml"
        if path.exists():
            return yaml.safe_load(path.read_text())
    provenance = model_path.parent / "provenance.json"
    if provenance.exists():
        return json.loads(provenance.read_text())
    return None


def find_vecnormalize(model_path: str | os.PathLike) -> Path | None:
    """VecNormalize statistics for a model: ``<stem>_vecnormalize.pkl``, else the folder's or
    the run's ``vecnormalize.pkl`` (None if there are none)."""
    model_path = Path(model_path)
    stem = model_path.name.removesuffix(".zip")
    candidates = [
        model_path.with_name(f"{stem}_vecnormalize.pkl"),
        model_path.with_name("vecnormalize.pkl"),
    ]
    if (model_path.parent.parent / "config.yaml").exists():
        candidates.append(model_path.parent.parent / "vecnormalize.pkl")
    return next((c for c in candidates if c.exists()), None)


@contextlib.contextmanager
def pretrained_files() -> Iterator[Path]:
    """The folder of the shipped policy (``ppo_smartcar.zip``, ``vecnormalize.pkl``, provenance)."""
    with resources.as_file(resources.files("smartcar_gym") / "pretrained") as folder:
        if not (folder / PRETRAINED_MODEL).exists():
            raise FileNotFoundError(
                f"no shipped policy: {folder / PRETRAINED_MODEL} does not exist (train one with "
                "smartcar-train and package it with python -m smartcar_gym.agents.export)"
            )
        yield folder


def load_model(path: str | os.PathLike, algo: str, device: str = "cpu") -> Any:
    """Load an SB3 model zip with the class for ``algo``."""
    from smartcar_gym.agents.hyperparams import algo_class

    return algo_class(algo).load(str(path), device=device)


# The module of each algorithm's policy classes, as recorded in a saved model's "data".
_POLICY_MODULES = {"stable_baselines3.common.policies": "ppo",
                   "stable_baselines3.sac.policies": "sac", "stable_baselines3.td3.policies": "td3"}


def saved_algo(path: str | os.PathLike) -> str | None:
    """The algorithm a model zip was saved by, from its policy class (None if unknown)."""
    try:
        with zipfile.ZipFile(path) as archive:
            policy = json.loads(archive.read("data"))["policy_class"]
    except (OSError, KeyError, ValueError, zipfile.BadZipFile):
        return None
    return _POLICY_MODULES.get(policy.get("__module__")) if isinstance(policy, dict) else None


# -- command line -----------------------------------------------------------------------------
def build_parser() -> argparse.ArgumentParser:
    """The ``smartcar-eval`` argument parser."""
    parser = argparse.ArgumentParser(
        prog="smartcar-eval",
        description="Evaluate a trained smartcar policy on seeded episodes (episode i uses "
                    "seed SEED+i); prints success rate, return, time to goal, final distance "
                    "and odometry error.",
    )
    source = parser.add_mutually_exclusive_group(required=True)
    source.add_argument("--model", type=Path, help="a model .zip (its run's config.yaml and "
                        "vecnormalize.pkl are found next to it)")
    source.add_argument("--pretrained", action="store_true", help="the policy shipped with the "
                        "package")
    source.add_argument("--random", action="store_true", help="uniform random actions, seeded "
                        "with --seed (a baseline)")
    parser.add_argument("--algo", choices=ALGOS, help="algorithm of --model (default: from the "
                        "run's config.yaml)")
    parser.add_argument("--env", dest="env_id", help="env id (default: the run's, else "
                        f"{DEFAULT_ENV_ID})")
    parser.add_argument("--env-kwargs", nargs="+", default=[], metavar="KEY=VALUE",
                        type=key_value_arg, help="gym.make keyword arguments (YAML values); "
                        "added to the run's own env kwargs")
    parser.add_argument("--vecnormalize", type=Path, help="VecNormalize statistics (default: "
                        "found next to the model)")
    parser.add_argument("--episodes", type=positive_int_arg, default=100)
    parser.add_argument("--n-envs", type=positive_int_arg, default=1,
                        help="envs run in parallel (worker processes when > 1)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--stochastic", action="store_true",
                        help="sample actions instead of taking the mean action")
    parser.add_argument("--device", default="cpu")
    parser.add_argument("--json", type=Path, metavar="FILE", help="write the metrics and "
                        "per-episode records as JSON")
    parser.add_argument("--video", type=Path, metavar="FILE.mp4|FILE.gif",
                        help="render the first --video-episodes episodes")
    parser.add_argument("--video-episodes", type=positive_int_arg, default=3)
    parser.add_argument("--plot", type=Path, metavar="FILE.png",
                        help="top-down trajectories of up to 16 episodes")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")
    return parser




def main(argv: Sequence[str] | None = None) -> int:
    """``smartcar-eval``: returns the exit code (2 for bad arguments, models or env kwargs)."""
    parser = build_parser()
    args = parser.parse_args(argv)
    check_outputs(parser, args)
    with contextlib.ExitStack() as stack:
        model_path = _model_path(parser, args, stack)
        run = {} if args.random else find_run_config(model_path) or {}
        algo = "random" if args.random else args.algo or run.get("algo")
        if algo is None:
            parser.error(f"cannot tell the algorithm of {model_path}: no config.yaml in its run "
                         "folder; pass --algo")
        if algo not in (*ALGOS, "random"):
            parser.error(f"unknown algorithm {algo!r} in the run's config; pass --algo")
        env_id = args.env_id or run.get("env") or DEFAULT_ENV_ID
        env_kwargs = {**(run.get("env_kwargs") or {}), **dict(args.env_kwargs)}
        try:
            check_env(env_id, env_kwargs)  # here, not in a worker: a clear error
        except EnvSetupError as err:
            parser.error(str(err))
        if args.random:
            vecnormalize, model = None, RandomPolicy(args.seed)
        else:
            if args.vecnormalize is not None and not args.vecnormalize.is_file():
                parser.error(f"--vecnormalize: no such file: {args.vecnormalize}")
            vecnormalize = args.vecnormalize or find_vecnormalize(model_path)
            model = _load_for_cli(parser, model_path, algo, args.device)
        common = dict(env_id=env_id, seed=args.seed, env_kwargs=env_kwargs,
                      deterministic=not args.stochastic, vecnormalize_path=vecnormalize)
        try:
            records = evaluate_policy_episodes(
                model, n_episodes=args.episodes, n_envs=args.n_envs,
                progress=not args.no_progress, **common,
            )
        except ObservationShapeError as err:
            parser.error(str(err))
        summary = summarize(records)
        files = {}
        if args.json is not None:
            payload = {
                "model": str(model_path if not args.pretrained else "pretrained:" +
                             PRETRAINED_MODEL),
                "algo": algo, "env": env_id, "env_kwargs": env_kwargs, "seed": args.seed,
                "n_envs": args.n_envs, "deterministic": not args.stochastic,
                "vecnormalize": None if vecnormalize is None else str(vecnormalize),
                **summary,
                "episode_records": [r.to_dict() for r in records],
            }
            args.json.parent.mkdir(parents=True, exist_ok=True)
            args.json.write_text(json.dumps(payload, indent=2) + "\n")
            files["json"] = args.json
        if args.plot is not None:
            from smartcar_gym.agents.plots import plot_trajectories

            tolerance = float(env_kwargs.get("goal_tolerance", 0.1))
            shown = " (first 16 shown)" if len(records) > 16 else ""
            plot_trajectories(records, args.plot, goal_tolerance_m=tolerance,
                              title=f"{model_path.name} on {env_id}: "
                                    f"{summary['success_rate']:.0%} success over "
                                    f"{len(records)} episodes{shown}")
            files["plot"] = args.plot
        if args.video is not None:
            n_frames = record_video(model, args.video, n_episodes=args.video_episodes, **common)
            files[f"video ({n_frames} frames)"] = args.video
    _print_summary(summary, model_path, env_id, args, files)
    return 0


def check_outputs(parser: argparse.ArgumentParser, args: argparse.Namespace) -> None:
    """Refuse (``parser.error``) output files that could not be written, before evaluating."""
    if args.video is not None and args.video.suffix.lower() not in (".gif", ".mp4"):
        parser.error(f"--video: the file must end in .gif or .mp4, got {str(args.video)!r}")
    if args.plot is not None and args.plot.suffix:
        from matplotlib.backend_bases import FigureCanvasBase

        formats = FigureCanvasBase.get_supported_filetypes()
        if args.plot.suffix[1:].lower() not in formats:
            parser.error(f"--plot: cannot write {args.plot.suffix} images; use .png, .svg or "
                         ".pdf")
    for option, path in (("--json", args.json), ("--plot", args.plot), ("--video", args.video)):
        problem = None if path is None else output_path_error(path)
        if problem:
            parser.error(f"{option}: {problem}")


def _model_path(parser: argparse.ArgumentParser, args: argparse.Namespace,
                stack: contextlib.ExitStack) -> Path:
    """The model file of ``--model`` / ``--pretrained`` (a placeholder for ``--random``)."""
    if args.random:
        return Path("random-policy")
    if args.pretrained:
        try:
            return stack.enter_context(pretrained_files()) / PRETRAINED_MODEL
        except FileNotFoundError as err:
            parser.error(str(err))
    if not args.model.is_file():
        parser.error(f"--model: no such file: {args.model}")
    if not zipfile.is_zipfile(args.model):
        parser.error(f"--model: {args.model} is not a model (SB3 models are .zip files)")
    return args.model


def _load_for_cli(parser: argparse.ArgumentParser, path: Path, algo: str, device: str) -> Any:
    """``load_model``, with a clear ``parser.error`` for the wrong algorithm or a bad file."""
    saved = saved_algo(path)
    if saved is not None and saved != algo:
        parser.error(f"{path} holds a {saved.upper()} model, not {algo.upper()}: pass "
                     f"--algo {saved}")
    try:
        return load_model(path, algo, device=device)
    except Exception as err:  # a file from anywhere: whatever fails, the file is the cause
        parser.error(f"--model: cannot load {path} as a {algo.upper()} model: "
                     f"{type(err).__name__}: {err}")


def _print_summary(summary: dict[str, Any], model_path: Path, env_id: str,
                   args: argparse.Namespace, files: dict[str, Path]) -> None:
    from rich.console import Console
    from rich.table import Table

    def fmt(value: float | None, spec: str) -> str:
        return "n/a" if value is None else format(value, spec)

    table = Table(title=f"{model_path.name} on {env_id}: {summary['episodes']} episodes, "
                        f"seeds {args.seed}..{args.seed + summary['episodes'] - 1}, "
                        f"{'stochastic' if args.stochastic else 'deterministic'}")
    table.add_column("metric")
    table.add_column("value", justify="right")
    table.add_row("success rate", fmt(summary["success_rate"], ".1%"))
    table.add_row("mean return", f"{summary['mean_return']:.2f} ± {summary['std_return']:.2f}")
    table.add_row("mean time to goal (s, successes)", fmt(summary["mean_time_to_goal_s"], ".2f"))
    table.add_row("mean final distance (m)", fmt(summary["mean_final_distance_m"], ".3f"))
    table.add_row("mean final odometry error (m)",
                  fmt(summary["mean_final_odom_error_m"], ".3f"))
    for name, path in files.items():
        table.add_row(name, str(path))
    Console().print(table)


if __name__ == "__main__":
    sys.exit(main())
