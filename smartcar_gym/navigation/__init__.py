"""Classical navigation: a grid global planner (move_base's navfn) and a DWA local planner."""

from smartcar_gym.navigation.dwa import DWAConfig, DWAPlanner
from smartcar_gym.navigation.grid_planner import NoPathError, distance_grid, plan_path

__all__ = ["DWAConfig", "DWAPlanner", "NoPathError", "distance_grid", "plan_path"]
