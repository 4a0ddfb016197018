"""The BARN worlds file, the scaled protocol and its score, and the grid global planner."""

from __future__ import annotations

import math

import numpy as np
import pytest

from smartcar_gym.envs.tasks.barn import BarnProtocol, RunClock, barn_score
from smartcar_gym.navigation.grid_planner import NoPathError, distance_grid, path_length, plan_path
from smartcar_gym.navigation.paths import PathTracker
from smartcar_gym.worlds.barn import (
    TEST_WORLDS,
    TRAIN_WORLDS,
    BarnWorldError,
    default_path,
    load_worlds,
    to_car_frame,
)


def test_the_shipped_worlds_and_their_licence():
    worlds = load_worlds()
    assert len(worlds) == 300
    assert (default_path().parent / "LICENSE").read_text().startswith("MIT")
    counts = [len(worlds.world(i).centres) for i in range(300)]
    assert min(counts) == 181 and max(counts) == 365  # as the README says
    assert np.all(worlds.world(0).radii == 0.075)
    # the README's path lengths of worlds 0, 6 and 150: 10.8-13.4 m
    lengths = [worlds.world(i).path_length_m for i in (0, 6, 150)]
    assert np.allclose(lengths, [13.43, 12.46, 10.82], atol=0.01)


def test_test_and_training_worlds_split_the_300():
    assert TEST_WORLDS[:3] == (0, 6, 12) and TEST_WORLDS[-1] == 294 and len(TEST_WORLDS) == 50
    assert len(TRAIN_WORLDS) == 250 and not set(TEST_WORLDS) & set(TRAIN_WORLDS)


@pytest.mark.parametrize("index", [-1, 300, np.int64(300)])
def test_a_world_index_out_of_range_is_one_line_naming_it(index):
    with pytest.raises(BarnWorldError, match=r"^BARN world .* is out of range: the worlds are "
                                             r"0 to 299 \(") as err:
        load_worlds().world(index)
    assert f"world {int(index)} " in str(err.value) and "\n" not in str(err.value)


def test_a_missing_or_corrupt_world_file_is_one_line_naming_it(tmp_path):
    missing = tmp_path / "none.npz"
    with pytest.raises(BarnWorldError, match=f"^BARN world file {missing}: no such file$"):
        load_worlds(missing)
    corrupt = tmp_path / "corrupt.npz"
    corrupt.write_bytes(b"not a zip at all")
    with pytest.raises(BarnWorldError, match=f"^BARN world file {corrupt}: not a readable npz"):
        load_worlds(corrupt)
    partial = tmp_path / "partial.npz"
    np.savez(partial, centres=np.zeros((3, 2)))
    with pytest.raises(BarnWorldError, match="not a readable npz with the arrays centres, radii"):
        load_worlds(partial)
    bad = tmp_path / "bad.npz"
    np.savez(bad, centres=np.zeros((3, 2)), radii=np.zeros(3), offsets=np.array([0, 5]),
             paths=np.zeros((1, 2), int), path_offsets=np.array([0, 1]))
    with pytest.raises(BarnWorldError, match=r"offsets must run from 0 to the 3 rows with at "
                                             r"least one world, got \[0, 5\] \(2 values\)$"):
        load_worlds(bad)


def test_the_car_frame_puts_the_start_at_the_origin_heading_along_x():
    scale = 0.5
    assert np.allclose(to_car_frame(np.array([-2.0, 3.0]), scale), [0.0, 0.0])
    assert np.allclose(to_car_frame(np.array([-2.0, 13.0]), scale), [5.0, 0.0])  # the goal
    assert np.allclose(to_car_frame(np.array([-3.0, 3.0]), scale), [0.0, 0.5])  # left of it


def test_the_protocol_scales_distances_and_times():
    p = BarnProtocol(scale=0.18 / 0.43, top_speed_m_s=0.5)
    assert p.goal_distance_m == pytest.approx(10 * 0.18 / 0.43)
    assert p.success_radius_m == pytest.approx(0.18 / 0.43)
    # 100 s at 2 m/s covers 200 m; scaled, at 0.5 m/s: 100 * 4 * 0.4186 s
    assert p.timeout_s == pytest.approx(167.44, abs=0.01)
    assert p.timeout_steps(0.1) == 1675
    with pytest.raises(ValueError, match="BARN scale must be a number > 0"):
        BarnProtocol(scale=0.0)


def test_the_score_is_the_challenges():
    ot = 10.0
    assert barn_score(True, 5.0, ot) == 0.5  # faster than 2 OT counts as 2 OT
    assert barn_score(True, 40.0, ot) == pytest.approx(0.25)
    assert barn_score(True, 200.0, ot) == pytest.approx(1 / 8)  # clipped at 8 OT
    assert barn_score(False, 30.0, ot) == 0.0
    assert barn_score(True, 5.0, ot, floor=4.0) == 0.25  # the metric before 2024
    assert barn_score(True, 50.0, ot, floor=4.0) == pytest.approx(0.2)


