"""The shipped smartcar in pybullet, without the controller: it stands and it rolls straight."""

from __future__ import annotations

import pytest

from smartcar_gym._bullet import pybullet


def _base_link_pose(sim, body):
    c = sim.client
    com_pos, com_orn = c.getBasePositionAndOrientation(body)
    info = c.getDynamicsInfo(body, -1)
    pos, orn = c.multiplyTransforms(com_pos, com_orn, *c.invertTransform(info[3], info[4]))
    up_z = c.getMatrixFromQuaternion(orn)[8]
    return pos, up_z


@pytest.fixture
def dropped_car(sim, shipped_model, tmp_path):
    """The shipped model dropped from 5 cm onto the plane, wheels free, settled for 2 s."""
    body = sim.load_urdf("car", shipped_model.write_urdf(tmp_path), (0.0, 0.0, 0.05))
    joints = sim.joint_indices("car")
    wheels = [joints[w.joint] for w in shipped_model.wheels]
    sim.client.setJointMotorControlArray(
        body, wheels, pybullet.VELOCITY_CONTROL, forces=[0.0] * len(wheels)
    )
    sim.step(1000)
    return body, wheels


def test_dropped_car_settles_upright_at_the_expected_height(sim, shipped_model, dropped_car):
    body, _ = dropped_car
    pos, up_z = _base_link_pose(sim, body)
    # wheel centres are 0.025 m above base_link and the wheels have a 0.025 m radius, so
    # base_link rests on the ground plane: expected z = 0.025 - 0.025 = 0
    expected = shipped_model.wheel_radius_m - shipped_model.wheels[0].position_m[2]
    assert expected == pytest.approx(0.0)
    assert pos[2] == pytest.approx(expected, abs=1e-3)
    assert up_z > 0.9999


def test_four_wheels_at_one_speed_drive_straight(sim, shipped_model, dropped_car):
    body, wheels = dropped_car
    start, _ = _base_link_pose(sim, body)
    speed = 0.2 / shipped_model.wheel_radius_m  # rad/s for 0.2 m/s
    sim.client.setJointMotorControlArray(
        body, wheels, pybullet.VELOCITY_CONTROL,
        targetVelocities=[speed * w.forward_sign for w in shipped_model.wheels],
        forces=[1.0] * len(wheels),
    )
    sim.step(round(5.0 * sim.physics_hz))
    end, up_z = _base_link_pose(sim, body)
    assert abs(end[1] - start[1]) < 0.02  # lateral drift under 2 cm
    assert end[0] - start[0] == pytest.approx(1.0, rel=0.05)  # 5 s at 0.2 m/s
    assert up_z > 0.999
