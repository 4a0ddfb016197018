"""SB3 agents for the smartcar envs: ``smartcar-train`` and ``smartcar-eval``.

Modules (imported on demand; this package imports nothing heavy):

* ``hyperparams``: zoo-format YAML (``smartcar_gym/config/<algo>.yaml``), key=value overrides.
* ``env_factory``: Monitor-wrapped vector envs (SubprocVecEnv) and VecNormalize.
* ``callbacks``: atomic checkpoints, evaluation by success rate, progress bar, Ctrl-C.
* ``train``: the ``smartcar-train`` command and ``train()``.
* ``evaluate``: ``evaluate_policy_episodes()`` (seeded, vectorised) and ``smartcar-eval``.
* ``plots``: learning curve and top-down trajectory figures.
* ``export``: package a run as the shipped policy with ``provenance.json``.
"""
