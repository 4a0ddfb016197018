"""Sensors beyond odometry: a simulated 2D laser scanner."""

from smartcar_gym.envs.sensors.scan import LaserConfig, LaserScan, scan_entry, scan_sectors

__all__ = ["LaserConfig", "LaserScan", "scan_entry", "scan_sectors"]
