"""``smartcar-calibrate --fit planar``: identify the planar engine from an engine or a bag.

    smartcar-calibrate --fit planar --engine pybullet -o planar_pybullet.yaml
    smartcar-calibrate --fit planar --bag robot.bag --truth-topic /mocap/pose -o mine.yaml

The first drives the robot on a physics engine through the fit's own maneuvers
(``recording.fit_maneuvers``), with ``--wheel-contact`` and ``--max-substep-s`` as the env's;
the second (where those two and ``--engine`` do not apply: refused) reads a ROS 1 or ROS 2 bag's
``cmd_vel``, ``odom`` and ground truth (``bag_source``). Either way the drives are replayed on
the planar engine and its free parameters fitted (``planar_fit``); the residual of each
maneuver is printed before (the starting parameters) and after, and ``--output`` writes the
parameter file that ``gym.make(..., engine="planar", planar_params=FILE)`` reads.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path
from typing import Any

from smartcar_gym.calibration.planar_fit import FitError, FitResult, describe, fit
from smartcar_gym.calibration.recording import Recording, record
from smartcar_gym.controller import ArbotixConfig
from smartcar_gym.model import ModelError, RobotModel
from smartcar_gym.sim.engines import get_engine
from smartcar_gym.sim.planar.params import KEYS, PlanarParams, PlanarParamsError, dump, resolve

PROG = "smartcar-calibrate"
#: the env keyword that carries the parameters this fit identifies
PARAMS_KEYWORD = "planar_params"
TOPIC_DEFAULTS = {"--truth-topic": "/base_pose_ground_truth", "--cmd-topic": "/cmd_vel",
                  "--odom-topic": "/odom"}


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The options of ``--fit planar``."""
    group = parser.add_argument_group("--fit planar (the planar engine's parameters)")
    group.add_argument("--bag", type=Path, metavar="FILE",
                       help="fit to a recorded ROS 1 (.bag, .mcap) or ROS 2 bag instead of "
                            "the drives on --engine")
    group.add_argument("--truth-topic", default=TOPIC_DEFAULTS["--truth-topic"],
                       metavar="TOPIC",
                       help="the bag's ground truth: nav_msgs/Odometry, or a motion-capture "
                            "geometry_msgs/PoseStamped (default: %(default)s)")
    group.add_argument("--cmd-topic", default=TOPIC_DEFAULTS["--cmd-topic"], metavar="TOPIC")
    group.add_argument("--odom-topic", default=TOPIC_DEFAULTS["--odom-topic"], metavar="TOPIC")
    group.add_argument("--keep", default="", metavar="KEYS",
                       help="parameters not to fit, kept at their start values "
                            f"(comma-separated: {', '.join(KEYS)})")
    group.add_argument("--start", metavar="FILE",
                       help="start (and kept) values: a parameter file or a shipped fit name "
                            "(default: the built-in defaults)")
    group.add_argument("--generations", type=_positive_int, default=40,
                       help="differential evolution generations at most (default: %(default)s)")


