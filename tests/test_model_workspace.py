"""The shipped model beside a user's ROS workspace: ``ROS_PACKAGE_PATH`` holding another
``smartcar_description`` (the tutorial's, a copy of ours without ``laser.urdf.xacro``, a broken
one) or nothing at all changes nothing for the shipped model, the env ids and the CLIs; a
user's own model keeps resolving ``$(find smartcar_description)`` through ``ROS_PACKAGE_PATH``.

The workspaces are built here from ``tests/fixtures/seed`` (the tutorial's files) and the
shipped description files.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import warnings
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import smartcar_gym
from smartcar_gym.model import ModelError, load_model
from smartcar_gym.model.packages import SHIPPED_DESCRIPTIONS, find_package

FIXTURES = Path(__file__).parent / "fixtures"
SHIPPED_PKG = SHIPPED_DESCRIPTIONS / "smartcar_description"
SHIPPED_MODEL = SHIPPED_PKG / "urdf" / "smartcar.urdf.xacro"
BIN = Path(sys.executable).parent
PACKAGE_XML = ('<?xml version="1.0"?>\n<package format="2"><name>smartcar_description</name>'
               '<version>0.0.0</version></package>\n')
WORKSPACES = ("tutorial", "copy", "broken", "empty")


def make_workspace(root: Path, kind: str) -> str:
    """A ROS_PACKAGE_PATH value: a catkin workspace's src/ holding a smartcar_description."""
    src = root / kind / "src"
    package = src / "smartcar_description"
    if kind == "tutorial":  # the tutorial's package: its three files, no laser.urdf.xacro
        shutil.copytree(FIXTURES / "seed" / "smartcar_description", package)
        (package / "package.xml").write_text(PACKAGE_XML)
    elif kind == "copy":  # our package copied into a workspace, laser.urdf.xacro left out
        shutil.copytree(SHIPPED_PKG, package)
        (package / "urdf" / "laser.urdf.xacro").unlink()
    elif kind == "broken":  # a package.xml, a truncated main file, no other file
        (package / "urdf").mkdir(parents=True)
        (package / "package.xml").write_text(PACKAGE_XML)
        (package / "urdf" / "smartcar.urdf.xacro").write_text('<robot name="x">\n  <link')
    else:
        return ""
    return str(src)


@pytest.fixture(scope="module")
def workspaces(tmp_path_factory) -> dict[str, str]:
    root = tmp_path_factory.mktemp("workspaces")
    return {kind: make_workspace(root, kind) for kind in WORKSPACES}


def _first_steps(env_id: str) -> list:
    """Observation after reset(seed=0) and one step of a fixed action, and the packages."""
    env = gym.make(env_id)
    try:
        obs, _ = env.reset(seed=0)
        obs2, reward, *_ = env.step(np.full(env.action_space.shape, 0.5, dtype=np.float32)
                                    if isinstance(env.action_space, gym.spaces.Box)
                                    else env.action_space.sample())
        return [obs, obs2, reward, env.unwrapped.robot_model.packages]
    finally:
        env.close()


@pytest.fixture(scope="module")
def reference() -> dict[str, list]:
    """Each env id's first steps without ROS_PACKAGE_PATH."""
    saved = os.environ.pop("ROS_PACKAGE_PATH", None)
    try:
        return {env_id: _first_steps(env_id) for env_id in smartcar_gym.ENV_IDS}
    finally:
        if saved is not None:
            os.environ["ROS_PACKAGE_PATH"] = saved


def _same(a, b) -> bool:
    if isinstance(a, dict):
        return a.keys() == b.keys() and all(_same(a[k], b[k]) for k in a)
    if isinstance(a, list):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b, strict=False))
    return bool(np.array_equal(a, b)) if isinstance(a, np.ndarray) else a == b


@pytest.mark.parametrize("kind", WORKSPACES)
def test_the_shipped_model_resolves_its_own_includes(kind, workspaces, monkeypatch):
    monkeypatch.setenv("ROS_PACKAGE_PATH", workspaces[kind])
    for laser in ("false", "true"):  # laser.urdf.xacro: only ours has it
        model = load_model(mappings={"laser": laser})
        assert model.packages == {"smartcar_description": SHIPPED_PKG}
        assert ("laser" in model.links) == (laser == "true")
    # what a file of the workspace asks for still comes from ROS_PACKAGE_PATH
    if kind != "empty":
        assert find_package("smartcar_description") == Path(workspaces[kind]) / (
            "smartcar_description")


