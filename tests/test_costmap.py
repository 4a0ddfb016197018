"""The laser-built costmap (navigation/costmap.py) and its planner (costmap_planner.py), with
numbers derived by hand from costmap_2d's rules (docs/barn.md, "The laser-built costmap").

The test grid: 0.05 m cells, 8 m square centred on the odom origin (cell (80, 80) holds
[0, 0.05) x [0, 0.05)), obstacle_range 2.5 m, raytrace_range 3.0 m (60 cells), inflation
radius 0.30 m (6 cells), cost_scaling_factor 10 / m, inscribed radius 0.12 m.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from smartcar_gym.navigation.costmap import (
    COMPILED,
    INSCRIBED,
    LETHAL,
    CostmapConfig,
    LaserCostmaps,
)
from smartcar_gym.navigation.costmap_loops import inflate_numpy
from smartcar_gym.navigation.costmap_planner import Replanner, plan_cells, plan_on_costmap
from smartcar_gym.navigation.grid_planner import NoPathError

CONFIG = CostmapConfig(size=8.0, inscribed_radius=0.12)
ONE = np.array([0.0])  # a one-beam laser looking along its x axis
ROUND = np.radians(np.arange(-180.0, 180.0, 1.0))  # the LDS-01's 360 beams
WAYS = [False, True] if COMPILED else [False]


def _beam(maps: LaserCostmaps, car: int, x: float, y: float, theta: float, r: float) -> None:
    maps.update([car], np.array([[x, y, theta]]), np.array([[r]], dtype=np.float32), ONE)


def _mark(maps: LaserCostmaps, x: float, y: float, car: int = 0) -> None:
    """Marks the cell of (x, y) with a 0.5 m beam from below it."""
    _beam(maps, car, x, y - 0.5, math.pi / 2, 0.5)


def _wall_scan(x: float, half: float) -> np.ndarray:
    """A 360-beam scan from the origin of a wall across x = ``x`` from -half to half."""
    r = np.full(len(ROUND), np.inf)
    front = (np.abs(ROUND) < math.pi / 2) & (np.abs(np.tan(ROUND)) * x <= half)
    r[front] = x / np.cos(ROUND[front])
    return r.astype(np.float32)[None]


@pytest.mark.parametrize("compiled", WAYS)
def test_a_beam_marks_its_return_and_clears_the_cells_before_it(compiled):
    maps = LaserCostmaps(CONFIG, 1, compiled=compiled)
    _mark(maps, 0.51, 0.01)  # cell (90, 80), on the beam's way
    assert maps.lethal(0)[80, 90]
    _beam(maps, 0, 0.01, 0.01, 0.0, 1.0)  # from cell (80, 80) to 1.01 m: cell (100, 80)
    assert np.argwhere(maps.lethal(0)).tolist() == [[80, 100]]
    costs = maps.costs(0)
    # 253 within 0.12 m (2 cells), then int(252 exp(-10 (d - 0.12))), 0 beyond 6 cells
    assert costs[80, 92:109].tolist() == [0, 0, 41, 68, 113, 186, 253, 253, 254, 253, 253, 186,
                                          113, 68, 41, 0, 0]
    assert costs[80, 80:94].max() == 0  # cleared, and more than 6 cells from the wall


@pytest.mark.parametrize("compiled", WAYS)
def test_inflation_is_costmap_2ds_compute_cost(compiled):
    maps = LaserCostmaps(CONFIG, 1, compiled=compiled)
    _mark(maps, 0.025, 0.025)  # cell (80, 80)
    costs = maps.costs(0).astype(int)
    expected = {(0, 0): 254, (1, 0): 253, (2, 0): 253, (1, 1): 253, (2, 1): 253,
                (2, 2): 203, (3, 0): 186, (4, 0): 113, (3, 4): 68, (5, 0): 68,
                (4, 4): 49, (6, 0): 41, (5, 4): 0, (7, 0): 0, (0, -6): 41}
    for (dx, dy), cost in expected.items():
        assert costs[80 + dy, 80 + dx] == cost, (dx, dy)
        d = math.hypot(dx, dy) * 0.05
        if 0.12 < d <= 0.3:  # the formula, by hand above
            assert cost == int(252 * math.exp(-10.0 * (d - 0.12)))
    # computeCost itself goes on past the radius; the inflation stops at it (enqueue's test)
    assert CONFIG.cost_of([0, 2, 2.4, 3, 6, 7]).tolist() == [254, 253, 253, 186, 41, 25]
    assert costs[80, 87:].max() == 0 and (costs > 0).sum() == len(CONFIG.kernel()[0])


@pytest.mark.parametrize("compiled", WAYS)
def test_a_beam_with_no_return_clears_to_raytrace_range_and_marks_nothing(compiled):
    maps = LaserCostmaps(CONFIG, 1, compiled=compiled)
    for x in (1.01, 3.01, 3.06):  # cells 100, 140 (3.0 m out) and 141
        _mark(maps, x, 0.01)
    _beam(maps, 0, 0.01, 0.01, 0.0, np.inf)
    assert np.argwhere(maps.lethal(0)).tolist() == [[80, 141]]


@pytest.mark.parametrize("compiled", WAYS)
def test_a_return_beyond_obstacle_range_clears_but_does_not_mark(compiled):
    maps = LaserCostmaps(CONFIG, 1, compiled=compiled)
    for x in (1.01, 2.71):  # cells 100 and 134, where the return lies
        _mark(maps, x, 0.01)
    _beam(maps, 0, 0.01, 0.01, 0.0, 2.7)
    assert not maps.lethal(0).any() and not maps.costs(0).any()
    _beam(maps, 0, 0.01, 0.01, 0.0, 2.4)  # within 2.5 m: marked
    assert np.argwhere(maps.lethal(0)).tolist() == [[80, 128]]
    _beam(maps, 0, 0.01, 0.01, 0.0, -np.inf)  # closer than range_min: nothing happens
    assert np.argwhere(maps.lethal(0)).tolist() == [[80, 128]]


@pytest.mark.skipif(not COMPILED, reason="numba (the fast extra) is not installed")
@pytest.mark.parametrize("changes", [{}, {"inscribed_radius": 0.125, "inflation_radius": 0.25,
                                          "obstacle_range": 3.0, "raytrace_range": 3.5}],
                         ids=["challenge", "mapless-policy"])
def test_numba_and_numpy_give_the_same_grids_bit_for_bit(changes):
    config = replace(CostmapConfig.challenge(0.4186, inscribed_radius=0.105), **changes)
    ways = [LaserCostmaps(config, 6, compiled=c, threads=t) for c, t in ((False, 1), (True, 2))]
    rng = np.random.default_rng(5)
    for _ in range(12):
        cars = rng.permutation(6)[:4]
        poses = np.c_[rng.uniform(-8.5, 8.5, (4, 2)), rng.uniform(-4, 4, 4)]  # some off it
        r = rng.uniform(0.05, 2.0, (4, 360)).astype(np.float32)
        for value, share in ((np.inf, 0.2), (-np.inf, 0.05), (np.nan, 0.02)):
            r[rng.random(r.shape) < share] = value
        for maps in ways:
            maps.update(cars, poses, r, ROUND)
    # then scans again and again from nearby poses with 1 cm of noise, as a car drives: the
    # same returns fall in one cell or the next, marks come and go (the compiled update
    # inflates again only around those)
    wall = _wall_scan(1.01, 0.6)[0].astype(float)
    for step in range(15):
        cars = np.array([0, 3, 5])
        poses = np.c_[np.full(3, 0.01 * step), rng.normal(0.0, 0.01, 3), rng.normal(0.0, 0.02, 3)]
        r = (wall + rng.normal(0.0, 0.01, (3, 360))).astype(np.float32)
        for maps in ways:
            maps.update(cars, poses, r, ROUND)
    for car in range(6):
        assert np.array_equal(ways[0].costs(car), ways[1].costs(car))
        assert np.array_equal(ways[0].lethal(car), ways[1].lethal(car))
    assert sum(ways[0].lethal(car).sum() for car in range(6)) > 1000
    # the update re-inflates only near what changed: the same as inflating it all at once
    whole = np.zeros((config.cells,) * 2, dtype=np.uint8)
    marks = np.where(ways[0].lethal(5), LETHAL, 0).astype(np.uint8)
    inflate_numpy(marks, whole, np.array([0, 0, config.cells, config.cells]),
                  config.inflation_cells, config.cost_table())
    assert np.array_equal(whole, ways[0].costs(5))
    # a reset clears a grid (within its bounds: outside them nothing was ever set)
    for maps in ways:
        maps.reset([0, 5])
        for car in (0, 5):
            assert not maps.costs(car).any() and not maps.lethal(car).any()
            assert maps.bounds(car)[0] >= maps.bounds(car)[2]
        assert maps.costs(3).any()


@pytest.mark.skipif(not COMPILED, reason="numba (the fast extra) is not installed")
def test_the_beams_cells_are_numpys_to_the_bit_when_compiled():
    from smartcar_gym.navigation.costmap_loops import beams_to_cells, beams_to_cells_compiled

    config = CostmapConfig.challenge(0.4186, inscribed_radius=0.105)
    rng = np.random.default_rng(11)
    # poses on the grid, near and along its edges and off it; returns short, long, beyond
    # the ranges, +-inf and NaN; beams that leave the grid on every side
    poses = np.c_[rng.uniform(-9.5, 9.5, (40, 2)), rng.uniform(-4, 4, 40)]
    poses[:8, 0] = config.corner[0] + rng.uniform(-0.01, 0.05, 8)
    poses[8:12, :2] = [[-8.372, -8.372], [8.3719, 8.3719], [0.0, -8.372], [8.372, 0.0]]
    r = rng.uniform(0.0, 3.0, (40, 360))
    for value, share in ((np.inf, 0.1), (-np.inf, 0.03), (np.nan, 0.03), (0.0, 0.02)):
        r[rng.random(r.shape) < share] = value
    r = r.astype(np.float32)
    want = beams_to_cells(config, poses, r, ROUND)
    got = beams_to_cells_compiled(config, poses, r, ROUND)
    for field in ("x0", "y0", "ok", "x1", "y1", "end", "trace", "mx", "my", "mark", "box"):
        a, b = getattr(want, field), getattr(got, field)
        assert a.dtype == b.dtype and np.array_equal(a, b), field
    assert want.trace.sum() > 5000 and want.mark.sum() > 2000 and not want.ok.all()


@pytest.mark.parametrize("compiled", WAYS)
def test_three_cars_keep_their_own_grids(compiled):
    maps = LaserCostmaps(CONFIG, 3, compiled=compiled)
    alone = [LaserCostmaps(CONFIG, 1, compiled=compiled) for _ in range(3)]
    scans = [_wall_scan(x, 0.5) for x in (0.6, 1.0, 1.4)]
    poses = np.array([[0.0, 0.0, 0.0], [0.3, -0.2, 0.5], [-0.4, 0.1, -1.0]])
    maps.update([2, 0, 1], poses[[2, 0, 1]], np.concatenate([scans[i] for i in (2, 0, 1)]),
                ROUND)
    for car in range(3):
        alone[car].update([0], poses[car:car + 1], scans[car], ROUND)
        assert np.array_equal(maps.costs(car), alone[car].costs(0))
    before = [maps.costs(car).copy() for car in range(3)]
    maps.reset([1])
    assert not maps.costs(1).any() and not maps.lethal(1).any()
    assert np.array_equal(maps.costs(0), before[0]) and np.array_equal(maps.costs(2), before[2])


def test_the_planner_goes_around_a_wall_it_has_seen_and_straight_through_unseen_space():
    maps = LaserCostmaps(CONFIG, 2)
    straight = plan_on_costmap(maps, 0, np.zeros(2), np.array([2.0, 0.0]))
    assert np.allclose(straight[:, 1], 0.025) and np.allclose(straight[[0, -1], 0],
                                                              [0.025, 2.025])
    maps.update([1], np.zeros((1, 3)), _wall_scan(1.01, 0.6), ROUND)
    assert maps.lethal(1)[80, 100] and maps.lethal(1)[89:92, 100].any()  # (1.01, 0.55)
    around = plan_on_costmap(maps, 1, np.zeros(2), np.array([2.0, 0.0]))
    ix, iy, inside = maps.world_to_cell(around)
    assert inside.all() and (maps.costs(1)[iy, ix] < INSCRIBED).all()
    assert np.abs(around[:, 1]).max() > 0.6 + 0.12  # past the wall's end, clear of it
    assert np.allclose(around[-1], [2.025, 0.025])
    with pytest.raises(NoPathError, match="the goal .* is in an obstacle's cell"):
        plan_on_costmap(maps, 1, np.zeros(2), np.array([1.0, 0.0]))
    with pytest.raises(NoPathError, match="off the costmap"):
        plan_on_costmap(maps, 1, np.zeros(2), np.array([5.0, 0.0]))


def test_one_points_cell_and_the_ways_cells_are_world_to_cells():
    maps = LaserCostmaps(CONFIG, 2)
    rng = np.random.default_rng(3)
    points = np.concatenate([rng.uniform(-4.5, 4.5, (500, 2)),  # some off the 8 m grid
                             [[-4.0, -4.0], [3.9999999, 0.0], [4.0, 0.0], [0.06, -0.06]]])
    ix, iy, inside = maps.world_to_cell(points)
    for (x, y), i, j, k in zip(points.tolist(), ix.tolist(), iy.tolist(), inside.tolist(),
                               strict=True):
        assert maps.cell_of(x, y) == ((i, j) if k else None)
    assert maps.cell_of(0.06, -0.06) == (81, 78) and maps.cell_of(4.0, 0.0) is None
    maps.update([1], np.zeros((1, 3)), _wall_scan(1.01, 0.6), ROUND)
    way = plan_on_costmap(maps, 1, np.zeros(2), np.array([2.0, 0.0]))
    cx, cy = plan_cells(maps, 1, np.zeros(2), np.array([2.0, 0.0]))
    ix, iy, inside = maps.world_to_cell(way)
    assert inside.all() and np.array_equal(cx, ix) and np.array_equal(cy, iy)
    with pytest.raises(IndexError, match=r"costmap cars must be in \[0, 2\), got \[2\]"):
        maps.costs(2)


def test_the_replanner_plans_at_its_rate_and_at_once_when_its_path_is_blocked():
    maps = LaserCostmaps(CONFIG, 3)
    replanner = Replanner(maps, period_s=0.1)
    cars = np.array([0, 1, 2])
    assert replanner.needs_plan(cars, np.zeros(3)).all() and replanner.path(0) is None
    for car in (0, 1):
        replanner.plan(car, np.zeros(2), np.array([2.0, 0.0]), 0.0)
    # car 2 has no path yet; car 1 is one period on
    assert replanner.needs_plan(cars, np.array([0.05, 0.1, 0.05])).tolist() == [False, True,
                                                                                 True]
    replanner.plan(0, np.zeros(2), np.array([2.0, 0.0]), 0.1)
    assert not replanner.needs_plan([0], np.array([0.15]))[0]
    assert replanner.blocked(cars).tolist() == [False, False, False]
    maps.update([0], np.zeros((1, 3)), _wall_scan(1.01, 0.3), ROUND)  # across car 0's path
    assert replanner.blocked(cars).tolist() == [True, False, False]
    assert replanner.needs_plan([1, 0], np.array([0.05, 0.15])).tolist() == [False, True]
    path = replanner.plan(0, np.zeros(2), np.array([2.0, 0.0]), 0.15)
    assert np.abs(path[:, 1]).max() > 0.3 and not replanner.needs_plan([0], np.array([0.2]))[0]
    with pytest.raises(IndexError, match=r"replanner cars must be in \[0, 3\), got \[-1\]"):
        replanner.needs_plan([-1], np.array([0.2]))
    with pytest.raises(IndexError, match=r"replanner cars must be in \[0, 3\), got \[3\]"):
        replanner.blocked([3])
    assert Replanner.challenge(maps, 0.4186, 0.25).period_s == pytest.approx(
        0.4186 / 0.25 / 20.0)  # 20 Hz, times scaled by 1.674
    assert Replanner.challenge(maps, 0.4186, 0.25, 5.0).period_s == pytest.approx(
        0.4186 / 0.25 / 5.0)


def test_planner_frequency_0_plans_only_when_the_path_is_blocked():
    """move_base's ``planner_frequency: 0``: no plan for as long as the path stays free."""
    maps = LaserCostmaps(CONFIG, 1)
    replanner = Replanner.challenge(maps, 0.4186, 0.25, frequency_hz=0)
    assert replanner.period_s == math.inf and replanner.needs_plan(0, 0.0)
    replanner.plan(0, np.zeros(2), np.array([2.0, 0.0]), 0.0)
    assert not replanner.needs_plan(0, 1e6)
    maps.update([0], np.zeros((1, 3)), _wall_scan(1.01, 0.3), ROUND)  # across the path
    assert replanner.needs_plan(0, 1e6)
    replanner.plan(0, np.zeros(2), np.array([2.0, 0.0]), 1e6)
    assert not replanner.needs_plan(0, 2e6)
    with pytest.raises(ValueError, match=r"planner_frequency must be a rate >= 0 Hz \(0: "):
        Replanner.challenge(maps, 1.0, 1.0, frequency_hz=-1.0)


