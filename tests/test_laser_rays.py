"""The simulator's ray casts (sim/rays.py) and static obstacles (sim/obstacles.py)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from smartcar_gym.envs.robots import drive
from smartcar_gym.sim.obstacles import add_obstacle, nearest_distance
from smartcar_gym.sim.rays import MAX_RAYS, cast_rays, hide_from_rays


def _rays(y_values, z=0.1, x0=-1.0, x1=3.0):
    starts = np.array([[x0, y, z] for y in y_values])
    ends = np.array([[x1, y, z] for y in y_values])
    return starts, ends


def test_rays_report_the_first_hit_fraction_point_and_body(sim):
    box = add_obstacle(sim, "box", "box", (0.2, 0.4), (1.0, 0.0), height=0.3)
    starts, ends = _rays([0.0, 0.15, 0.3])
    hits = cast_rays(sim, starts, ends)
    # the face at x = 0.9 is 1.9 m along a 4 m ray; y = 0.3 passes beside the box
    assert hits.fraction[:2] == pytest.approx([1.9 / 4, 1.9 / 4])
    assert hits.body.tolist() == [box.uid, box.uid, -1]
    assert hits.hit.tolist() == [True, True, False]
    assert hits.fraction[2] == 1.0
    assert hits.point[1] == pytest.approx([0.9, 0.15, 0.1])


def test_a_ray_above_an_obstacle_misses_it_and_a_turned_box_is_hit_at_its_corner(sim):
    add_obstacle(sim, "low", "box", (0.2, 0.2), (1.0, 0.0), height=0.05)
    assert not cast_rays(sim, *_rays([0.0])).hit[0]
    add_obstacle(sim, "diamond", "box", (0.2, 0.2), (2.0, 0.0), yaw=math.pi / 4)
    hits = cast_rays(sim, *_rays([0.0]))
    # Bullet rounds box corners by its collision margin: 0.4 mm short of the sharp corner
    assert hits.point[0][0] == pytest.approx(2.0 - 0.1 * math.sqrt(2), abs=1e-3)


def test_a_cylinder_is_round(sim):
    add_obstacle(sim, "cyl", "cylinder", (0.4,), (1.0, 0.0))
    hits = cast_rays(sim, *_rays([0.0, 0.1, 0.19]))
    expected = [1.0 - math.sqrt(0.2**2 - y**2) for y in (0.0, 0.1, 0.19)]  # a box: 0.8 for all
    assert hits.point[:, 0] == pytest.approx(expected, abs=1e-3)  # within Bullet's margin


def test_a_pillar_asleep_after_its_first_step_is_grazed_as_when_awake(monkeypatch):
    """pybullet puts a pillar to sleep after the first physics step, once that step has set
    its bounding box with Bullet's contact margin. Rays grazing its side hit it as they hit
    an awake pillar; asleep from its creation, its bare box let some of them pass."""
    import pybullet

    from smartcar_gym.sim.pybullet.simulator import Simulator

    fan = [(y, angle) for y in np.linspace(0.07, 0.08, 101) for angle in (-0.3, 0.0, 0.3)]
    starts = np.array([[0.0, y, 0.1] for y, _ in fan])
    ends = starts + 3.0 * np.array([[math.cos(a), math.sin(a), 0.0] for _, a in fan])

    def grazed(asleep_at_creation: bool = False) -> np.ndarray:
        world = Simulator(draws=False)
        try:
            pillar = add_obstacle(world, "pillar", "cylinder", (0.15,), (1.0, 0.0), pillar=True)
            if asleep_at_creation:
                world.client.changeDynamics(pillar.uid, -1,
                                            activationState=pybullet.ACTIVATION_STATE_SLEEP)
            world.run_until(world.now_ns + 20_000_000)
            return cast_rays(world, starts, ends).hit
        finally:
            world.close()

    asleep = grazed()
    early = grazed(asleep_at_creation=True)
    monkeypatch.setattr(Simulator, "_sleep_pillars", lambda self: None)
    awake = grazed()
    assert 0 < asleep.sum() < len(fan) and np.array_equal(asleep, awake)
    assert early.sum() < awake.sum()


def test_hidden_bodies_let_rays_through_but_still_collide(sim, hardware_robot):
    robot = hardware_robot
    wall = add_obstacle(sim, "wall", "box", (0.1, 2.0), (0.6, 0.0))
    starts, ends = _rays([0.0], z=0.05, x0=-1.0)
    assert cast_rays(sim, starts, ends).body[0] == robot.body.uid  # the car's back
    hide_from_rays(robot.body)
    assert cast_rays(sim, starts, ends).body[0] == wall.uid
    z0 = robot.pose().z
    drive(robot, 0.4, 0.0, 30)  # 3 s at 0.4 m/s: into the wall at 0.55 m
    pose = robot.pose()
    assert pose.z == pytest.approx(z0, abs=5e-3)  # still on the ground
    assert 0.35 < pose.x < 0.43  # stopped by the wall (front at x + 0.125 = 0.55)
    assert nearest_distance(robot.body, [wall], 0.3) <= 0.0  # touching


def test_nearest_distance_reads_current_poses_without_a_physics_step(sim, hardware_robot):
    body = hardware_robot.body
    box = add_obstacle(sim, "box", "box", (0.2, 0.2), (1.0, 0.0))
    far = add_obstacle(sim, "far", "cylinder", (0.2,), (-2.0, 0.0))
    x = hardware_robot.pose().x
    # the car's front (base box, x + 0.125) to the box's face (0.9)
    assert nearest_distance(body, [box, far], 1.0) == pytest.approx(0.9 - x - 0.125, abs=2e-3)
    assert nearest_distance(body, [box, far], 0.3) == 0.3  # none nearer than that
    assert nearest_distance(body, [], 0.3) == 0.3
    body.set_link_pose((0.8, 0.0, 0.0), (0.0, 0.0, 0.0, 1.0))  # teleported into it
    assert nearest_distance(body, [box, far], 0.3) < 0.0


def test_bad_rays_and_obstacles_are_refused(sim):
    with pytest.raises(ValueError, match=r"\(N, 3\)"):
        cast_rays(sim, np.zeros((2, 3)), np.zeros((3, 3)))
    with pytest.raises(ValueError, match=r"\(N, 3\)"):
        cast_rays(sim, np.zeros((2, 2)), np.zeros((2, 2)))
    with pytest.raises(ValueError, match=f"1 to {MAX_RAYS} rays"):
        cast_rays(sim, np.zeros((MAX_RAYS + 1, 3)), np.ones((MAX_RAYS + 1, 3)))
    with pytest.raises(ValueError, match="shape must be one of"):
        add_obstacle(sim, "cone", "cone", (0.1,), (0.0, 0.0))
    add_obstacle(sim, "a", "box", (0.1, 0.1), (1.0, 0.0))
    with pytest.raises(ValueError, match="already exists"):
        add_obstacle(sim, "a", "box", (0.1, 0.1), (2.0, 0.0))
    assert sim.body("a").name == "a"
