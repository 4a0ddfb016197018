"""``RerunRecorder``: a gymnasium wrapper that records each episode as Rerun entities."""

from __future__ import annotations

import os
from typing import Any

import gymnasium as gym

from smartcar_gym.viewers import missing_rerun
from smartcar_gym.viewers.capture import Episode, FrameReader, scene_of


class RerunRecorder(gym.Wrapper):
    """Records every episode of a SmartCarEnv into a Rerun recording.

    ::

        env = RerunRecorder(gym.make("SmartCarNav-v0"), "episodes.rrd")
        ...  # any loop: reset, step
        env.close()  # the .rrd file is complete now

    Each finished episode (terminated or truncated) becomes the entities of
    ``smartcar_gym.viewers.rerun_log`` (``world/episode_NNN/...``, ``wheel_speed/...``, ...);
    an episode cut short by a ``reset`` or ``close`` is recorded as far as it went. Wrap the
    env from ``gym.make`` (outside its ``TimeLimit``). Recording only reads the simulator.

    Args:
        env: a SmartCarEnv (SmartCar-v0, SmartCarSim-v0, SmartCarNav-v0, SmartCarGoal-v0).
        path: the ``.rrd`` file to write.
        serve: also host Rerun's web viewer (``recorder.web_url``) and stream to it.
        recording: a ``rerun.RecordingStream`` of your own instead of ``path``/``serve``.
        grpc_port, web_port: the ports when serving.
        bind: the IP address they listen on: 127.0.0.1 (this machine only) unless given.
    """

    def __init__(self, env: gym.Env, path: str | os.PathLike | None = None, *,
                 serve: bool = False, recording: Any = None, grpc_port: int | None = None,
                 web_port: int | None = None, bind: str = "127.0.0.1") -> None:
        super().__init__(env)
        problem = missing_rerun()
        if problem:
            raise ImportError(problem)
        from smartcar_gym.viewers.rerun_log import GRPC_PORT, WEB_PORT, RerunSink

        self._reader = FrameReader(env)  # ValueError for an env that is not a SmartCarEnv
        self.sink = RerunSink(path, serve=serve, recording=recording,
                              grpc_port=grpc_port or GRPC_PORT, web_port=web_port or WEB_PORT,
                              bind=bind)
        self.web_url = self.sink.web_url
        self._episode: Episode | None = None
        self._count = 0

    def reset(self, **kwargs: Any) -> tuple[Any, dict[str, Any]]:
        self._finish()
        obs, info = self.env.reset(**kwargs)
        self._episode = Episode(self._count, kwargs.get("seed"), scene_of(self.env),
                                [self._reader.reset(info)])
        self._count += 1
        return obs, info

    def step(self, action: Any) -> tuple[Any, float, bool, bool, dict[str, Any]]:
        obs, reward, terminated, truncated, info = self.env.step(action)
        if self._episode is not None:
            self._episode.frames.append(
                self._reader.step(action, reward, terminated, truncated, info))
            if terminated or truncated:
                self._finish()
        return obs, reward, terminated, truncated, info

    def _finish(self) -> None:
        episode, self._episode = self._episode, None
        if episode is not None and episode.steps > 0:
            self.sink.write(episode)

    @property
    def episodes_recorded(self) -> int:
        """How many episodes were sent to the recording."""
        return self.sink.episodes

    def close(self) -> None:
        try:
            self._finish()
            self.sink.close()
        finally:
            super().close()
