"""Robots: a body in the simulator plus the controller that drives it."""

from smartcar_gym.envs.robots.entries import robot_entries
from smartcar_gym.envs.robots.smartcar import JointStates, Pose2D, SmartCarRobot, drive

__all__ = ["JointStates", "Pose2D", "SmartCarRobot", "drive", "robot_entries"]
