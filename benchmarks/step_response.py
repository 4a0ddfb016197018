"""Step response of the emulated ArbotiX base in pybullet: commanded vs measured wheel speed, PWM.

    python benchmarks/step_response.py -o docs/step_response.png

cmd_vel steps 0 -> 0.2 -> 0.4 -> 0 m/s (then a turn at 1 rad/s) in hardware mode; the wheel
speed is read from the simulator after every physics substep (the env's default stepping), the
PWM from the board.
"""

from __future__ import annotations

import argparse

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from smartcar_gym.controller import load_controller_config  # noqa: E402
from smartcar_gym.envs.robots import SmartCarRobot, drive  # noqa: E402
from smartcar_gym.model import load_model  # noqa: E402
from smartcar_gym.sim.pybullet.simulator import Simulator  # noqa: E402

SCHEDULE = [(0.5, 0.0, 0.0), (2.0, 0.2, 0.0), (2.0, 0.4, 0.0), (1.5, 0.0, 0.0), (2.0, 0.0, 1.0)]


def record(max_substep_s: float = 0.01) -> dict[str, np.ndarray]:
    """Run the schedule; return per-physics-substep time, commands, wheel speeds and PWM."""
    config = load_controller_config()
    model = load_model()
    sim = Simulator(max_substep_s=max_substep_s)
    robot = SmartCarRobot(sim, model, config, mode="hardware")
    robot.spawn()
    radius = model.wheel_radius_m
    left = [i for i, w in enumerate(robot.wheels) if w.side == "left"][0]
    right = [i for i, w in enumerate(robot.wheels) if w.side == "right"][0]
    keys = ("t", "cmd_left", "cmd_right", "left", "right", "pwm_l", "pwm_r")
    log: dict[str, list[float]] = {k: [] for k in keys}
    to_m_s = 30.0 / config.ticks_meter  # ticks per 1/30 s frame -> m/s, as the driver means it

    def probe(t: float) -> None:
        v = robot.joint_states().velocity
        state = robot.base.state()
        log["t"].append(t)
        log["left"].append(v[left] * radius * robot.wheels[left].forward_sign)
        log["right"].append(v[right] * radius * robot.wheels[right].forward_sign)
        log["cmd_left"].append(state["last_write"][0] * to_m_s if state["last_write"] else 0.0)
        log["cmd_right"].append(state["last_write"][1] * to_m_s if state["last_write"] else 0.0)
        log["pwm_l"].append(state["pwm"][0])
        log["pwm_r"].append(state["pwm"][1])

    for seconds, v, w in SCHEDULE:
        drive(robot, v, w, round(seconds * config.rate_hz), probe=probe)
    sim.close()
    return {k: np.asarray(x) for k, x in log.items()}


def plot(log: dict[str, np.ndarray], path: str) -> None:
    fig, (ax1, ax2) = plt.subplots(2, 1, figsize=(9, 6), sharex=True)
    ax1.step(log["t"], log["cmd_left"], where="post", color="C0", ls="--",
             label="left target (written to the board)")
    ax1.step(log["t"], log["cmd_right"], where="post", color="C1", ls="--",
             label="right target")
    ax1.plot(log["t"], log["left"], color="C0", label="left wheel (measured)")
    ax1.plot(log["t"], log["right"], color="C1", label="right wheel (measured)")
    ax1.set_ylabel("wheel surface speed (m/s)")
    ax1.set_title("ArbotiX emulation step response: cmd_vel 0.2, 0.4, 0 m/s, then 1 rad/s")
    ax1.legend(loc="lower left", fontsize=8)
    ax1.grid(alpha=0.3)
    ax2.step(log["t"], log["pwm_l"], where="post", color="C0", label="left PWM")
    ax2.step(log["t"], log["pwm_r"], where="post", color="C1", label="right PWM")
    ax2.set_ylabel("board PWM")
    ax2.set_xlabel("time (s)")
    ax2.set_ylim(-270, 270)
    ax2.legend(loc="lower left", fontsize=8)
    ax2.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("-o", "--output", default="step_response.png")
    args = parser.parse_args()
    log = record()
    plot(log, args.output)
    print(f"wrote {args.output}")
    for command, (start, end) in ((0.2, (2.0, 2.5)), (0.4, (4.0, 4.5))):  # the last 0.5 s
        steady = (log["t"] > start) & (log["t"] < end)
        speed, target = log["left"][steady].mean(), log["cmd_left"][steady].mean()
        print(f"cmd_vel {command} m/s: wheels at {speed:.4f} m/s, target {target:.4f} "
              f"({100 * (speed / target - 1):+.1f} %)")


if __name__ == "__main__":
    main()
