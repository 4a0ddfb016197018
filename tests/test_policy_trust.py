"""A policy's files are data (docs/export.md, "What a policy file can and cannot make the
package do"): the env id, engine and env kwargs an exported ``.onnx`` file, its ``.json`` or a
run folder names are checked by one function (``registration.check_policy_env``) before
anything is imported or built; every metadata key's type and shape is checked when it is read;
the numpy runtime checks a graph's wiring when it loads it. Each refusal is one line."""

from __future__ import annotations

import json
import sys
import zipfile
from pathlib import Path

import numpy as np
import pytest

onnx = pytest.importorskip("onnx")
pytest.importorskip("stable_baselines3")

from onnx import TensorProto, helper  # noqa: E402

from smartcar_gym.agents.models import PRETRAINED_POLICIES, pretrained_files  # noqa: E402
from smartcar_gym.export.cli import main as export_main  # noqa: E402
from smartcar_gym.policy import Policy, PolicyError  # noqa: E402
from smartcar_gym.runtime.metadata import METADATA_KEY, check_metadata, side_file  # noqa: E402
from smartcar_gym.runtime.onnx_policy import OnnxPolicyError, load_onnx  # noqa: E402

IDS = "SmartCar-v0, SmartCarSim-v0, SmartCarArrive-v0, SmartCarNav-v0, SmartCarGoal-v0"


@pytest.fixture(scope="module")
def exported(tmp_path_factory) -> Path:
    """The default shipped policy, exported."""
    path = tmp_path_factory.mktemp("trust") / "policy.onnx"
    assert export_main(["--pretrained", "-o", str(path), "--check", "0"]) == 0
    return path


def _metadata(path: Path) -> dict:
    model = onnx.load(path)
    return json.loads(next(p.value for p in model.metadata_props if p.key == METADATA_KEY))


def _with_metadata(source: Path, target: Path, **changes) -> Path:
    """``source`` saved as ``target`` with its metadata's keys changed (only the metadata)."""
    model = onnx.load(source)
    for prop in model.metadata_props:
        if prop.key == METADATA_KEY:
            prop.value = json.dumps({**json.loads(prop.value), **changes})
    onnx.save(model, target)
    return target


def _refused(exported: Path, tmp_path: Path, changes: dict, expected: str) -> None:
    """The exported policy with its metadata changed is refused in one line: ``expected``."""
    path = _with_metadata(exported, tmp_path / "policy.onnx", **changes)
    with pytest.raises(PolicyError) as err:
        Policy.load(path, runtime="numpy")
    assert str(err.value).startswith(f"{path}: {expected}"), str(err.value)
    assert "\n" not in str(err.value)


def _payload(folder: Path) -> Path:
    """A ``payload.py`` in ``folder`` that leaves a mark when imported; the mark's path."""
    mark = folder / "payload-ran"
    (folder / "payload.py").write_text(f"open({str(mark)!r}, 'w').close()\n")
    return mark


# -- 1. the env a policy file names ---------------------------------------------------------
def test_a_policy_file_naming_a_module_in_its_env_id_imports_nothing(exported, tmp_path,
                                                                      monkeypatch):
    mark = _payload(tmp_path)
    monkeypatch.syspath_prepend(str(tmp_path))  # as a script run from that folder has it
    monkeypatch.chdir(tmp_path)
    evil = _with_metadata(exported, tmp_path / "policy.onnx", env_id="payload:SmartCar-v0")
    with pytest.raises(PolicyError) as err:
        Policy.load(evil).make_env()
    line = str(err.value)
    assert line.startswith(f"{evil}: metadata: env id 'payload:SmartCar-v0' is not an id "
                           "smartcar-gym registered (a policy's file cannot name a module to "
                           f"import); expected one of {IDS}")
    assert "\n" not in line and not mark.exists() and "payload" not in sys.modules


def test_an_installed_module_before_the_colon_is_not_imported(exported, tmp_path):
    had_this = "this" in sys.modules
    evil = _with_metadata(exported, tmp_path / "this.onnx", env_id="this:SmartCar-v0")
    with pytest.raises(PolicyError, match="env id 'this:SmartCar-v0' is not an id"):
        Policy.load(evil)
    assert ("this" in sys.modules) == had_this


