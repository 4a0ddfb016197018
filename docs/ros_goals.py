"""20 2D Nav Goals one after another with the shipped ``ros`` policy: docs/ros_goals.png.

::

    python docs/ros_goals.py sim  --json sim.json    # GoalDriver and the simulated robot, no ROS
    python docs/ros_goals.py sim --policy runs/ft/step_49152 --seed 3   # another policy folder
    python docs/ros_goals.py live --json live.json   # roscore, bringup and policy nodes
    python docs/ros_goals.py plot sim.json live.json --out docs/ros_goals.png
    python docs/ros_goals.py slip      # calibrated odometry against the truth, by motion

``live`` starts its own roscore on a free loopback port, ``smartcar-ros bringup --speed 4``
on ``/clock`` and ``smartcar-ros policy --pretrained``, then sends each goal on
``/move_base_simple/goal`` from where the odometry says the car stands (the goals of
``smartcar_gym.ros.goal_run.next_goal`` with the same seed), waits for the policy's "reached"
line on ``/rosout`` (or 30 s of ROS time), leaves the car 1 s and records ``odom`` and
``base_pose_ground_truth``.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import signal
import socket
import subprocess
import sys
import tempfile
import time
from dataclasses import asdict
from pathlib import Path

import numpy as np

from smartcar_gym.ros.goal_run import ARENA_MARGIN_M, GoalResult, meant_goal, next_goal

REST_M_S = 0.01
TOLERANCE_M = 0.1


def run_sim(count: int, seed: int, source: str = "ros") -> list[GoalResult]:
    from smartcar_gym.policy import Policy
    from smartcar_gym.ros.goal_run import drive_goals

    policy = Policy.load(source if source == "ros" else Path(source))
    return drive_goals(policy.settings, policy.act, count, seed)


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _yaw(q) -> float:
    return 2.0 * math.atan2(q.z, q.w)


def _drive_live(count: int, seed: int, half: float) -> list[GoalResult]:
    from smartcar_gym.ros.debian import import_ros

    ros = import_ros()
    rospy = ros.rospy

    rospy.init_node("goal_sender", disable_signals=True)
    latest: dict[str, object] = {}
    reached = {"count": 0}

    def on_log(msg) -> None:
        if "smartcar_policy" in msg.name and "reached" in msg.msg:
            reached["count"] += 1

    rospy.Subscriber("/odom", ros.nav_msgs.Odometry, lambda m: latest.update(odom=m))
    rospy.Subscriber("/base_pose_ground_truth", ros.nav_msgs.Odometry,
                     lambda m: latest.update(truth=m))
    rospy.Subscriber("/rosout", ros.rosgraph_msgs.Log, on_log)
    pub = rospy.Publisher("/move_base_simple/goal", ros.geometry_msgs.PoseStamped,
                          queue_size=1)
    deadline = time.monotonic() + 120
    while (pub.get_num_connections() == 0 or "odom" not in latest or "truth" not in latest
           or rospy.Time.now().to_sec() == 0.0):
        if time.monotonic() > deadline:
            raise RuntimeError("no policy node subscribed, or no odom/ground truth in 120 s")
        time.sleep(0.1)
    time.sleep(3.0)  # the policy node's own subscriptions connect
    rng = np.random.default_rng(seed)
    results = []
    for _ in range(count):
        odom, truth = latest["odom"], latest["truth"]
        op, tp = odom.pose.pose, truth.pose.pose
        goal = next_goal(rng, op.position.x, op.position.y, (0.3, 2.0), half)
        real = meant_goal(goal, (op.position.x, op.position.y, _yaw(op.orientation)),
                          (tp.position.x, tp.position.y, _yaw(tp.orientation)))
        msg = ros.geometry_msgs.PoseStamped()
        msg.header.frame_id = odom.header.frame_id
        msg.header.stamp = rospy.Time.now()
        msg.pose.position.x, msg.pose.position.y = goal
        msg.pose.orientation.w = 1.0
        before, start = reached["count"], rospy.Time.now().to_sec()
        pub.publish(msg)
        while reached["count"] == before and rospy.Time.now().to_sec() - start < 30.0:
            time.sleep(0.01)
        done = reached["count"] > before
        time_s = rospy.Time.now().to_sec() - start
        if not done:  # the user gives up: a zero goal is not in rviz; stop by timing out
            print(f"goal {goal} not reached in 30 s", file=sys.stderr)
        rospy.sleep(1.0)
        odom, truth = latest["odom"], latest["truth"]
        tv = truth.twist.twist.linear
        results.append(GoalResult(
            goal, real, done, min(time_s, 30.0),
            (odom.pose.pose.position.x, odom.pose.pose.position.y),
            (truth.pose.pose.position.x, truth.pose.pose.position.y),
            abs(odom.twist.twist.linear.x), math.hypot(tv.x, tv.y)))
        print(f"{len(results):2d} {describe(results[-1])}", file=sys.stderr)
    rospy.signal_shutdown("done")
    return results


def run_live(count: int, seed: int, speed: float) -> list[GoalResult]:
    """roscore, bringup and the policy node as processes of their own, then the goals."""
    port = _free_port()
    home = tempfile.mkdtemp(prefix="ros_goals_")
    env = {**os.environ, "ROS_MASTER_URI": f"http://127.0.0.1:{port}", "ROS_IP": "127.0.0.1",
           "ROS_HOME": home}
    os.environ.update(env)
    procs = []

    def start(name: str, command: list[str]) -> None:
        log = open(Path(home) / f"{name}.log", "w")  # noqa: SIM115 (the process keeps it)
        procs.append(subprocess.Popen(command, env=env, stdout=log, stderr=subprocess.STDOUT,
                                      start_new_session=True))

    try:
        start("roscore", ["roscore", "-p", str(port)])
        time.sleep(4.0)
        subprocess.run(["rosparam", "set", "/use_sim_time", "true"], env=env, check=True)
        ros_cli = [sys.executable, "-m", "smartcar_gym.ros"]
        start("bringup", [*ros_cli, "bringup", "--speed", f"{speed:g}"])
        start("policy", [*ros_cli, "policy", "--pretrained"])
        from smartcar_gym.envs.policy_settings import policy_settings

        half = policy_settings("SmartCarArrive-v0").task.arena_half_size_m - ARENA_MARGIN_M
        return _drive_live(count, seed, half)
    finally:
        for proc in reversed(procs):
            with_group = os.getpgid(proc.pid) if proc.poll() is None else None
            if with_group is not None:
                os.killpg(with_group, signal.SIGINT)
                try:
                    proc.wait(15)
                except subprocess.TimeoutExpired:
                    os.killpg(with_group, signal.SIGKILL)
        print(f"node logs in {home}", file=sys.stderr)


SLIP_MOTIONS = ((0.25, 0.0, 4.0), (0.5, 0.0, 2.0), (0.0, 1.0, 6.28), (0.0, 2.0, 3.14),
                (0.25, 0.5, 6.28), (0.5, 1.0, 3.14), (0.2, 2.0, 1.57))


def slip() -> None:
    """cmd_vel (v, w) for T s, then 1.5 s at rest, on the calibrated odometry (hardware mode):
    the odometry's error in position and heading at the end."""
    from smartcar_gym.controller import load_controller_config
    from smartcar_gym.controller.config_yaml import calibrated_config_path
    from smartcar_gym.model import load_model
    from smartcar_gym.ros.bringup import start_robot

    config, model = load_controller_config(calibrated_config_path()), load_model(None)
    print("| cmd_vel (m/s, rad/s) for T s | position error | heading error |\n|---|---|---|")
    for v, w, seconds in SLIP_MOTIONS:
        robot = start_robot(model, config, "hardware")
        sim = robot.sim
        for i in range(round(seconds * config.rate_hz) + 15):
            robot.cmd_vel(*((v, w) if i < seconds * config.rate_hz else (0.0, 0.0)))
            sim.run_until(sim.now_ns + robot.update_period_ns)
        odom, pose = robot.odometry, robot.pose()
        sim.close()
        error = math.hypot(odom.x - pose.x, odom.y - pose.y)
        turn = abs(math.remainder(odom.theta - pose.yaw, 2 * math.pi))
        print(f"| ({v:g}, {w:g}) for {seconds:g} s | {error:.3f} m | {turn:.4f} rad |")


