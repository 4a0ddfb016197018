"""``RerunProcessSink``: a Rerun recording made by a process of its own.

The evaluating process never imports ``rerun``: a recorder process (``multiprocessing``,
"spawn") imports it, holds the ``RecordingStream`` and its file and server sinks (a
``RerunSink``), and logs each episode that it is sent. The evaluating process only packs a
finished episode into arrays (``packing.pack``) and pickles it into a pipe, so on a machine
with a core to spare the recording costs an evaluation little wall time. The recording is the
same as ``RerunSink``'s. The recorder ignores Ctrl-C (SIGINT, which a terminal sends to both
processes): the evaluating process decides, with ``close`` (the ``.rrd`` appears whole) or
``discard`` (no file). An error of the recorder (a port in use, a file it cannot write) comes
back as the same exception type with the recorder's message, from the next call.
"""

from __future__ import annotations

import builtins
import multiprocessing
import os
import signal
import sys
from pathlib import Path
from typing import Any

from smartcar_gym.viewers import missing_rerun
from smartcar_gym.viewers.capture import Episode
from smartcar_gym.viewers.web_viewer import LOOPBACK, check_bind

START_TIMEOUT_S = 120.0  # the recorder's start (importing rerun, binding the ports)
CLOSE_TIMEOUT_S = 300.0  # logging what is still queued, writing the file
STOP_TIMEOUT_S = 10.0


class RerunProcessSink:
    """Writes ``Episode`` objects to a Rerun recording from a recorder process.

    Args:
        path: an ``.rrd`` file, written whole when ``close`` is called.
        serve: host a gRPC server (``grpc_port``) and Rerun's web viewer (``web_port``) in
            the recorder process; ``web_url`` is where to look. They stay up after ``close``
            until ``stop`` (or until this process ends).
        bind: the IP address both listen on (``RerunSink``'s): 127.0.0.1, this machine only,
            unless another is asked for.
        recording_id: the recording's id (Rerun makes one up if None).
    """

    def __init__(self, path: str | os.PathLike | None = None, *, serve: bool = False,
                 grpc_port: int = 9876, web_port: int = 9090,
                 recording_id: str | None = None, bind: str = LOOPBACK) -> None:
        problem = missing_rerun()
        if problem:
            raise ImportError(problem)
        bind = check_bind(bind)  # here, before any process starts
        self.path = None if path is None else Path(path)
        if self.path is None and not serve:
            raise ValueError("a Rerun recording needs a path (.rrd), serve=True or both")
        if self.path is not None and self.path.suffix != ".rrd":
            raise ValueError(f"Rerun recordings end in .rrd, got {self.path.name!r}")
        self.serve = serve
        self.web_url: str | None = None
        self.episodes = 0
        self._described = False
        self._closed = False
        context = multiprocessing.get_context("spawn")
        self._conn, child = context.Pipe()
        self._process = context.Process(
            target=_record,
            args=(child, self.path, serve, grpc_port, web_port, recording_id, bind),
            name="smartcar-rerun-recorder", daemon=True)
        self._process.start()
        child.close()
        if serve:  # the address is the recorder's to tell; a port in use fails here
            try:
                (self.web_url,) = self._receive("ready", START_TIMEOUT_S)
            except BaseException:
                self._end()
                raise

    def __call__(self, episode: Episode) -> None:
        self.write(episode)

    def write(self, episode: Episode) -> None:
        """Send one whole episode to the recorder (it logs it while this process goes on)."""
        from smartcar_gym.viewers.packing import pack

        if self._closed:
            raise ValueError("this Rerun recording is closed")
        self._check()
        packet = pack(episode, urdf=not self._described)
        try:
            self._conn.send(("episode", packet))
        except (BrokenPipeError, ConnectionResetError, EOFError):
            self._check()
            raise self._died() from None
        self._described = True
        self.episodes += 1

    def close(self) -> None:
        """Wait for the recorder to log every episode sent; the ``.rrd`` file appears at its
        path now, complete. A serving recorder keeps serving until ``stop``."""
        if self._closed:
            return
        self._closed = True
        try:
            self._send(("close",))
            self._receive("closed", CLOSE_TIMEOUT_S)
        except BaseException:
            self._end()
            raise
        if not self.serve:
            self._end()

    def discard(self) -> None:
        """Stop without leaving a file (after an error); never raises."""
        self._closed = True
        if self._process.is_alive():
            try:
                self._conn.send(("discard",))
                self._receive("discarded", STOP_TIMEOUT_S)
            except BaseException:  # the recorder is ended below all the same
                pass
        self._end()
        if self.path is not None:  # what a recorder ended mid-write leaves (RerunSink's name)
            self.path.with_name(f".{self.path.stem}.partial.rrd").unlink(missing_ok=True)

    def stop(self) -> None:
        """End the recorder (and its server): after ``close``, or instead (like ``discard``)."""
        if not self._closed:
            self.discard()
        self._end()

    def serve_until_interrupted(self) -> None:
        """Keep serving until Ctrl-C or SIGTERM, then ``stop``.

        Both stop it the same way (the recorder and its server end), also where this process
        was started with SIGINT ignored, as a shell script's background job is: Python then
        leaves Ctrl-C ignored. The previous handlers are back afterwards."""
        import time

        def interrupt(signum: int, frame: Any) -> None:
            raise KeyboardInterrupt

        previous = {sig: signal.signal(sig, interrupt) for sig in (signal.SIGINT,
                                                                   signal.SIGTERM)}
        try:
            while True:
                time.sleep(3600)
        except KeyboardInterrupt:
            pass
        finally:
            for sig, handler in previous.items():
                signal.signal(sig, handler)
            self.stop()

    def _send(self, message: tuple) -> None:
        try:
            self._conn.send(message)
        except (BrokenPipeError, ConnectionResetError, EOFError, OSError):
            self._check()
            raise self._died() from None

    def _check(self) -> None:
        """Raise the recorder's error if it has reported one."""
        while self._process is not None and self._conn.poll():
            try:
                kind, *body = self._conn.recv()
            except (EOFError, OSError):
                return
            if kind == "error":
                raise _rebuild(*body)

    def _receive(self, expected: str, timeout_s: float) -> list:
        """The body of the recorder's next message, which must be ``expected``."""
        try:
            if not self._conn.poll(timeout_s):
                raise TimeoutError(f"the Rerun recorder process did not answer in {timeout_s:g} "
                                   f"s (waiting for {expected!r})")
            kind, *body = self._conn.recv()
        except (EOFError, OSError):
            raise self._died() from None
        if kind == "error":
            raise _rebuild(*body)
        if kind != expected:
            raise RuntimeError(f"the Rerun recorder process said {kind!r}, not {expected!r}")
        return body

    def _died(self) -> RuntimeError:
        self._process.join(STOP_TIMEOUT_S)
        return RuntimeError(f"the Rerun recorder process ended (exit code "
                            f"{self._process.exitcode}) before the recording was complete")

    def _end(self) -> None:
        """No recorder process left running: asked (its pipe closes), then terminated, then
        killed. A recorder that outlived SIGTERM would otherwise hang this process at exit,
        where multiprocessing joins its daemonic children without a timeout."""
        self._conn.close()
        self._process.join(STOP_TIMEOUT_S)
        if self._process.is_alive():
            self._process.terminate()
            self._process.join(STOP_TIMEOUT_S)
        if self._process.is_alive():
            self._process.kill()
            self._process.join(STOP_TIMEOUT_S)


