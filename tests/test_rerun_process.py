"""``RerunProcessSink``: the recording made by a recorder process is the in-process one, its
errors come back, and no recorder process outlives ``close``, ``discard`` or ``stop``."""

from __future__ import annotations

import gc
import multiprocessing
import socket
import urllib.request
import warnings

import numpy as np
import pytest

import smartcar_gym  # noqa: F401  (registers the envs)
from smartcar_gym.agents.episodes import evaluate_policy_episodes
from smartcar_gym.agents.random_policy import RandomPolicy
from tests.test_rerun_recording import _store, needs_reader, pytestmark  # noqa: F401


def _tables(path):
    """Every entity's rows of an .rrd file: the static ones and those on sim_time."""
    store = _store(path)
    static = store.reader(index=None, contents="/**").to_pandas()
    timed = store.reader(index="sim_time", contents="/**").to_pandas()
    return static, timed


def _free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _plain(value):
    """A cell of a store's table as nested lists (arrow lists come as arrays of arrays)."""
    if isinstance(value, np.ndarray):
        return [_plain(v) for v in value] if value.dtype == object else value.tolist()
    return value


def _same(a, b):
    assert list(a.columns) == list(b.columns)
    assert a["sim_time"].equals(b["sim_time"])
    for column in a.columns.drop("sim_time"):
        for x, y in zip(a[column], b[column], strict=True):
            np.testing.assert_equal(_plain(x), _plain(y), err_msg=column)


@needs_reader
def test_the_recorder_process_writes_what_the_in_process_sink_writes(tmp_path):
    from smartcar_gym.viewers.rerun_log import RerunSink
    from smartcar_gym.viewers.rerun_process import RerunProcessSink

    here = RerunSink(tmp_path / "here.rrd", recording_id="same")
    there = RerunProcessSink(tmp_path / "there.rrd", recording_id="same")
    evaluate_policy_episodes(RandomPolicy(5), "SmartCarNav-v0", n_episodes=2, seed=5,
                             env_kwargs={"max_episode_steps": 25}, recorders=[here, there])
    here.close()
    assert not (tmp_path / "there.rrd").exists()  # written whole on close
    there.close()
    assert there.episodes == 2 and not there._process.is_alive()
    assert there._process.exitcode == 0
    static_here, timed_here = _tables(tmp_path / "here.rrd")
    static_there, timed_there = _tables(tmp_path / "there.rrd")
    assert "/world/episode_001/car/laser/scan:Points3D:positions" in timed_here.columns
    assert "/robot_description:TextDocument:text" in static_here.columns  # sent once, kept
    assert len(timed_here) == 26  # the reset and 25 steps (both episodes on one timeline)
    _same(static_here, static_there)
    _same(timed_here, timed_there)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["here.rrd", "there.rrd"]  # no partial


def test_close_is_idempotent_and_discard_leaves_no_file(tmp_path):
    from smartcar_gym.viewers.rerun_process import RerunProcessSink

    sink = RerunProcessSink(tmp_path / "none.rrd")
    evaluate_policy_episodes(RandomPolicy(1), "SmartCarSim-v0", n_episodes=1, seed=1,
                             env_kwargs={"max_episode_steps": 5}, recorders=[sink])
    sink.discard()  # what smartcar-eval does after an error or Ctrl-C
    assert not sink._process.is_alive()
    assert list(tmp_path.iterdir()) == []
    sink.close()  # after discard: nothing to do

    sink = RerunProcessSink(tmp_path / "one.rrd")
    evaluate_policy_episodes(RandomPolicy(1), "SmartCarSim-v0", n_episodes=1, seed=1,
                             env_kwargs={"max_episode_steps": 5}, recorders=[sink])
    sink.close()
    size = (tmp_path / "one.rrd").stat().st_size
    sink.close()
    sink.discard()  # after close: the file stays
    sink.stop()
    assert (tmp_path / "one.rrd").stat().st_size == size > 1000
    assert not sink._process.is_alive() and sink._process.exitcode == 0
    with pytest.raises(ValueError, match="closed"):
        sink.write(None)


def test_an_error_of_the_recorder_comes_back_as_its_own(tmp_path):
    from smartcar_gym.viewers.rerun_process import RerunProcessSink

    (tmp_path / "file").write_text("not a folder")
    sink = RerunProcessSink(tmp_path / "file" / "x.rrd")  # the recorder cannot make the folder
    with pytest.raises(FileExistsError, match="file"):
        sink.close()
    assert not sink._process.is_alive()
    with pytest.raises(ValueError, match=r"end in \.rrd, got 'x\.mcap'"):
        RerunProcessSink(tmp_path / "x.mcap")  # refused here, before any process starts