@pytest.mark.parametrize("threads", [1, 2])
def test_planning_many_cars_at_once_gives_each_cars_own_plan(threads):
    maps = LaserCostmaps(CONFIG, 4)
    for car, x in enumerate((0.6, 1.0, 1.4, 1.0)):
        maps.update([car], np.zeros((1, 3)), _wall_scan(x, 0.4 + 0.1 * car), ROUND)
    one, many = Replanner(maps, period_s=0.1), Replanner(maps, period_s=0.1)
    goals = np.array([[2.0, 0.0], [2.0, 0.3], [2.5, -0.2], [1.0, 0.0]])  # car 3's in its wall
    starts = np.zeros((4, 2))
    for car in range(3):
        one.plan(car, starts[car], goals[car], 0.5)
    before = many.plan(3, starts[3], np.array([2.0, 0.0]), 0.0)
    assert many.plan_many([0, 1, 2, 3], starts, goals, [0.5] * 4, threads=threads) == [0, 1, 2]
    for car in range(3):
        assert np.array_equal(many.path(car), one.path(car))
    # car 3 keeps its last path, and the try counts as the plan of its period
    assert many.path(3) is before and not many.needs_plan(3, 0.55) and many.needs_plan(3, 0.6)
    assert len({len(many.path(car)) for car in range(3)}) == 3  # three different ways