def test_the_run_clock_starts_when_the_car_has_moved():
    clock = RunClock(np.zeros(2), moved_m=0.1)
    clock.update(np.array([0.05, 0.0]), 1.0)
    assert clock.elapsed_s(2.0) == 0.0
    clock.update(np.array([0.1, 0.0]), 2.5)
    clock.update(np.array([0.0, 0.0]), 3.0)  # back at the start: the clock runs on
    assert clock.elapsed_s(4.0) == pytest.approx(1.5)


def test_the_tracker_looks_ahead_along_the_path_and_never_goes_back():
    path = np.stack([np.linspace(0, 2, 201), np.zeros(201)], axis=1)
    tracker = PathTracker(path, lookahead_m=0.5)
    assert np.allclose(tracker.waypoint(np.array([0.3, 0.1])), [0.8, 0.0])
    assert np.allclose(tracker.waypoint(np.array([0.0, 0.0])), [0.8, 0.0])  # no going back
    # 1.9 is beyond the 1 m window from 0.3: the nearest point is 1.3 this time
    assert np.allclose(tracker.waypoint(np.array([1.9, 0.0])), [1.8, 0.0])
    assert np.allclose(tracker.waypoint(np.array([1.9, 0.0])), [2.0, 0.0])  # clipped at the end


def test_the_trackers_arc_lengths_are_the_norms_of_the_paths_steps_to_the_bit():
    rng = np.random.default_rng(5)
    for m in (1, 2, 7, 300):
        path = np.cumsum(rng.normal(size=(m, 2)) * 0.02, axis=0)
        arc = PathTracker(path, lookahead_m=0.5).arc
        steps = np.linalg.norm(np.diff(path, axis=0), axis=1)
        assert np.array_equal(arc, np.concatenate([[0.0], np.cumsum(steps)]))
    with pytest.raises(ValueError, match="a path needs at least one point"):
        PathTracker(np.zeros((0, 2)), lookahead_m=0.5)


def _wall_with_gap(gap: float) -> tuple[np.ndarray, np.ndarray]:
    """A wall of 0.05 m circles across x = 1, from y = -1 to 1 (the whole map), with a gap
    at y = 0.5."""
    ys = np.round(np.arange(-1.0, 1.0001, 0.05), 6)
    ys = ys[np.abs(ys - 0.5) >= gap / 2 + 0.025 - 1e-9]
    return np.stack([np.ones_like(ys), ys], axis=1), np.full(len(ys), 0.025)


def test_the_planner_goes_through_the_gap_in_its_middle():
    centres, radii = _wall_with_gap(0.4)
    grid = distance_grid(centres, radii, [-0.2, -1.0], [2.2, 1.0], 0.02)
    path = plan_path(grid, np.zeros(2), np.array([2.0, 0.0]), inflation_m=0.09)
    assert np.allclose(path[0], [0.0, 0.0]) and np.allclose(path[-1], [2.0, 0.0])
    at_wall = path[np.argmin(np.abs(path[:, 0] - 1.0))]
    assert at_wall[1] == pytest.approx(0.5, abs=0.03)  # the middle of the gap
    clear = np.min(np.linalg.norm(path[:, None] - centres[None], axis=-1) - radii)
    assert clear >= 0.09
    assert 2.0 < path_length(path) < 2.0 + 2 * math.hypot(1.0, 0.5) - 2.0 + 0.2


def test_the_planner_refuses_a_gap_narrower_than_the_inflated_robot():
    centres, radii = _wall_with_gap(0.15)
    grid = distance_grid(centres, radii, [-0.2, -1.0], [2.2, 1.0], 0.02)
    plan_path(grid, np.zeros(2), np.array([2.0, 0.0]), inflation_m=0.05)  # fits a thin one
    with pytest.raises(NoPathError, match="no way from .* keeps 0.090 m from every obstacle"):
        plan_path(grid, np.zeros(2), np.array([2.0, 0.0]), inflation_m=0.09)
    with pytest.raises(NoPathError, match="the goal .* is within 0.090 m of an obstacle"):
        plan_path(grid, np.zeros(2), np.array([1.0, 0.0]), inflation_m=0.09)


def test_the_distance_grid_is_exact_for_circles_of_several_radii():
    centres = np.array([[0.0, 0.0], [1.0, 0.0]])
    grid = distance_grid(centres, np.array([0.1, 0.3]), [0.0, 0.0], [1.0, 0.0], 0.5)
    assert np.allclose(grid.distance, [[-0.1, 0.2, -0.3]])
