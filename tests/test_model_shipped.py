"""The shipped smartcar description: structure, wheels, inertias, no defects."""

from __future__ import annotations

import math
import warnings
import xml.etree.ElementTree as ET

import pytest

from smartcar_gym.model import SHIPPED_MODEL, RobotModel, load_model

WHEELS = {
    "left_front_wheel": ("left", (0.08, 0.08, 0.025)),
    "right_front_wheel": ("right", (0.08, -0.08, 0.025)),
    "left_back_wheel": ("left", (-0.08, 0.08, 0.025)),
    "right_back_wheel": ("right", (-0.08, -0.08, 0.025)),
}


@pytest.fixture(scope="module")
def model() -> RobotModel:
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # the shipped model loads without any warning
        return load_model()


def test_default_path_is_the_shipped_xacro(model: RobotModel) -> None:
    assert model.source == SHIPPED_MODEL
    assert model.source.name == "smartcar.urdf.xacro"
    assert model.name == "smartcar"


def test_six_links_five_joints_with_the_tutorial_names(model: RobotModel) -> None:
    assert list(model.links) == ["base_link", *WHEELS, "head"]
    assert list(model.joints) == [f"{w}_joint" for w in WHEELS] + ["tobox"]
    assert model.base_link == "base_link"
    assert model.joints["tobox"].type == "fixed"
    assert (model.joints["tobox"].parent, model.joints["tobox"].child) == ("base_link", "head")
    assert model.joints["tobox"].origin.xyz == (0.08, 0.0, 0.08)


@pytest.mark.parametrize("link", list(WHEELS))
def test_wheel_joint(model: RobotModel, link: str) -> None:
    joint = model.joints[f"{link}_joint"]
    assert (joint.type, joint.parent, joint.child) == ("continuous", "base_link", link)
    assert joint.axis == (0.0, 0.0, 1.0)
    assert joint.origin.xyz == WHEELS[link][1]
    assert joint.origin.rpy == pytest.approx((0.0, math.pi / 2, math.pi / 2), abs=1e-12)


def test_four_wheels_found_with_their_sides(model: RobotModel) -> None:
    assert [(w.joint, w.link, w.side) for w in model.wheels] == [
        (f"{link}_joint", link, side) for link, (side, _) in WHEELS.items()
    ]
    for wheel in model.wheels:
        assert wheel.position_m == pytest.approx(WHEELS[wheel.link][1], abs=1e-12)
        assert wheel.radius_m == 0.025
        assert wheel.forward_sign == 1  # joint z is turned onto base_link +y
    assert [w.link for w in model.left_wheels] == ["left_front_wheel", "left_back_wheel"]
    assert [w.link for w in model.right_wheels] == ["right_front_wheel", "right_back_wheel"]
    assert model.wheel_radius_m == pytest.approx(0.025)
    assert model.track_width_m == pytest.approx(0.16)


def test_wheel_inertia_is_a_solid_cylinder(model: RobotModel) -> None:
    inertial = model.links["left_front_wheel"].inertial
    assert inertial.mass == 0.1
    ixx = 0.1 * (3 * 0.025**2 + 0.02**2) / 12
    izz = 0.1 * 0.025**2 / 2
    assert ixx == pytest.approx(1.8958333e-05)
    assert izz == pytest.approx(3.125e-05)
    assert sum(inertial.inertia, ()) == pytest.approx((ixx, 0, 0, 0, ixx, 0, 0, 0, izz))


def test_base_and_head_inertia_are_solid_boxes(model: RobotModel) -> None:
    base = model.links["base_link"].inertial
    assert base.origin.xyz == (0.0, 0.0, 0.055)
    assert [base.inertia[i][i] for i in range(3)] == pytest.approx(
        [(0.16**2 + 0.05**2) / 12, (0.25**2 + 0.05**2) / 12, (0.25**2 + 0.16**2) / 12])
    head = model.links["head"].inertial
    assert [head.inertia[i][i] for i in range(3)] == pytest.approx(
        [0.1 * (0.03**2 + 0.03**2) / 12, 0.1 * (0.02**2 + 0.03**2) / 12,
         0.1 * (0.02**2 + 0.03**2) / 12])


def test_geometry(model: RobotModel) -> None:
    base = model.links["base_link"]
    assert base.collisions[0].geometry.type == "box"
    assert base.collisions[0].geometry.size == (0.25, 0.16, 0.05)
    assert base.collisions[0].origin.xyz == (0.0, 0.0, 0.055)
    wheel = model.links["left_front_wheel"].collisions[0]
    assert (wheel.geometry.type, wheel.geometry.size) == ("cylinder", (0.025, 0.02))
    assert wheel.geometry.radius == 0.025
    assert wheel.origin.xyz == (0.0, 0.0, 0.0)
    assert model.links["head"].visuals[0].geometry.type == "box"


def test_no_defects_no_repairs(model: RobotModel) -> None:
    assert model.defects == ()
    assert model.repairs == ()


def test_write_urdf_round_trips(model: RobotModel, tmp_path) -> None:
    path = model.write_urdf(tmp_path / "out")
    assert path == tmp_path / "out" / "smartcar.urdf"
    root = ET.parse(path).getroot()
    assert root.tag == "robot"
    assert [e.get("name") for e in root.findall("link")] == list(model.links)
    reloaded = load_model(path)
    assert reloaded.links == model.links
    assert reloaded.joints == model.joints
    assert reloaded.wheels == model.wheels


def test_repaired_model_stands_level_in_pybullet(model: RobotModel, tmp_path) -> None:
    from smartcar_gym.sim.pybullet.bullet import connect

    client = connect()
    try:
        client.setGravity(0, 0, -9.81)
        client.loadURDF("plane.urdf")
        body = client.loadURDF(str(model.write_urdf(tmp_path)), [0, 0, 0.001],
                               flags=client.URDF_USE_INERTIA_FROM_FILE)
        names = [client.getJointInfo(body, i)[1].decode() for i in range(5)]
        assert names == list(model.joints)
        for _ in range(240):
            client.stepSimulation()
        com, orientation = client.getBasePositionAndOrientation(body)
        up_z = client.getMatrixFromQuaternion(orientation)[8]
    finally:
        client.disconnect()
    assert up_z > 0.999
    assert com[2] == pytest.approx(0.055, abs=0.003)  # base_link on the ground, COM 55 mm up
