"""``$(find pkg)`` without ROS: package_path, ROS_PACKAGE_PATH, enclosing folders, shipped."""

from __future__ import annotations

import os
import warnings
from pathlib import Path

import pytest

from smartcar_gym.model import ModelError, find_package, load_model
from smartcar_gym.model.packages import SHIPPED_DESCRIPTIONS, search_roots

FIXTURES = Path(__file__).parent / "fixtures"
SEED_PKG = FIXTURES / "seed" / "smartcar_description"
SEED = SEED_PKG / "urdf" / "smartcar.urdf.xacro"
LEGACY_PKG = FIXTURES / "legacy" / "smartcar_description"
SHIPPED_PKG = SHIPPED_DESCRIPTIONS / "smartcar_description"

ROBOT = """<?xml version="1.0"?>
<robot name="{name}" xmlns:xacro="http://ros.org/wiki/xacro">
  <xacro:include filename="$(find {pkg})/urdf/parts.xacro"/>
  <xacro:parts/>
</robot>
"""
PARTS = """<?xml version="1.0"?>
<robot xmlns:xacro="http://ros.org/wiki/xacro">
  <xacro:macro name="parts">
    <link name="base_link"/>
    <link name="{wheel}_l"><collision><geometry><sphere radius="0.05"/></geometry></collision>
    </link>
    <link name="{wheel}_r"><collision><geometry><sphere radius="0.05"/></geometry></collision>
    </link>
    <joint name="{wheel}_l_joint" type="continuous"><parent link="base_link"/>
      <child link="{wheel}_l"/><origin xyz="0 0.1 0"/><axis xyz="0 1 0"/></joint>
    <joint name="{wheel}_r_joint" type="continuous"><parent link="base_link"/>
      <child link="{wheel}_r"/><origin xyz="0 -0.1 0"/><axis xyz="0 1 0"/></joint>
  </xacro:macro>
</robot>
"""


def make_package(folder: Path, *, name: str | None = None, wheel: str = "wheel") -> Path:
    """A package folder with urdf/parts.xacro; with package.xml naming ``name`` if given."""
    (folder / "urdf").mkdir(parents=True)
    (folder / "urdf" / "parts.xacro").write_text(PARTS.format(wheel=wheel))
    if name is not None:
        (folder / "package.xml").write_text(
            f'<?xml version="1.0"?>\n<package format="2"><name>{name}</name></package>\n')
    return folder


def robot_file(tmp_path: Path, pkg: str) -> Path:
    path = tmp_path / "robot.urdf.xacro"
    path.write_text(ROBOT.format(name="probe", pkg=pkg))
    return path


