"""``train()``: train (or continue) a run of PPO, SAC or TD3 as its config says.

The envs and the model are made from the config (``RunSetupError`` if they cannot be), then
trained with checkpoints, evaluation by success rate and a progress bar; ``summary.json``
and ``learning_curve.png`` are written at the end. ``smartcar-train`` (``cli_train``) is the
command line.
"""

from __future__ import annotations

import contextlib
import json
import os
import signal
import sys
import time
from collections.abc import Iterator, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import yaml

from smartcar_gym.agents import zoo_keys
from smartcar_gym.agents.hyperparams import (
    build_algo_kwargs,
    policy_class,
    vecnormalize_settings,
)
from smartcar_gym.agents.runs import utc_timestamp


@dataclass
class TrainResult:
    """What a training call did (also written to ``summary.json``)."""

    run_dir: str
    start_timesteps: int
    num_timesteps: int
    wall_time_s: float
    steps_per_s: float
    interrupted: bool
    stop_signal: str | None = None  # "SIGINT" or "SIGTERM" when interrupted
    final_eval: dict[str, Any] | None = None
    #: seconds after training until the best model was known: the final evaluation and, with
    #: eval_async, the evaluations still running (and saving model.zip and a checkpoint)
    final_eval_s: float = 0.0
    best_eval: dict[str, Any] | None = None
    files: list[str] = field(default_factory=list)


class RunSetupError(ValueError):
    """The envs or the model of a run cannot be made from its config (the message says why)."""


