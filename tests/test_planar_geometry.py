"""The planar engine's 2D geometry (sim/planar/geometry.py and its modules): rays, footprints,
clearances, by hand and against pybullet (and MuJoCo's analytic ray casts)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from smartcar_gym.envs.tasks.obstacles import Obstacle, ObstacleField
from smartcar_gym.model import load_model
from smartcar_gym.model.contact import simulated_urdf
from smartcar_gym.model.urdf import parse_urdf
from smartcar_gym.sim.obstacles import add_obstacle, nearest_distance
from smartcar_gym.sim.planar.geometry import (
    BOX,
    BULLET_BOX_MARGIN_M,
    CIRCLE,
    Shapes2D,
    cast,
    clearance,
    distances,
    footprint,
    ray_hits,
)
from smartcar_gym.sim.planar.mesh_bounds import mesh_bounds
from smartcar_gym.sim.planar.projection import Footprint
from smartcar_gym.sim.planar.raycast_jit import COMPILED as CAST_COMPILED
from smartcar_gym.sim.rays import cast_rays

FIXTURES = Path(__file__).parent / "fixtures"
SCAN_Z = 0.1  # the shipped laser's height
#: pybullet's rayTestBatch stops up to this far outside a surface (its convex cast's tolerance)
BULLET_RAY_TOLERANCE_M = 1e-3
#: how far pybullet's rounded box edges are from the sharp corner, two boxes together
BULLET_CORNERS_M = 2 * (math.sqrt(2) - 1) * BULLET_BOX_MARGIN_M


def _box(x, y, length, width, yaw=0.0):
    return Obstacle("box", (x, y), (length, width), yaw)


def _cylinder(x, y, diameter):
    return Obstacle("cylinder", (x, y), (diameter,))


def _layouts(seed, count, n=8, half_extent=2.0):
    rng = np.random.default_rng(seed)
    field = ObstacleField(count=n, half_extent_m=half_extent, clearance_m=0.0)
    return rng, [field.sample(rng, np.zeros(2), np.array([0.8, 0.3])) for _ in range(count)]


def _scan(origin, beams=360, length=3.5):
    angles = np.linspace(-math.pi, math.pi, beams, endpoint=False)
    starts = np.tile([origin[0], origin[1], SCAN_Z], (beams, 1))
    return starts, starts + length * np.c_[np.cos(angles), np.sin(angles), np.zeros(beams)]


# -- rays by hand ----------------------------------------------------------------------------
def test_a_ray_hits_a_box_face_at_its_range_and_a_turned_box_at_its_corner():
    shapes = Shapes2D.from_layout([_box(1.0, 0.0, 0.2, 0.4), _box(0.0, 2.0, 0.2, 0.2, math.pi / 4)])
    found = cast(np.zeros((1, 2)), np.array([0.0, math.pi / 2, 0.3]), 3.0, shapes)
    assert found.distance[0, 0] == pytest.approx(0.9, abs=1e-12)  # the face at x = 0.9
    assert found.distance[0, 1] == pytest.approx(2.0 - 0.1 * math.sqrt(2), abs=1e-12)
    assert found.shape.tolist() == [[0, 1, -1]]  # tan 0.3 * 0.9 = 0.28 > 0.2: beside the box
    assert found.distance[0, 2] == 3.0 and found.fraction[0, 2] == 1.0
    assert found.fraction[0, 0] == pytest.approx(0.3)
    # a slanted ray meets the face x = 0.9 at y = 0.9 tan(0.2)
    slanted = cast(np.zeros((1, 2)), np.array([0.2]), 3.0, shapes)
    assert slanted.distance[0, 0] == pytest.approx(0.9 / math.cos(0.2), abs=1e-12)


def test_a_ray_tangent_to_a_circle_touches_it_and_one_beside_misses():
    shapes = Shapes2D.from_layout([_cylinder(1.0, 0.25, 0.5)])  # touches y = 0 at x = 1
    origins = np.array([[0.0, 0.0], [0.0, -1e-9], [0.0, 0.25]])
    found = cast(origins, np.zeros((3, 1)), 3.0, shapes)
    assert found.shape[:, 0].tolist() == [0, -1, 0]
    assert found.distance[0, 0] == pytest.approx(1.0, abs=1e-9)
    assert found.distance[2, 0] == pytest.approx(0.75, abs=1e-12)  # through the centre
    # along a box's face line: touching it counts too
    along = cast(np.zeros((1, 2)), np.zeros(1), 3.0,
                 Shapes2D.from_layout([_box(1.0, 0.25, 0.5, 0.5)]))
    assert along.shape[0, 0] == 0 and along.distance[0, 0] == pytest.approx(0.75)


def test_a_ray_starting_inside_a_shape_passes_through_it():
    shapes = Shapes2D.from_layout([_box(0.0, 0.0, 0.4, 0.4), _cylinder(1.0, 0.0, 0.4),
                                   _box(3.0, 0.0, 0.2, 2.0)])
    origins = np.array([[0.05, 0.0], [1.1, 0.0]])  # inside the box, inside the cylinder
    found = cast(origins, np.zeros(1), 5.0, shapes)
    # from inside the box: the cylinder; from inside the cylinder: the wall at x = 2.9
    assert found.shape[:, 0].tolist() == [1, 2]
    assert found.distance[:, 0] == pytest.approx([0.8 - 0.05, 2.9 - 1.1])
    behind = cast(origins[:1], np.array([math.pi]), 5.0, shapes)
    assert not behind.hit.any()  # nothing behind it but the box it starts in


def test_beams_come_back_in_order_for_angles_vectors_and_shared_worlds():
    ranges = np.array([0.5, 1.0, 1.5, 2.0])
    bearings = np.array([0.0, math.pi / 2, math.pi, -math.pi / 2])
    layout = [_cylinder(r * math.cos(a), r * math.sin(a), 0.2) for r, a in zip(ranges, bearings,
                                                                               strict=True)]
    shapes = Shapes2D.from_layout(layout)
    angles = np.array([-math.pi / 2, 0.0, math.pi / 2, math.pi, math.pi / 4])
    found = cast(np.zeros((1, 2)), angles, 3.0, shapes)
    assert found.shape.tolist() == [[3, 0, 1, 2, -1]]
    assert found.distance[0, :4] == pytest.approx([1.9, 0.4, 0.9, 1.4])
    # two cars sharing the world, per-car angles, unit vectors: the same
    per_car = np.stack([angles, angles[::-1]])
    units = np.stack([np.cos(per_car), np.sin(per_car)], axis=-1)
    for directions in (per_car, units):
        both = cast(np.zeros((2, 2)), directions, 3.0, shapes)
        assert both.shape.tolist() == [[3, 0, 1, 2, -1], [-1, 2, 1, 0, 3]]
    # each car its own world; padding is never hit
    worlds = Shapes2D.from_layouts([layout, layout[:1]])
    assert worlds.valid.tolist() == [[True] * 4, [True, False, False, False]]
    two = cast(np.zeros((2, 2)), angles, 3.0, worlds)
    assert two.shape.tolist() == [[3, 0, 1, 2, -1], [-1, 0, -1, -1, -1]]


def test_max_range_cuts_rays_and_ties_go_to_the_lower_index():
    shapes = Shapes2D.from_layout([_box(1.5, 0.0, 1.0, 1.0), _box(1.5, 0.0, 1.0, 1.0)])
    found = cast(np.zeros((1, 2)), np.zeros(3), np.array([[0.9, 1.0, 3.0]]), shapes)
    assert found.shape.tolist() == [[-1, 0, 0]]  # the face at 1.0: just reached by a 1 m ray
    assert found.distance.tolist() == [[0.9, 1.0, 1.0]]
    assert found.fraction[0].tolist() == pytest.approx([1.0, 1.0, 1 / 3])


def test_laser_frames_give_the_world_frame_ranges():
    rng, layouts = _layouts(0, 6)
    shapes = Shapes2D.from_layouts(layouts)
    poses = np.c_[rng.uniform(-2, 2, (6, 2)), rng.uniform(-math.pi, math.pi, 6)]
    beams = np.linspace(-math.pi, math.pi, 360, endpoint=False)
    world = cast(poses[:, :2], poses[:, 2:] + beams, 3.5, shapes)
    local = cast(np.zeros((6, 2)), beams, 3.5, shapes.relative_to(poses))
    assert world.hit.sum() > 100
    np.testing.assert_array_equal(local.shape, world.shape)
    np.testing.assert_allclose(local.distance, world.distance, rtol=0, atol=1e-12)


def test_ray_hits_are_cast_rays_for_horizontal_rays():
    shapes = Shapes2D.from_layout([_box(1.0, 0.0, 0.2, 0.4), _cylinder(0.0, 1.0, 0.4)])
    starts = np.array([[0.0, 0.0, 0.1], [0.0, 0.0, 0.1], [0.0, 0.0, 0.4], [0.0, 0.5, 0.2]])
    ends = starts + np.array([[4.0, 0, 0], [0, 4.0, 0], [4.0, 0, 0], [4.0, 0, 0]])
    hits = ray_hits(starts, ends, shapes, [7, 9])
    assert hits.body.tolist() == [7, 9, -1, -1]  # above the 0.3 m obstacles: nothing
    assert hits.fraction.tolist() == pytest.approx([0.9 / 4, 0.8 / 4, 1.0, 1.0])
    assert hits.point[0] == pytest.approx([0.9, 0.0, 0.1])
    one = ray_hits(starts[:1], ends[:1], shapes, [7, 9])  # a single ray
    assert one.body.tolist() == [7]
    with pytest.raises(ValueError, match="horizontal"):
        ray_hits(starts, ends + [0.0, 0.0, 0.01], shapes, [7, 9])
    with pytest.raises(ValueError, match="bodies"):
        ray_hits(starts, ends, shapes, [7])


# -- rays against the engines ----------------------------------------------------------------
def test_rays_equal_mujocos_analytic_ray_casts():
    pytest.importorskip("smartcar_gym.sim.mujoco", reason="needs the mujoco extra")
    from smartcar_gym.sim.engines import make_simulator

    sim = make_simulator("mujoco")
    rng, layouts = _layouts(1, 8)
    try:
        for layout in layouts:
            sim.reset()
            bodies = [add_obstacle(sim, f"o{i}", o.shape, o.size, o.position, o.yaw).uid
                      for i, o in enumerate(layout)]
            origin = rng.uniform(-2.5, 2.5, 2)
            while min(o.distance(origin) for o in layout) <= 0:  # MuJoCo hits from inside
                origin = rng.uniform(-2.5, 2.5, 2)
            starts, ends = _scan(origin)
            expected = cast_rays(sim, starts, ends)
            hits = ray_hits(starts, ends, Shapes2D.from_layout(layout), bodies)
            np.testing.assert_array_equal(hits.body, expected.body)
            np.testing.assert_allclose(hits.point, expected.point, rtol=0, atol=1e-12)
    finally:
        sim.close()


def test_rays_equal_pybullets_within_its_tolerance(sim):
    rng, layouts = _layouts(2, 12)
    exact = box_hits = 0
    for trial, layout in enumerate(layouts):
        sim.reset()
        bodies = [add_obstacle(sim, f"o{i}", o.shape, o.size, o.position, o.yaw).uid
                  for i, o in enumerate(layout)]
        shapes = Shapes2D.from_layout(layout)
        starts, ends = _scan(rng.uniform(-2.5, 2.5, 2))
        expected = cast_rays(sim, starts, ends)
        hits = ray_hits(starts, ends, shapes, bodies)
        same = hits.body == expected.body
        for i in np.flatnonzero(same & hits.hit):  # pybullet stops short, up to its tolerance
            obstacle = layout[bodies.index(hits.body[i])]
            outside = float(obstacle.distance(expected.point[i, :2]))
            inside = BULLET_CORNERS_M / 2 if obstacle.shape == "box" else 0.0  # rounded corners
            assert -inside - 3e-5 <= outside <= BULLET_RAY_TOLERANCE_M + 3e-5, (trial, i)
            if obstacle.shape == "box":
                box_hits += 1
                exact += abs(expected.fraction[i] - hits.fraction[i]) * 3.5 <= 1e-6
        for i in np.flatnonzero(~same):  # grazing rays, within the tolerance of an outline
            ray = starts[i:i + 1], ends[i:i + 1]
            if expected.body[i] >= 0:  # pybullet's shape, a millimetre bigger: hit
                body = int(expected.body[i])
                grown = _grown(layout[bodies.index(body)], BULLET_RAY_TOLERANCE_M + 3e-5)
                assert ray_hits(*ray, grown, [body]).hit[0], (trial, i)
            else:  # pybullet missed ours past a rounded corner: a millimetre smaller, missed
                body = int(hits.body[i])
                shrunk = _grown(layout[bodies.index(body)], -BULLET_RAY_TOLERANCE_M - 3e-5)
                assert not ray_hits(*ray, shrunk, [body]).hit[0], (trial, i)
        assert same.mean() > 0.99
    # where pybullet's cast converges exactly (most box faces), the ranges agree to 1e-6 m
    assert box_hits > 300 and exact / box_hits > 0.8


def _grown(obstacle, by):
    size = tuple(s + 2 * by for s in obstacle.size)
    return Shapes2D.from_layout([Obstacle(obstacle.shape, obstacle.position, size, obstacle.yaw)])


# -- footprints ------------------------------------------------------------------------------
def test_the_shipped_cars_footprint_with_sphere_and_cylinder_wheels():
    model = load_model(mappings={"laser": "true"})
    spheres = footprint(model)  # as simulated: sphere wheels
    assert spheres.links == ("base_link", "left_front_wheel", "right_front_wheel",
                             "left_back_wheel", "right_back_wheel", "head", "laser")
    local = spheres.shapes
    assert local.kind[0].tolist() == [BOX, CIRCLE, CIRCLE, CIRCLE, CIRCLE, BOX, CIRCLE]
    np.testing.assert_allclose(local.centre[0], [[0, 0], [0.08, 0.08], [0.08, -0.08],
                                                 [-0.08, 0.08], [-0.08, -0.08], [0.08, 0],
                                                 [0, 0]], atol=1e-12)
    np.testing.assert_allclose(local.half[0], [[0.125, 0.08]] + [[0.025, 0.025]] * 4
                               + [[0.01, 0.015], [0.025, 0.025]], atol=1e-12)
    np.testing.assert_allclose(spheres.z_range[[0, 1, 6]], [[0.03, 0.08], [0.0, 0.05],
                                                            [0.07, 0.11]], atol=1e-12)
    assert spheres.exact.all()
    assert spheres.radius == pytest.approx(math.hypot(0.125, 0.08))
    # the URDF's wheels: cylinders about y, seen from the side, 2 cm wide and 5 cm long
    wheels = footprint(model, wheel_contact="urdf").shapes
    assert wheels.kind[0, 1] == BOX
    np.testing.assert_allclose(np.abs(wheels.rotation[0, 1]), [0.0, 1.0], atol=1e-12)
    np.testing.assert_allclose(wheels.half[0, 1], [0.01, 0.025], atol=1e-12)
    # from URDF text, or its parsed tables: the same
    text = simulated_urdf(model)
    for source in (text, parse_urdf(text)):
        np.testing.assert_allclose(footprint(source).shapes.half, local.half)


@pytest.mark.filterwarnings("ignore::smartcar_gym.model.ModelDefectWarning")  # seedlike's
def test_fixture_footprints_upright_cylinders_meshes_and_tilted_wheels():
    caster = footprint(load_model(FIXTURES / "casterbot_description/urdf/casterbot.urdf.xacro"),
                       wheel_contact="urdf")
    base = caster.links.index("base_link")  # an upright cylinder: its circle
    assert caster.shapes.kind[0, base] == CIRCLE and caster.shapes.half[0, base, 0] == 0.1
    mesh = footprint(load_model(FIXTURES / "meshbot_description/urdf/meshbot.urdf"))
    sensor = mesh.links.index("sensor")  # a unit cube scaled by 0.03: its bounding box
    assert not mesh.exact[sensor]
    np.testing.assert_allclose(mesh.shapes.half[0, sensor], [0.015, 0.015], atol=1e-12)
    np.testing.assert_allclose(mesh.z_range[sensor], [0.02, 0.05], atol=1e-12)
    # seedlike's wheels are turned by 1.57075 rad, not pi/2: a bounding rectangle a micron big
    seedlike = footprint(load_model(FIXTURES / "seedlike.urdf"), wheel_contact="urdf")
    wheel = seedlike.links.index("left_front_wheel")
    assert not seedlike.exact[wheel]
    np.testing.assert_allclose(seedlike.shapes.half[0, wheel], [0.01, 0.025], atol=2e-6)


def test_the_model_the_footprint_and_the_picture_share_one_projection():
    """The shipped car on the planar engine: each shape its picture draws is its footprint's
    (``projection.outline``) at its pose, and each wheel's ground contact is the centre of its
    footprint's circle, from the centre of mass."""
    import gymnasium as gym

    import smartcar_gym  # noqa: F401
    from smartcar_gym.sim.planar.layout import CX, CY
    from smartcar_gym.sim.planar.render import NOSE, robot_shapes
    from smartcar_gym.sim.planar.world import footprint_of

    env = gym.make("SmartCar-v0", engine="planar")
    env.reset(seed=2)
    for _ in range(5):
        env.step(np.array([0.5, -0.3], dtype=np.float32))
    body = env.unwrapped.robot.body
    (x, y, _), q = body.link_pose()
    yaw = 2.0 * math.atan2(q[2], q[3])
    placed = footprint_of(body).place([[x, y, yaw]])
    drawn = [shape for shape, colour in robot_shapes(body) if colour is not NOSE]
    assert len(drawn) == placed.num_shapes == 6  # the base, four wheels, the head
    for k, shape in enumerate(drawn):
        assert shape[0] == ("disc" if placed.kind[0, k] == CIRCLE else "rect")
        np.testing.assert_allclose(shape[1:3], placed.centre[0, k], atol=1e-12)
        np.testing.assert_allclose(shape[-2 if shape[0] == "rect" else -1:],
                                   placed.half[0, k][:2 if shape[0] == "rect" else 1], atol=0)
        if shape[0] == "rect":
            turn = math.atan2(placed.rotation[0, k, 1], placed.rotation[0, k, 0])
            assert math.cos(shape[3] - turn) == pytest.approx(1.0, abs=1e-12)
    local = footprint_of(body).shapes
    wheels = [k for k, link in enumerate(footprint_of(body).links) if link.endswith("_wheel")]
    contacts = np.array(body.model.contacts)[:, [CX, CY]]
    np.testing.assert_array_equal(contacts, local.centre[0, wheels] - body.com[:2])
    env.close()


