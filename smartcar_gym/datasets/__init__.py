"""Evaluated episodes as offline-RL datasets.

* ``steps``: ``EpisodeSteps``, every step of the episodes an evaluation runs (observations,
  actions, rewards, terminations, truncations, the infos that are arrays), collected from its
  vector env, sequential or batched, on any engine.
* ``minari_writer``: those episodes as a Minari dataset (``smartcar-eval --minari``), with the
  env spec, reference scores and a description (needs the ``minari`` extra).
"""
