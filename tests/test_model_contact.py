"""The wheel contact model: sphere wheels (one ground contact each) or the URDF's own shapes."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from smartcar_gym.envs.robots import SmartCarRobot, drive
from smartcar_gym.model import ModelDefectWarning, RobotModel, load_model
from smartcar_gym.model.contact import check_wheel_contact, simulated_urdf
from smartcar_gym.model.urdf import parse_urdf
from smartcar_gym.sim.pybullet.bullet import pybullet
from smartcar_gym.sim.pybullet.simulator import Simulator

WHEELS = ("left_front_wheel", "right_front_wheel", "left_back_wheel", "right_back_wheel")


def test_urdf_contact_is_the_model_text_unchanged(shipped_model: RobotModel) -> None:
    assert simulated_urdf(shipped_model, "urdf") is shipped_model.urdf


def test_sphere_contact_changes_only_the_wheel_collision_shapes(shipped_model: RobotModel) -> None:
    spheres = parse_urdf(simulated_urdf(shipped_model, "sphere"))
    before = shipped_model.links
    for name in WHEELS:
        (shape,) = spheres.links[name].collisions
        assert (shape.geometry.type, shape.geometry.size) == ("sphere", (0.025,))
        assert shape.origin == before[name].collisions[0].origin  # the wheel's centre
        assert spheres.links[name].visuals == before[name].visuals  # still drawn as cylinders
        assert spheres.links[name].inertial == before[name].inertial
    assert spheres.links["base_link"] == before["base_link"]
    assert spheres.joints == shipped_model.joints


def test_sphere_wheels_are_found_as_the_same_wheels(shipped_model: RobotModel, tmp_path) -> None:
    path = shipped_model.write_urdf(tmp_path, simulated_urdf(shipped_model, "sphere"))
    # loaded as a model of its own, the swap is a visual/collision mismatch (4 warnings)
    with pytest.warns(ModelDefectWarning, match="collision geometry sphere differs from visual"):
        assert load_model(path).wheels == shipped_model.wheels


def test_only_the_round_shape_that_gave_the_radius_is_replaced(tmp_path: Path) -> None:
    wheel = (
        '<collision><origin xyz="0 0 0"/><geometry><box size="0.01 0.01 0.01"/></geometry>'
        '</collision><collision><origin xyz="0 0.005 0" rpy="1.5708 0 0"/><geometry>'
        '<cylinder radius="0.04" length="0.02"/></geometry></collision>'
        '<collision><geometry><cylinder radius="0.01" length="0.05"/></geometry></collision>'
    )
    text = '<?xml version="1.0"?>\n<robot name="r">\n  <link name="base"/>\n'
    for side, y in (("l", 0.1), ("r", -0.1)):
        text += (f'  <link name="{side}">{wheel}</link>\n  <joint name="{side}_j" '
                 f'type="continuous"><parent link="base"/><child link="{side}"/>'
                 f'<origin xyz="0 {y} 0"/><axis xyz="0 1 0"/></joint>\n')
    (tmp_path / "r.urdf").write_text(text + "</robot>\n")
    model = load_model(tmp_path / "r.urdf")
    shapes = parse_urdf(simulated_urdf(model, "sphere")).links["l"].collisions
    assert [(s.geometry.type, s.geometry.size) for s in shapes] == [
        ("box", (0.01, 0.01, 0.01)), ("sphere", (0.04,)), ("cylinder", (0.01, 0.05))]
    assert shapes[1].origin == model.links["l"].collisions[1].origin


def test_wheels_that_are_spheres_already_leave_the_text_alone(tmp_path: Path) -> None:
    text = '<?xml version="1.0"?>\n<robot name="r">\n  <link name="base"/>\n'
    for side, y in (("l", 0.1), ("r", -0.1)):
        text += (f'  <link name="{side}"><collision><geometry><sphere radius="0.03"/></geometry>'
                 f'</collision></link>\n  <joint name="{side}_j" type="continuous"><parent '
                 f'link="base"/><child link="{side}"/><origin xyz="0 {y} 0"/>'
                 '<axis xyz="0 1 0"/></joint>\n')
    (tmp_path / "r.urdf").write_text(text + "</robot>\n")
    model = load_model(tmp_path / "r.urdf")
    assert simulated_urdf(model, "sphere") is model.urdf


@pytest.mark.parametrize("value", ["cylinder", "Sphere", None, 1])
def test_unknown_contact_models_are_refused(value) -> None:
    with pytest.raises(ValueError, match=r"wheel_contact must be one of \('sphere', 'urdf'\), "
                                         rf"got {value!r}"):
        check_wheel_contact(value)


@pytest.mark.parametrize(("contact", "geom"), [("sphere", pybullet.GEOM_SPHERE),
                                               ("urdf", pybullet.GEOM_CYLINDER)])
def test_the_simulated_wheels_touch_the_ground_as_told(shipped_model, shipped_config,
                                                       contact: str, geom: int) -> None:
    # 2 ms steps: at 10 ms a fast-rolling sphere's manifold may keep up to 4 stale points
    sim = Simulator(max_substep_s=0.002)
    robot = SmartCarRobot(sim, shipped_model, shipped_config, wheel_contact=contact)
    robot.spawn()
    c, body = sim.client, robot.body.uid
    joints = robot.body.joints
    for wheel in robot.wheels:
        (shape,) = c.getCollisionShapeData(body, joints[wheel.joint])
        assert shape[2] == geom
    counts = []
    for _ in range(10):  # drive forward and turn for 1 s
        drive(robot, 0.3, 1.0)
        points = c.getContactPoints(bodyA=sim.body("plane").uid, bodyB=body)
        counts.append(len(points))
        assert {p[4] for p in points} == set(joints[w.joint] for w in robot.wheels)
    sim.close()
    if contact == "sphere":
        assert counts == [4] * 10  # one point per wheel
    else:  # the cylinder manifold keeps several points across each tyre (measured 8-16)
        assert np.mean(counts) > 6


def test_a_robot_refuses_an_unknown_contact_model(sim, shipped_model, shipped_config) -> None:
    with pytest.raises(ValueError, match=r"wheel_contact must be one of .*got 'cylinder'"):
        SmartCarRobot(sim, shipped_model, shipped_config, wheel_contact="cylinder")