def test_mesh_bounds_of_stl_files_and_unread_formats(tmp_path):
    triangle = np.array([[0, 0, 0], [0.1, -0.2, 0], [0, 0.3, 0.4]], dtype="<f4")
    binary = tmp_path / "part.stl"
    binary.write_bytes(b"\0" * 80 + np.uint32(1).tobytes() + np.zeros(3, "<f4").tobytes()
                       + triangle.tobytes() + b"\0\0")
    ascii_ = tmp_path / "part_ascii.STL"
    ascii_.write_text("solid p\nfacet normal 0 0 1\nouter loop\n"
                      + "".join(f"vertex {x} {y} {z}\n" for x, y, z in triangle.tolist())
                      + "endloop\nendfacet\nendsolid p\n")
    for path in (binary, ascii_):
        low, high = mesh_bounds(path)
        np.testing.assert_allclose([low, high], [[0, -0.2, 0], [0.1, 0.3, 0.4]], atol=1e-7)
    (tmp_path / "part.dae").write_text("<COLLADA/>")
    with pytest.raises(ValueError, match=r"link 'base': collision mesh .*part.dae: .*OBJ and STL"):
        mesh_bounds(tmp_path / "part.dae", "base")


# -- distances and clearances ----------------------------------------------------------------
def test_distances_by_hand():
    a = Shapes2D.from_arrays([[BOX, CIRCLE]], [[[0.0, 0.0], [0.0, 0.0]]], [[0.0, 0.0]],
                             [[[0.5, 0.25], [0.25, 0.25]]])
    b = Shapes2D.from_layout([_box(1.5, 0.0, 1.0, 1.0), _box(1.5, 1.5, 1.0, 1.0),
                              _box(0.0, 1.0, 1.0, 1.0, math.pi / 4), _cylinder(0.0, 1.0, 0.5),
                              _box(0.25, 0.0, 0.5, 0.5)])
    d = distances(a, b)[0]
    diagonal = math.hypot(0.5, 0.75)  # corner (0.5, 0.25) to corner (1, 1)
    corner = 1.0 - math.sqrt(0.5) - 0.25  # the diamond's lower corner to y = 0.25
    assert d[0] == pytest.approx([0.5, diagonal, corner, 0.5, -0.5], abs=1e-12)
    # the circle: its centre on the last box's face is r deep
    assert d[1] == pytest.approx([0.75, math.sqrt(2) - 0.25, corner, 0.5, -0.25], abs=1e-12)
    # Bullet's boxes: corners rounded by the margin, sides kept
    rounded = distances(a, b, box_margin=0.01)[0]
    assert rounded[0, [0, 3]] == pytest.approx([0.5, 0.5], abs=1e-12)
    # core corners (0.49, 0.24) and (1.01, 1.01), less the two radii
    assert rounded[0, 1] == pytest.approx(math.hypot(0.52, 0.77) - 0.02, abs=1e-12)