def describe(r: GoalResult) -> str:
    ok = r.arrived(TOLERANCE_M, REST_M_S)
    return (f"{'ok  ' if ok else 'MISS'} goal ({r.goal[0]:+.2f}, {r.goal[1]:+.2f}) "
            f"{r.time_s:4.1f} s  odometry {r.odom_distance:.3f} m  truth {r.truth_distance:.3f} m"
            f"  world {r.world_distance:.3f} m  |v| odom {r.odom_speed:.4f} true "
            f"{r.truth_speed:.4f} m/s")


def summary(results: list[GoalResult]) -> dict:
    d = np.array([[r.odom_distance, r.truth_distance, r.world_distance] for r in results])
    return {"goals": len(results),
            "arrived": sum(r.arrived(TOLERANCE_M, REST_M_S) for r in results),
            "reached": sum(r.reached for r in results),
            "max_odom_distance_m": float(d[:, 0].max()),
            "max_truth_distance_m": float(d[:, 1].max()),
            "max_world_distance_m": float(d[:, 2].max()),
            "max_speed_m_s": max(max(r.odom_speed, r.truth_speed) for r in results),
            "mean_time_s": float(np.mean([r.time_s for r in results]))}


def plot(runs: dict[str, list[GoalResult]], out: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, len(runs), figsize=(6.2 * len(runs), 6.2), squeeze=False)
    for ax, (title, results) in zip(axes[0], runs.items(), strict=True):
        previous = (0.0, 0.0)
        for i, r in enumerate(results, 1):
            ax.plot(*zip(previous, r.goal, strict=True), color="0.85", lw=0.8, zorder=0)
            previous = r.odom
            ax.add_patch(plt.Circle(r.goal, TOLERANCE_M, fill=False, color="0.5", lw=0.8))
            # where the car really stopped, drawn relative to the goal as it was meant
            true_stop = (r.goal[0] + r.truth[0] - r.real_goal[0],
                         r.goal[1] + r.truth[1] - r.real_goal[1])
            ax.plot(*r.odom, "o", ms=4, color="tab:blue",
                    label="stopped, by odometry" if i == 1 else None)
            ax.plot(*true_stop, "x", ms=6, color="tab:red",
                    label="stopped, in ground truth" if i == 1 else None)
            ax.plot(*r.truth, ".", ms=4, color="tab:orange", alpha=0.6,
                    label="ground truth in world (odometry drift)" if i == 1 else None)
            ax.annotate(str(i), r.goal, xytext=(5, 5), textcoords="offset points", fontsize=7)
        s = summary(results)
        ax.set_title(f"{title}: {s['arrived']}/{s['goals']} at rest within {TOLERANCE_M} m\n"
                     f"max {s['max_odom_distance_m']:.3f} m by odometry, "
                     f"{s['max_truth_distance_m']:.3f} m in truth", fontsize=10)
        ax.set_aspect("equal")
        ax.set_xlabel("x in odom (m)")
        ax.set_ylabel("y in odom (m)")
        ax.grid(alpha=0.3)
        ax.legend(loc="lower left", fontsize=7)
    fig.tight_layout()
    fig.savefig(out, dpi=110)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("mode", choices=("sim", "live", "plot", "slip"))
    parser.add_argument("files", nargs="*", type=Path, help="plot: result JSON files")
    parser.add_argument("--count", type=int, default=20)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--speed", type=float, default=4.0, help="live: bringup --speed")
    parser.add_argument("--json", type=Path, help="sim/live: write the results here")
    parser.add_argument("--policy", default="ros",
                        help="sim: the shipped 'ros' policy or a policy folder")
    parser.add_argument("--out", type=Path, default=Path("docs/ros_goals.png"))
    args = parser.parse_args()
    if args.mode == "slip":
        slip()
        return
    if args.mode == "plot":
        runs = {}
        for path in args.files:
            data = json.loads(path.read_text())
            runs[data["title"]] = [GoalResult(**{k: tuple(v) if isinstance(v, list) else v
                                                 for k, v in r.items()})
                                   for r in data["results"]]
        plot(runs, args.out)
        return
    started = time.monotonic()
    results = (run_sim(args.count, args.seed, args.policy) if args.mode == "sim"
               else run_live(args.count, args.seed, args.speed))
    wall = time.monotonic() - started
    for i, r in enumerate(results, 1):
        print(f"{i:2d} {describe(r)}")
    print(json.dumps(summary(results)), f"wall {wall:.0f} s")
    if args.json:
        title = ("GoalDriver, no ROS" if args.mode == "sim"
                 else f"through roscore (bringup --speed {args.speed:g})")
        args.json.write_text(json.dumps({"title": title, "summary": summary(results),
                                         "results": [asdict(r) for r in results]}, indent=1))


if __name__ == "__main__":
    main()
