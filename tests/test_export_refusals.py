"""``smartcar-export`` writes a file only when it loads and agrees with its model: every
refusal is one line with exit code 2, and on any failure what was at ``-o`` (and its
``.json``) is left as it was, with no temporary file beside it."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

pytest.importorskip("onnx")
pytest.importorskip("stable_baselines3")

import smartcar_gym.export.cli as cli  # noqa: E402
from smartcar_gym.policy import Policy  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
OLD, OLD_SIDE = b"the user's old model", "the user's old metadata\n"


def _refused(capsys, tmp_path: Path, *args: str) -> str:
    """``smartcar-export --pretrained -o <tmp>/policy.onnx *args``'s one line; checks exit
    code 2 and that the old files at -o are untouched, with nothing else in the folder."""
    out = tmp_path / "policy.onnx"
    out.write_bytes(OLD)
    out.with_suffix(".json").write_text(OLD_SIDE)
    with pytest.raises(SystemExit) as exit_info:
        cli.main(["--pretrained", "-o", str(out), *args])
    assert exit_info.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert out.read_bytes() == OLD and out.with_suffix(".json").read_text() == OLD_SIDE
    assert sorted(p.name for p in tmp_path.iterdir()) == ["policy.json", "policy.onnx"]
    assert err[-1].startswith("smartcar-export: error: ")
    return err[-1].removeprefix("smartcar-export: error: ")


@pytest.mark.parametrize("check", ["0", "10"])
def test_an_env_whose_observations_are_not_the_model_s_is_refused(capsys, tmp_path, check):
    line = _refused(capsys, tmp_path, "--env", "SmartCarNav-v0", "--check", check)
    assert line == ("the model takes observations of shape (21,) but SmartCarNav-v0 with no "
                    "env kwargs gives (57,) (57 named); export it with the env it was trained "
                    "on (--env, --env-kwargs)")


@pytest.mark.parametrize(("args", "expected"), [
    (["--env", "NoSuch-v0"], "--env: env id 'NoSuch-v0' is not an id smartcar-gym registered; "
                             "expected one of SmartCar-v0, "),
    (["--env", "payload:SmartCar-v0"], "--env: env id 'payload:SmartCar-v0' is not an id "
                                       "smartcar-gym registered (a policy's file cannot name "
                                       "a module to import)"),
    (["--env-kwargs", "bogus=1"], "--env-kwargs: env_kwargs 'bogus' is not a keyword "
                                  "SmartCar-v0 takes; expected some of arena_size, "),
    (["--env-kwargs", "goal_range=2020-01-01"], "--env-kwargs: {'goal_range': "
                                                "datetime.date(2020, 1, 1)} cannot be written "
                                                "as JSON: "),
    (["--env-kwargs", "goal_range=[1, 0]"], "cannot make SmartCar-v0 with goal_range=[1, 0]: "
                                            "goal_range must be (min, max) metres with "),
    (["--env-kwargs", "engine=warp"], "--env-kwargs: env_kwargs engine 'warp' is not a "
                                      "registered engine; expected one of pybullet, mujoco, "
                                      "planar"),
])
def test_an_env_the_file_could_not_name_is_one_line(capsys, tmp_path, args, expected):
    assert _refused(capsys, tmp_path, *args).startswith(expected)


def test_actions_that_differ_leave_the_old_file(capsys, tmp_path, monkeypatch):
    monkeypatch.setattr(cli, "TOLERANCE", -1.0)  # any difference, even none, is too much
    line = _refused(capsys, tmp_path, "--check", "3")
    assert line.startswith("the export's actions differ from the SB3 model's by up to ")
    assert line.endswith("(more than -1); nothing written")


def test_a_file_that_would_not_load_is_not_written(capsys, tmp_path, monkeypatch):
    real = cli.export_metadata

    def wrong_types(policy, source):  # metadata that Policy.load would refuse
        return {**real(policy, source), "action_low": "-1"}

    monkeypatch.setattr(cli, "export_metadata", wrong_types)
    line = _refused(capsys, tmp_path, "--check", "0")
    out = tmp_path / "policy.onnx"
    assert line == (f"{out}: metadata action_low is '-1'; expected a list of 2 finite numbers "
                    "(action_shape [2]); nothing written")


def test_a_good_export_replaces_the_old_file_and_loads(capsys, tmp_path):
    out = tmp_path / "policy.onnx"
    out.write_bytes(OLD)
    assert cli.main(["--pretrained", "-o", str(out), "--check", "5"]) == 0
    assert sorted(p.name for p in tmp_path.iterdir()) == ["policy.json", "policy.onnx"]
    policy = Policy.load(out, runtime="numpy")
    assert policy.env_id == "SmartCar-v0"
    assert json.loads(out.with_suffix(".json").read_text())["env_id"] == "SmartCar-v0"


def test_a_refusal_is_one_line_with_warnings_as_errors(tmp_path):
    out = tmp_path / "x.onnx"
    result = subprocess.run(
        [sys.executable, "-W", "error", "-m", "smartcar_gym.export.cli", "--pretrained", "-o",
         str(out), "--env", "SmartCarNav-v0", "--check", "0"],
        capture_output=True, text=True, cwd=ROOT, timeout=300,
        env={**os.environ, "PYTHONPATH": str(ROOT)})
    assert result.returncode == 2, result.stderr
    assert "Traceback" not in result.stderr
    assert result.stderr.strip().splitlines()[-1].startswith(
        "smartcar-export: error: the model takes observations of shape (21,) but SmartCarNav-v0")
    assert not out.exists() and list(tmp_path.iterdir()) == []