def test_distances_of_points_are_the_obstacles_own():
    rng, layouts = _layouts(3, 1)
    layout = layouts[0]
    points = rng.uniform(-2.2, 2.2, (400, 2))
    dots = Shapes2D.from_arrays(np.full((400, 1), CIRCLE), points[:, None], np.zeros((400, 1)),
                                np.full((400, 1, 2), 1e-9))
    got = distances(dots, Shapes2D.from_layout(layout))[:, 0] + 1e-9
    expected = np.stack([o.distance(points) for o in layout], axis=1)
    assert (expected < 0).any()  # inside some
    np.testing.assert_allclose(got, expected, rtol=0, atol=1e-12)


def test_clearance_equals_pybullets_nearest_distance(sim, shipped_model, tmp_path):
    path = shipped_model.write_urdf(tmp_path, simulated_urdf(shipped_model))  # sphere wheels
    car_footprint = footprint(shipped_model)
    rng, layouts = _layouts(4, 8, half_extent=1.0)
    expected, sharp, rounded, flat = [], [], [], []
    for layout in layouts:
        sim.reset()
        bodies = [add_obstacle(sim, f"o{i}", o.shape, o.size, o.position, o.yaw)
                  for i, o in enumerate(layout)]
        car = sim.load_urdf("car", path)
        poses = []
        for _ in range(25):  # near an obstacle, some overlapping it deeply
            obstacle = layout[rng.integers(len(layout))]
            bearing, yaw = rng.uniform(-math.pi, math.pi, 2)
            reach = obstacle.radius + rng.uniform(-0.1, 0.3)
            poses.append([obstacle.position[0] + reach * math.cos(bearing),
                          obstacle.position[1] + reach * math.sin(bearing), yaw])
            car.set_link_pose((*poses[-1][:2], 0.0), (0.0, 0.0, math.sin(yaw / 2),
                                                      math.cos(yaw / 2)))
            expected.append(nearest_distance(car, bodies, 0.3))
        shapes = Shapes2D.from_layout(layout)
        sharp.append(clearance(car_footprint, poses, shapes, 0.3))
        rounded.append(clearance(car_footprint, poses, shapes, 0.3,
                                 box_margin=BULLET_BOX_MARGIN_M))
        flat.append(clearance(car_footprint, poses, shapes, 0.3, height=None))
    expected = np.array(expected)
    sharp, rounded, flat = (np.concatenate(v) for v in (sharp, rounded, flat))
    assert (expected < -0.05).sum() > 20 and (expected > 0).sum() > 50
    np.testing.assert_allclose(rounded, expected, rtol=0, atol=1e-4)  # measured: 1e-5
    np.testing.assert_allclose(sharp, expected, rtol=0, atol=BULLET_CORNERS_M + 1e-5)
    # in 2D alone, a deep overlap is deeper than the part's way out over the ground
    assert (flat < expected - 0.01).sum() > 20
    apart = expected >= 0
    np.testing.assert_allclose(flat[apart], sharp[apart], rtol=0, atol=1e-12)