def test_make_env_refuses_an_id_that_names_a_module(tmp_path, monkeypatch):
    mark = _payload(tmp_path)
    monkeypatch.syspath_prepend(str(tmp_path))
    policy = Policy(model=None, env_id="payload:SmartCar-v0")
    with pytest.raises(PolicyError, match=r"^env_id: env id 'payload:SmartCar-v0' is not an id "
                                          r"smartcar-gym registered"):
        policy.make_env()
    assert not mark.exists()


@pytest.mark.parametrize(("changes", "expected"), [
    ({"env_kwargs": {"bogus": 1}}, "metadata: env_kwargs 'bogus' is not a keyword SmartCar-v0 "
                                   "takes; expected some of arena_size, controller_config, "),
    ({"env_kwargs": {"model": "robot.xacro"}}, "metadata: env_kwargs 'model' is not taken "
                                               "from a policy's file"),
    ({"env_kwargs": {"task": "nav"}}, "metadata: env_kwargs 'task' is not a keyword"),
    ({"env_kwargs": {"engine": "nosuch"}, "engine": "nosuch"},
     "metadata: env_kwargs engine 'nosuch' is not a registered engine; expected one of "
     "pybullet, mujoco, planar"),
    ({"engine": "warp"}, "metadata: engine 'warp' is not a registered engine"),
    ({"engine": "mujoco"}, "metadata: engine 'mujoco' but env_kwargs run on 'pybullet'; "
                           "expected the same engine"),
    ({"env_kwargs": {"max_episode_steps": -1}}, "metadata: env_kwargs max_episode_steps must "
                                                "be a whole number > 0, got -1"),
    ({"env_id": "CartPole-v1"}, "metadata: env id 'CartPole-v1' is not an id smartcar-gym "
                                "registered; expected one of SmartCar-v0,"),
])
def test_the_env_kwargs_and_engine_a_policy_file_names_are_checked(exported, tmp_path, changes,
                                                                    expected):
    _refused(exported, tmp_path, changes, expected)


def test_the_side_file_is_read_with_the_same_check(exported, tmp_path):
    meta = {**_metadata(exported), "env_id": "payload:SmartCar-v0"}
    side = side_file(tmp_path / "policy.onnx")
    side.write_text(json.dumps(meta))
    with pytest.raises(ValueError, match=r"policy.json: metadata: env id 'payload:SmartCar-v0'"):
        check_metadata(side.read_text(), str(side))
    assert check_metadata(side_file(exported).read_text(), "x")["env_id"] == "SmartCar-v0"


def _train_run(folder: Path, env: str, env_kwargs: dict) -> Path:
    import yaml

    folder.mkdir()
    (folder / "config.yaml").write_text(yaml.safe_dump({
        "algo": "ppo", "env": env, "env_kwargs": env_kwargs, "seed": 0, "n_envs": 1,
        "n_timesteps": 1, "hyperparams": {}, "eval_freq": 1, "eval_episodes": 1,
        "checkpoint_freq": 1}))
    return folder / "config.yaml"


def _exported_folder(folder: Path, env: str, env_kwargs: dict) -> Path:
    folder.mkdir()
    (folder / "provenance.json").write_text(json.dumps({
        "algo": "ppo", "env": env, "env_kwargs": env_kwargs, "source": "x", "evaluation": {},
        "exported": "now"}))
    return folder / "provenance.json"


def _zoo_run(folder: Path, env: str, env_kwargs: dict) -> Path:
    import yaml

    params = folder / "SmartCar-v0"
    params.mkdir(parents=True)
    (params / "config.yml").write_text("normalize: false\n")
    (params / "args.yml").write_text(yaml.safe_dump({"algo": "ppo", "env": env,
                                                     "env_kwargs": env_kwargs}))
    return params / "args.yml"