def test_a_web_port_in_use_fails_like_the_in_process_sink():
    from smartcar_gym.viewers.rerun_log import RerunSink
    from smartcar_gym.viewers.rerun_process import RerunProcessSink

    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        with pytest.raises(RuntimeError, match="in use") as here:
            RerunSink(serve=True, grpc_port=_free_port(), web_port=port)
        with pytest.raises(RuntimeError) as there:
            RerunProcessSink(serve=True, grpc_port=_free_port(), web_port=port)
    assert str(there.value) == str(here.value).splitlines()[0]
    assert not any(p.name == "smartcar-rerun-recorder" for p in multiprocessing.active_children())
    with warnings.catch_warnings(record=True) as caught:  # the failed start closed its pipe
        warnings.simplefilter("always")
        del here, there
        gc.collect()
    assert not [w for w in caught if issubclass(w.category, ResourceWarning)], caught


def test_a_recorder_that_died_is_named(tmp_path):
    from smartcar_gym.viewers.rerun_process import RerunProcessSink

    episodes = []
    evaluate_policy_episodes(RandomPolicy(1), "SmartCarSim-v0", n_episodes=1, seed=1,
                             env_kwargs={"max_episode_steps": 5}, recorders=[episodes.append])
    sink = RerunProcessSink(tmp_path / "x.rrd")
    sink._process.kill()
    sink._process.join(10)
    with pytest.raises(RuntimeError, match=r"recorder process ended \(exit code -9\)"):
        for _ in range(50):  # the pipe's buffer may take a few episodes first
            sink.write(episodes[0])
    sink.discard()
    assert list(tmp_path.iterdir()) == []  # neither the file nor a partial one


def test_serving_outlives_close_until_stop(tmp_path):
    from smartcar_gym.viewers.rerun_process import RerunProcessSink

    web_port = _free_port()
    sink = RerunProcessSink(tmp_path / "served.rrd", serve=True, grpc_port=_free_port(),
                            web_port=web_port)
    try:
        assert sink.web_url.startswith(f"http://127.0.0.1:{web_port}/?url=rerun%2Bhttp")
        evaluate_policy_episodes(RandomPolicy(1), "SmartCarSim-v0", n_episodes=1, seed=1,
                                 env_kwargs={"max_episode_steps": 5}, recorders=[sink])
        sink.close()
        assert (tmp_path / "served.rrd").stat().st_size > 1000
        assert sink._process.is_alive()  # still serving
        page = urllib.request.urlopen(f"http://localhost:{web_port}/", timeout=10).read()
        assert b"<html" in page.lower()
    finally:
        sink.stop()
    assert not sink._process.is_alive()


@pytest.mark.slow
def test_eval_cli_interrupted_leaves_no_file_and_no_recorder(tmp_path, monkeypatch):
    """Ctrl-C during ``smartcar-eval --rerun``: no half-written file, no recorder process
    left (as with the in-process sink); a finished run leaves the file and no process."""
    import smartcar_gym.agents.cli_eval as evaluate

    real = evaluate.evaluate_policy_episodes

    def interrupted(*args, **kwargs):
        real(*args, **{**kwargs, "n_episodes": 1})  # one episode recorded, then Ctrl-C
        raise KeyboardInterrupt

    monkeypatch.setattr(evaluate, "evaluate_policy_episodes", interrupted)
    with pytest.raises(KeyboardInterrupt):
        evaluate.main(["--random", "--env", "SmartCarSim-v0", "--episodes", "2",
                       "--no-progress", "--rerun", str(tmp_path / "x.rrd")])
    assert list(tmp_path.iterdir()) == []
    assert not [p for p in multiprocessing.active_children()
                if p.name == "smartcar-rerun-recorder"]
    monkeypatch.setattr(evaluate, "evaluate_policy_episodes", real)
    assert evaluate.main(["--random", "--env", "SmartCarSim-v0", "--episodes", "2",
                          "--no-progress", "--rerun", str(tmp_path / "x.rrd")]) == 0
    assert (tmp_path / "x.rrd").stat().st_size > 10_000
    assert not [p for p in multiprocessing.active_children()
                if p.name == "smartcar-rerun-recorder"]


def test_a_recorder_that_outlives_sigterm_is_killed():
    """``_end``: asked, terminated, then killed, so that no recorder is left for
    multiprocessing to join without a timeout at exit."""
    from smartcar_gym.viewers import rerun_process

    class Stubborn:  # a recorder that ignores its pipe closing and SIGTERM
        def __init__(self) -> None:
            self.calls: list[str] = []
            self.alive = True

        def join(self, timeout=None) -> None:
            self.calls.append("join")

        def is_alive(self) -> bool:
            return self.alive

        def terminate(self) -> None:
            self.calls.append("terminate")

        def kill(self) -> None:
            self.calls.append("kill")
            self.alive = False

    class Pipe:
        def close(self) -> None:
            pass

    sink = rerun_process.RerunProcessSink.__new__(rerun_process.RerunProcessSink)
    sink._conn, sink._process = Pipe(), Stubborn()
    sink._end()
    assert sink._process.calls == ["join", "terminate", "join", "kill", "join"]
    assert not sink._process.is_alive()
