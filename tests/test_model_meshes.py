"""Mesh filenames: package:// and relative paths made absolute, missing meshes reported."""

from __future__ import annotations

import shutil
import warnings
from pathlib import Path

import pytest

from smartcar_gym.model import ModelError, load_model
from smartcar_gym.model.defects import GEOMETRY_MISMATCH, find_defects
from smartcar_gym.model.urdf import parse_urdf
from smartcar_gym.sim.pybullet.bullet import pybullet

FIXTURE_PKG = Path(__file__).parent / "fixtures" / "meshbot_description"
CUBE = FIXTURE_PKG / "meshes" / "cube.obj"
PACKAGE_URI = "package://meshbot_description/meshes/cube.obj"
MESH_LINKS = [("base_link", "visuals"), ("sensor", "visuals"), ("sensor", "collisions")]


@pytest.fixture
def package(tmp_path: Path) -> Path:
    """A writable copy of the meshbot package."""
    return Path(shutil.copytree(FIXTURE_PKG, tmp_path / "meshbot_description"))


def mesh_files(model) -> list[str]:
    return [getattr(model.links[link], kind)[0].geometry.filename for link, kind in MESH_LINKS]


@pytest.mark.parametrize(("urdf", "packages"), [
    ("meshbot.urdf", {"meshbot_description": FIXTURE_PKG}),
    ("meshbot_relative.urdf", {}),
])
def test_mesh_paths_become_absolute_and_pybullet_loads_them(sim, tmp_path: Path, urdf: str,
                                                            packages: dict) -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # and no defect: mesh visuals over a box are fine
        model = load_model(FIXTURE_PKG / "urdf" / urdf)
    assert mesh_files(model) == [str(CUBE)] * 3
    assert model.packages == packages
    assert model.urdf.count(f'filename="{CUBE}"') == 3
    body = sim.load_urdf("meshbot", model.write_urdf(tmp_path / "elsewhere")).uid
    sensor = sim.body("meshbot").joints["sensor_joint"]
    shapes = sim.client.getCollisionShapeData(body, sensor)
    assert [(s[2], s[4].decode()) for s in shapes] == [(pybullet.GEOM_MESH, str(CUBE))]
    visuals = {(s[1], s[4].decode()) for s in sim.client.getVisualShapeData(body)}
    assert (-1, str(CUBE)) in visuals and (sensor, str(CUBE)) in visuals


@pytest.mark.parametrize("filename", ["file://{cube}", "{cube}", "file://../meshes/cube.obj"])
def test_file_uris_and_absolute_paths(package: Path, filename: str) -> None:
    path = package / "urdf" / "meshbot.urdf"
    cube = package / "meshes" / "cube.obj"
    path.write_text(path.read_text().replace(PACKAGE_URI, filename.format(cube=cube)))
    assert mesh_files(load_model(path)) == [str(cube)] * 3


def test_package_path_decides_which_package_a_mesh_comes_from(package: Path,
                                                               tmp_path: Path) -> None:
    other = Path(shutil.copytree(package, tmp_path / "ws" / "meshbot_description"))
    model = load_model(package / "urdf" / "meshbot.urdf", package_path=[tmp_path / "ws"])
    assert model.packages == {"meshbot_description": other}
    assert mesh_files(model) == [str(other / "meshes" / "cube.obj")] * 3


@pytest.mark.parametrize(("filename", "looked_for", "how"), [
    ("package://meshbot_description/meshes/nothere.obj", "meshes/nothere.obj",
     "package 'meshbot_description' is {pkg}"),
    ("../meshes/nothere.obj", "meshes/nothere.obj", "relative to {pkg}/urdf"),
    ("file://{pkg}/nothere.stl", "nothere.stl", "an absolute path"),
])
def test_missing_mesh_names_file_line_mesh_and_where_it_looked(
        package: Path, filename: str, looked_for: str, how: str) -> None:
    path = package / "urdf" / "meshbot.urdf"
    filename = filename.format(pkg=package)
    text = path.read_text()
    path.write_text(text.replace(PACKAGE_URI, filename, 1))
    with pytest.raises(ModelError) as info:
        load_model(path)
    assert str(info.value) == (
        f"{path}:10: mesh '{filename}' not found: looked for {package / looked_for} "
        f"({how.format(pkg=package)}); expected an existing mesh file")