def test_clearance_is_capped_and_takes_the_vertical_way_out():
    car = footprint(load_model(mappings={"laser": "true"}))
    shapes = Shapes2D.from_layouts([[_box(1.0, 0.0, 0.2, 0.2)], [_box(5.0, 0.0, 0.2, 0.2)]])
    poses = np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 0.0]])
    # the body's front (x = 0.125) to the box (x = 0.9); nothing within 0.3 m of the other
    assert clearance(car, poses, shapes, 1.0).tolist() == pytest.approx([0.775, 1.0])
    assert clearance(car, poses, shapes, 0.3).tolist() == [0.3, 0.3]
    # over the box: the laser (0.07 to 0.11 m up, 0.125 m deep) is the deepest to lift out;
    # in 2D alone the body is (0.08 + 0.1 m deep across)
    box = Shapes2D.from_layout([_box(1.0, 0.0, 0.2, 0.2)])
    assert clearance(car, [[1.0, 0.0, 0.0]], box, 0.3)[0] == pytest.approx(-0.11)
    assert clearance(car, [[1.0, 0.0, 0.0]], box, 0.3, height=None)[0] == pytest.approx(-0.18)
    # an obstacle 2 cm tall under the body (from 3 cm up): 1 cm below it
    low = Shapes2D.from_layout([_box(0.0, 0.0, 0.1, 0.1)])
    assert clearance(car, [[0.0, 0.0, 0.0]], low, 0.3, height=0.02)[0] == pytest.approx(0.01)


