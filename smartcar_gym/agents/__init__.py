"""SB3 agents for the smartcar envs: ``smartcar-train`` and ``smartcar-eval``.

They need the ``train`` extra (``pip install "smartcar-gym[train]"``: Stable-Baselines3, torch,
TensorBoard, pandas, matplotlib, imageio-ffmpeg, tqdm, rich); the env does not.

Modules (imported on demand; this package imports nothing heavy):

* ``hyperparams``: zoo-format YAML (``smartcar_gym/config/<algo>.yaml``), key=value overrides.
* ``zoo_keys``: the zoo keys that shape a run (env_wrapper, frame_stack, callback, ...).
* ``env_factory``: Monitor-wrapped vector envs (SubprocVecEnv) and VecNormalize.
* ``run_files``: files written atomically, checkpoint names.
* ``callbacks``: checkpoints, evaluation by success rate, progress bar, Ctrl-C.
* ``run_folder``: a new run's config and folder, or the run to resume (``config.yaml``).
* ``training``: ``train()``, training a run with checkpoints and evaluation.
* ``train``: the ``smartcar-train`` command.
* ``rollouts``: ``evaluate_policy_episodes()`` (seeded, vectorised), ``summarize()``, videos.
* ``smartcar_gym.policy`` (outside this package, used by the commands here and in ``ros``):
  ``Policy.load()``, a model with its normaliser and env settings, and ``act(obs)``.
* ``model_files``: a model's run config and the VecNormalize statistics its place assigns to
  it (never a pickle that the user did not name or that its run folder does not list), the
  shipped policy, ``load_model()``.
* ``zoo_folder``: rl-baselines3-zoo run folders, read with a safe YAML loader.
* ``evaluate``: the ``smartcar-eval`` command.
* ``plots``: learning curve and top-down trajectory figures.
* ``export``: package a run as the shipped policy with ``provenance.json``.
"""

from __future__ import annotations

import importlib.util
import sys

TRAIN_EXTRA = 'pip install "smartcar-gym[train]"'
# Import names of what the commands import themselves (SB3 brings torch, pandas, matplotlib).
TRAIN_MODULES = ("stable_baselines3", "torch", "tensorboard", "pandas", "matplotlib", "tqdm",
                 "rich")
EVAL_MODULES = ("stable_baselines3", "torch", "matplotlib", "tqdm", "rich")


def missing_modules(modules: tuple[str, ...]) -> list[str]:
    """The names in ``modules`` that cannot be imported (found without importing them)."""
    missing = []
    for name in modules:
        try:
            found = importlib.util.find_spec(name) is not None
        except (ImportError, ValueError):
            found = False
        if not found:
            missing.append(name)
    return missing


def require_train_extra(prog: str, modules: tuple[str, ...] = TRAIN_MODULES) -> None:
    """Exit with code 2 and one line on stderr if the ``train`` extra is not installed."""
    missing = missing_modules(modules)
    if missing:
        print(f"{prog}: error: {', '.join(missing)} not installed; {prog} needs the train "
              f"extra: {TRAIN_EXTRA}", file=sys.stderr)
        raise SystemExit(2)