def train(
    config: dict[str, Any],
    run_dir: str | os.PathLike,
    checkpoint: str | os.PathLike | None = None,
    command: str = "",
    progress: bool = True,
    save_replay_buffer: bool | None = None,
    extra_callbacks: Sequence[Any] = (),
    threads: int | None = None,
) -> TrainResult:
    """Train (or continue from ``checkpoint``) as ``config`` says, writing into ``run_dir``.

    Ctrl-C (SIGINT) or SIGTERM stops training at the next step; a checkpoint and
    ``model.zip`` are saved and the result has ``interrupted=True``. A second signal, or a
    KeyboardInterrupt raised by a callback, stops at once but still saves.

    ``save_replay_buffer`` (SAC/TD3; default: ``config["save_replay_buffer"]``) keeps the
    replay buffer with the checkpoints; the choice is stored in ``config.yaml``. Raises
    ``RunSetupError`` (or ``HyperparamsError``) if the envs or the model cannot be made; the
    failed start then leaves nothing behind (``config.yaml`` is written once both exist). Any
    other error (a full disk when saving a checkpoint...) closes the env workers and is raised;
    the checkpoints saved before it are left intact.

    ``threads``: the worker threads a batched run's cars are stepped on (the vector env's
    ``num_threads``; None: one per CPU); a subproc run has one process per env instead.
    """
    from stable_baselines3.common.callbacks import CallbackList

    from smartcar_gym.agents.callbacks import (
        CheckpointCallback,
        SuccessEvalCallback,
        atomic_write_text,
        checkpoint_steps,
        save_model_atomic,
    )
    from smartcar_gym.agents.run_control import ProgressBarCallback, StopOnSigint

    run_dir = Path(run_dir)
    algo = config["algo"]
    if save_replay_buffer is not None:
        config["save_replay_buffer"] = bool(save_replay_buffer)
    config.setdefault("save_replay_buffer", False)
    start = 0 if checkpoint is None else checkpoint_steps(checkpoint)
    segment = len(config.get("resumes", [])) + (checkpoint is not None)
    seed = int(config["seed"]) + start  # a resumed run does not replay the first run's goals
    with _undo_on_failure(run_dir, f"seg{segment}_"):
        venv, eval_env = _make_envs(config, run_dir, seed, segment, checkpoint, threads)
        try:
            model = _make_model(config, venv, seed, run_dir / "tb", checkpoint)
            if checkpoint is not None:
                _load_replay_buffer(model, Path(checkpoint), config)
                config["resumes"] = [*config.get("resumes", []), {
                    "from_checkpoint": str(Path(checkpoint).relative_to(run_dir)),
                    "from_timesteps": start, "n_timesteps": int(config["n_timesteps"]),
                    "command": command, "started": utc_timestamp(),
                    **_kept_episodes(Path(checkpoint)),
                }]
            atomic_write_text(run_dir / "config.yaml", yaml.safe_dump(config, sort_keys=False))
        except BaseException:
            for env in (venv, eval_env):
                if env is not None:
                    close_env(env)
            raise

    target = int(config["n_timesteps"])
    checkpoints = CheckpointCallback(run_dir, int(config["checkpoint_freq"]),
                                     config["save_replay_buffer"], segment=segment)
    callbacks: list[Any] = [checkpoints]
    evaluation = None
    if eval_env is not None:
        evaluation = SuccessEvalCallback(
            eval_env, run_dir / "eval", run_dir / "best_model.zip", int(config["eval_freq"]),
            int(config["eval_episodes"]), eval_seed=int(config["seed"]) + 1_000_000,
            eval_start=int(config.get("eval_start", 0)),  # runs before it existed: 0
        )
        callbacks.append(evaluation)
    bar = ProgressBarCallback(target, evaluation) if progress else None
    if bar is not None:
        callbacks.append(bar)
    callbacks.extend(zoo_keys.make_callbacks(config["hyperparams"].get("callback")))
    callbacks.extend(extra_callbacks)

    aborted = False  # a KeyboardInterrupt went through (second Ctrl-C, or raised by a callback)
    failed = False  # any other exception: the workers are closed before it goes on
    t0 = time.monotonic()
    with StopOnSigint() as stop:
        try:
            try:
                if model.num_timesteps < target:
                    model.learn(target - model.num_timesteps,
                                callback=CallbackList([stop, *callbacks]),
                                reset_num_timesteps=checkpoint is None, tb_log_name=algo.upper())
            except KeyboardInterrupt:
                aborted = True
            finally:
                if bar is not None:
                    bar.close()
            wall = time.monotonic() - t0
            trained = model.num_timesteps - start
            try:
                if checkpoints.model is None:  # learn() did not run (already at the target)
                    checkpoints.init_callback(model)
                checkpoints.save()
                save_model_atomic(model, run_dir / "model.zip")
                if evaluation is not None and not aborted:
                    if evaluation.model is None:
                        evaluation.init_callback(model)
                    evaluation.drain()  # eval_async: the evaluations still in the worker
                    last = evaluation.last_result
                    if not stop.requested and (last is None
                                               or last.timesteps != model.num_timesteps):
                        evaluation.evaluate()
                        evaluation.drain()
            except KeyboardInterrupt:
                aborted = True
            final_eval_s = time.monotonic() - t0 - wall
        except BaseException:
            # Workers left alive would keep the process from exiting (they ignore SIGTERM, so
            # multiprocessing's exit handler waits for them forever).
            failed = True
            raise
        finally:
            for env in (venv, eval_env):
                if env is not None:
                    close_env(env, force=aborted or failed)
            if evaluation is not None:
                evaluation.discard_pending()
        interrupted = aborted or stop.requested
        stop_signal = signal.Signals(stop.signum or signal.SIGINT).name if interrupted else None
    _close_logger(model)

    from smartcar_gym.agents.plots import plot_learning_curve

    plot_learning_curve(run_dir)
    result = TrainResult(
        run_dir=str(run_dir), start_timesteps=start, num_timesteps=int(model.num_timesteps),
        wall_time_s=wall, steps_per_s=trained / wall if wall > 0 else 0.0,
        final_eval_s=final_eval_s,
        interrupted=interrupted, stop_signal=stop_signal,
        final_eval=None if evaluation is None or evaluation.last_result is None
        else asdict(evaluation.last_result),
        best_eval=_read_json(run_dir / "best_model.json"),
    )
    result.files = sorted(
        {p.name + ("/" if p.is_dir() else "") for p in run_dir.iterdir()} | {"summary.json"}
    )
    atomic_write_text(run_dir / "summary.json", json.dumps(asdict(result), indent=2) + "\n")
    return result


@contextlib.contextmanager
def _undo_on_failure(run_dir: Path, monitor_prefix: str) -> Iterator[None]:
    """If the body raises, remove what a failed start-up created: this segment's Monitor files
    and the folders that did not exist before (only if left empty)."""
    created, folder = [], (run_dir / "monitor").absolute()
    while not folder.exists():
        created.append(folder)  # deepest first
        folder = folder.parent
    try:
        yield
    except BaseException:
        for path in (run_dir / "monitor").glob(f"{monitor_prefix}*.monitor.csv"):
            path.unlink(missing_ok=True)
        for folder in created:
            with contextlib.suppress(OSError):
                folder.rmdir()
        raise


