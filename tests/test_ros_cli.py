"""``smartcar-ros`` without ROS and its shipped ROS package: one-line errors, the package files."""

from __future__ import annotations

import os
import shutil
import socket
import subprocess
import sys
import textwrap
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest
import ros_needs
import yaml

from smartcar_gym.model import load_model
from smartcar_gym.model.packages import SHIPPED_DESCRIPTIONS
from smartcar_gym.ros.cli import main
from smartcar_gym.ros.debian import APT_LINE
from smartcar_gym.ros.package import package_folder, ros_package

BLOCKER = textwrap.dedent("""
    import sys

    BLOCKED = {blocked!r}

    class Blocker:
        def find_spec(self, name, path=None, target=None):
            if name.partition(".")[0] in BLOCKED:
                raise ModuleNotFoundError(f"No module named {{name!r}} (blocked)", name=name)
            return None

    sys.meta_path.insert(0, Blocker())
    from smartcar_gym.ros.cli import main
    sys.exit(main({argv!r}))
""")


def _run(argv: list[str], blocked: tuple[str, ...] = (), env: dict | None = None,
         ) -> subprocess.CompletedProcess:
    code = BLOCKER.format(blocked=blocked, argv=argv)
    # warnings on, as many developers and CI have them: a one-line error stays one line
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=120, env={**os.environ, "PYTHONWARNINGS": "default",
                                            **(env or {})})


@pytest.mark.parametrize("command", [["bringup"], ["policy", "--pretrained"]])
def test_without_rospy_one_line_names_the_debian_packages(command):
    result = _run(command, blocked=("rospy",))
    assert result.returncode == 2, result.stderr
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1, result.stderr
    assert lines[0].startswith("smartcar-ros: error: cannot import rospy (ModuleNotFoundError")
    assert lines[0].endswith(f"(python3-rospy): {APT_LINE}")
    for package in ("ros-core", "python3-rospy", "python3-nav-msgs", "python3-geometry-msgs",
                    "python3-sensor-msgs", "python3-tf2-msgs"):
        assert package in APT_LINE


def test_a_missing_message_package_is_named():
    result = _run(["bringup"], blocked=("nav_msgs",))
    line = result.stderr.strip()
    assert result.returncode == 2 and "\n" not in line
    if "cannot import rospy" not in line:  # ROS is installed: the blocked package is named
        assert "cannot import nav_msgs.msg" in line and "(python3-nav-msgs)" in line


def test_policy_without_the_train_extra_says_so():
    result = _run(["policy", "--pretrained"], blocked=("torch", "stable_baselines3"))
    assert result.returncode == 2
    assert result.stderr.strip() == (
        "smartcar-ros policy: error: stable_baselines3, torch not installed; smartcar-ros "
        'policy needs the train extra: pip install "smartcar-gym[train]"')


@ros_needs.needs(ros_needs.ROSPY)
def test_no_master_is_one_line_not_a_hang():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]  # nothing listens there once closed
    result = _run(["bringup"], env={"ROS_MASTER_URI": f"http://127.0.0.1:{port}"})
    assert result.returncode == 2
    assert result.stderr.strip() == (
        f"smartcar-ros: error: no ROS master at http://127.0.0.1:{port}: start roscore (or "
        "roslaunch) first, or set ROS_MASTER_URI")


@pytest.mark.parametrize("argv, expected", [
    (["bringup", "--speed", "0"], "argument --speed: expected a positive number, got '0'"),
    (["bringup", "--mode", "fast"], "argument --mode: invalid choice: 'fast'"),
    (["policy"], "one of the arguments --model --pretrained is required"),
    (["policy", "--pretrained", "--stop-on", "truth"], "argument --stop-on: invalid choice"),
])
def test_bad_arguments_exit_2(argv, expected, capsys):
    with pytest.raises(SystemExit) as exit_info:
        main(argv)
    assert exit_info.value.code == 2
    assert expected in capsys.readouterr().err


def test_ros_arguments_are_left_to_rospy(capsys):
    assert main(["package", "__name:=other", "_sim:=true"]) == 0  # not argparse errors
    assert capsys.readouterr().out.strip() == str(package_folder())


