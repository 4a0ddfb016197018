"""``smartcar-export`` and ``smartcar_gym.runtime``: every shipped policy as ONNX, run by
onnxruntime and by the numpy evaluator, acts as its SB3 model does (within 1e-5 over 10,000
observations of seeded episodes), drives without torch, and bad files get one line."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap
import zipfile
from pathlib import Path

import numpy as np
import pytest

onnx = pytest.importorskip("onnx")
pytest.importorskip("onnxruntime")
pytest.importorskip("stable_baselines3")

from smartcar_gym.agents.cli_eval import main as eval_main  # noqa: E402
from smartcar_gym.agents.episodes import RECORD_TOLERANCE, act_batch  # noqa: E402
from smartcar_gym.agents.models import PRETRAINED_POLICIES  # noqa: E402
from smartcar_gym.export.checks import episode_observations  # noqa: E402
from smartcar_gym.export.cli import main as export_main  # noqa: E402
from smartcar_gym.policy import Policy, PolicyError  # noqa: E402
from smartcar_gym.runtime.metadata import METADATA_KEY, side_file  # noqa: E402
from smartcar_gym.runtime.onnx_file import read_model  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
OBSERVATIONS = 10_000


@pytest.fixture(scope="module")
def exported(tmp_path_factory) -> dict[str, Path]:
    """Every shipped policy exported with ``smartcar-export --pretrained NAME``."""
    folder = tmp_path_factory.mktemp("onnx")
    paths = {}
    for name in PRETRAINED_POLICIES:
        paths[name] = folder / f"{name}.onnx"
        assert export_main(["--pretrained", name, "-o", str(paths[name]), "--check", "0"]) == 0
    return paths


@pytest.mark.slow
@pytest.mark.parametrize("name", list(PRETRAINED_POLICIES))
def test_onnxruntime_numpy_and_sb3_take_the_same_actions(exported, name):
    sb3 = Policy.load(name)
    by_ort = Policy.load(exported[name], runtime="onnxruntime")
    by_numpy = Policy.load(exported[name], runtime="numpy")
    assert (by_ort.algo, by_ort.env_id, by_ort.env_kwargs) == (sb3.algo, sb3.env_id,
                                                               sb3.env_kwargs)
    obs = episode_observations(by_numpy, OBSERVATIONS)
    assert obs.shape[0] == OBSERVATIONS and np.unique(obs, axis=0).shape[0] > OBSERVATIONS // 2
    expected = act_batch(sb3, obs)
    actions = {"onnxruntime": act_batch(by_ort, obs), "numpy": act_batch(by_numpy, obs)}
    for runtime, got in actions.items():
        assert np.abs(got - expected).max() <= 1e-5, runtime
    assert np.abs(actions["numpy"] - actions["onnxruntime"]).max() <= 1e-5
    one_at_a_time = np.array([by_numpy.act(o) for o in obs[:500]])  # Policy.act, batch of one
    assert np.abs(one_at_a_time - expected[:500]).max() <= 1e-5
    assert sb3.algo == ("sac" if name == "nav" else "ppo")  # PPO and SAC both covered


def test_the_metadata_says_env_engine_observations_and_versions(exported):
    meta = json.loads(side_file(exported["mujoco"]).read_text())
    embedded = json.loads(read_model(exported["mujoco"].read_bytes()).metadata[METADATA_KEY])
    assert meta == embedded
    assert (meta["env_id"], meta["env_kwargs"], meta["engine"]) == ("SmartCar-v0",
                                                                    {"engine": "mujoco"},
                                                                    "mujoco")
    assert meta["observation_names"][:2] == ["odom_x", "odom_y"]
    assert len(meta["observation_names"]) == meta["observation_shape"][0] == 21
    assert meta["versions"]["stable-baselines3"] and meta["versions"]["smartcar-gym"]
    assert meta["source"] == "pretrained:mujoco"


def test_the_protobuf_reader_reads_what_onnx_wrote(exported):
    from onnx import numpy_helper

    theirs = onnx.load(exported["nav"])
    ours = read_model(exported["nav"].read_bytes())
    assert [n.op_type for n in ours.graph.nodes] == [n.op_type for n in theirs.graph.node]
    for tensor in theirs.graph.initializer:
        np.testing.assert_array_equal(ours.graph.initializers[tensor.name],
                                      numpy_helper.to_array(tensor))
    assert ours.graph.inputs[0].shape == (None, 57)
    assert ours.opsets == {"": 17}


def test_the_graph_has_the_normalisation_and_the_clipping(exported):
    ops = [n.op_type for n in read_model(exported["default"].read_bytes()).graph.nodes]
    assert ops[:3] == ["Sub", "Div", "Clip"] and ops[-2:] == ["Max", "Min"]
    policy = Policy.load(exported["default"], runtime="numpy")
    assert policy.normalizer is None
    far = np.full((1, 21), 1e6, dtype=np.float32)  # clipped to +-10 std, actions into [-1, 1]
    action, _ = policy.model.predict(far)
    assert np.all(np.abs(action) <= 1.0)


# -- without torch ---------------------------------------------------------------------------
#: what a plain install lacks: None in sys.modules makes each import of them fail
BLOCKED_RUN = textwrap.dedent("""
    import sys

    for name in ("torch", "stable_baselines3", "onnx", "onnxruntime"):
        sys.modules[name] = None
