"""Sideways drift of robots driven straight, over substeps, with and without the guards.

    python benchmarks/drive_straight.py [--substeps 0.001,0.002,0.005,0.01,0.02]

The issue's drive: cmd_vel (0.2, 0) once per controller period for 5 s from rest; forward and
sideways travel over the last 3 s, in the heading the robot had after the first 2 s. Robots:
the shipped smartcar and the test fixtures casterbot (differential drive) and heavybot (skid
steer). ``unguarded``: the robot taken for a skid base (10 solver iterations, pybullet's 1e-7
residual, encoders starting on a tick edge), as every robot was stepped before.
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

from smartcar_gym.controller import load_controller_config
from smartcar_gym.envs.robots import SmartCarRobot, drive
from smartcar_gym.model import RobotModel, load_model
from smartcar_gym.sim.pybullet.simulator import Simulator

FIXTURES = Path(__file__).resolve().parent.parent / "tests" / "fixtures"
ROBOTS = {
    "smartcar": (None, None),
    "casterbot": (FIXTURES / "casterbot_description/urdf/casterbot.urdf.xacro",
                  FIXTURES / "casterbot_description/config/casterbot_arbotix.yaml"),
    "heavybot": (FIXTURES / "heavybot_description/urdf/heavybot.urdf.xacro",
                 FIXTURES / "heavybot_description/config/heavybot_arbotix.yaml"),
}


def straight(model: RobotModel, config_path: Path | None, substep: float) -> tuple[float, float]:
    """(forward, sideways) m over the last 3 s of 5 s at cmd_vel 0.2 m/s."""
    sim = Simulator(max_substep_s=substep)
    robot = SmartCarRobot(sim, model, load_controller_config(config_path))
    robot.spawn()
    drive(robot, 0.2, 0.0, 20)
    start = robot.pose()
    drive(robot, 0.2, 0.0, 30)
    end = robot.pose()
    sim.close()
    dx, dy = end.x - start.x, end.y - start.y
    c, s = math.cos(start.yaw), math.sin(start.yaw)
    return dx * c + dy * s, -dx * s + dy * c


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--substeps", default="0.001,0.002,0.005,0.01,0.02")
    args = parser.parse_args()
    substeps = [float(s) for s in args.substeps.split(",")]
    print("| robot | " + " | ".join(f"{s * 1000:g} ms" for s in substeps) + " |")
    print("|---|" + "---:|" * len(substeps))
    guarded = RobotModel.drive_kind
    for name, (model_path, config_path) in ROBOTS.items():
        model = load_model(model_path)
        for label, kind in (("", guarded), (" unguarded", property(lambda self: "skid"))):
            if label and model.drive_kind == "skid":
                continue  # a skid base has no guards
            RobotModel.drive_kind = kind
            cells = []
            for substep in substeps:
                forward, sideways = straight(model, config_path, substep)
                cells.append(f"{forward:.3f} m, {100 * sideways / forward:+.2f}")
            RobotModel.drive_kind = guarded
            print(f"| {name}{label} ({model.drive_kind}) | " + " | ".join(cells) + " |",
                  flush=True)


if __name__ == "__main__":
    main()