def test_the_challenges_values_scale_to_the_same_cell_counts():
    config = CostmapConfig.challenge(0.4186)
    assert (config.cells, config.raytrace_cells, config.inflation_cells) == (800, 60, 6)
    assert config.resolution == pytest.approx(0.02093)
    assert config.obstacle_range == pytest.approx(1.0465)
    assert config.inflation_radius == pytest.approx(0.12558)
    assert config.inscribed_radius == pytest.approx(0.265 * 0.4186)
    assert config.cost_scaling_factor == pytest.approx(10 / 0.4186)
    assert config.corner == pytest.approx((-8.372, -8.372))
    assert np.array_equal(config.kernel()[2], CostmapConfig(inscribed_radius=0.265).kernel()[2])


@pytest.mark.parametrize("kwargs, message", [
    (dict(resolution=0.001), r"costmap size 40.0 m at resolution 0.001 m is 1.6e\+09 cells, "
                             r"more than 4,000,000"),
    (dict(obstacle_range=-1.0), "costmap obstacle_range must be a positive number, got -1.0"),
    (dict(raytrace_range=float("nan")), "costmap raytrace_range must be a positive number"),
    (dict(inscribed_radius=0.4), "costmap inscribed_radius 0.4 m must not exceed "
                                 "inflation_radius 0.3 m"),
])
def test_a_bad_config_is_one_line_naming_its_field(kwargs, message):
    with pytest.raises(ValueError, match=message) as error:
        CostmapConfig(**kwargs)
    assert "\n" not in str(error.value)


