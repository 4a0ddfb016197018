"""Training past one machine with Ray (the optional ``ray`` extra: ``pip install
"smartcar-gym[ray]"``).

Modules (this package imports nothing heavy; Ray is imported on demand):

* ``space``: the search space of a sweep (YAML or command line), checked before Ray starts.
* ``ray_session``: start a local Ray instance or connect to a cluster; CPU checks.
* ``trial``: one Tune trial, which is a ``smartcar-train`` run in ``<out>/<trial>/``.
* ``results``: the results table of a sweep (CSV, JSON) and its best hyperparameters (YAML).
* ``tune``: the ``smartcar-tune`` command (Ray Tune, grid/random search, ASHA, resume).
* ``rllib_env``: the env creator RLlib's EnvRunners import (one pybullet client per env).
* ``rllib``: the RLlib PPO recipe for one large run with many EnvRunners.
"""

RAY_EXTRA = 'pip install "smartcar-gym[ray]"'