@pytest.mark.parametrize("place", [_train_run, _exported_folder, _zoo_run])
@pytest.mark.parametrize(("env", "env_kwargs", "expected"), [
    ("payload:SmartCar-v0", {}, "env id 'payload:SmartCar-v0' is not an id smartcar-gym "
                                "registered (a policy's file cannot name a module to import)"),
    ("SmartCar-v0", {"model": "robot.xacro"}, "env_kwargs 'model' is not taken from a "
                                              "policy's file"),
    ("SmartCar-v0", {"nonsense": 1}, "env_kwargs 'nonsense' is not a keyword SmartCar-v0 "
                                     "takes"),
])
def test_a_run_folder_s_env_is_checked_before_its_model_is_unpickled(tmp_path, monkeypatch,
                                                                     place, env, env_kwargs,
                                                                     expected):
    import smartcar_gym.agents.policies as policies

    mark = _payload(tmp_path)
    monkeypatch.syspath_prepend(str(tmp_path))
    run_file = place(tmp_path / "run", env, env_kwargs)
    model = run_file.parent / {"config.yaml": "model.zip", "provenance.json": "policy.zip",
                               "args.yml": "../SmartCar-v0.zip"}[run_file.name]
    with zipfile.ZipFile(model, "w") as archive:
        archive.writestr("data", "{}")

    def unpickled(*args, **kwargs):
        raise AssertionError("the model was loaded before its run's env was checked")

    monkeypatch.setattr(policies, "_load_model", unpickled)
    with pytest.raises(PolicyError) as err:
        Policy.load(model.resolve())
    assert str(err.value).startswith(f"{run_file.resolve()}: {expected}"), str(err.value)
    assert not mark.exists()


def test_the_shipped_policies_name_what_the_check_lets_through():
    from smartcar_gym.registration import PolicyEnvError, check_policy_env

    for name in PRETRAINED_POLICIES:
        with pretrained_files(name) as folder:
            run = json.loads((folder / "provenance.json").read_text())
        assert check_policy_env(name, run["env"], run["env_kwargs"]) == (run["env"],
                                                                         run["env_kwargs"])
    with pytest.raises(PolicyEnvError, match="^x: env_kwargs must be a mapping"):
        check_policy_env("x", "SmartCar-v0", ["engine"])


# -- 3. metadata of the wrong types ---------------------------------------------------------
@pytest.mark.parametrize(("changes", "expected"), [
    ({"env_kwargs": ["engine", "planar"]}, "metadata: env_kwargs must be a mapping of keyword "
                                           "names to values, got ['engine', 'planar']"),
    ({"action_low": "-1"}, "metadata action_low is '-1'; expected a list of 2 finite numbers "
                           "(action_shape [2])"),
    ({"action_high": [1.0]}, "metadata action_high is [1.0]; expected a list of 2 finite "
                             "numbers"),
    ({"action_low": [1.0, 1.0], "action_high": [0.0, 0.0]}, "metadata action_low [1.0, 1.0] "
                                                            "lies above action_high"),
    ({"observation_names": list(range(21))}, "metadata observation_names is [0, 1, 2, "),
    ({"observation_shape": "21"}, "metadata observation_shape is '21'; expected [D], one "
                                  "whole number > 0"),
    ({"action_shape": [1000000000, 1]}, "metadata action_shape is [1000000000, 1]; expected "
                                        "[A], one whole number > 0"),
    ({"versions": ["1.0"]}, "metadata versions is ['1.0']; expected a mapping"),
    ({"algo": 3}, "metadata algo is 3; expected a string"),
    ({"algo": "dqn"}, "metadata algo 'dqn'; expected one of ppo, sac, td3"),
    ({"observation_names": ["x"] * 20}, "metadata names 20 observations but observation_shape "
                                        "is [21]"),
])
def test_metadata_of_the_wrong_type_is_one_line_naming_the_key(exported, tmp_path, changes,
                                                               expected):
    _refused(exported, tmp_path, changes, expected)


def test_metadata_that_is_not_an_object_is_named():
    with pytest.raises(ValueError, match=r"^f.onnx: its 'smartcar_gym' metadata is a list; "
                                         r"expected a JSON object$"):
        check_metadata("[1, 2]", "f.onnx")


# -- 4. the graph's wiring ------------------------------------------------------------------
META = {"format": "smartcar-gym policy 1", "algo": "ppo", "env_id": "SmartCar-v0",
        "env_kwargs": {}, "engine": "pybullet", "observation_names": ["a", "b", "c"],
        "observation_shape": [3], "action_shape": [2], "action_low": [-1.0, -1.0],
        "action_high": [1.0, 1.0], "input": "obs", "output": "action", "versions": {}}