def _rebuild(kind: str, message: str) -> BaseException:
    """The recorder's exception, here: a built-in type as itself, any other as RuntimeError."""
    cls = getattr(builtins, kind, None)
    if isinstance(cls, type) and issubclass(cls, Exception):
        try:
            return cls(message)
        except TypeError:
            pass
    return RuntimeError(f"Rerun recorder: {kind}: {message}")


def _record(conn: Any, path: Path | None, serve: bool, grpc_port: int, web_port: int,
            recording_id: str | None, bind: str) -> None:
    """The recorder process: a ``RerunSink`` fed from ``conn`` until told to stop."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is the evaluating process's to handle
    sink = None
    try:
        from smartcar_gym.viewers.rerun_log import RerunSink, skip_pandas_probe

        skip_pandas_probe()
        sink = RerunSink(path, serve=serve, grpc_port=grpc_port, web_port=web_port,
                         recording_id=recording_id, bind=bind)
        if serve:
            conn.send(("ready", sink.web_url))
        while True:
            kind, *body = conn.recv()
            if kind == "episode":
                sink.send(*body)
            elif kind == "close":
                sink.close()
                conn.send(("closed",))
                if not serve:  # the file is complete: skip tearing down rerun's modules
                    conn.close()
                    sys.stdout.flush()
                    sys.stderr.flush()
                    os._exit(0)
            elif kind == "discard":
                sink.discard()
                sink = None
                conn.send(("discarded",))
                return
    except EOFError:  # the evaluating process is gone (or stop): no file from a partial run
        pass
    except BaseException as err:
        try:
            conn.send(("error", type(err).__name__, str(err).splitlines()[0] if str(err)
                       else type(err).__name__))
        except OSError:
            pass
    if sink is not None:
        sink.discard()
        sink.stop()  # the web viewer's server process