def test_a_stack_of_footprints_places_each_car_its_own():
    """``Footprint.stack``: car i's clearance is its own footprint's, bit for bit: wheels 30 %
    bigger reach a box off the front wheel's corner 3.8 mm nearer, and sink deeper into a
    low one under it (each car's parts' heights are its own)."""
    model = load_model()
    small = footprint(model, wheel_contact="urdf")
    radius = model.wheels[0].radius_m
    big = footprint(simulated_urdf(model, "urdf").replace(f'radius="{radius}"',
                                                          f'radius="{radius * 1.3}"'))
    stack = Footprint.stack([small, big, small])
    own = (small, big, small)
    for box, height in ((_box(0.14, 0.12, 0.02, 0.02), 0.1), (_box(0.08, 0.08, 0.02, 0.02), 0.01)):
        shapes = Shapes2D.from_layouts([[box]] * 3)
        poses = np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 0.0], [0.01, 0.0, 0.2]])
        got = clearance(stack, poses, shapes, 0.5, height=height)
        want = [clearance(f, poses[i:i + 1], shapes.take(np.array([i]), 1), 0.5,
                          height=height)[0] for i, f in enumerate(own)]
        assert got.tolist() == want and got[1] < got[0] - 0.003, (got, height)
    assert stack.radius == max(small.radius, big.radius)
    with pytest.raises(ValueError, match="footprints of different shapes"):
        Footprint.stack([small, footprint(load_model(mappings={"laser": "true"}))])