""")


def _run_blocked(body: str, *args: str) -> subprocess.CompletedProcess:
    code = BLOCKED_RUN + textwrap.dedent(body)
    return subprocess.run([sys.executable, "-c", code, *args], capture_output=True, text=True,
                          timeout=600, cwd=ROOT, env={**os.environ, "PYTHONWARNINGS": "ignore",
                                                      "PYTHONPATH": str(ROOT)})


@pytest.mark.slow
def test_the_shipped_policy_drives_from_onnx_where_torch_cannot_be_imported(exported):
    result = _run_blocked("""
        import json
        from smartcar_gym.agents.episodes import evaluate_batched_episodes
        from smartcar_gym.agents.records import summarize
        from smartcar_gym.policy import Policy
        try:
            import torch
        except ImportError:
            torch = None
        policy = Policy.load(sys.argv[1])
        records = evaluate_batched_episodes(policy, policy.env_id, n_episodes=100, n_envs=100,
                                            env_kwargs={"engine": "planar"})
        print(json.dumps({"torch": torch is not None, "runtime": policy.model.runtime,
                          "success": summarize(records)["success_rate"],
                          "loaded": sorted(m for m in ("torch", "stable_baselines3", "onnx",
                                                       "onnxruntime") if sys.modules.get(m))}))
    """, str(exported["default"]))
    assert result.returncode == 0, result.stderr
    out = json.loads(result.stdout.strip().splitlines()[-1])
    assert out["torch"] is False and out["loaded"] == [] and out["runtime"] == "numpy"
    assert out["success"] >= 0.95, out


def test_the_ros_node_drives_from_onnx_without_torch(exported):
    result = _run_blocked("""
        from types import SimpleNamespace
        import numpy as np
        from smartcar_gym.controller import Odometry
        from smartcar_gym.envs.robots.smartcar import JointStates
        from smartcar_gym.policy import Policy
        from smartcar_gym.bags import messages as m
        from smartcar_gym.ros.driving import GoalDriver

        class Types:
            def __call__(self, msg_type, /, **fields):
                return SimpleNamespace(**fields)
            def time(self, ns):
                return SimpleNamespace(secs=ns // m.NS_PER_S, nsecs=ns % m.NS_PER_S)

        T, now = Types(), m.NS_PER_S
        policy = Policy.load(sys.argv[1])
        driver = GoalDriver(policy.settings, policy.act, 0.5, "odometry")
        driver.on_goal(m.goal_message(T, (1.0, 0.5), 0, "odom"))
        driver.on_odometry(m.odometry_message(
            T, Odometry(0.0, "odom", "base_link", 0.0, 0.0, 0.0, 0.0, 0.0), now))
        wheels = policy.settings.wheel_joints
        driver.on_joint_states(m.joint_state_message(T, JointStates(
            tuple(wheels), np.zeros(len(wheels)), np.zeros(len(wheels)),
            np.zeros(len(wheels))), now))
        print(driver.step(now).twist)
    """, str(exported["ros"]))
    assert result.returncode == 0, result.stderr
    linear, angular = eval(result.stdout.strip().splitlines()[-1])  # a tuple of two floats
    assert linear > 0.0  # the goal is ahead: it drives toward it


def test_smartcar_ros_policy_takes_onnx_without_the_train_extra(exported):
    result = _run_blocked("""
        from smartcar_gym.ros.cli import main
        sys.exit(main(["policy", "--model", sys.argv[1]]))
    """, str(exported["ros"]))
    assert result.returncode == 2
    assert "train extra" not in result.stderr and len(result.stderr.strip().splitlines()) == 1
    assert "rospy" in result.stderr or "ROS master" in result.stderr


# -- smartcar-eval --model X.onnx ------------------------------------------------------------
@pytest.mark.slow
@pytest.mark.parametrize("vectorization", ["subproc", "batched"])
def test_smartcar_eval_runs_the_onnx_file_as_the_sb3_model(exported, tmp_path, vectorization):
    runs = {}
    for label, model in (("onnx", ["--model", str(exported["default"])]),
                         ("sb3", ["--pretrained"])):
        out = tmp_path / f"{label}.json"
        assert eval_main([*model, "--engine", "planar", "--episodes", "6", "--no-progress",
                          "--vectorization", vectorization, "--json", str(out)]) == 0
        runs[label] = json.loads(out.read_text())
    assert runs["onnx"]["normalizer_source"].startswith("folded into default.onnx")
    for ours, theirs in zip(runs["onnx"]["episode_records"], runs["sb3"]["episode_records"],
                            strict=True):
        assert ours["success"] == theirs["success"] and ours["length"] == theirs["length"]
        assert ours["episode_return"] == pytest.approx(theirs["episode_return"],
                                                       abs=RECORD_TOLERANCE)


# -- bad input: one line each ----------------------------------------------------------------
def _one_line_error(capsys, argv) -> str:
    with pytest.raises(SystemExit) as exit_info:
        eval_main(argv)
    assert exit_info.value.code == 2
    lines = capsys.readouterr().err.strip().splitlines()
    return lines[-1]


def test_a_file_that_is_not_onnx_is_named(tmp_path, capsys):
    text = tmp_path / "notes.onnx"
    text.write_text("this is not a model\n")
    renamed = tmp_path / "model.onnx"
    with zipfile.ZipFile(renamed, "w") as archive:
        archive.writestr("data", "{}")
    for path in (text, renamed):
        line = _one_line_error(capsys, ["--model", str(path), "--episodes", "1"])
        assert line.startswith(f"smartcar-eval: error: --model: {path} is not an ONNX model:")


def test_a_model_for_another_observation_space_is_refused(exported, capsys):
    line = _one_line_error(capsys, ["--model", str(exported["default"]), "--env",
                                    "SmartCarNav-v0", "--engine", "planar", "--episodes", "1"])
    assert "expects observations of shape (21,) but SmartCarNav-v0 gives (57,)" in line
    policy = Policy.load(exported["default"])
    with pytest.raises(ValueError, match=r"observations of shape \(1, 57\); .* takes \(21,\)"):
        policy.model.predict(np.zeros((1, 57), np.float32))


def test_an_operator_the_numpy_evaluator_does_not_know_is_named(exported, tmp_path):
    from onnx import helper

    model = onnx.load(exported["default"])
    last = model.graph.node[-1]
    last.output[0] = "clipped"
    model.graph.node.append(helper.make_node("Softplus", ["clipped"], ["action"],
                                             name="smooth"))
    path = tmp_path / "softplus.onnx"
    onnx.save(model, path)
    with pytest.raises(PolicyError) as err:
        Policy.load(path, runtime="numpy")
    assert str(err.value).startswith(f"{path}: operator Softplus (node 'smooth') is not one "
                                     "the numpy evaluator runs (Gemm, ")
    assert "\n" not in str(err.value)
    assert Policy.load(path, runtime="onnxruntime").act(np.zeros(21)).shape == (2,)


def test_export_refuses_what_it_cannot_take(tmp_path, capsys):
    with pytest.raises(SystemExit):
        export_main(["--pretrained", "-o", str(tmp_path / "policy.zip")])
    assert capsys.readouterr().err.strip().endswith(
        "-o: the file must end in .onnx, got '" + str(tmp_path / "policy.zip") + "'")
    with pytest.raises(PolicyError, match="has its normalisation in the graph"):
        Policy.load(tmp_path / "x.onnx", normalizer=tmp_path / "vecnormalize.pkl")


def test_stochastic_is_refused_for_an_onnx_file(exported, capsys):
    line = _one_line_error(capsys, ["--model", str(exported["default"]), "--stochastic",
                                    "--episodes", "1"])
    assert line.endswith("holds the deterministic policy only; sampled actions need the SB3 "
                         "model (.zip)")
