"""Evaluations in a second process, while training goes on (``eval_async``).

A batched run trains in one process, on one core. Its evaluations on pybullet (a loop of
single envs) stopped the training for a third of its wall time while the second core idled.
``EvalWorker`` runs them in a process of its own instead: the training sends each
evaluation's policy and normalisation statistics and goes on; the worker, which built the
eval env once, plays the seeded episodes (``episodes.run_sb3_episodes``) and sends the records
back, in order. They are the
records the same evaluation makes in the training process (same policy, statistics, seed and
env), so a run picks the same best model either way, only sooner.

Before it builds its env, the worker compiles the boards' loops
(``controller.compiled.compile_loops``; loaded from numba's cache after the first run): the
training compiles its physics first and the boards next, so on a first run it finds them in
the cache (2 s of the README's first training on the 2-core machine).
"""

from __future__ import annotations

import contextlib
import multiprocessing
import signal
import threading
import traceback
from collections.abc import Callable
from typing import Any

from smartcar_gym.agents.episodes import run_sb3_episodes
from smartcar_gym.agents.records import EpisodeRecord

#: what the worker's forkserver imports once (as for SubprocVecEnv's workers)
PRELOAD = ("stable_baselines3.common.evaluation", "smartcar_gym.envs.smartcar_env")
#: an evaluation's records (``episodes.run_sb3_episodes``), in the order the episodes ended
Records = list[EpisodeRecord]


class EvalWorkerError(RuntimeError):
    """The evaluation process failed or stopped; the message says where and why."""


def _normalizers(venv: Any) -> list[Any]:
    from stable_baselines3.common.vec_env import VecEnvWrapper, VecNormalize

    found = []
    while isinstance(venv, VecEnvWrapper):
        if isinstance(venv, VecNormalize):
            found.append(venv)
        venv = venv.venv
    return found


def normalization_stats(venv: Any) -> list[tuple[Any, Any]]:
    """The ``(obs_rms, ret_rms)`` of each VecNormalize in ``venv``'s wrapper chain, outermost
    first: what ``sync_envs_normalization`` copies."""
    return [(wrapper.obs_rms, wrapper.ret_rms) for wrapper in _normalizers(venv)]


def apply_normalization_stats(venv: Any, stats: list[tuple[Any, Any]]) -> None:
    """Give ``venv``'s VecNormalize wrappers the statistics that ``normalization_stats`` took
    from an env wrapped the same way."""
    wrappers = _normalizers(venv)
    if len(wrappers) != len(stats):
        raise EvalWorkerError(f"the eval env has {len(wrappers)} VecNormalize wrappers, the "
                              f"training env {len(stats)}")
    for wrapper, (obs_rms, ret_rms) in zip(wrappers, stats, strict=True):
        wrapper.obs_rms, wrapper.ret_rms = obs_rms, ret_rms


def _serve(conn: Any, make_env: Any) -> None:
    """The worker: build the eval env, then answer each ``(steps, policy, stats, episodes,
    seed, deterministic)`` with ``("result", steps, records)`` until ``None`` comes or the
    pipe closes. An error is answered with ``("error", message)`` and ends the worker."""
    # a Ctrl-C or kill sent to the process group is the training process's to act on: it
    # drains or kills this worker itself (as SubprocVecEnv's training workers)
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_IGN)
    import torch

    from smartcar_gym.controller.compiled import compile_loops

    torch.set_num_threads(1)
    venv = None
    try:
        # idle until the first evaluation: the boards' compiled loops, which the training
        # compiles after its physics, compiled (or loaded) here meanwhile, on the other core
        compile_loops()
        venv = make_env.var()
        while True:
            try:
                message = conn.recv()
            except EOFError:
                break
            if message is None:
                break
            steps, policy, stats, n_episodes, seed, deterministic = message
            apply_normalization_stats(venv, stats)
            records = run_sb3_episodes(policy, venv, n_episodes, seed, deterministic)
            conn.send(("result", steps, records))
    except Exception as err:
        place = traceback.extract_tb(err.__traceback__)[-1]
        with contextlib.suppress(EOFError, OSError):
            conn.send(("error", f"{type(err).__name__}: {err} ({place.filename}:"
                                f"{place.lineno})"))
    finally:
        if venv is not None:
            venv.close()
        conn.close()


