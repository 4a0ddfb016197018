"""Bad arguments to ``load_model``: each error names the argument and what was expected."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from smartcar_gym.model import SHIPPED_MODEL, ModelError, load_model

EXPECTED = "a .urdf file, or a xacro file (.urdf.xacro, .xacro)"


@pytest.mark.parametrize("path", ["", "  "])
def test_empty_path_says_so_and_that_none_is_the_shipped_model(path) -> None:
    with pytest.raises(ModelError) as info:  # was "no such robot description: <the cwd>"
        load_model(path)
    assert str(info.value) == (f"robot description path is empty ({os.fspath(path)!r}); "
                               f"expected the path of {EXPECTED}, or None for the shipped "
                               "smartcar")


def test_a_directory_is_named_as_one_with_the_descriptions_it_holds() -> None:
    package = SHIPPED_MODEL.parents[1]  # smartcar_description/, a ROS package
    with pytest.raises(IsADirectoryError) as info:  # was "no such robot description"
        load_model(package)
    assert str(info.value) == (
        f"{package} is a directory, not a robot description; expected {EXPECTED}; it holds "
        "urdf/gazebo.urdf.xacro, urdf/laser.urdf.xacro, urdf/smartcar.urdf.xacro, "
        "urdf/smartcar_body.urdf.xacro")


def test_a_directory_without_descriptions_says_so(tmp_path: Path) -> None:
    (tmp_path / "urdf").mkdir()
    (tmp_path / "notes.txt").write_text("x")
    with pytest.raises(IsADirectoryError, match=r"; it holds no \.urdf or \.xacro file \(nor "
                                                r"does its urdf/ folder\)$"):
        load_model(tmp_path)


def test_a_path_of_the_wrong_type() -> None:
    with pytest.raises(TypeError, match=r"^path=123: expected the path \(str or os\.PathLike\) "
                                        r"of a \.urdf file, .*or None for the shipped smartcar$"):
        load_model(123)


WHEELS_DICT = "expected a dict {'left': [joint, ...], 'right': [joint, ...]}"


@pytest.mark.parametrize(("wheels", "expected"), [
    ("x", f"wheels='x': {WHEELS_DICT} naming the drive wheel joints of each side, or None to "
          "find them"),
    (5, f"wheels=5: {WHEELS_DICT} naming the drive wheel joints of each side, or None to find "
        "them"),
    (["left_front_wheel_joint"], "wheels=['left_front_wheel_joint']: expected a dict"),
    ({"left": "left_front_wheel_joint", "right": ["right_front_wheel_joint"]},
     "wheels['left']='left_front_wheel_joint': expected a list of joint names, as in "
     "{'left': [joint, ...], 'right': [joint, ...]}"),
    ({"left": ["left_front_wheel_joint"], "right": [3]},
     "wheels['right']=[3]: expected a list of joint names"),
    ({"left": ["left_front_wheel_joint"]},  # as before: file-less now, same words
     "wheels={'left': ['left_front_wheel_joint']}: expected {'left': [joint, ...], 'right': "
     "[joint, ...]} with at least one joint per side"),
])
def test_wheels_of_the_wrong_shape(wheels, expected: str) -> None:
    with pytest.raises(ModelError) as info:  # 'x' and 5 were a ValueError/TypeError from dict()
        load_model(wheels=wheels)
    assert str(info.value).startswith(expected)


def test_wheels_as_tuples_are_accepted() -> None:
    model = load_model(wheels={"left": ("left_back_wheel_joint",),
                               "right": ("right_back_wheel_joint",)})
    assert [w.joint for w in model.wheels] == ["left_back_wheel_joint", "right_back_wheel_joint"]


@pytest.mark.parametrize(("package_path", "expected"), [
    (123, "package_path=123: expected a list of folders (str or os.PathLike), one folder, or "
          "None"),
    (b"/opt/ros", "package_path=b'/opt/ros': expected a list of folders"),
    ({"a": 1}, "package_path={'a': 1}: expected a list of folders"),
    (["/tmp", 7], "package_path[1]=7: expected a folder (str or os.PathLike); package_path: "
                  "expected a list of folders"),
])
def test_package_path_of_the_wrong_type(package_path, expected: str) -> None:
    with pytest.raises(ModelError) as info:  # 123 was "xacro: <class 'TypeError'>: 'int' ..."
        load_model(package_path=package_path)
    assert str(info.value).startswith(expected)


def test_package_path_takes_one_folder_a_tuple_or_a_generator(tmp_path: Path) -> None:
    folder = str(SHIPPED_MODEL.parents[2])
    for package_path in (folder, (folder,), (f for f in [folder])):
        model = load_model(package_path=package_path)
        assert model.packages["smartcar_description"] == SHIPPED_MODEL.parents[1]


def test_mappings_of_the_wrong_type() -> None:
    with pytest.raises(ModelError, match=r"^mappings=\['a'\]: expected a dict of xacro "
                                         r"arguments \{name: value\}, or None$"):
        load_model(mappings=["a"])