def test_the_ros_package_is_shipped_for_ros_package_path():
    package = ros_package()
    # only smartcar_gym_ros goes on ROS_PACKAGE_PATH: the shipped smartcar_description would
    # shadow (or be shadowed by) a workspace's own
    assert package_folder() == package
    assert ET.parse(package / "package.xml").getroot().findtext("name") == "smartcar_gym_ros"
    assert not list(package.glob("*/**/package.xml"))
    for launch in ("smartcar_display.launch", "smartcar_policy.launch"):
        root = ET.parse(package / "launch" / launch).getroot()  # well-formed XML
        assert root.tag == "launch"
        text = (package / "launch" / launch).read_text()
        assert "$(find smartcar_description)" not in text  # found from $(dirname) instead
    display = ET.parse(package / "launch" / "smartcar_display.launch").getroot()
    node = display.find("node[@name='arbotix']")
    assert (node.get("pkg"), node.get("type")) == ("smartcar_gym_ros", "bringup")
    assert node.find("rosparam[@command='load']") is not None  # the tutorial's private params
    for script in ("bringup", "policy"):
        assert os.access(package / "nodes" / script, os.X_OK)
    rviz = (package / "urdf.rviz").read_text()
    assert "Topic: /move_base_simple/goal" in rviz and "Fixed Frame: /odom" in rviz


def test_node_script_says_how_to_find_smartcar_ros(tmp_path):
    result = subprocess.run([str(ros_package() / "nodes" / "bringup")], capture_output=True,
                            text=True, timeout=30, env={"PATH": "/usr/bin:/bin"})
    assert result.returncode == 2
    assert "smartcar-ros is not on PATH: activate the virtualenv" in result.stderr


TUTORIAL = Path(__file__).parent / "fixtures" / "seed" / "smartcar_description"


@pytest.mark.slow
@ros_needs.needs("roslaunch")
@pytest.mark.parametrize("ours_first", [True, False])
def test_roslaunch_keeps_the_shipped_model_and_the_tutorials_package_apart(ours_first,
                                                                            tmp_path):
    """A workspace with the tutorial's smartcar_description beside $(smartcar-ros package) on
    ROS_PACKAGE_PATH, in either order: the shipped launch files load the shipped model and
    YAML, and the workspace's $(find smartcar_description) is the workspace's package."""
    tutorial = tmp_path / "src" / "smartcar_description"
    shutil.copytree(TUTORIAL, tutorial)
    (tutorial / "package.xml").write_text(
        '<?xml version="1.0"?>\n<package format="2"><name>smartcar_description</name>'
        "<version>0.0.0</version></package>\n")
    (tutorial / "launch").mkdir()
    where = tutorial / "launch" / "where.launch"
    where.write_text('<launch><param name="where" value="$(find smartcar_description)"/>'
                     "</launch>\n")
    folders = [str(package_folder()), str(tmp_path / "src")]
    env = {**os.environ, "ROS_PACKAGE_PATH": os.pathsep.join(folders if ours_first
                                                             else folders[::-1]),
           "ROS_HOME": str(tmp_path / "ros"), "PYTHONWARNINGS": "ignore",
           "PATH": f"{Path(sys.executable).parent}{os.pathsep}{os.environ.get('PATH', '')}"}
    launch = ros_package() / "launch" / "smartcar_policy.launch"
    result = subprocess.run(["roslaunch", "--dump-params", str(launch), str(where)],
                            capture_output=True, text=True, timeout=120, env=env)
    assert result.returncode == 0, result.stdout + result.stderr
    params = yaml.safe_load(result.stdout)
    assert params["/where"] == str(tutorial)
    assert params["/robot_description"].strip() == load_model().urdf.strip()
    # the calibrated YAML, the odometry the ros policy was trained on
    assert params["/arbotix/controllers/base_controller/base_width"] == 0.33
    assert params["/arbotix/smartcar_gym/board/frame_ms"] == 33
    node = subprocess.run(["roslaunch", "--args", "/arbotix", "smartcar_gym_ros",
                           "smartcar_policy.launch"], capture_output=True, text=True,
                          timeout=120, env=env)
    model = node.stdout.split("--model ")[1].split()[0]
    assert Path(model).resolve() == SHIPPED_DESCRIPTIONS / "smartcar_description" / "urdf" / (
        "smartcar.urdf.xacro"), node.stdout + node.stderr
