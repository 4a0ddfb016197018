"""Rerun's web viewer, served from the ``rerun-sdk`` package, opened in headless Chromium
(Debian's ``chromium``, which ``.ci/run`` installs): a screenshot must show the recording."""

from __future__ import annotations

import importlib.util
import os
import signal
import socket

import numpy as np
import pytest

from smartcar_gym.agents.episodes import evaluate_policy_episodes
from smartcar_gym.agents.random_policy import RandomPolicy
from smartcar_gym.viewers.chromium import color_pixels, find_chromium

pytestmark = [
    pytest.mark.slow,
    pytest.mark.skipif(importlib.util.find_spec("rerun") is None,
                       reason='rerun-sdk not installed: pip install "smartcar-gym[rerun]"'),
    pytest.mark.skipif(find_chromium() is None,
                       reason="chromium not installed (Debian: apt-get install chromium; "
                              ".ci/run installs it when it runs as root with apt)"),
]


def _free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _colors(image):
    return len(np.unique(image[::2, ::2].reshape(-1, 3), axis=0))


def test_web_viewer_shows_the_recording(tmp_path):
    from smartcar_gym.viewers.chromium import screenshot
    from smartcar_gym.viewers.rerun_log import GOAL_COLOR, TRUTH_COLOR, RerunSink

    sink = RerunSink(serve=True, grpc_port=_free_port(), web_port=_free_port())
    try:
        blank = screenshot("about:blank", tmp_path / "blank.png", width=800, height=500)
        assert _colors(blank) == 1  # what a page without the viewer looks like
        evaluate_policy_episodes(RandomPolicy(1), "SmartCarSim-v0", n_episodes=1, seed=1,
                                 recorders=[sink])
        sink.rec.flush()

        def shows_episode(image):  # the goal (red) and the true path (green) are drawn
            return (color_pixels(image, GOAL_COLOR) > 200
                    and color_pixels(image, TRUTH_COLOR) > 200)

        image = screenshot(sink.web_url, tmp_path / "viewer.png", width=1400, height=800,
                           ready=shows_episode, timeout_s=150)
    finally:
        sink.close()
    assert image.shape == (800, 1400, 3)
    assert _colors(image) > 500  # panels, plots, text: not a blank or loading page


def test_rerun_serve_web_shows_a_recorded_file(tmp_path):
    """The docs' way: ``rerun --serve-web --bind 127.0.0.1 episodes.rrd`` (the rerun-sdk
    package's CLI), with its settings in the test's folder rather than ``~/.config/rerun``."""
    import subprocess
    import sys

    from smartcar_gym.viewers.chromium import screenshot
    from smartcar_gym.viewers.rerun_log import GOAL_COLOR, TRUTH_COLOR, RerunSink

    path = tmp_path / "episodes.rrd"
    sink = RerunSink(path)
    evaluate_policy_episodes(RandomPolicy(4), "SmartCarSim-v0", n_episodes=2, seed=4,
                             recorders=[sink])
    sink.close()
    grpc, web = _free_port(), _free_port()
    server = subprocess.Popen([sys.executable, "-m", "rerun", "--serve-web", "--bind",
                               "127.0.0.1", "--port", str(grpc), "--web-viewer-port", str(web),
                               str(path)],
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                              env={**os.environ, "XDG_CONFIG_HOME": str(tmp_path),
                                   "XDG_DATA_HOME": str(tmp_path)},
                              start_new_session=True)  # python -m rerun runs rerun_cli/rerun
    try:
        image = screenshot(f"http://127.0.0.1:{web}/?url=rerun%2Bhttp%3A%2F%2F127.0.0.1%3A"
                           f"{grpc}%2Fproxy", tmp_path / "file.png",
                           ready=lambda i: (color_pixels(i, GOAL_COLOR) > 200
                                            and color_pixels(i, TRUTH_COLOR) > 200),
                           timeout_s=150)
    finally:  # the whole group: the wrapper and the viewer binary it started
        os.killpg(server.pid, signal.SIGTERM)
        server.wait(timeout=30)
    assert _colors(image) > 500