@pytest.mark.parametrize("stacked", [False, True])
def test_clearance_of_listed_cars_is_their_clearance_of_all(stacked):
    """``cars``: the listed cars' clearances are the same bits as measuring every car, the
    others are ``max_distance`` (a batch measures only the cars it runs), for one footprint
    and for a stack; a mask of another shape or type is one line."""
    rng, layouts = _layouts(7, 12, n=6, half_extent=1.0)
    shapes = Shapes2D.from_layouts(layouts)
    poses = np.c_[rng.uniform(-0.9, 0.9, (12, 2)), rng.uniform(-np.pi, np.pi, 12)]
    car = footprint(load_model(), wheel_contact="urdf")
    car = Footprint.stack([car] * 12) if stacked else car
    every = clearance(car, poses, shapes, 0.3)
    assert (every < 0.3).sum() >= 6 and (every < 0).any()  # near and touching cars too
    listed = np.zeros(12, dtype=bool)
    listed[[0, 3, 4, 9, 11]] = True
    got = clearance(car, poses, shapes, 0.3, cars=listed)
    assert got[listed].tolist() == every[listed].tolist()
    assert (got[~listed] == 0.3).all()
    assert (clearance(car, poses, shapes, 0.3, cars=np.zeros(12, dtype=bool)) == 0.3).all()
    for bad in (listed.astype(int), listed[:5], [True] * 12):
        with pytest.raises(ValueError, match=r"cars must be a bool mask of shape \(12,\)"):
            clearance(car, poses, shapes, 0.3, cars=bad)


