"""The MuJoCo simulator facade (sim/mujoco/): bodies, rays, obstacles, the wheel chain, errors."""

from __future__ import annotations

import math

import numpy as np
import pytest

pytest.importorskip("smartcar_gym.sim.mujoco", reason="engine='mujoco' needs the mujoco extra")

from smartcar_gym.envs.robots import SmartCarRobot, drive  # noqa: E402
from smartcar_gym.model import ModelError  # noqa: E402
from smartcar_gym.sim.contracts import BASE  # noqa: E402
from smartcar_gym.sim.engines import (  # noqa: E402
    check_engine,
    engine_names,
    get_engine,
    make_simulator,
)
from smartcar_gym.sim.obstacles import add_obstacle, nearest_distance  # noqa: E402
from smartcar_gym.sim.rays import cast_rays, hide_from_rays  # noqa: E402


@pytest.fixture
def world():
    sim = make_simulator("mujoco")
    yield sim
    sim.close()


@pytest.fixture
def car(world, shipped_model, shipped_config):
    robot = SmartCarRobot(world, shipped_model, shipped_config)
    robot.spawn()
    return robot


def _rays(y_values, z=0.1, x0=-1.0, x1=3.0):
    return (np.array([[x0, y, z] for y in y_values]), np.array([[x1, y, z] for y in y_values]))


def test_rays_report_the_first_hit_fraction_point_and_body(world):
    box = add_obstacle(world, "box", "box", (0.2, 0.4), (1.0, 0.0), height=0.3)
    hits = cast_rays(world, *_rays([0.0, 0.15, 0.3]))
    assert hits.fraction[:2] == pytest.approx([1.9 / 4, 1.9 / 4])  # face x = 0.9 of a 4 m ray
    assert hits.body.tolist() == [box.uid, box.uid, -1]
    assert hits.fraction[2] == 1.0
    assert hits.point[1] == pytest.approx([0.9, 0.15, 0.1])
    # from one common start (the laser's case: mj_multiRay) the same distances
    starts = np.zeros((3, 3)) + [0.0, 0.0, 0.1]
    ends = np.array([[3.0, 0.0, 0.1], [3.0, 0.45, 0.1], [0.0, 3.0, 0.1]])
    fan = cast_rays(world, starts, ends)
    assert fan.fraction[0] == pytest.approx(0.9 / 3.0)
    assert fan.point[1] == pytest.approx([0.9, 0.135, 0.1])
    assert fan.body.tolist() == [box.uid, box.uid, -1]


def test_a_cylinder_is_round(world):
    add_obstacle(world, "cyl", "cylinder", (0.4,), (1.0, 0.0))
    hits = cast_rays(world, *_rays([0.0, 0.1, 0.19]))
    expected = [1.0 - math.sqrt(0.2**2 - y**2) for y in (0.0, 0.1, 0.19)]
    assert hits.point[:, 0] == pytest.approx(expected, abs=1e-6)


def test_hidden_car_lets_rays_through_and_still_hits_the_wall(world, car):
    wall = add_obstacle(world, "wall", "box", (0.1, 2.0), (0.6, 0.0))
    starts, ends = _rays([0.0], z=0.05, x0=-1.0)
    assert cast_rays(world, starts, ends).body[0] == car.body.uid  # the car's back
    hide_from_rays(car.body)
    assert cast_rays(world, starts, ends).body[0] == wall.uid
    assert nearest_distance(car.body, [wall], 1.0) == pytest.approx(0.55 - 0.125, abs=1e-3)
    z0 = car.pose().z
    drive(car, 0.4, 0.0, 30)  # 3 s at 0.4 m/s: into the wall at 0.55 m
    pose = car.pose()
    assert pose.z == pytest.approx(z0, abs=5e-3)
    assert 0.35 < pose.x < 0.43  # stopped by the wall (front at x + 0.125 = 0.55)
    assert nearest_distance(car.body, [wall], 1.0) < 0.01


def test_the_car_has_the_urdf_masses_and_the_rotor_inertia(world, car, shipped_config):
    body = car.body
    model = world.model_compiled()
    assert float(np.sum(model.body_mass)) == pytest.approx(1.5)  # base 1.0, wheels 4 x 0.1, head
    assert body.dynamics(BASE).mass_kg == pytest.approx(1.0)
    share = 0.5  # two wheels per side share a motor
    armature = model.dof_armature[body._ids.dadr]
    assert armature == pytest.approx([share * shipped_config.motor.reflected_inertia_kg_m2] * 4)
    assert body.dynamics(car.wheel_joint_indices[0]).lateral_friction == 0.5  # pybullet's default