def _graph(tmp_path: Path, nodes: list, outputs=(("action", 2),), weights: int = 2) -> Path:
    """A model of ``nodes`` on ``obs`` (N, 3) with initializers W (weights x 3) and B."""
    rng = np.random.default_rng(0)
    inits = [helper.make_tensor("W", TensorProto.FLOAT, (weights, 3),
                                rng.normal(size=(weights, 3)).ravel().tolist()),
             helper.make_tensor("B", TensorProto.FLOAT, (weights,), [0.0] * weights)]
    graph = helper.make_graph(
        nodes, "g", [helper.make_tensor_value_info("obs", TensorProto.FLOAT, ["N", 3])],
        [helper.make_tensor_value_info(name, TensorProto.FLOAT, ["N", size])
         for name, size in outputs], inits)
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 17)])
    model.ir_version = 8
    helper.set_model_props(model, {METADATA_KEY: json.dumps(META)})
    path = tmp_path / "graph.onnx"
    onnx.save(model, path)
    return path


def _gemm(inputs=("obs", "W", "B"), outputs=("action",), name="layer"):
    return helper.make_node("Gemm", list(inputs), list(outputs), name=name, transB=1)


def test_a_well_wired_graph_loads(tmp_path):
    path = _graph(tmp_path, [_gemm(outputs=["h"]), helper.make_node("Tanh", ["h"], ["action"])])
    assert load_onnx(path, runtime="numpy").predict(np.zeros(3))[0].shape == (2,)


@pytest.mark.parametrize(("nodes", "outputs", "expected"), [
    ([_gemm(inputs=["obs"])], None, "node 'layer' (Gemm) has 1 inputs and 1 outputs; Gemm "
                                    "takes 2 to 3 inputs and gives one output"),
    ([_gemm(outputs=["h"]), helper.make_node("Relu", ["h"], [], name="act")], None,
     "node 'act' (Relu) has 1 inputs and 0 outputs; Relu takes 1 inputs"),
    ([_gemm(outputs=["h"]), helper.make_node("Add", ["h", "ghost"], ["action"], name="add")],
     None, "node 'add' (Add) takes 'ghost', which no earlier node, input or initializer "
           "defines"),
    ([_gemm(outputs=["h"])], None, "the graph's output 'action' is produced by no node"),
    ([helper.make_node("Tanh", ["h"], ["action"], name="early"), _gemm(outputs=["h"])], None,
     "node 'early' (Tanh) takes 'h', which no earlier node"),
    ([_gemm()], (("action", 2), ("b", 2), ("c", 2)), "the graph has 1 inputs and 3 outputs; a "
                                                     "policy graph has one of each"),
    ([_gemm()], (("action", 3),), "the graph's output has shape (None, 3) but its metadata "
                                  "declares action_shape [2]; expected (N, 2)"),
    ([helper.make_node("Gemm", ["obs", "W", "B"], ["action"], name="layer", transB=1,
                       alpha=[1.0, 2.0])], None, "node 'layer' (Gemm): its attributes cannot "
                                                 "be read"),
])
def test_a_graph_wired_wrong_is_one_line_naming_the_node(tmp_path, nodes, outputs, expected):
    path = _graph(tmp_path, nodes, outputs or (("action", 2),))
    with pytest.raises(OnnxPolicyError) as err:
        load_onnx(path, runtime="numpy")
    assert str(err.value).startswith(f"{path}: {expected}"), str(err.value)
    assert "\n" not in str(err.value)


@pytest.mark.parametrize("runtime", ["numpy", "onnxruntime"])
def test_actions_of_another_shape_than_the_metadata_s_are_refused_at_load(tmp_path, runtime):
    if runtime == "onnxruntime":
        pytest.importorskip("onnxruntime")
    path = _graph(tmp_path, [_gemm()], (("action", None),), weights=3)
    with pytest.raises(OnnxPolicyError, match=r"the graph gives actions of shape \(1, 3\) for "
                                              r"one observation; its metadata declares "
                                              r"action_shape \[2\]$"):
        load_onnx(path, runtime=runtime)