# -- bad input -------------------------------------------------------------------------------
def test_bad_input_is_refused_naming_the_argument():
    shapes = Shapes2D.from_layout([_box(1.0, 0.0, 0.2, 0.4)])
    car = footprint(load_model())
    with pytest.raises(ValueError, match="origins"):
        cast(np.zeros((1, 3)), np.zeros(2), 1.0, shapes)
    with pytest.raises(ValueError, match="directions"):
        cast(np.zeros((1, 2)), np.zeros((2, 3)), 1.0, shapes)
    with pytest.raises(ValueError, match="unit vectors"):
        cast(np.zeros((1, 2)), np.ones((1, 3, 2)), 1.0, shapes)
    with pytest.raises(ValueError, match="max_range"):
        cast(np.zeros((1, 2)), np.zeros(2), -1.0, shapes)
    with pytest.raises(ValueError, match="shapes"):
        cast(np.zeros((1, 2)), np.zeros(2), 1.0, [shapes])
    with pytest.raises(ValueError, match="shapes hold 2"):
        cast(np.zeros((3, 2)), np.zeros(2), 1.0, Shapes2D.from_layouts([[], []]))
    with pytest.raises(ValueError, match=r"layouts\[0\]\[1\]"):
        Shapes2D.from_layouts([[_box(1.0, 0.0, 0.2, 0.4), "wall"]])
    with pytest.raises(ValueError, match="half"):
        Shapes2D.from_arrays([[BOX]], [[[0.0, 0.0]]], [[0.0]], [[[0.0, 1.0]]])
    with pytest.raises(ValueError, match="poses"):
        clearance(car, np.zeros((2, 2)), shapes, 0.3)
    with pytest.raises(ValueError, match="max_distance"):
        clearance(car, np.zeros((1, 3)), shapes, math.inf)
    with pytest.raises(ValueError, match="box_margin"):
        clearance(car, np.zeros((1, 3)), shapes, 0.3, box_margin=-1.0)
    with pytest.raises(ValueError, match="robot"):
        footprint(42)


