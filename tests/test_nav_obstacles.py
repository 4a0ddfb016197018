"""Obstacle layouts (envs/tasks/obstacles.py): geometry, seeded drawing, user layouts."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from smartcar_gym.envs.tasks.nav import NavTask
from smartcar_gym.envs.tasks.obstacles import (
    MIN_GAP_M,
    Obstacle,
    ObstacleField,
    clearance,
    read_layout,
)
from tests.stub_cars import StubCars


def test_box_distance_is_signed_and_turns_with_yaw():
    box = Obstacle("box", (1.0, 2.0), (0.4, 0.2))
    points = np.array([[1.5, 2.0], [1.0, 2.5], [1.5, 2.4], [1.0, 2.0], [1.1, 2.0]])
    assert box.distance(points) == pytest.approx([0.3, 0.4, math.hypot(0.3, 0.3), -0.1, -0.1])
    turned = Obstacle("box", (1.0, 2.0), (0.4, 0.2), yaw=math.pi / 2)  # now 0.2 along x
    assert turned.distance(np.array([1.5, 2.0])) == pytest.approx(0.4)
    assert turned.distance(np.array([1.0, 2.5])) == pytest.approx(0.3)
    assert box.radius == pytest.approx(math.hypot(0.4, 0.2) / 2)


def test_cylinder_distance_and_radius():
    cyl = Obstacle("cylinder", (0.0, 0.0), (0.5,))
    assert cyl.distance(np.array([[1.0, 0.0], [0.0, 0.0], [0.3, 0.4]])) == pytest.approx(
        [0.75, -0.25, 0.25])
    assert cyl.radius == 0.25
    assert clearance([cyl, Obstacle("box", (2.0, 0.0), (0.2, 0.2))], np.array([1.5, 0.0])) == (
        pytest.approx(0.4))
    assert clearance([], np.zeros(2)) == math.inf


def test_drawn_layouts_are_seeded_and_keep_their_distances():
    field = ObstacleField(count=8, size_range_m=(0.15, 0.35), clearance_m=0.2,
                          half_extent_m=2.0, robot_radius_m=0.15)
    start, goal = np.zeros(2), np.array([1.2, -0.8])
    layouts = [field.sample(np.random.default_rng(s), start, goal) for s in (1, 1, 2)]
    assert layouts[0] == layouts[1] and layouts[0] != layouts[2]
    shapes = set()
    for layout in layouts:
        assert len(layout) == 8
        for i, o in enumerate(layout):
            shapes.add(o.shape)
            assert o.distance(start) >= 0.35 and o.distance(goal) >= 0.35
            assert np.all(np.abs(o.position) <= 2.0)
            assert all(0.15 <= s <= 0.35 for s in o.size)
            for other in layout[:i]:
                gap = np.linalg.norm(np.subtract(o.position, other.position))
                assert gap - o.radius - other.radius >= MIN_GAP_M
    assert shapes == {"box", "cylinder"}
    assert field.sample(np.random.default_rng(0), start, goal)[0] != layouts[0][0]
    assert ObstacleField(count=0).sample(np.random.default_rng(0), start, goal) == ()


def test_a_field_that_cannot_be_drawn_says_so():
    field = ObstacleField(count=40, size_range_m=(0.3, 0.5), half_extent_m=1.0)
    with pytest.raises(RuntimeError, match="could not place 40 obstacles.*lower obstacles"):
        field.sample(np.random.default_rng(0), np.zeros(2), np.array([0.5, 0.5]))


@pytest.mark.parametrize("kwargs, match", [
    ({"count": -1}, "obstacles must be"), ({"count": 2.5}, "obstacles must be"),
    ({"size_range_m": (0.3, 0.1)}, "obstacle_size"),
    ({"size_range_m": (0.0, 0.1)}, "obstacle_size"),
    ({"clearance_m": -0.1}, "obstacle_clearance"),
    ({"clearance_m": float("inf")}, "obstacle_clearance"),
])
def test_bad_field_settings_are_refused(kwargs, match):
    with pytest.raises(ValueError, match=match):
        ObstacleField(**kwargs)


def test_layouts_from_lists_yaml_and_json(tmp_path):
    entries = [{"shape": "box", "position": [1, 0], "size": [0.2, 0.4], "yaw": 0.5},
               {"shape": "cylinder", "position": np.array([0.0, 1.0]), "size": 0.3}]
    layout = read_layout(entries)
    assert layout == (Obstacle("box", (1.0, 0.0), (0.2, 0.4), 0.5),
                      Obstacle("cylinder", (0.0, 1.0), (0.3,), 0.0))
    assert read_layout([o.to_dict() for o in layout]) == layout
    (tmp_path / "a.yaml").write_text(
        "obstacles:\n  - {shape: box, position: [1, 0], size: [0.2, 0.4], yaw: 0.5}\n"
        "  - {shape: cylinder, position: [0, 1], size: [0.3]}\n")
    assert read_layout(tmp_path / "a.yaml") == layout
    (tmp_path / "b.json").write_text(json.dumps([o.to_dict() for o in layout]))
    assert read_layout(str(tmp_path / "b.json")) == layout
    assert read_layout([]) == ()


@pytest.mark.parametrize("value, match", [
    ({"shape": "box"}, "must be a list of obstacles"),
    ([{"shape": "box", "position": [0, 1]}], r"obstacles\[0\]: missing size"),
    ([{"shape": "cone", "position": [0, 1], "size": 1}], r"obstacles\[0\]: shape must be"),
    ([{"shape": "box", "position": [0, 1], "size": [1]}], r"size must be \[length, width\]"),
    ([{"shape": "box", "position": [0, 1], "size": [1, -1]}], "size must be positive"),
    ([{"shape": "box", "position": "01", "size": [1, 1]}], r"position must be \[x, y\]"),
    ([{"shape": "box", "position": [0, float("nan")], "size": [1, 1]}], "position"),
    ([{"shape": "box", "position": [0, 1], "size": [1, 1], "colour": 1}], "unknown key"),
    ([{"shape": "box", "position": [0, 1], "size": [1, 1], "yaw": "x"}], "yaw must be"),
    ([3], r"obstacles\[0\] must be a mapping"),
])
def test_bad_layouts_name_the_obstacle_and_key(value, match):
    with pytest.raises(ValueError, match=match):
        read_layout(value)


def test_bad_layout_files_name_the_file(tmp_path):
    with pytest.raises(FileNotFoundError, match="no such file"):
        read_layout(tmp_path / "missing.yaml")
    bad = tmp_path / "bad.yaml"
    bad.write_text("obstacles: [1, 2\n")
    with pytest.raises(ValueError, match=f"{bad}: not valid YAML"):
        read_layout(bad)
    other = tmp_path / "other.yaml"
    other.write_text("walls: []\n")
    with pytest.raises(ValueError, match="the one key 'obstacles'"):
        read_layout(other)
    entry = tmp_path / "entry.json"
    entry.write_text('[{"shape": "box", "position": [0, 1], "size": [1]}]')
    with pytest.raises(ValueError, match=rf"{entry}: obstacles\[0\]: size"):
        read_layout(entry)


def nav_terms(task: NavTask, clearance) -> tuple[np.ndarray, np.ndarray]:
    """The collision and proximity terms of a step's reward (the reaching terms, a car that
    made no progress with no action, taken off) and the failures, of cars that far from an
    obstacle."""
    cars = StubCars(len(clearance), clearance=clearance)
    cars.state.goal[:] = (1.0, 0.0)  # cars at the origin, their goals 1 m ahead
    task.attach(len(cars.clearance))
    task.distance[:] = 1.0  # no progress
    reward, _, failure = task.score(cars, np.zeros((len(cars.clearance), 2)))
    return reward + task.time_cost, failure


def test_collision_and_proximity_terms_of_the_reward():
    task = NavTask(collision_penalty=7.0, proximity_penalty=0.5, proximity_m=0.2)
    terms, failure = nav_terms(task, [0.3, 0.2, 0.15, 0.0, -0.01])
    # proximity: 0.5 * (0.2 - clearance) / 0.2, at most 0.5; a clearance <= 0 collides: 7
    assert terms == pytest.approx([0.0, 0.0, -0.125, -7.5, -7.5])
    assert task.collision.tolist() == failure.tolist() == [False, False, False, True, True]
    assert task.clearance.tolist() == [0.2, 0.2, 0.15, 0.0, -0.01]  # at most proximity_m
    terms, failure = nav_terms(NavTask(collision_penalty=7.0, proximity_penalty=0.5,
                                       proximity_m=0.2), [0.5, 0.5])
    assert terms.tolist() == [0.0, 0.0] and not failure.any()
    terms, _ = nav_terms(NavTask(), [0.01])
    assert terms.tolist() == [0.0]  # proximity off by default (and no collision)
    terms, _ = nav_terms(NavTask(), [0.0])
    assert terms.tolist() == [-10.0]  # the default collision penalty
    with pytest.raises(ValueError, match="collision_penalty"):
        NavTask(collision_penalty=-1.0)
    with pytest.raises(ValueError, match="proximity_penalty"):
        NavTask(proximity_penalty=-1.0)
    with pytest.raises(ValueError, match="proximity_m"):
        NavTask(proximity_m=0.0)