def test_mesh_of_an_unknown_package(package: Path) -> None:
    path = package / "urdf" / "meshbot.urdf"
    path.write_text(path.read_text().replace(PACKAGE_URI, "package://nosuch_description/x.stl"))
    with pytest.raises(ModelError) as info:
        load_model(path)
    message = str(info.value)
    assert message.startswith(f"{path}:10: package 'nosuch_description' not found (asked for "
                              "by mesh 'package://nosuch_description/x.stl'); searched ")
    assert "the folders enclosing meshbot.urdf" in message


@pytest.mark.parametrize("filename", ["http://example.org/x.stl", "package://x"])
def test_unsupported_mesh_uris(package: Path, filename: str) -> None:
    path = package / "urdf" / "meshbot.urdf"
    path.write_text(path.read_text().replace(PACKAGE_URI, filename))
    with pytest.raises(ModelError, match=f"^{path}:10: mesh '{filename}': .*; expected "
                                         "package://PACKAGE/PATH, file://PATH or a file path$"):
        load_model(path)


def test_missing_mesh_in_a_xacro_file_names_the_xacro_file(package: Path) -> None:
    path = package / "urdf" / "meshbot.urdf.xacro"
    text = (package / "urdf" / "meshbot.urdf").read_text()
    path.write_text(text.replace("<robot ", '<robot xmlns:xacro="http://ros.org/wiki/xacro" ')
                    .replace('<link name="sensor">', '<xacro:property name="d" value="meshes"/>'
                             '\n  <link name="sensor">')
                    .replace(f"{PACKAGE_URI}\" scale=\"0.03",
                             "package://meshbot_description/${d}/x.obj\" scale=\"0.03"))
    with pytest.raises(ModelError) as info:
        load_model(path)
    # written with a property, the name is not in the file: the xacro output's line is given
    assert info.value.file == f"{path} (xacro output)"
    assert "mesh 'package://meshbot_description/meshes/x.obj' not found" in str(info.value)
    path.write_text(text.replace(PACKAGE_URI, "package://meshbot_description/meshes/y.obj"))
    with pytest.raises(ModelError) as info:
        load_model(path)
    assert (info.value.file, info.value.line) == (str(path), 10)  # written as is: its line


def test_mesh_visual_over_a_primitive_collision_is_no_mismatch() -> None:
    text = (FIXTURE_PKG / "urdf" / "meshbot_relative.urdf").read_text()
    assert find_defects(parse_urdf(text)) == []
    swapped = text.replace('<box size="0.2 0.12 0.04"/>', '<sphere radius="0.1"/>')
    assert find_defects(parse_urdf(swapped)) == []  # any primitive under a mesh
    collision_mesh = text.replace('<cylinder radius="0.03" length="0.02"/></geometry>\n'
                                  '    </collision>', '<mesh filename="x.obj"/></geometry>\n'
                                  '    </collision>', 1)
    assert [d.kind for d in find_defects(parse_urdf(collision_mesh))] == [GEOMETRY_MISMATCH]


def test_simulator_turns_a_pybullet_failure_into_a_model_error(sim, tmp_path: Path,
                                                               capfd) -> None:
    path = tmp_path / "raw.urdf"  # written directly, not through load_model
    path.write_text((FIXTURE_PKG / "urdf" / "meshbot_relative.urdf").read_text())
    with pytest.raises(ModelError) as info:
        sim.load_urdf("raw", path)
    assert str(info.value) == (
        f"{path}:10: pybullet cannot load this URDF (Cannot load URDF file.): mesh "
        f"'../meshes/cube.obj' not found (looked for {tmp_path.parent}/meshes/cube.obj); expected "
        "an existing mesh file (load_model makes mesh paths absolute and checks them)")
    with pytest.raises(ModelError, match=f"^{tmp_path}/none.urdf: pybullet cannot load this "
                                         r"URDF \(Cannot load URDF file.\): no such file"):
        sim.load_urdf("none", tmp_path / "none.urdf")
    captured = capfd.readouterr()
    assert (captured.out, captured.err) == ("", "")  # no b3Error spam
    assert not sim.has_body("raw")
