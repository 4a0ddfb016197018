"""An SB3 policy with its VecNormalize statistics as one ONNX graph.

``actor_layers(model)`` reads the deterministic actor of a PPO, SAC or TD3 ``MlpPolicy`` as
layers (``("Gemm", weight, bias)``, ``("Tanh",)``, ``("Relu",)``, ``("Sigmoid",)``) and
says how ``predict`` ends: clipping into the action space (PPO) or ``tanh`` then rescaling
into it (SAC, TD3). ``policy_graph`` builds the ONNX model (opset ``OPSET``): ``obs`` (float32
``(N, D)``) minus the statistics' mean, divided by ``sqrt(var + epsilon)``, clipped to
``clip_obs``; the layers; the action's end; ``action`` out. Only the operators that
``runtime.numpy_graph`` runs appear in it.
"""

from __future__ import annotations

import json
from typing import Any

import numpy as np

__all__ = ["INPUT", "OPSET", "OUTPUT", "ExportError", "actor_layers", "policy_graph"]

INPUT, OUTPUT = "obs", "action"
OPSET = 17
IR_VERSION = 8  # onnxruntime 1.13 and later read it


class ExportError(ValueError):
    """A policy that cannot be exported (one line naming what is not supported)."""


def _module_layers(modules: Any) -> list[tuple[Any, ...]]:
    """torch modules (Linear and activations) as layers."""
    from torch import nn

    layers: list[tuple[Any, ...]] = []
    activations = {nn.Tanh: "Tanh", nn.ReLU: "Relu", nn.Sigmoid: "Sigmoid"}
    for module in modules:
        if isinstance(module, nn.Linear):
            weight = module.weight.detach().cpu().numpy().astype(np.float32)
            bias = (np.zeros(weight.shape[0], np.float32) if module.bias is None
                    else module.bias.detach().cpu().numpy().astype(np.float32))
            layers.append(("Gemm", weight, bias))
        elif type(module) in activations:
            layers.append((activations[type(module)],))
        elif not isinstance(module, (nn.Identity, nn.Flatten)):
            raise ExportError(f"the policy network has a {type(module).__name__} layer; the "
                              "export takes Linear layers with Tanh, ReLU or Sigmoid")
    return layers


def actor_layers(model: Any) -> tuple[list[tuple[Any, ...]], bool]:
    """The deterministic actor of an SB3 model as layers, and whether ``predict`` squashes
    (``tanh``, then rescales into the action space) rather than clips."""
    from stable_baselines3.common.torch_layers import FlattenExtractor

    policy = model.policy
    name = type(model).__name__
    space = model.observation_space
    if len(getattr(space, "shape", ()) or ()) != 1:
        raise ExportError(f"a {name} policy for observations {space}; the export takes flat "
                          "Box observations (MlpPolicy), not Dict spaces or images")
    if name == "PPO":
        extractor, squash = policy.pi_features_extractor, policy.squash_output
        modules = [*policy.mlp_extractor.policy_net, policy.action_net]
    elif name == "SAC":
        actor = policy.actor
        extractor, squash = actor.features_extractor, True
        modules = [*actor.latent_pi, actor.mu, _tanh()]
    elif name == "TD3":
        actor = policy.actor
        extractor, squash = actor.features_extractor, True
        modules = list(actor.mu)
    else:
        raise ExportError(f"a {name} model; the export takes PPO, SAC and TD3")
    if not isinstance(extractor, FlattenExtractor):
        raise ExportError(f"the {name} policy's features extractor is "
                          f"{type(extractor).__name__}; the export takes FlattenExtractor")
    return _module_layers(modules), bool(squash)


def _tanh() -> Any:
    from torch import nn

    return nn.Tanh()


def policy_graph(model: Any, vec_normalize: Any, metadata: dict[str, Any]) -> Any:
    """The ONNX ``ModelProto`` of ``model`` (SB3) after ``vec_normalize`` (its VecNormalize,
    or None), with ``metadata`` as the ``smartcar_gym`` metadata property."""
    from onnx import TensorProto, checker, helper, numpy_helper

    from smartcar_gym.runtime.metadata import METADATA_KEY

    layers, squash = actor_layers(model)
    size = int(model.observation_space.shape[0])
    low = np.asarray(model.action_space.low, np.float32)
    high = np.asarray(model.action_space.high, np.float32)
    consts: dict[str, np.ndarray] = {}
    nodes: list[Any] = []
    value = INPUT

    def add(op: str, *inputs: Any, **attributes: Any) -> None:
        nonlocal value
        names = [value]
        for i, array in enumerate(inputs):
            name = f"{op.lower()}{len(nodes)}_{i}"
            consts[name] = np.asarray(array, np.float32)
            names.append(name)
        out = f"{op.lower()}{len(nodes)}"
        nodes.append(helper.make_node(op, names, [out], name=out, **attributes))
        value = out

    if vec_normalize is not None and vec_normalize.norm_obs:
        rms = vec_normalize.obs_rms
        if not hasattr(rms, "mean") or np.shape(rms.mean) != (size,):
            raise ExportError(f"VecNormalize statistics of shape {np.shape(rms.mean)}; the "
                              f"model takes ({size},)")
        add("Sub", rms.mean)
        add("Div", np.sqrt(rms.var + vec_normalize.epsilon))
        add("Clip", -vec_normalize.clip_obs, vec_normalize.clip_obs)
    for op, *params in layers:
        add(op, *params, **({"transB": 1} if op == "Gemm" else {}))
    if squash:
        scale, offset = (high - low) / 2, (high + low) / 2
        if not (np.all(scale == 1) and np.all(offset == 0)):
            add("Mul", scale)
            add("Add", offset)
    elif np.isfinite(low).all() and np.isfinite(high).all():
        add("Max", low)
        add("Min", high)
    nodes[-1].output[0] = OUTPUT
    n_actions = int(np.prod(model.action_space.shape))
    graph = helper.make_graph(
        nodes, "smartcar_policy",
        [helper.make_tensor_value_info(INPUT, TensorProto.FLOAT, ["N", size])],
        [helper.make_tensor_value_info(OUTPUT, TensorProto.FLOAT, ["N", n_actions])],
        [numpy_helper.from_array(array, name) for name, array in consts.items()])
    onnx_model = helper.make_model(graph, producer_name="smartcar-export",
                                   opset_imports=[helper.make_opsetid("", OPSET)])
    onnx_model.ir_version = IR_VERSION
    helper.set_model_props(onnx_model, {METADATA_KEY: json.dumps(metadata, sort_keys=True)})
    checker.check_model(onnx_model, full_check=True)
    return onnx_model
