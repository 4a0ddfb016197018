"""Looking at episodes: Rerun recordings and the capture of what they show.

* ``capture``: ``Scene`` and ``Frame`` read from a SmartCarEnv, ``CaptureWrapper`` (into
  ``info``, for vector-env workers), ``EpisodeCollector`` (whole episodes, in order).
* ``packing``: ``pack``, a finished episode as plain arrays (``Packet``), without ``rerun``.
* ``rerun_log``: ``RerunSink``, episodes into an ``.rrd`` file and/or Rerun's web viewer.
* ``rerun_process``: ``RerunProcessSink``, the same from a recorder process of its own (what
  ``smartcar-eval --rerun`` uses: the evaluating process never imports ``rerun``).

``smartcar_gym.wrappers.RerunRecorder`` records any loop; ``smartcar-eval --rerun`` the
evaluation. ROS 2 bags are written by ``smartcar_gym.bags.ros2`` from the same episodes.
"""

from __future__ import annotations

RERUN_EXTRA = 'pip install "smartcar-gym[rerun]"'


def missing_rerun() -> str | None:
    """One line naming the extra if ``rerun-sdk`` is not installed, else None."""
    from smartcar_gym.extras import missing_modules

    if missing_modules(("rerun",)):
        return f"rerun-sdk not installed; recording needs the rerun extra: {RERUN_EXTRA}"
    return None
