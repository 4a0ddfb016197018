"""SmartCarBARN-v0's ``map_mode="laser"``: each car's global costmap built from its own scans
and its global path planned on it, as the challenge's move_base builds and plans them.

``LaserMap`` holds N cars' costmaps (``navigation.costmap.LaserCostmaps``, the challenge's
values scaled) and their replanner (``navigation.costmap_planner.Replanner``, move_base's
``planner_frequency``, the challenge's 20 Hz by default, scaled); ``start`` clears the listed
cars' costmaps and marks their first scans, ``update`` marks each new scan at the odometry pose
(the laser scans at the controller's rate) and plans again where the replanner says (its rate,
or a new mark on the path), returning the cars whose path changed. Until a plan succeeds a car
keeps the path it had.

With ``localize`` each new scan is first matched to the map the car's earlier scans made
(``navigation.scan_map.ScanMaps``: a laser SLAM front end's map -> odom correction), and the
pose on that map (``poses``) takes the odometry's place: the scan is marked there and the path
planned from there.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping

import numpy as np

from smartcar_gym import checks
from smartcar_gym.envs.state import SCAN, SCAN_TIME, CarState
from smartcar_gym.navigation import localization
from smartcar_gym.navigation.costmap import CostmapConfig, LaserCostmaps
from smartcar_gym.navigation.costmap_planner import (
    PLANNER_FREQUENCY_HZ,
    Replanner,
    check_planner_frequency,
)
from smartcar_gym.navigation.scan_map import ScanMaps
from smartcar_gym.sim.clock import NS_PER_S


def costmap_changes(costmap: Mapping[str, float] | None, map_mode: str) -> dict[str, float]:
    """The ``costmap`` argument: the laser costmap's fields to change (numbers), checked
    against ``CostmapConfig``'s; an error naming an unknown field, or any with the known map."""
    if costmap is None:
        return {}
    if not isinstance(costmap, Mapping):
        raise TypeError(f"costmap must be a dict of CostmapConfig fields, got "
                        f"{type(costmap).__name__}: {costmap!r}")
    if costmap and map_mode != "laser":
        raise ValueError(f"costmap changes the laser costmap's fields: map_mode={map_mode!r} "
                         "has none (pass map_mode='laser')")
    fields = [f.name for f in dataclasses.fields(CostmapConfig) if f.name != "origin"]
    unknown = sorted(set(map(str, costmap)) - set(fields))
    if unknown:
        raise ValueError(f"costmap: unknown field(s) {unknown}; CostmapConfig has "
                         f"{', '.join(fields)}")
    return {str(name): checks.positive_number(f"costmap {name}", value)
            for name, value in costmap.items()}


def checked_planner_frequency(frequency: float | None, map_mode: str) -> float:
    """The ``planner_frequency`` argument as the rate to plan at (Hz before scaling; None: the
    challenge's 20; 0: only when the path is blocked); an error for the known map or a rate
    below 0."""
    if frequency is None:
        return PLANNER_FREQUENCY_HZ
    if map_mode != "laser":
        raise ValueError("planner_frequency is the laser map's replanning rate: "
                         f"map_mode={map_mode!r} plans once (pass map_mode='laser')")
    return check_planner_frequency(frequency)


class LaserMap:
    """N cars' laser costmaps and replanner (module docstring): ``config``, the costmaps'
    settings; ``scale`` and ``speed_scale``, the world's and the speed's against the
    challenge's (the planner's rate follows them); ``angles`` and ``mount``, the laser's beams
    (rad) and its 4 x 4 pose in base_link; ``planner_frequency`` (Hz, before scaling; 0: only
    when the path is blocked); ``localize``: the scans matched to the car's own map."""

    def __init__(self, config: CostmapConfig, num: int, scale: float, speed_scale: float,
                 angles: np.ndarray, mount: np.ndarray,
                 planner_frequency: float = PLANNER_FREQUENCY_HZ,
                 localize: bool = False) -> None:
        #: each car's costmap (``costs(car)``, ``lethal(car)``)
        self.costmaps = LaserCostmaps(config, num)
        self.replanner = Replanner.challenge(self.costmaps, scale, speed_scale,
                                             planner_frequency)
        self.angles, self.mount = angles, mount
        self._marked = np.full(num, -1, dtype=np.int64)  # the time of the scan last marked
        #: ``localize``: each car's map of its own returns (on the costmap's grid), else None
        self.scan_maps = ScanMaps(config, num) if localize else None
        #: each car's map -> odom correction (x, y, yaw), (N, 3): zero without ``localize``
        self.corrections = np.zeros((num, 3))
        self._beams = localization.beam_geometry(angles, mount)

    def start(self, state: CarState, idx: np.ndarray, paths: list[np.ndarray],
              threads: int = 1) -> None:
        """Cars ``idx`` start a run: nothing seen, then their first scans marked and their
        paths planned (into ``paths``)."""
        self.costmaps.reset(idx)
        self.replanner.reset(idx.tolist())
        self._marked[idx] = -1
        if self.scan_maps is not None:
            self.scan_maps.reset(idx)
        self.corrections[idx] = 0.0
        self.update(state, idx, paths, threads)

    def poses(self, state: CarState, idx: np.ndarray) -> np.ndarray:
        """Cars ``idx``' base_link poses (K, 3) in their costmaps' frame: the odometry's, or
        with ``localize`` the pose on the map (``localization.compose``, one car at a time)."""
        odometry = state.odometry[idx, :3]
        if self.scan_maps is None:
            return odometry
        return np.array([localization.compose(tuple(c), tuple(o)) for c, o in
                         zip(self.corrections[idx].tolist(), odometry.tolist(), strict=True)],
                        dtype=float).reshape(-1, 3)

    def update(self, state: CarState, idx: np.ndarray, paths: list[np.ndarray],
               threads: int = 1) -> list[int]:
        """Cars ``idx``' new scans marked, and their paths planned again where due (written
        into ``paths``); the cars whose path changed. The compiled marking and searches run
        on ``threads`` threads (the same grids and paths whatever the count)."""
        fresh = idx[state.readings[SCAN_TIME][idx] != self._marked[idx]]
        if len(fresh):
            if self.scan_maps is not None:
                self.corrections[fresh] = self.scan_maps.correct(
                    fresh, self.corrections[fresh], state.odometry[fresh, :3],
                    state.readings[SCAN][fresh], *self._beams, threads=threads)
            self.costmaps.update(fresh, self.poses(state, fresh), state.readings[SCAN][fresh],
                                 self.angles, self.mount, threads=threads)
            self._marked[fresh] = state.readings[SCAN_TIME][fresh]
        now_s = state.now_ns[idx] / NS_PER_S
        due = self.replanner.needs_plan(idx, now_s)
        cars = idx[due]
        changed = self.replanner.plan_many(cars.tolist(), self.poses(state, cars)[:, :2],
                                           state.goal[cars], now_s[due].tolist(), threads)
        for i in changed:
            paths[i] = self.replanner.path(i)
        return changed