class EvalWorker:
    """A process that evaluates policies on an eval env of its own, one request after another.

    ``make_env`` (any callable, closures included: it is sent with cloudpickle) builds the
    wrapped eval VecEnv in the worker. ``submit`` sends a policy and returns at once;
    ``results`` returns the evaluations finished so far and ``wait`` blocks until every
    submitted one is in, both in the order submitted. An error in the worker (or its end) is
    raised here as ``EvalWorkerError``. ``close`` stops the process (``force``: at once).

    The process starts in a thread: its forkserver imports the package (``PRELOAD``) on
    another core while the training sets up, instead of the training waiting for it (about a
    second of every run's start); the first call waits for the start to be done.
    """

    def __init__(self, make_env: Callable[[], Any]) -> None:
        from stable_baselines3.common.vec_env.base_vec_env import CloudpickleWrapper

        # forkserver (as SB3's SubprocVecEnv on Linux and macOS): the worker does not inherit
        # the training process's threads and state; spawn where there is none (Windows)
        if "forkserver" in multiprocessing.get_all_start_methods():
            context = multiprocessing.get_context("forkserver")
            multiprocessing.set_forkserver_preload(list(PRELOAD))
        else:
            context = multiprocessing.get_context("spawn")
        self._conn, child = context.Pipe()
        self._process = context.Process(target=_serve, args=(child, CloudpickleWrapper(make_env)),
                                        daemon=True, name="smartcar-eval-worker")
        self._start_error: BaseException | None = None
        self._starting: threading.Thread | None = threading.Thread(
            target=self._start, args=(child,), name="smartcar-eval-start", daemon=True)
        self._starting.start()
        self.pending: list[int] = []  # the step counts submitted and not answered yet

    def _start(self, child: Any) -> None:
        try:
            self._process.start()
        except BaseException as err:  # raised by the first call (``_started``)
            self._start_error = err
        finally:
            child.close()

    def _started(self) -> None:
        """Wait for the process's start; EvalWorkerError if it could not start."""
        if self._starting is not None:
            self._starting.join()
            self._starting = None
        if self._start_error is not None:
            raise EvalWorkerError(f"the evaluation process could not start: "
                                  f"{type(self._start_error).__name__}: {self._start_error}")

    def submit(self, steps: int, policy: Any, stats: list[tuple[Any, Any]], n_episodes: int,
               seed: int, deterministic: bool = True) -> None:
        """Evaluate ``policy`` (pickled now: later training does not change it) with the
        training env's normalisation ``stats`` at ``steps``: ``n_episodes`` from ``seed``."""
        import cloudpickle

        self._started()
        message = (int(steps), policy, stats, int(n_episodes), int(seed), bool(deterministic))
        try:
            self._conn.send_bytes(cloudpickle.dumps(message))
        except (EOFError, OSError) as err:
            raise self._stopped() from err
        self.pending.append(int(steps))

    def results(self) -> list[tuple[int, Records]]:
        """The evaluations finished since the last call, as ``(steps, records)``."""
        self._started()
        done = []
        while self.pending and self._poll():
            done.append(self._receive())
        return done

    def wait(self) -> list[tuple[int, Records]]:
        """Block until every submitted evaluation is in; returns them as ``results`` does."""
        self._started()
        done = []
        while self.pending:
            done.append(self._receive())
        return done

    def _poll(self) -> bool:
        try:
            return self._conn.poll()
        except (EOFError, OSError) as err:
            raise self._stopped() from err

    def _receive(self) -> tuple[int, Records]:
        try:
            message = self._conn.recv()
        except (EOFError, OSError) as err:
            raise self._stopped() from err
        if message[0] == "error":
            self.pending.clear()
            raise EvalWorkerError(f"the evaluation process failed: {message[1]}")
        _, steps, records = message
        expected = self.pending.pop(0)
        if steps != expected:  # a pipe keeps the order; anything else is a bug
            raise EvalWorkerError(f"the evaluation process answered for {steps} steps, "
                                  f"expected {expected}")
        return steps, records

    def _stopped(self) -> EvalWorkerError:
        """The error for a worker that is gone: its own message if it sent one."""
        self.pending.clear()
        with contextlib.suppress(EOFError, OSError):
            while self._conn.poll():
                message = self._conn.recv()
                if message[0] == "error":
                    return EvalWorkerError(f"the evaluation process failed: {message[1]}")
        self._process.join(timeout=1)
        return EvalWorkerError(f"the evaluation process stopped (exit code "
                               f"{self._process.exitcode}) before answering")

    def close(self, force: bool = False) -> None:
        """Stop the worker; ``force`` kills it without waiting for the evaluation it runs."""
        with contextlib.suppress(EvalWorkerError):  # one that never started: nothing to stop
            self._started()
        if self._start_error is not None:
            self._conn.close()
            self.pending.clear()
            return
        if not force and self._process.is_alive():
            with contextlib.suppress(EOFError, OSError):
                self._conn.send(None)
            self._process.join(timeout=60)
        if self._process.is_alive():
            self._process.kill()
            self._process.join(timeout=5)
        self._conn.close()
        self.pending.clear()
