"""SB3 agents for the smartcar envs: ``smartcar-train`` and ``smartcar-eval``.

Modules (imported on demand; this package imports nothing heavy):

* ``hyperparams``: zoo-format YAML (``smartcar_gym/config/<algo>.yaml``), key=value overrides.
* ``env_factory``: Monitor-wrapped vector envs (SubprocVecEnv) and VecNormalize.
* ``run_files``: files written atomically, checkpoint names.
* ``callbacks``: checkpoints, evaluation by success rate, progress bar, Ctrl-C.
* ``run_folder``: a new run's config and folder, or the run to resume (``config.yaml``).
* ``training``: ``train()``, training a run with checkpoints and evaluation.
* ``train``: the ``smartcar-train`` command.
* ``rollouts``: ``evaluate_policy_episodes()`` (seeded, vectorised), ``summarize()``, videos.
* ``model_files``: a model's run config and the VecNormalize statistics its place assigns to
  it (never a pickle that the user did not name or that its run folder does not list), the
  shipped policy, ``load_model()``.
* ``zoo_folder``: rl-baselines3-zoo run folders, read with a safe YAML loader.
* ``evaluate``: the ``smartcar-eval`` command.
* ``plots``: learning curve and top-down trajectory figures.
* ``export``: package a run as the shipped policy with ``provenance.json``.
"""
