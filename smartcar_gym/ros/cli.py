"""``smartcar-ros``: the simulated smartcar and trained policies as ROS 1 nodes.

::

    smartcar-ros bringup [--model URDF|XACRO] [--controller-config YAML] [--speed N]
                         [--engine pybullet|mujoco]
    smartcar-ros policy (--pretrained [NAME] | --model ZIP|ONNX) [--vecnormalize FILE]
    smartcar-ros package        # the ROS package folder, for ROS_PACKAGE_PATH

``--pretrained`` alone is the ``ros`` policy (SmartCarArrive-v0: it drives to a goal and
stops there, on the calibrated odometry that bringup publishes by default).

Arguments with ``:=`` are ROS's (``__name:=``, remappings, ``_param:=value``) and go to rospy,
so the commands run as nodes under ``roslaunch`` (see the ``smartcar_gym_ros`` package).
Bad arguments, a missing rospy or no ROS master: one line on stderr and exit code 2.
"""

from __future__ import annotations

import argparse
import math
import signal
import sys
import threading
import time
import warnings
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from smartcar_gym.agents.models import PRETRAINED_POLICIES
from smartcar_gym.ros.debian import RosUnavailable, import_ros
from smartcar_gym.ros.driving import STOP_ON
from smartcar_gym.ros.package import package_folder
from smartcar_gym.sim.engines import DEFAULT_ENGINE, add_engine_argument

PROG = "smartcar-ros"
STALE_AFTER_S = 0.5  # five controller periods of the shipped config
#: the shipped policy ``--pretrained`` alone names: trained on SmartCarArrive-v0 (docs/ros.md)
ROS_POLICY = "ros"
POLICY_MODULES = ("stable_baselines3", "torch")