@pytest.mark.parametrize("env_id", smartcar_gym.ENV_IDS)
@pytest.mark.parametrize("kind", WORKSPACES)
def test_every_env_id_runs_as_without_a_workspace(env_id, kind, workspaces, reference,
                                                  monkeypatch):
    monkeypatch.setenv("ROS_PACKAGE_PATH", workspaces[kind])
    steps = _first_steps(env_id)
    assert steps[-1] == {"smartcar_description": SHIPPED_PKG}
    assert _same(steps, reference[env_id])  # bit for bit the run without ROS_PACKAGE_PATH


def test_a_users_model_still_resolves_through_ros_package_path(workspaces, monkeypatch):
    monkeypatch.setenv("ROS_PACKAGE_PATH", workspaces["tutorial"])
    tutorial = Path(workspaces["tutorial"]) / "smartcar_description"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the tutorial's legacy xacro and defects
        model = load_model(tutorial / "urdf" / "smartcar.urdf.xacro")
    assert model.packages == {"smartcar_description": tutorial}
    assert len(model.defects) == 17  # the tutorial's body, not our fixed one
    # a model outside any package, including the workspace's body, gets the workspace's
    mine = tutorial.parent.parent / "mine.urdf.xacro"
    mine.write_text('<?xml version="1.0"?>\n<robot name="mine" xmlns:xacro='
                    '"http://ros.org/wiki/xacro">\n  <xacro:include filename="$(find '
                    'smartcar_description)/urdf/smartcar_body.urdf.xacro"/>\n'
                    '  <xacro:smartcar_body/>\n</robot>\n')
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        assert load_model(mine).packages == {"smartcar_description": tutorial}
    # and a broken package of that name is still reported where it is
    monkeypatch.setenv("ROS_PACKAGE_PATH", workspaces["broken"])
    with pytest.raises(ModelError, match="cannot read included file .*broken.*smartcar_body"):
        load_model(mine)


def _cli(name: str, args: list[str], ros_package_path: str, cwd: Path,
         ) -> subprocess.CompletedProcess:
    env = {**os.environ, "ROS_PACKAGE_PATH": ros_package_path, "PYTHONWARNINGS": "ignore",
           "MPLBACKEND": "Agg"}
    return subprocess.run([str(BIN / name), *args], capture_output=True, text=True, cwd=cwd,
                          env=env, timeout=300)


@pytest.mark.parametrize("kind", WORKSPACES)
def test_smartcar_model_check_reports_the_shipped_package(kind, workspaces, tmp_path):
    result = _cli("smartcar-model", ["check"], workspaces[kind], tmp_path)
    assert result.returncode == 0, result.stderr
    assert str(SHIPPED_PKG) in result.stdout and "result: OK" in result.stdout
    assert workspaces[kind] == "" or workspaces[kind] not in result.stdout


CLIS = {
    "model-urdf-laser": ("smartcar-model", ["urdf", "--arg", "laser:=true", "-o", "car.urdf"]),
    "eval-pretrained": ("smartcar-eval", ["--pretrained", "--episodes", "1",
                                          "--json", "eval.json"]),
    "eval-pretrained-nav": ("smartcar-eval", ["--pretrained", "nav", "--episodes", "1",
                                              "--json", "eval.json"]),
    "calibrate": ("smartcar-calibrate", ["--fit", "spin", "--output", "calibrated.yaml"]),
    "train": ("smartcar-train", ["--n-envs", "1", "--timesteps", "64", "--hyperparams",
                                 "n_steps=64", "batch_size=64", "n_epochs=1", "--eval-freq",
                                 "0", "--run-dir", "run", "--no-progress"]),
    "ros-package": ("smartcar-ros", ["package"]),
}


# every CLI beside the tutorial's workspace; three beside the broken one, one with it empty
CLI_RUNS = [(cli, "tutorial") for cli in CLIS] + [
    ("model-urdf-laser", "broken"), ("eval-pretrained", "broken"), ("calibrate", "broken"),
    ("model-urdf-laser", "empty")]


@pytest.mark.slow
@pytest.mark.parametrize(("cli", "kind"), CLI_RUNS)
def test_the_clis_run_beside_a_workspace(cli, kind, workspaces, tmp_path):
    name, args = CLIS[cli]
    result = _cli(name, args, workspaces[kind], tmp_path)
    assert result.returncode == 0, result.stderr[-2000:]
    assert "smartcar_description" not in result.stderr, result.stderr[-2000:]
    if cli == "model-urdf-laser":
        assert '<link name="laser">' in (tmp_path / "car.urdf").read_text()
    elif cli.startswith("eval"):
        assert json.loads((tmp_path / "eval.json").read_text())["episodes"] == 1
    elif cli == "calibrate":
        assert "base_width" in (tmp_path / "calibrated.yaml").read_text()
    elif cli == "train":
        assert (tmp_path / "run" / "model.zip").is_file()
    else:
        assert result.stdout.strip() == str(SHIPPED_DESCRIPTIONS / "smartcar_gym_ros")