def _make_envs(config: dict[str, Any], run_dir: Path, seed: int, segment: int,
               checkpoint: str | os.PathLike | None,
               threads: int | None = None) -> tuple[Any, Any]:
    """The training VecEnv (Monitor files ``seg<segment>_<i>``) and the eval VecEnv (or None;
    with ``eval_async`` an ``EvalWorker`` that builds it in a process of its own), batched
    ones on ``threads`` worker threads (None: the vector env's default),
    wrapped as the hyperparameters say: zoo's env_wrapper and vec_env_wrapper, VecNormalize
    (statistics from ``checkpoint``), VecFrameStack."""
    from stable_baselines3.common.vec_env import VecFrameStack

    from smartcar_gym.agents.env_factory import EnvSetupError, check_env
    from smartcar_gym.agents.eval_worker import EvalWorker
    from smartcar_gym.agents.models import vecnormalize_path_for
    from smartcar_gym.agents.vec_envs import make_vec_env, wrap_normalize
    from smartcar_gym.sim.engines import DEFAULT_ENGINE, on_engine

    env_id, hp = config["env"], config["hyperparams"]
    n_envs, env_kwargs = int(config["n_envs"]), dict(config.get("env_kwargs") or {})
    normalize, gamma = vecnormalize_settings(hp)
    wrapper, n_stack = hp.get("env_wrapper"), zoo_keys.frame_stack(hp.get("frame_stack"))
    monitor_kwargs = zoo_keys.monitor_kwargs(hp.get("monitor_kwargs"))
    try:
        # here, not in a worker: a clear error
        check_env(env_id, env_kwargs, env_wrapper=wrapper, monitor_kwargs=monitor_kwargs)
    except EnvSetupError as err:
        raise RunSetupError(str(err)) from err
    stats = None if checkpoint is None or normalize is None else vecnormalize_path_for(checkpoint)
    init = config.get("init")  # runs before it existed: none
    if checkpoint is None and normalize is not None and init and init["normalizer"]:
        stats = Path(init["normalizer"])

    def wrap(env: Any, **normalize_args: Any) -> Any:
        env = zoo_keys.wrap_vec_env(env, hp.get("vec_env_wrapper"))
        env = wrap_normalize(env, normalize, gamma, **normalize_args)
        return env if n_stack is None else VecFrameStack(env, n_stack)

    batched = config.get("vectorization", "subproc") == "batched"
    if config.get("eval_async") and config["eval_freq"] > 0 and not batched:
        raise RunSetupError("eval_async evaluates in a second process beside a batched run "
                            "(--vectorization batched); a subproc run's env workers have the "
                            "cores already")
    vectorization = "batched" if batched else "subproc"
    # the vector env's own argument, not the single env's (check_env, on_engine never see it)
    on_threads = {"num_threads": threads} if batched and threads is not None else {}
    if batched and wrapper is not None:
        raise RunSetupError("env_wrapper wraps single envs; --vectorization batched has "
                            "none (use vec_env_wrapper, or --vectorization subproc)")
    try:
        venv = make_vec_env(env_id, n_envs, seed=seed, env_kwargs={**env_kwargs, **on_threads},
                            monitor_dir=run_dir / "monitor", monitor_prefix=f"seg{segment}_",
                            env_wrapper=wrapper, monitor_kwargs=monitor_kwargs,
                            vectorization=vectorization)
    except EnvSetupError as err:
        raise RunSetupError(str(err)) from err
    eval_env = None
    try:
        try:
            venv = wrap(venv, load_path=stats)
        except (AssertionError, ValueError) as err:
            if checkpoint is not None or not init:
                raise
            raise RunSetupError(f"--init {init['model']}: its normaliser {stats} does not fit "
                                f"the run's observations ({err})") from None
        eval_engine = config.get("eval_engine")
        checked = env_kwargs  # the training env's, made above (check_env)
        if eval_engine is not None and eval_engine != env_kwargs.get("engine", DEFAULT_ENGINE):
            # evaluated on another engine (planar training, pybullet evaluations)
            env_kwargs = on_engine(env_kwargs, eval_engine)
        if config["eval_freq"] > 0:
            def make_eval_env() -> Any:
                # wrapped as the training env (batched on pybullet: a loop of single envs)
                n_eval_envs = min(n_envs, int(config["eval_episodes"]))
                if not batched:
                    n_eval_envs = min(n_eval_envs, os.cpu_count() or 1)
                env = make_vec_env(env_id, n_eval_envs, env_kwargs={**env_kwargs, **on_threads},
                                   env_wrapper=wrapper, monitor_kwargs=monitor_kwargs,
                                   vectorization=vectorization)
                return wrap(env, training=False)

            if config.get("eval_async"):  # runs before it existed: in the training process
                try:  # here, not in the worker: a clear error now (another engine's env)
                    if env_kwargs != checked:
                        check_env(env_id, env_kwargs, monitor_kwargs=monitor_kwargs)
                except EnvSetupError as err:
                    raise RunSetupError(f"the eval env: {err}") from err
                eval_env = EvalWorker(make_eval_env)
            else:
                eval_env = make_eval_env()
    except BaseException:
        for env in (venv, eval_env):
            if env is not None:
                close_env(env)
        raise
    return venv, eval_env


def _close_logger(model: Any) -> None:
    """Close the files of ``model``'s logger (TensorBoard's, CSV's) once the run is done with
    them; a model whose ``learn`` never ran has no logger."""
    try:
        logger = model.logger
    except AttributeError:
        return
    logger.close()