def test_a_side_s_wheels_turn_together_and_the_car_drives_straight(car):
    drive(car, 0.3, 0.0, 20)
    position, velocity = car.body.joint_states(car.wheel_joint_indices)
    signs = np.array(car.wheel_signs)
    forward = velocity * signs
    left = [f for f, is_left in zip(forward, car.wheel_left, strict=True) if is_left]
    assert left[0] == pytest.approx(left[1], rel=1e-3)  # the chain holds them 1:1
    pose = car.pose()
    assert 0.4 < pose.x < 0.6 and abs(pose.y) < 0.01 and abs(pose.yaw) < 0.01


def test_friction_is_the_product_of_the_ground_s_and_the_wheel_s(world, car):
    plane = world.body("plane")
    plane.set_friction(BASE, 0.6)
    model = world.model_compiled()
    wheels = car.body._ids.link_of_body  # the bodies of the four wheel joints
    wheel_geoms = [g for g in car.body._ids.collision_geoms if model.geom_bodyid[g] in wheels]
    assert model.geom_friction[wheel_geoms, 0] == pytest.approx([0.6 * 0.5] * 4)


def test_engine_names_and_the_factory():
    assert engine_names() == ("pybullet", "mujoco", "planar")
    assert check_engine("mujoco") == "mujoco" == get_engine("mujoco").name
    with pytest.raises(ValueError,
                       match="engine must be one of 'pybullet', 'mujoco', 'planar', got 'ode'"):
        check_engine("ode")
    sim = make_simulator("pybullet")
    assert sim.engine == "pybullet"
    sim.close()


def test_a_model_mujoco_cannot_compile_names_the_file_and_the_reason(world, tmp_path):
    urdf = tmp_path / "massless.urdf"
    urdf.write_text(
        '<robot name="r"><link name="base"><inertial><mass value="1"/>'
        '<inertia ixx="1" iyy="1" izz="1" ixy="0" ixz="0" iyz="0"/></inertial></link>'
        '<link name="wheel"/>'
        '<joint name="j" type="continuous"><parent link="base"/><child link="wheel"/>'
        '<axis xyz="0 1 0"/></joint></robot>')
    with pytest.raises(ModelError, match=r"massless\.urdf.*MuJoCo cannot compile") as error:
        world.load_urdf("r", urdf)
    assert "\n" not in str(error.value) and "mass" in str(error.value)


def test_missing_mujoco_names_the_extra(monkeypatch):
    import sys

    from smartcar_gym.sim import engines

    for name in [m for m in sys.modules if m == "mujoco" or m.startswith(("mujoco.",
                                                                            "smartcar_gym.sim.mujoco"))]:
        monkeypatch.delitem(sys.modules, name)
    monkeypatch.setitem(sys.modules, "mujoco", None)
    with pytest.raises(ImportError, match=r'pip install "smartcar-gym\[mujoco\]"'):
        engines.make_simulator("mujoco")


def test_close_frees_the_world_and_is_idempotent(world, car):
    world.close()
    assert world.model is None and not world.connected
    world.close()
    with pytest.raises(RuntimeError, match="closed"):
        world.reset()


def test_randomize_factors_reach_the_mujoco_model(world, shipped_model, shipped_config):
    from smartcar_gym.envs.robots.variation import Variation

    robot = SmartCarRobot(world, shipped_model, shipped_config)
    robot.vary(Variation(base_mass=2.0, wheel_mass=0.5, wheel_friction=0.4, wheel_radius=1.2))
    robot.spawn()
    model = world.model_compiled()
    ids = robot.body._ids
    assert model.body_mass[ids.root] == pytest.approx(2.0)
    wheel_bodies = sorted(ids.link_of_body)
    assert model.body_mass[wheel_bodies] == pytest.approx([0.05] * 4)
    wheel_geoms = [g for g in ids.collision_geoms if model.geom_bodyid[g] in ids.link_of_body]
    assert model.geom_friction[wheel_geoms, 0] == pytest.approx([0.4 * 0.5] * 4)
    assert model.geom_size[wheel_geoms, 0] == pytest.approx([0.025 * 1.2] * 4)
    assert robot.pose().z == pytest.approx(robot.spawn_z, abs=5e-4)  # on its bigger wheels


def test_one_car_s_spec_from_urdf_text_for_batched_worlds(shipped_model):
    import mujoco

    from smartcar_gym.model.contact import simulated_urdf
    from smartcar_gym.sim.mujoco.model import GROUP_COLLISION, car_spec_from_text

    model = car_spec_from_text(simulated_urdf(shipped_model), shipped_model.source).compile()
    assert model.nq == 7 + 4  # a free joint and four wheels
    assert float(np.sum(model.body_mass)) == pytest.approx(1.5)
    spheres = [g for g in range(model.ngeom) if model.geom_type[g] == mujoco.mjtGeom.mjGEOM_SPHERE
               and model.geom_group[g] == GROUP_COLLISION]
    assert model.geom_size[spheres, 0] == pytest.approx([0.025] * 4)  # sphere wheel contact
