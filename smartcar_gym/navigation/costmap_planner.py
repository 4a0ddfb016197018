"""navfn's role on a laser costmap (``navigation/costmap.py``): the global path, replanned.

``plan_on_costmap`` is the challenge's global planner (``navfn/NavfnROS``) on one car's
costmap: the cells LETHAL or INSCRIBED are obstacles (navfn's ``COST_OBS``), except the start's
(navfn's ``clearRobotCell``); every other cell costs navfn's ``COST_NEUTRAL + COST_FACTOR *
cost`` (50 + 0.8 cost, truncated, as ``NavFn::setCostmap``); an unseen cell is free (the
challenge tracks no unknown space; navfn's ``allow_unknown`` would pass it anyway). The path is
the cheapest 8-connected way (``astar.search``, A*, compiled where the ``fast`` extra is
installed: a move costs its length in cells times the sum of its two cells' costs), where navfn
propagates a potential and descends its gradient. Only the cells that can matter are searched:
the box of the start, the goal and every cell that has had a cost since the reset
(``LaserCostmaps.bounds``), grown by a cell (outside it every cell is neutral, so a way out of
the box is never cheaper than along its edge).

``Replanner`` is move_base's planning loop per car: a new plan every ``period_s`` (move_base's
``planner_frequency``, 20 Hz in the challenge, times scaled with the world and the speed), and
at once when a cell of the current path has become an obstacle; with a frequency of 0 (an
infinite period) only then, as move_base plans with ``planner_frequency: 0``.
``Replanner.plan_many`` plans a batch's due cars at once, their searches split over threads
(numba's search frees the GIL).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from smartcar_gym import checks
from smartcar_gym.navigation import astar
from smartcar_gym.navigation.astar import compiled_search
from smartcar_gym.navigation.costmap import INSCRIBED, LaserCostmaps
from smartcar_gym.navigation.grid_planner import NoPathError
from smartcar_gym.parallel import run_chunks

NEUTRAL_COST = 50  # navfn.h: COST_NEUTRAL, the cost of a free cell
COST_FACTOR = 0.8  # navfn.h: COST_FACTOR, per unit of the costmap's cost
PLANNER_FREQUENCY_HZ = 20.0  # the challenge's move_base_params.yaml: planner_frequency


def check_planner_frequency(frequency_hz: Any) -> float:
    """``frequency_hz`` as move_base's ``planner_frequency`` (Hz, >= 0; 0: plan only when the
    path is blocked); ValueError otherwise."""
    if not (checks.is_finite(frequency_hz) and frequency_hz >= 0):
        raise ValueError(f"planner_frequency must be a rate >= 0 Hz (0: only when the path is "
                         f"blocked), got {frequency_hz!r}")
    return float(frequency_hz)


def navfn_costs(costs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """navfn's view of costmap ``costs``: ``(cost, free)``, ``50 + int(0.8 cost)`` per cell
    and whether it may be crossed (below INSCRIBED)."""
    c = np.asarray(costs)
    free = c < INSCRIBED
    cost = NEUTRAL_COST + np.trunc(COST_FACTOR * c.astype(float))
    return np.where(free, cost, np.inf), free


#: navfn's cost of each costmap cost (0-255): ``navfn_costs``' table, ``inf`` impassable
NAVFN_TABLE = navfn_costs(np.arange(256))[0]


def plan_on_costmap(costmaps: LaserCostmaps, car: int, start: np.ndarray, goal: np.ndarray
                    ) -> np.ndarray:
    """The cheapest way (cell centres, (M, 2) m, odom frame) from ``start``'s cell to
    ``goal``'s on car ``car``'s costmap (module docstring). NoPathError if either is off the
    grid, the goal's cell is an obstacle, or no way avoids them."""
    return costmaps.cell_to_world(*plan_cells(costmaps, car, start, goal))