def close_env(env: Any, force: bool = False) -> None:
    """Close a VecEnv (``close_vec_env``) or stop an ``EvalWorker``."""
    from smartcar_gym.agents.eval_worker import EvalWorker
    from smartcar_gym.agents.vec_envs import close_vec_env

    if isinstance(env, EvalWorker):
        env.close(force=force)
    else:
        close_vec_env(env, force=force)


def _make_model(config: dict[str, Any], venv: Any, seed: int, tb_dir: Path,
                checkpoint: str | os.PathLike | None) -> Any:
    """A new model from the hyperparameters, or the checkpoint's; ``RunSetupError`` if the
    algorithm refuses them."""
    from smartcar_gym.agents.hyperparams import algo_class
    from smartcar_gym.agents.optimizers import foreach_updates

    algo, hp, device = config["algo"], config["hyperparams"], config["device"]
    cls = algo_class(algo)
    if checkpoint is not None:
        try:
            model = cls.load(str(checkpoint), env=venv, device=device, tensorboard_log=str(tb_dir))
        except Exception as err:
            raise RunSetupError(f"cannot load checkpoint {checkpoint}: {err}") from err
        model.set_random_seed(seed)
        foreach_updates(model)
        return model
    kwargs = build_algo_kwargs(algo, hp, n_actions=venv.action_space.shape[0])
    try:
        model = cls(policy_class(hp), venv, seed=seed, device=device,
                    tensorboard_log=str(tb_dir), verbose=0, **kwargs)
    except (ValueError, TypeError, AssertionError, RuntimeError) as err:
        given = ", ".join(f"{k}={v}" for k, v in hp.items() if k not in ("n_envs", "n_timesteps"))
        raise RunSetupError(
            f"{cls.__name__} refuses its hyperparameters: {type(err).__name__}: {err} "
            f"(hyperparameters: {given}; set in {config.get('hyperparams_file', 'the file')} "
            "or with --hyperparams)"
        ) from err
    if config.get("init"):  # runs before it existed: none
        _load_init(model, config["init"]["model"], algo, device)
    foreach_updates(model)  # the same numbers sooner
    return model


def _load_init(model: Any, path: str, algo: str, device: str) -> None:
    """``model``'s policy weights set to those of the model at ``path`` (``--init``);
    ``RunSetupError`` if it cannot be loaded or its spaces or network differ."""
    from smartcar_gym.agents.models import load_model

    try:
        source = load_model(path, algo, device=device)
    except Exception as err:
        raise RunSetupError(f"--init {path}: cannot load it as a {algo.upper()} model: "
                            f"{err}") from err
    for name in ("observation_space", "action_space"):
        if getattr(source, name) != getattr(model, name):
            raise RunSetupError(f"--init {path}: its {name.replace('_', ' ')} "
                                f"{getattr(source, name)} is not the run's "
                                f"{getattr(model, name)}")
    try:
        model.policy.load_state_dict(source.policy.state_dict())
    except RuntimeError as err:
        first = str(err).splitlines()[0]
        raise RunSetupError(f"--init {path}: its network is not the run's ({first}); give "
                            "the hyperparameters it was trained with") from err


def _load_replay_buffer(model: Any, checkpoint: Path, config: dict[str, Any]) -> None:
    """Load the replay buffer saved with ``checkpoint`` (SAC/TD3); warn if there is none."""
    from smartcar_gym.agents.runs import replay_buffer_path_for

    if not hasattr(model, "load_replay_buffer"):
        return
    path = replay_buffer_path_for(checkpoint)
    if path.is_file():
        model.load_replay_buffer(str(path))
        return
    others = sorted(p.name for p in checkpoint.parent.glob("*replay_buffer.pkl"))
    if others:
        why = f"{', '.join(others)} is not the buffer of {checkpoint.name}, so it is not used"
    elif config.get("save_replay_buffer"):
        why = f"no replay buffer was saved with {checkpoint.name}"
    else:
        why = "the run was started without --save-replay-buffer"
    print(f"smartcar-train: warning: {config['algo'].upper()} resumes with an empty replay "
          f"buffer: {why}", file=sys.stderr)


def _kept_episodes(checkpoint: Path) -> dict[str, Any]:
    """For the resume record: the Monitor rows written before ``checkpoint`` (from its
    ``.json``; nothing for checkpoints of versions that did not write one)."""
    from smartcar_gym.agents.runs import checkpoint_info_path_for

    try:
        info = json.loads(checkpoint_info_path_for(checkpoint).read_text())
        kept = {"segment": int(info["segment"]),
                "per_env": [int(n) for n in info["monitor_episodes"]]}
    except (OSError, ValueError, KeyError, TypeError):
        return {}
    return {"kept_episodes": kept}


def _read_json(path: Path) -> dict[str, Any] | None:
    return json.loads(path.read_text()) if path.exists() else None
