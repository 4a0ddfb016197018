"""SB3 agents for the smartcar envs: ``smartcar-train`` and ``smartcar-eval``.

They need the ``train`` extra (``pip install "smartcar-gym[train]"``: Stable-Baselines3, torch,
TensorBoard, pandas, matplotlib, imageio-ffmpeg, tqdm, rich); the env does not.

Modules (imported on demand; this package imports nothing heavy), by concern:

* Command lines (argparse; each calls the library below):
  ``cli_train`` (``smartcar-train``), ``cli_eval`` (``smartcar-eval``), ``eval_outputs``
  (``smartcar-eval``'s output files checked before it runs, and the recorders its episodes
  stream to), ``cli_args`` (the options' value types: key=value, counts, percentages,
  distances), ``process_start`` and ``process_exit`` (the two commands' processes: the
  garbage collector's threshold at the start, the end without Python's teardown).
* Configuration: ``hyperparams`` (zoo-format YAML, ``smartcar_gym/config/<algo>.yaml``,
  key=value overrides, the algorithm's arguments), ``zoo_keys`` (the zoo keys that shape a
  run: env_wrapper, frame_stack, callback, ...).
* Envs: ``env_factory`` (single envs: ``make_env`` with Monitor and zoo's wrappers, and the
  one-line checks of an env id and its kwargs), ``vec_envs`` (every vector env: SB3's
  SubprocVecEnv/DummyVecEnv, the batched vector entry points, Gymnasium's Sync/Async vector
  envs of single envs; VecNormalize), ``sb3_vec_env`` (``GymVectorVecEnv``: a Gymnasium
  vector env seen as an SB3 VecEnv).
* Episodes: ``runner`` (the one episode runner: jobs handed to the cars of a vector env,
  with hooks), ``episodes`` (every evaluation's episodes, sequential, batched and SB3's during
  training), ``records`` (``EpisodeRecord``, ``summarize``, the hooks that record them),
  ``random_policy`` (``RandomPolicy``, the baseline), ``video`` (episodes
  rendered to a .gif or .mp4) and ``bag`` (as a ROS 1 bag or MCAP file), both through the
  runner's hooks, ``references`` (a Minari dataset's reference scores), ``eval_worker``
  (evaluations in a second process while
  training goes on).
* Training: ``training`` (``train()``: a run with checkpoints and evaluation),
  ``callbacks`` (checkpoints, evaluation by success rate), ``run_control`` (the progress
  bar, a clean stop on Ctrl-C or SIGTERM), ``optimizers`` (the models' Adam optimizers on
  torch's multi-tensor update: the same numbers sooner).
* Files: ``runs`` (a run's folder: a new run's config, the run to resume, checkpoint
  names), ``atomic_files`` (files written atomically; whether a path can be written),
  ``models`` (a saved model's run config and the VecNormalize statistics its place assigns
  to it, never a pickle that the user did not name or that its run folder does not list;
  the shipped policies; ``load_model()``), ``zoo_runs`` (rl-baselines3-zoo run folders, read
  with a safe YAML loader), ``export`` (package a run as the shipped policy with
  ``provenance.json``).
* Figures: ``plots`` (learning curve and top-down trajectory figures).
* ``policies``: ``Policy.load()``, a model with its normaliser and env settings, and
  ``act(obs)``; ``smartcar_gym.policy`` is its public face (used by users, the commands here
  and ``ros``).
"""

from __future__ import annotations

import sys

from smartcar_gym.extras import TRAIN_EXTRA, missing_modules

# Import names of what the commands import themselves (SB3 brings torch, pandas, matplotlib).
TRAIN_MODULES = ("stable_baselines3", "torch", "tensorboard", "pandas", "matplotlib", "tqdm",
                 "rich")
EVAL_MODULES = ("stable_baselines3", "torch", "matplotlib", "tqdm", "rich")


def require_train_extra(prog: str, modules: tuple[str, ...] = TRAIN_MODULES) -> None:
    """Exit with code 2 and one line on stderr if the ``train`` extra is not installed."""
    missing = missing_modules(modules)
    if missing:
        print(f"{prog}: error: {', '.join(missing)} not installed; {prog} needs the train "
              f"extra: {TRAIN_EXTRA}", file=sys.stderr)
        raise SystemExit(2)


__all__ = ["EVAL_MODULES", "TRAIN_EXTRA", "TRAIN_MODULES", "missing_modules",
           "require_train_extra"]