def plan_cells(costmaps: LaserCostmaps, car: int, start: np.ndarray, goal: np.ndarray
               ) -> tuple[np.ndarray, np.ndarray]:
    """``plan_on_costmap``'s way as its cells ``(ix, iy)`` (M,) each."""
    search = _Search(costmaps, car, start, goal)
    return search.cells(search.run(costmaps.compiled))


class _Search:
    """One plan's search on car ``car``'s costmap (``plan_on_costmap``): the grid's box
    (``grid``, its corner ``x_lo, y_lo``, its width ``w``) and the two ends' cells in it;
    NoPathError (at once) if an end is off the grid or the goal's cell is an obstacle."""

    def __init__(self, costmaps: LaserCostmaps, car: int, start: np.ndarray,
                 goal: np.ndarray) -> None:
        self.ends = np.asarray([start, goal], dtype=float).reshape(2, 2)
        cells = [costmaps.cell_of(x, y) for x, y in self.ends.tolist()]
        for k, name in enumerate(("start", "goal")):
            if cells[k] is None:
                raise NoPathError(f"the {name} {np.round(self.ends[k], 3).tolist()} is off "
                                  "the costmap")
        (sx, sy), (gx, gy) = cells
        costs = costmaps.costs(car)
        if costs[gy, gx] >= INSCRIBED:
            raise NoPathError(f"the goal {np.round(self.ends[1], 3).tolist()} is in an "
                              f"obstacle's cell (cost {costs[gy, gx]})")
        n = costs.shape[0]
        bx_lo, by_lo, bx_hi, by_hi = costmaps.bounds(car)
        self.x_lo = max(min(sx, gx, bx_lo) - 1, 0)
        self.y_lo = max(min(sy, gy, by_lo) - 1, 0)
        x_hi = min(max(sx + 1, gx + 1, bx_hi) + 1, n)
        y_hi = min(max(sy + 1, gy + 1, by_hi) + 1, n)
        self.w = x_hi - self.x_lo
        self.grid = costs[self.y_lo:y_hi, self.x_lo:x_hi]
        self.start = (sy - self.y_lo) * self.w + sx - self.x_lo
        self.goal = (gy - self.y_lo) * self.w + gx - self.x_lo

    def run(self, compiled: bool) -> np.ndarray:
        """The way's flat indices in the box (``astar.search``; empty if there is none)."""
        search = compiled_search if compiled else astar.search
        return search(self.grid, NAVFN_TABLE, self.start, self.goal)

    def cells(self, way: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``way`` (``run``'s) as the grid's cells; NoPathError if it is empty."""
        if len(way) == 0:
            raise NoPathError(f"no way on the costmap from {np.round(self.ends[0], 3).tolist()} "
                              f"to {np.round(self.ends[1], 3).tolist()} avoids its obstacles")
        return way % self.w + self.x_lo, way // self.w + self.y_lo


class Replanner:
    """Each car's current global path on its costmap, and when to plan it again:
    ``needs_plan`` is true with no path, ``period_s`` after the last plan (``math.inf``:
    never), or at once when a cell of the path past its first has become LETHAL or INSCRIBED
    (``blocked``)."""

    def __init__(self, costmaps: LaserCostmaps, period_s: float) -> None:
        self.costmaps = costmaps
        self.period_s = (math.inf if period_s == math.inf
                         else checks.positive_number("replanner period_s", period_s))
        self._paths: list[np.ndarray | None] = [None] * costmaps.n
        self._cells: list[tuple[np.ndarray, np.ndarray]] = [(np.zeros(0, int),) * 2] * costmaps.n
        self._last = np.full(costmaps.n, -np.inf)

    @classmethod
    def challenge(cls, costmaps: LaserCostmaps, scale: float = 1.0, speed_scale: float = 1.0,
                  frequency_hz: float = PLANNER_FREQUENCY_HZ) -> Replanner:
        """move_base's ``planner_frequency`` (the challenge's 20 Hz; 0: only when the path is
        blocked) for a world ``scale`` times as big driven ``speed_scale`` times as fast: its
        period times ``scale / speed_scale``."""
        checks.positive_number("replanner scale", scale)
        checks.positive_number("replanner speed_scale", speed_scale)
        if check_planner_frequency(frequency_hz) == 0:
            return cls(costmaps, math.inf)
        return cls(costmaps, scale / speed_scale / frequency_hz)

    def reset(self, cars: Sequence[int]) -> None:
        """Forgets the paths of ``cars``."""
        for car in cars:
            self._paths[car] = None
            self._cells[car] = (np.zeros(0, int),) * 2
            self._last[car] = -np.inf

    def path(self, car: int) -> np.ndarray | None:
        """Car ``car``'s current path ((M, 2) m, odom frame), None before its first."""
        return self._paths[car]

    def blocked(self, cars: Sequence[int] | np.ndarray) -> np.ndarray:
        """Whether a cell of each listed car's path past its first is now an obstacle ((K,)
        bool)."""
        cars = checks.car_indices("replanner", cars, self.costmaps.n)
        cells = [self._cells[car] for car in cars.tolist()]
        counts = np.array([max(len(ix) - 1, 0) for ix, _ in cells], dtype=np.int64)
        if not counts.any():
            return np.zeros(len(cars), dtype=bool)
        ix = np.concatenate([ix[1:] for ix, _ in cells])
        iy = np.concatenate([iy[1:] for _, iy in cells])
        hit = self.costmaps.costs_at(np.repeat(cars, counts), ix, iy) >= INSCRIBED
        owner = np.repeat(np.arange(len(cars)), counts)
        return np.bincount(owner[hit], minlength=len(cars)) > 0

    def needs_plan(self, cars: Sequence[int] | np.ndarray, now_s: np.ndarray) -> np.ndarray:
        """Whether each listed car should plan at its time ``now_s`` (K,) s ((K,) bool)."""
        cars = checks.car_indices("replanner", cars, self.costmaps.n)
        due = np.array([self._paths[car] is None for car in cars.tolist()], dtype=bool)
        due |= np.asarray(now_s, dtype=float) - self._last[cars] >= self.period_s - 1e-9
        rest = np.flatnonzero(~due)
        if len(rest):
            due[rest] = self.blocked(cars[rest])
        return due

    def plan(self, car: int, start: np.ndarray, goal: np.ndarray, now_s: float) -> np.ndarray:
        """Plans car ``car``'s path at ``now_s`` (``plan_on_costmap``) and keeps it; on
        NoPathError the last path stays and the attempt counts as the plan for the period."""
        self._last[car] = now_s
        self._keep(car, plan_cells(self.costmaps, car, start, goal))
        return self._paths[car]

    def plan_many(self, cars: Sequence[int], starts: np.ndarray, goals: np.ndarray,
                  now_s: Sequence[float], threads: int = 1) -> list[int]:
        """``plan`` for each of ``cars`` (starts and goals (K, 2), times (K,)), the searches
        split over ``threads`` where compiled (numba's frees the GIL; each car's search is its
        own, so the paths are the same whatever the split); the cars whose plan succeeded
        (the others keep their last path)."""
        searches = []
        for car, start, goal, now in zip(cars, starts, goals, now_s, strict=True):
            self._last[car] = now
            try:
                searches.append((car, _Search(self.costmaps, car, start, goal)))
            except NoPathError:
                continue
        ways: list[np.ndarray] = [np.zeros(0, np.int64)] * len(searches)
        compiled = self.costmaps.compiled

        def work(a: int, b: int) -> None:
            for k in range(a, b):
                ways[k] = searches[k][1].run(compiled)

        run_chunks(work, len(searches), threads if compiled else 1, min_chunk=2)
        planned = []
        for (car, search), way in zip(searches, ways, strict=True):
            if len(way):
                self._keep(car, search.cells(way))
                planned.append(car)
        return planned

    def _keep(self, car: int, cells: tuple[np.ndarray, np.ndarray]) -> None:
        self._paths[car], self._cells[car] = self.costmaps.cell_to_world(*cells), cells
