"""An exported policy (``smartcar-export``'s ``.onnx``) as a model with SB3's ``predict``.

``load_onnx(path)`` reads the file and its metadata and runs the graph with onnxruntime where
it is installed (``runtime="auto"``), else with ``numpy_graph.NumpyGraph``; neither needs
torch. The graph takes raw float32 observations ``(N, D)`` and gives the actions the SB3
model's deterministic ``predict`` gives after its VecNormalize statistics: normalisation and
action clipping are inside it, so ``Policy`` applies no normaliser of its own.

Bad input raises ``OnnxPolicyError`` with one line: a file that is not ONNX, no smartcar
metadata or metadata of the wrong types (``metadata.check_metadata``, which also checks the
env it names), a graph wired wrong (``numpy_graph.check_graph``), whose input disagrees with
its metadata or whose actions for one observation are not of the metadata's action shape, an
operator the numpy evaluator does not know, or observations of another shape.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

import gymnasium as gym
import numpy as np

from smartcar_gym.extras import missing_modules
from smartcar_gym.runtime.metadata import METADATA_KEY, check_metadata
from smartcar_gym.runtime.numpy_graph import NumpyGraph, check_graph
from smartcar_gym.runtime.onnx_file import OnnxFormatError, read_model

__all__ = ["RUNTIMES", "OnnxPolicy", "OnnxPolicyError", "is_onnx_path", "load_onnx"]

RUNTIMES = ("auto", "onnxruntime", "numpy")
Runtime = Literal["auto", "onnxruntime", "numpy"]


class OnnxPolicyError(ValueError):
    """An exported policy that cannot be run (one line naming the file and the cause)."""


def is_onnx_path(source: Any) -> bool:
    """Whether ``source`` names an ONNX file (by its ``.onnx`` suffix)."""
    return isinstance(source, (str, os.PathLike)) and Path(source).suffix.lower() == ".onnx"


@dataclass(eq=False)
class OnnxPolicy:
    """An exported policy: ``predict`` as SB3's, ``metadata`` as ``smartcar-export`` wrote
    it, ``runtime`` the engine that runs the graph (``"onnxruntime"`` or ``"numpy"``)."""

    path: Path
    metadata: dict[str, Any]
    runtime: str
    observation_space: gym.spaces.Box
    action_space: gym.spaces.Box
    _run: Any

    def predict(self, observation: np.ndarray, state: Any = None, episode_start: Any = None,
                deterministic: bool = True) -> tuple[np.ndarray, None]:
        """The actions for a batch ``(N, D)`` (or one observation ``(D,)``): float32, as
        SB3's deterministic ``predict``. The graph has no sampling: ``deterministic=False``
        raises ``OnnxPolicyError``."""
        if not deterministic:
            raise OnnxPolicyError(f"{self.path} holds the deterministic policy only; sampled "
                                  "actions need the SB3 model (.zip)")
        obs = np.asarray(observation, dtype=np.float32)
        size = self.observation_space.shape[0]
        if obs.shape[-1:] != (size,) or obs.ndim > 2:
            raise OnnxPolicyError(f"observations of shape {obs.shape}; {self.path} takes "
                                  f"({size},) or a batch (N, {size})")
        single = obs.ndim == 1
        actions = self._run(obs[None] if single else obs)
        actions = np.asarray(actions, dtype=np.float32)
        return (actions[0] if single else actions), None


def load_onnx(path: str | os.PathLike, runtime: Runtime = "auto") -> OnnxPolicy:
    """The policy exported to ``path`` (see the module docstring); ``runtime``: ``"auto"``
    (onnxruntime if installed, else numpy), ``"onnxruntime"`` or ``"numpy"``."""
    path = Path(path)
    if runtime not in RUNTIMES:
        raise OnnxPolicyError(f"unknown ONNX runtime {runtime!r}; expected one of "
                              f"{', '.join(RUNTIMES)}")
    try:
        data = path.read_bytes()
    except OSError as err:
        raise OnnxPolicyError(f"--model: cannot read {path}: {err.strerror or err}") from None
    try:
        model = read_model(data)
    except OnnxFormatError as err:
        raise OnnxPolicyError(f"--model: {path} is not an ONNX model: {err}") from None
    try:
        meta = check_metadata(model.metadata.get(METADATA_KEY), str(path))
    except ValueError as err:
        raise OnnxPolicyError(str(err)) from None
    try:
        check_graph(model)
    except ValueError as err:
        raise OnnxPolicyError(f"{path}: {err}") from None
    size = _input_size(model, meta, path)
    action_shape = tuple(meta["action_shape"])
    _check_output(model, action_shape, path)
    if runtime == "auto":
        runtime = "numpy" if missing_modules(("onnxruntime",)) else "onnxruntime"
    run = _onnxruntime(data, path) if runtime == "onnxruntime" else _numpy(model, path)
    _check_actions(run, size, action_shape, path)
    return OnnxPolicy(
        path=path, metadata=meta, runtime=runtime,
        observation_space=gym.spaces.Box(-np.inf, np.inf, (size,), np.float32),
        action_space=gym.spaces.Box(np.asarray(meta["action_low"], dtype=np.float32),
                                    np.asarray(meta["action_high"], dtype=np.float32),
                                    dtype=np.float32),
        _run=run)


def _check_output(model: Any, action_shape: tuple[int, ...], path: Path) -> None:
    """The graph's output, as declared, is a batch of the metadata's actions ``(N, A)``."""
    shape = model.graph.outputs[0].shape
    if shape is not None and (len(shape) != 1 + len(action_shape) or any(
            d is not None and d != a for d, a in zip(shape[1:], action_shape, strict=True))):
        raise OnnxPolicyError(f"{path}: the graph's output has shape {shape} but its metadata "
                              f"declares action_shape {list(action_shape)}; expected "
                              f"(N, {', '.join(map(str, action_shape))})")


def _check_actions(run: Any, size: int, action_shape: tuple[int, ...], path: Path) -> None:
    """The graph, run on one observation of zeros, gives one action of ``action_shape``."""
    try:
        actions = np.asarray(run(np.zeros((1, size), dtype=np.float32)))
    except Exception as err:  # numpy's or onnxruntime's errors: the file is the cause
        first = (str(err).strip().splitlines() or [type(err).__name__])[0]
        raise OnnxPolicyError(f"{path}: the graph fails on one observation: "
                              f"{type(err).__name__}: {first}") from None
    if actions.shape != (1, *action_shape):
        raise OnnxPolicyError(f"{path}: the graph gives actions of shape {actions.shape} for "
                              f"one observation; its metadata declares action_shape "
                              f"{list(action_shape)}")


def _input_size(model: Any, meta: dict[str, Any], path: Path) -> int:
    """The observation size, the same in the graph's input and in the metadata."""
    inputs = [v for v in model.graph.inputs if v.name not in model.graph.initializers]
    shape = inputs[0].shape if len(inputs) == 1 else None
    if shape is None or len(shape) != 2 or shape[1] is None:
        raise OnnxPolicyError(f"{path}: the graph's input should be one batch of observations "
                              "(N, D); it is not")
    names, declared = meta["observation_names"], tuple(meta["observation_shape"])
    if declared != (shape[1],) or len(names) != shape[1]:
        raise OnnxPolicyError(f"{path}: the graph takes {shape[1]} observation values but its "
                              f"metadata declares shape {declared} and names {len(names)}")
    return int(shape[1])


def _numpy(model: Any, path: Path) -> Any:
    try:
        return NumpyGraph(model).run
    except ValueError as err:  # UnknownOperatorError among them
        raise OnnxPolicyError(f"{path}: {err}") from None


def _onnxruntime(data: bytes, path: Path) -> Any:
    try:
        import onnxruntime as ort
    except ImportError:
        raise OnnxPolicyError("runtime onnxruntime: not installed (pip install "
                              "\"smartcar-gym[onnx]\"); the numpy runtime needs nothing") from None
    options = ort.SessionOptions()
    options.intra_op_num_threads = 1  # an MLP of a few layers: threads cost more than they save
    options.inter_op_num_threads = 1
    options.log_severity_level = 3
    try:
        session = ort.InferenceSession(data, options, providers=["CPUExecutionProvider"])
    except Exception as err:  # onnxruntime's own errors: the file is the cause
        first = str(err).strip().splitlines()[0] if str(err).strip() else type(err).__name__
        raise OnnxPolicyError(f"{path}: onnxruntime cannot load it: {first}") from None
    name = session.get_inputs()[0].name
    output = session.get_outputs()[0].name
    return lambda obs: session.run([output], {name: obs})[0]