@pytest.fixture(autouse=True)
def no_ros_package_path(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("ROS_PACKAGE_PATH", raising=False)


def test_shipped_description_is_found_without_any_path() -> None:
    assert find_package("smartcar_description") == SHIPPED_DESCRIPTIONS / "smartcar_description"
    assert search_roots() == [SHIPPED_DESCRIPTIONS]


def test_package_path_by_folder_name(tmp_path: Path) -> None:
    pkg = make_package(tmp_path / "src" / "probe_description")
    assert find_package("probe_description", [tmp_path]) == pkg
    model = load_model(robot_file(tmp_path, "probe_description"), package_path=[tmp_path])
    assert [w.joint for w in model.wheels] == ["wheel_l_joint", "wheel_r_joint"]


def test_package_xml_name_wins_over_folder_name(tmp_path: Path) -> None:
    pkg = make_package(tmp_path / "checkout" / "some_folder", name="probe_description")
    # a folder named like the package but declaring another name is not it
    make_package(tmp_path / "checkout" / "probe_description", name="other_description",
                 wheel="decoy")
    assert find_package("probe_description", [tmp_path]) == pkg
    assert find_package("other_description", [tmp_path]) == tmp_path / "checkout" / (
        "probe_description")
    model = load_model(robot_file(tmp_path, "probe_description"), package_path=[tmp_path])
    assert sorted(model.links) == ["base_link", "wheel_l", "wheel_r"]


def test_ros_package_path(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    first = make_package(tmp_path / "a" / "probe_description", wheel="first")
    make_package(tmp_path / "b" / "probe_description", wheel="second")
    monkeypatch.setenv("ROS_PACKAGE_PATH", os.pathsep.join([str(tmp_path / "a"),
                                                            str(tmp_path / "b")]))
    assert find_package("probe_description") == first
    model = load_model(robot_file(tmp_path, "probe_description"))
    assert sorted(model.joints) == ["first_l_joint", "first_r_joint"]


def test_package_path_before_ros_package_path_before_shipped(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    explicit = make_package(tmp_path / "explicit" / "smartcar_description")
    env = make_package(tmp_path / "env" / "smartcar_description")
    monkeypatch.setenv("ROS_PACKAGE_PATH", str(tmp_path / "env"))
    assert find_package("smartcar_description", [tmp_path / "explicit"]) == explicit
    assert find_package("smartcar_description") == env
    assert search_roots([tmp_path / "explicit"]) == [
        tmp_path / "explicit", tmp_path / "env", SHIPPED_DESCRIPTIONS]


def test_search_order_puts_enclosing_folders_before_the_shipped_ones(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("ROS_PACKAGE_PATH", str(tmp_path / "env"))
    asker = tmp_path / "ws" / "pkg" / "urdf" / "robot.xacro"
    roots = search_roots([tmp_path / "explicit"], requested_by=asker)
    assert roots[:5] == [tmp_path / "explicit", tmp_path / "env", asker.parent,
                         tmp_path / "ws" / "pkg", tmp_path / "ws"]
    assert roots[-2:] == [Path("/"), SHIPPED_DESCRIPTIONS]


def test_the_seed_without_package_path_finds_its_own_folder() -> None:
    # the tutorial's files, checked out anywhere, are not swapped for our shipped package
    assert find_package("smartcar_description", requested_by=SEED) == SEED_PKG
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        model = load_model(SEED)
    assert model.packages == {"smartcar_description": SEED_PKG}
    assert len(model.defects) == 17  # the seed's own body, not our fixed one


def test_an_enclosing_folder_is_a_package_by_its_package_xml(tmp_path: Path) -> None:
    pkg = make_package(tmp_path / "checkout", name="probe_description")
    robot = pkg / "urdf" / "robot.urdf.xacro"
    robot.write_text(ROBOT.format(name="probe", pkg="probe_description"))
    model = load_model(robot)
    assert model.packages == {"probe_description": pkg}
    # an enclosing folder named like the package but declaring another name is not it
    other = make_package(tmp_path / "other" / "probe_description", name="other_description")
    with pytest.raises(ModelError, match="package 'probe_description' not found"):
        find_package("probe_description", requested_by=other / "urdf" / "robot.urdf.xacro")
    assert find_package("other_description", requested_by=other / "urdf" / "x") == other


def test_package_path_wins_over_the_enclosing_folder() -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        model = load_model(SEED, package_path=[FIXTURES / "legacy"])
    assert model.packages == {"smartcar_description": LEGACY_PKG}
    assert model.defects == ()  # the legacy fixture's corrected body was included
    assert "head" not in model.links  # which has no head in its smartcar_body macro


def test_an_unrelated_file_falls_back_to_the_shipped_package(tmp_path: Path) -> None:
    path = tmp_path / "mine.urdf.xacro"
    path.write_text(SEED.read_text())
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        model = load_model(path)
    assert model.packages == {"smartcar_description": SHIPPED_PKG}
    assert model.defects == ()  # our corrected body


def test_a_root_that_is_the_package_itself(tmp_path: Path) -> None:
    pkg = make_package(tmp_path / "probe_description")
    assert find_package("probe_description", [pkg]) == pkg
    assert find_package("probe_description", str(pkg)) == pkg  # a single folder is accepted


@pytest.mark.parametrize("marker", ["CATKIN_IGNORE", "COLCON_IGNORE"])
def test_ignored_and_hidden_folders_are_skipped(tmp_path: Path, marker: str) -> None:
    make_package(tmp_path / "ignored" / "probe_description")
    (tmp_path / "ignored" / marker).touch()
    make_package(tmp_path / ".hidden" / "probe_description")
    with pytest.raises(ModelError, match="package 'probe_description' not found"):
        find_package("probe_description", [tmp_path])


def test_unknown_package_names_package_asking_file_line_and_folders(tmp_path: Path) -> None:
    path = robot_file(tmp_path, "no_such_description")
    with pytest.raises(ModelError) as info:
        load_model(path, package_path=[tmp_path / "nowhere"])
    message = str(info.value)
    assert message.startswith(f"{path}:3: package 'no_such_description' not found (asked for "
                              "by $(find no_such_description)); searched package_path/")
    assert str(tmp_path / "nowhere") in message
    assert "the folders enclosing robot.urdf.xacro" in message
    assert str(SHIPPED_DESCRIPTIONS) in message
    assert "ROS_PACKAGE_PATH" in message
    assert (info.value.file, info.value.line) == (str(path), 3)


def test_unknown_package_from_an_included_file_names_that_file(tmp_path: Path) -> None:
    make_package(tmp_path / "probe_description")
    parts = tmp_path / "probe_description" / "urdf" / "parts.xacro"
    parts.write_text(parts.read_text().replace(
        "<xacro:macro", '<xacro:include filename="$(find missing_pkg)/x.xacro"/>\n  <xacro:macro'))
    with pytest.raises(ModelError, match="package 'missing_pkg' not found") as info:
        load_model(robot_file(tmp_path, "probe_description"), package_path=[tmp_path])
    assert (info.value.file, info.value.line) == (str(parts), 3)


def test_find_is_restored_after_loading(tmp_path: Path) -> None:
    import xacro.substitution_args as sa

    before = (sa._eval_find, sa._eval_dict["find"])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        load_model()
    assert (sa._eval_find, sa._eval_dict["find"]) == before


def test_a_shipped_file_searches_the_shipped_descriptions_first(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    other = make_package(tmp_path / "ws" / "smartcar_description", name="smartcar_description")
    monkeypatch.setenv("ROS_PACKAGE_PATH", str(tmp_path / "ws"))
    asker = SHIPPED_PKG / "urdf" / "smartcar.urdf.xacro"
    assert search_roots([tmp_path / "explicit"], requested_by=asker)[:3] == [
        SHIPPED_DESCRIPTIONS, tmp_path / "explicit", tmp_path / "ws"]
    assert find_package("smartcar_description", requested_by=asker) == SHIPPED_PKG
    assert find_package("smartcar_description", requested_by=robot_file(tmp_path, "x")) == other
    # a package the shipped descriptions lack is searched for as from any other file
    make_package(tmp_path / "ws" / "probe_description")
    assert find_package("probe_description", requested_by=asker) == (
        tmp_path / "ws" / "probe_description")
    with pytest.raises(ModelError, match=r"searched the shipped descriptions .* \(asked for by "
                                         r"a shipped file\); package_path/ROS_PACKAGE_PATH"):
        find_package("missing_description", requested_by=asker)