def _positive(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not (math.isfinite(value) and value > 0):
        raise argparse.ArgumentTypeError(f"expected a positive number, got {text!r}")
    return value


def build_parser() -> argparse.ArgumentParser:
    """The ``smartcar-ros`` argument parser."""
    from smartcar_gym.agents.cli_args import key_value_arg

    parser = argparse.ArgumentParser(
        prog=PROG, description="The simulated smartcar and trained policies as ROS 1 nodes "
        "(rospy from Debian: apt-get install ros-core python3-rospy ...; see docs/ros.md).",
        epilog="Arguments containing ':=' (__name:=, remappings, _param:=value) are passed "
               "to rospy.")
    sub = parser.add_subparsers(dest="command", required=True)
    bringup = sub.add_parser(
        "bringup", help="the simulated robot in place of arbotix_driver (node name arbotix)",
        description="Run the pybullet smartcar with the emulated ArbotiX controller as a ROS "
                    "node: subscribes cmd_vel; publishes odom, /tf (odom -> base_link), "
                    "joint_states and, with /use_sim_time, /clock. The controller's parameters "
                    "are read from the node's private namespace (as arbotix_driver does) when "
                    "~controllers is set, else from --controller-config.")
    bringup.add_argument("--model", type=Path, help="robot description, .urdf or .xacro "
                         "(default: the shipped smartcar)")
    bringup.add_argument("--package-path", type=Path, action="append", metavar="DIR",
                         help="folder searched for $(find pkg) and package:// (repeatable)")
    bringup.add_argument("--controller-config", type=Path, metavar="YAML",
                         help="ArbotiX driver YAML used when the parameter server has no "
                              "~controllers (default: the shipped "
                              "smartcar_arbotix_calibrated.yaml, base_width 0.33: the "
                              "odometry smartcar-ros policy --pretrained was trained on)")
    bringup.add_argument("--mode", choices=("hardware", "sim"),
                         help="hardware (PID, encoders, motors) or sim (kinematic, the "
                              "driver's sim: true); default: the config's sim parameter")
    add_engine_argument(bringup, default=DEFAULT_ENGINE, what="the robot's")
    bringup.add_argument("--speed", type=_positive, default=1.0, metavar="N",
                         help="simulated seconds per wall-clock second (default 1); other "
                              "than 1 needs /use_sim_time true")
    policy = sub.add_parser(
        "policy", help="a trained policy driving to the goals of rviz's 2D Nav Goal",
        description="Subscribe odom, joint_states and /move_base_simple/goal; publish cmd_vel "
                    "at the controller's rate until odometry says the goal is reached.",
        epilog="SB3 model zips and VecNormalize files are pickles: loading one runs the code "
               "it holds. A normaliser is loaded only from --vecnormalize or from the model's "
               "own place, as smartcar-eval does.")
    source = policy.add_mutually_exclusive_group(required=True)
    source.add_argument("--model", type=Path, help="a model .zip, a run folder of "
                        "smartcar-train or rl-baselines3-zoo, or an .onnx file of "
                        "smartcar-export (runs without torch)")
    source.add_argument("--pretrained", nargs="?", const=ROS_POLICY, metavar="NAME",
                        choices=tuple(PRETRAINED_POLICIES), help="a policy shipped with the "
                        f"package: {ROS_POLICY} (the one --pretrained alone names: it drives "
                        "to a goal and stops there, on bringup's default calibrated "
                        f"odometry) or another of {', '.join(PRETRAINED_POLICIES)}")
    policy.add_argument("--algo", help="algorithm of --model (default: from its run)")
    policy.add_argument("--env", dest="env_id", help="the env the policy was trained in "
                        "(default: the run's, else SmartCar-v0)")
    policy.add_argument("--env-kwargs", nargs="+", default=[], metavar="KEY=VALUE",
                        type=key_value_arg, help="added to the run's env kwargs")
    policy.add_argument("--vecnormalize", type=Path, metavar="FILE",
                        help="VecNormalize statistics (a pickle: only from a trusted source)")
    policy.add_argument("--stale-after", type=_positive, default=STALE_AFTER_S, metavar="S",
                        help=f"odometry or joint states older than S seconds stop the car "
                             f"(default {STALE_AFTER_S})")
    policy.add_argument("--stop-on", choices=STOP_ON, default="odometry",
                        help="what says the goal is reached: odometry (default; all a real "
                             "robot has) or, with smartcar-ros bringup, the simulator's "
                             "base_pose_ground_truth (the env's own success test; see "
                             "docs/ros.md for why --pretrained default needs it)")
    policy.add_argument("--device", default="cpu")
    sub.add_parser("package", help="print the folder to add to ROS_PACKAGE_PATH",
                   description="Print the folder holding the smartcar_gym_ros and "
                               "smartcar_description ROS packages.")
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run ``smartcar-ros``; returns the exit code."""
    argv = list(sys.argv[1:] if argv is None else argv)
    ros_args = [a for a in argv if ":=" in a]
    parser = build_parser()
    args = parser.parse_args([a for a in argv if ":=" not in a])
    if args.command == "package":
        print(package_folder())
        return 0
    try:
        if args.command == "policy":
            return _policy(parser, args, ros_args)
        return _bringup(args, ros_args)
    except KeyboardInterrupt:  # Ctrl-C while starting, before the node's own handling
        return 130


def _fail(message: str) -> int:
    print(f"{PROG}: error: {' '.join(message.split())}", file=sys.stderr)
    return 2


@contextmanager
def _master(caller_id: str) -> Iterator[Any]:
    """A ``rosgraph.Master`` whose connection is closed on the way out: left open, its socket
    is a ResourceWarning when collected, printed (with warnings on) before a one-line error."""
    import rosgraph

    master = rosgraph.Master(caller_id)
    try:
        yield master
    finally:
        master.handle("close")()


def _ros_or_fail() -> Any:
    ros = import_ros()  # RosUnavailable: one line, said by the caller
    import rosgraph

    with _master("/rosgraph") as master:  # rosgraph.is_master_online(), closed
        online = master.is_online()
    if not online:
        raise RosUnavailable(f"no ROS master at {rosgraph.get_master_uri()}: start roscore (or "
                             "roslaunch) first, or set ROS_MASTER_URI")
    return ros


def _init_node(ros: Any, name: str, ros_args: list[str]) -> threading.Event:
    """``rospy.init_node`` with our own SIGINT/SIGTERM handling; the event is set on a signal.

    rospy's own handler shuts the node down inside the signal handler, which deadlocks when
    the signal arrives while the main thread holds one of rospy's locks (publishing, as the
    bringup loop nearly always is at high ``--speed``): the loops stop on this event instead
    and shut rospy down from the main thread.
    """
    ros.rospy.init_node(name, argv=[PROG, *ros_args], disable_signals=True)
    stop = threading.Event()

    def on_signal(signum: int, frame: Any) -> None:
        stop.set()

    signal.signal(signal.SIGINT, on_signal)
    signal.signal(signal.SIGTERM, on_signal)
    return stop


def _bringup(args: argparse.Namespace, ros_args: list[str]) -> int:
    try:
        ros = _ros_or_fail()
    except RosUnavailable as err:
        return _fail(str(err))
    # Everything that can be refused is decided before the node exists: a refused
    # configuration is then this one line and nothing else, however loaded the machine (with
    # a node, rospy's registration and /rosout threads were still at work when it exited).
    try:
        setup = _bringup_setup(args, ros_args)
    except _Refused as err:
        print(f"[FATAL] [{time.time():.6f}]: {err}", file=sys.stderr, flush=True)
        return 2
    rospy = ros.rospy
    stop = _init_node(ros, "arbotix", ros_args)
    try:
        return _run_bringup(ros, args, setup, stop)
    finally:
        rospy.signal_shutdown("smartcar-ros bringup ended")


class _Refused(Exception):
    """A configuration, model or option the bringup refuses (one line)."""


def _private_name(ros_args: list[str]) -> str:
    """The bringup node's name, as ``rospy.init_node("arbotix", argv)`` will resolve it
    (``__name:=``, ``__ns:=`` or ``ROS_NAMESPACE``): its private namespace."""
    import rosgraph.names

    argv = [PROG, *ros_args]
    name = rosgraph.names.load_mappings(argv).get("__name", "arbotix")
    return rosgraph.names.ns_join(rosgraph.names.get_ros_namespace(argv=argv), name)


def _bringup_setup(args: argparse.Namespace, ros_args: list[str]) -> tuple:
    """The robot, its configuration and where it came from, the warnings seen and whether
    ``/use_sim_time`` is set, read from the parameter server without a node (``rosgraph``);
    ``_Refused`` with one line for what the node would refuse."""
    import rosgraph

    from smartcar_gym.controller.config_values import ControllerConfigError
    from smartcar_gym.controller.config_yaml import calibrated_config_path
    from smartcar_gym.model import ModelError, load_model
    from smartcar_gym.ros.bringup import start_robot
    from smartcar_gym.ros.params import controller_config

    try:
        name = _private_name(ros_args)
        with _master(name) as master, warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            params = master.getParam(name) if master.hasParam(name) else {}
            sim_time = bool(master.hasParam("/use_sim_time")
                            and master.getParam("/use_sim_time"))
            config, source = controller_config(params if isinstance(params, dict) else {}, name,
                                               args.controller_config or calibrated_config_path())
            model = load_model(args.model, package_path=args.package_path)
        mode = args.mode or ("sim" if config.kinematic else "hardware")
        if args.speed != 1.0 and not sim_time:
            raise ValueError(f"--speed {args.speed:g} needs /use_sim_time true (set it before "
                             "the nodes start, e.g. <param name=\"/use_sim_time\" value=\"true\"/>"
                             "): without it other nodes stamp and wait in wall-clock time")
        robot = start_robot(model, config, mode, args.engine)
    except (ControllerConfigError, ModelError, OSError, ValueError, ImportError,
            rosgraph.MasterException) as err:
        raise _Refused(" ".join(str(err).split())) from err
    return robot, config, source, model, mode, sim_time, caught


def _run_bringup(ros: Any, args: argparse.Namespace, setup: tuple,
                 stop: threading.Event) -> int:
    from smartcar_gym.ros.bringup import Bringup, BringupOptions
    from smartcar_gym.ros.params import describe

    rospy = ros.rospy
    robot, config, source, model, mode, sim_time, caught = setup
    for warning in caught:
        rospy.logwarn(" ".join(str(warning.message).split()))
    if not rospy.has_param("robot_description"):
        rospy.set_param("robot_description", model.urdf)
        rospy.loginfo(f"set {rospy.resolve_name('robot_description')} from {model.source}")
    rospy.loginfo(f"simulating {model.source.name} on {args.engine} in {mode} mode, "
                  f"{describe(config)} (from "
                  f"{source}); speed {args.speed:g}, "
                  f"{'/use_sim_time: publishing /clock' if sim_time else 'wall-clock time'}")
    try:
        Bringup(ros, robot, BringupOptions(args.speed, sim_time)).run(stop)
    finally:
        robot.sim.close()
    return 0


def _policy(parser: argparse.ArgumentParser, args: argparse.Namespace,
            ros_args: list[str]) -> int:
    from smartcar_gym.agents import require_train_extra
    from smartcar_gym.runtime.onnx_policy import is_onnx_path

    if not is_onnx_path(args.model):  # an exported .onnx runs without torch
        require_train_extra(f"{PROG} policy", POLICY_MODULES)
    from smartcar_gym.agents.policies import Policy, PolicyError
    from smartcar_gym.model import ModelError
    from smartcar_gym.ros.driving import GoalDriver
    from smartcar_gym.ros.policy import PolicyNode

    try:
        ros = _ros_or_fail()  # before the slow part
    except RosUnavailable as err:
        return _fail(str(err))
    try:  # the rules of smartcar-eval, its errors
        policy = Policy.load(args.model or args.pretrained, algo=args.algo,
                             env_id=args.env_id, env_kwargs=dict(args.env_kwargs),
                             normalizer=args.vecnormalize, device=args.device)
    except PolicyError as err:
        parser.error(str(err))
    env_id, env_kwargs = policy.env_id, policy.env_kwargs
    try:
        settings = policy.settings
    except (ModelError, OSError, ValueError) as err:
        parser.error(f"{env_id} with {env_kwargs or 'no env kwargs'}: {err}")
    expected = tuple(getattr(policy.observation_space, "shape", ()))
    observed = settings.observation.space.shape
    if expected != observed:
        parser.error(f"{policy.model_path} expects observations of shape {expected} but "
                     f"{env_id} gives {observed}: the env changed since the model was trained")
    stop = _init_node(ros, "smartcar_policy", ros_args)
    rospy = ros.rospy
    rospy.loginfo(f"policy {policy.model_path} ({policy.algo.upper()}, {env_id}); normaliser: "
                  f"{policy.normalizer_source}")
    if policy.warning:
        rospy.logwarn(policy.warning)
    driver = GoalDriver(settings, policy.act, args.stale_after, args.stop_on)
    try:
        node = PolicyNode(ros, driver)
        node.announce_listening(stop)
        node.spin(stop)
    finally:
        rospy.signal_shutdown("smartcar-ros policy ended")
    return 0


if __name__ == "__main__":
    sys.exit(main())
