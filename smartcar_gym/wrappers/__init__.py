"""Gymnasium wrappers for the smartcar envs.

* ``RerunRecorder``: records every episode of any loop (SB3, rl-zoo3, RLlib, your own) as a
  Rerun recording, to an ``.rrd`` file and/or Rerun's web viewer (the ``rerun`` extra).
"""

from __future__ import annotations

from smartcar_gym.wrappers.rerun_recorder import RerunRecorder

__all__ = ["RerunRecorder"]