def _positive_int(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        value = 0
    if value < 1:
        raise argparse.ArgumentTypeError(f"expected a positive integer, got {text!r}")
    return value


#: the options that shape the drives on --engine, and so do not apply to a --bag's
DRIVE_OPTIONS = (("engine", "--engine"), ("wheel_contact", "--wheel-contact"),
                 ("max_substep_s", "--max-substep-s"))


def bag_conflict(args: argparse.Namespace, parser: argparse.ArgumentParser) -> str | None:
    """Why the options cannot go with ``--bag`` (None if they can): an option of the drives on
    ``--engine`` set to other than its default (the bag's drives are the robot's own)."""
    if args.bag is None:
        return None
    for key, flag in DRIVE_OPTIONS:
        if getattr(args, key) != parser.get_default(key):
            return (f"{flag} {getattr(args, key)} does not apply with --bag: the fit replays "
                    "the bag's drives, recorded on the robot")
    return None


def recordings_of(args: argparse.Namespace, model: RobotModel,
                  config: ArbotixConfig) -> tuple[list[Recording], str]:
    """The drives to fit to, and where they came from (for the report)."""
    if args.bag is not None:
        from smartcar_gym.calibration.bag_source import read_recordings

        for flag in ("--truth-topic", "--cmd-topic", "--odom-topic"):
            topic = getattr(args, flag[2:].replace("-", "_"))
            if not topic.strip():
                raise FitError(f"{flag} {topic!r}: expected a topic name, e.g. "
                               f"{TOPIC_DEFAULTS[flag]}")

        recordings = read_recordings(args.bag, truth_topic=args.truth_topic,
                                     cmd_topic=args.cmd_topic, odom_topic=args.odom_topic,
                                     rate_hz=config.rate_hz)
        return recordings, f"{args.bag} ({len(recordings)} episodes)"
    # an engine that takes the fitted parameters runs the planar model itself
    fitted = PARAMS_KEYWORD in get_engine(args.engine).kwargs
    if fitted and args.start is None:
        raise FitError(f"--engine {args.engine}: fitting the planar engine to itself needs "
                       "--start (the parameters to recover)")
    options = {PARAMS_KEYWORD: resolve(args.start)} if fitted else {}
    recordings = record(model, config, args.engine, wheel_contact=args.wheel_contact,
                        max_substep_s=args.max_substep_s, **options)
    return recordings, f"the fit's drives on {args.engine}"


def run(args: argparse.Namespace, parser: argparse.ArgumentParser, model: RobotModel,
        config: ArbotixConfig) -> int:
    """The ``--fit planar`` path of ``smartcar-calibrate``; returns the exit code."""
    conflict = bag_conflict(args, parser)
    if conflict:
        parser.error(f"planar fit failed: {conflict}")
    keep = [k.strip() for k in args.keep.split(",") if k.strip()]
    unknown = [k for k in keep if k not in KEYS]
    if unknown:
        parser.error(f"planar fit failed: --keep {unknown[0]}: not a planar parameter; the "
                     f"parameters are {', '.join(KEYS)}")
    started = time.perf_counter()
    try:
        start = PlanarParams() if args.start is None else resolve(args.start)
        recordings, source = recordings_of(args, model, config)
        result = fit(model, config, recordings, start=start, keep=keep,
                     generations=args.generations, seed=args.seed)
    except (FitError, PlanarParamsError, ModelError, ImportError, OSError, ValueError) as err:
        parser.error(f"planar fit failed: {str(err).replace(chr(10), ' ')}")
    seconds = time.perf_counter() - started
    print(report(result, source, model, seconds))
    provenance = {"source": source, "model": Path(model.source).name,
                  "controller": Path(config.source).name,
                  "seconds": round(seconds, 1), **describe(result)}
    if args.output is not None:
        try:
            args.output.write_text(dump(result.params, provenance), encoding="utf-8")
        except OSError as err:
            parser.error(f"--output: cannot write {args.output}: {err.strerror or err}")
        print(f"wrote {args.output}: gym.make(..., engine='planar', "
              f"planar_params='{args.output}')")
    if args.json is not None:
        args.json.write_text(json.dumps(figures(result, provenance), indent=2) + "\n")
    return 0


def report(result: FitResult, source: str, model: RobotModel, seconds: float) -> str:
    """The printed report: parameters, and the RMS scaled residual per maneuver."""
    lines = [f"{PROG} --fit planar: {model.name} from {source}; {result.evaluations} "
             f"candidates in {seconds:.0f} s", ""]
    for key in KEYS:
        marker = "" if key in result.free else "  (kept)"
        lines.append(f"  {key:<26}{getattr(result.params, key):.5g}{marker}")
    lines += ["", f"  {'residual (RMS, scaled)':<36}{'before':>9}{'after':>9}"]
    for name, after in result.after.items():
        lines.append(f"  {name:<36}{result.before[name]:>9.3f}{after:>9.3f}")
    lines.append(f"  {'all':<36}{'':>9}{result.rms:>9.3f}")
    return "\n".join(lines)


def figures(result: FitResult, provenance: dict[str, Any]) -> dict[str, Any]:
    return {"params": {k: getattr(result.params, k) for k in KEYS}, **provenance}