def test_a_bad_thread_count_for_an_update_is_one_line():
    maps = LaserCostmaps(CONFIG, 1)
    with pytest.raises(ValueError, match=r"^costmap threads must be a positive integer, got 0$"):
        maps.update([0], np.zeros((1, 3)), _wall_scan(1.01, 0.6), ROUND, threads=0)
    assert not maps.lethal(0).any()  # refused before anything was marked


def test_too_many_cars_grids_are_refused_before_allocating():
    with pytest.raises(ValueError, match="costmap cars: 1000 grids of 800 x 800 cells are more"):
        LaserCostmaps(CostmapConfig(), 1000)


def test_the_cost_never_rises_with_the_distance():
    # the compiled update stamps a cluster of lethal cells as one, from each cell's nearest
    # (costmap_loops.update_loops): exact only while the cost does not rise with the distance,
    # for any config
    rng = np.random.default_rng(3)
    for _ in range(50):
        inflation = rng.uniform(0.05, 1.0)
        config = CostmapConfig(resolution=rng.uniform(0.01, 0.1), size=8.0,
                               inflation_radius=inflation,
                               inscribed_radius=rng.uniform(0.0, inflation),
                               cost_scaling_factor=rng.uniform(0.1, 50.0))
        table = config.cost_table().astype(int)
        assert table[0] == LETHAL and np.all(np.diff(table) <= 0)