@pytest.mark.skipif(not CAST_COMPILED, reason="numba (the fast extra) is off or not installed")
def test_the_compiled_cast_is_numpys_bit_for_bit():
    """Random worlds of boxes and circles (padding, origins inside shapes, rays that end
    short, beams shared or per car, angles past +-pi, a fan as a laser's): numba's loops
    give numpy's distances and shapes exactly, ties to the lower shape included."""
    rng = np.random.default_rng(7)
    for trial in range(60):
        n, m, b = int(rng.integers(1, 5)), int(rng.integers(1, 30)), int(rng.integers(1, 200))
        kind = rng.integers(0, 2, (n, m)).astype(np.int8)
        half = rng.uniform(0.01, 0.5, (n, m, 2))
        half[kind == CIRCLE, 1] = half[kind == CIRCLE, 0]
        if trial == 0:  # two equal circles on one spot: every hit is a tie
            kind[:] = CIRCLE
            half[:] = 0.2
        shapes = Shapes2D.from_arrays(kind, rng.uniform(-3, 3, (n, m, 2)) * (trial > 0),
                                      rng.uniform(-4, 4, (n, m)), half,
                                      (rng.random((n, m)) < 0.9) | (trial == 0))
        origins = rng.uniform(-3, 3, (n, 2)) + 0.7 * (trial == 0)
        directions = (rng.uniform(-np.pi, np.pi, b) if trial % 3 == 0
                      else rng.uniform(-7, 7, (n, b)) if trial % 3 == 1
                      else np.linspace(-np.pi, np.pi, b))
        reach = rng.uniform(0.5, 6) if trial % 2 else rng.uniform(0.1, 6, (n, b))
        numpy_cast = cast(origins, directions, reach, shapes, compiled=False)
        loops = cast(origins, directions, reach, shapes, compiled=True)
        assert np.array_equal(numpy_cast.distance, loops.distance)
        assert np.array_equal(numpy_cast.shape, loops.shape)
        if trial == 0:
            assert (numpy_cast.shape[numpy_cast.hit] == 0).all() and numpy_cast.hit.any()
