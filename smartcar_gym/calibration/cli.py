"""``smartcar-calibrate``: UMBmark-style odometry calibration of an arbotix YAML, in pybullet.

    smartcar-calibrate                                   # the shipped car and YAML
    smartcar-calibrate --controller-config my.yaml --output my_calibrated.yaml
    smartcar-calibrate --model robot.urdf.xacro --package-path ~/ws/src --fit umbmark
    smartcar-calibrate --randomize "{track: 1.1, left_encoder_scale: 1.05}"
    smartcar-calibrate --fit planar --engine mujoco -o planar_mujoco.yaml
    smartcar-calibrate --fit planar --bag robot.bag --truth-topic /mocap/pose -o mine.yaml

Drives the car in the simulator, steered by its own odometry: 2 m straight, two revolutions in
place each way, and Borenstein's UMBmark square (1 m) clockwise and counter-clockwise. Compares
where odometry says each run ended with the ground truth, fits the effective ``base_width``
and a ``ticks_meter`` correction, drives again with them, and prints the odometry errors
before and after. ``--output`` writes the YAML with the two values replaced (layout and
comments kept). ``--fit planar`` instead identifies the planar engine's free parameters from
the drives on ``--engine`` or from a ``--bag`` and writes its parameter file
(``calibration/planar_cli.py``). ``--randomize`` makes the simulated car differ from what the
YAML claims (the env's ``randomize`` factors, drawn once with ``--seed``): in the simulator the
encoders otherwise count exactly the YAML's ticks_meter.

exit status: 0 done; 2 bad input (model, YAML, options) or a car that cannot do the drives,
with one line on stderr.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from collections.abc import Sequence
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from smartcar_gym.agents.cli_args import non_negative_int_arg
from smartcar_gym.calibration import planar_cli
from smartcar_gym.calibration.drives import DriveError, Plan
from smartcar_gym.calibration.estimate import CalibrationError, RunError, umbmark_error
from smartcar_gym.calibration.procedure import FIT_HELP, FITS, Calibration, calibrate
from smartcar_gym.calibration.yaml_edit import calibrated_text, format_values
from smartcar_gym.controller import ControllerConfigError, load_controller_config
from smartcar_gym.controller.config_yaml import read_config_file
from smartcar_gym.envs.randomization import FACTORS, Randomization
from smartcar_gym.model import ModelError, load_model
from smartcar_gym.model.contact import WHEEL_CONTACTS
from smartcar_gym.sim.clock import check_max_substep
from smartcar_gym.sim.engines import DEFAULT_ENGINE, add_engine_argument

PROG = "smartcar-calibrate"


def _positive(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not (math.isfinite(value) and value > 0):
        raise argparse.ArgumentTypeError(f"expected a positive number, got {text!r}")
    return value


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of ``smartcar-calibrate``."""
    doc = __doc__
    parser = argparse.ArgumentParser(
        prog=PROG, description=doc[doc.index("Drives the car"):doc.index("exit status")].strip(),
        epilog=doc[doc.index("exit status"):].strip(),
        formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--model", type=Path, help=".urdf or .xacro robot description "
                        "(default: the shipped smartcar)")
    parser.add_argument("--package-path", action="append", default=[], metavar="DIR",
                        help="folder searched first for $(find pkg) (repeatable)")
    parser.add_argument("--wheels", metavar="YAML", help="drive wheels, e.g. \"{left: "
                        "[lw_joint], right: [rw_joint]}\" (default: found from the model)")
    parser.add_argument("--controller-config", type=Path, metavar="YAML",
                        help="arbotix YAML to calibrate (default: the shipped one)")
    parser.add_argument("--wheel-contact", choices=WHEEL_CONTACTS, default="sphere")
    parser.add_argument("--max-substep-s", type=float, default=0.01,
                        help="longest physics substep (s), as the env's max_substep_s")
    add_engine_argument(parser, default=DEFAULT_ENGINE, what="the calibration drives'")
    parser.add_argument("--randomize", metavar="SPEC", help="how the simulated car differs "
                        "from the YAML: a preset (default), a YAML file or a mapping such as "
                        "\"{track: 1.1}\"; drawn once")
    parser.add_argument("--seed", type=non_negative_int_arg, default=0,
                        help="seed of the --randomize draw (an integer >= 0)")
    parser.add_argument("--fit", choices=(*FITS, "planar"), default="spin",
                        help="; ".join(f"{k}: {v}" for k, v in FIT_HELP.items())
                        + "; planar: the planar engine's tyre, rolling and dead-band "
                          "parameters, from --engine's drives or a --bag (docs/planar.md)")
    parser.add_argument("--speed", type=_positive, default=0.2, help="m/s on straight legs")
    parser.add_argument("--turn-rate", type=_positive, default=1.0, help="rad/s in turns")
    parser.add_argument("--side", type=_positive, default=1.0, help="UMBmark square side (m)")
    parser.add_argument("--output", "-o", type=Path, metavar="FILE",
                        help="write the calibrated YAML (--fit planar: the parameter file) here")
    parser.add_argument("--json", type=Path, metavar="FILE", help="write the figures as JSON")
    planar_cli.add_arguments(parser)
    return parser


def _randomize_spec(text: str | None) -> Any:
    """A ``--randomize`` argument: a preset or file name as given, else a YAML mapping."""
    if text is None or text in ("default",) or Path(text).exists():
        return text
    try:
        return yaml.safe_load(text)
    except yaml.YAMLError:
        return text  # from_spec names it


def _check_output(path: Path | None, option: str) -> str | None:
    if path is None:
        return None
    if path.is_dir():
        return f"{option}: {path} is a folder; expected a file name"
    if not path.parent.is_dir():
        return f"{option}: the folder {path.parent} does not exist"
    return None


def _planar_flags_given(argv: Sequence[str] | None) -> list[str]:
    """The ``--fit planar`` options on the command line, default values given included."""
    group = argparse.ArgumentParser(add_help=False)
    planar_cli.add_arguments(group)
    dests = list(vars(group.parse_args([])))
    probe = build_parser()
    unset = object()
    probe.set_defaults(**dict.fromkeys(dests, unset))
    given = vars(probe.parse_args(argv))
    return ["--" + dest.replace("_", "-") for dest in dests if given[dest] is not unset]


def main(argv: Sequence[str] | None = None) -> int:
    """``smartcar-calibrate``; returns the exit code."""
    parser = build_parser()
    args = parser.parse_args(argv)
    planar_flags = _planar_flags_given(argv) if args.fit != "planar" else []
    if planar_flags:
        parser.error(f"{', '.join(planar_flags)}: only with --fit planar (the planar engine's "
                     "parameters); the other fits ignore them")
    for problem in (_check_output(args.output, "--output"), _check_output(args.json, "--json")):
        if problem:
            parser.error(problem)
    try:
        check_max_substep(args.max_substep_s, "--max-substep-s")
        wheels = yaml.safe_load(args.wheels) if args.wheels is not None else None
        model = load_model(args.model, package_path=args.package_path or None, wheels=wheels)
        config = load_controller_config(args.controller_config)
        text, _ = read_config_file(args.controller_config)
        spec = Randomization.from_spec(_randomize_spec(args.randomize))
    except (ModelError, ControllerConfigError, OSError, ValueError, TypeError,
            yaml.YAMLError) as err:
        parser.error(str(err).replace("\n", " "))
    if args.fit == "planar":
        if spec is not None:
            parser.error("--fit planar fits to the engine's car as it is; --randomize does "
                         "not apply")
        return planar_cli.run(args, parser, model, config)
    draw = spec.draw(np.random.default_rng(args.seed)) if spec is not None else None
    plan = Plan(speed_m_s=args.speed, turn_rate_rad_s=args.turn_rate, square_side_m=args.side)
    try:
        result = calibrate(
            model, config, plan, args.fit,
            variation=None if draw is None else draw.variation,
            ground_friction=1.0 if draw is None else draw.values["ground_friction"],
            wheel_contact=args.wheel_contact, max_substep_s=args.max_substep_s,
            engine=args.engine)
    except (DriveError, CalibrationError, ModelError, ImportError) as err:
        parser.error(f"calibration failed: {err}")
    report = _report(result, args, draw)
    print(report)
    if args.output is not None:
        note = _note(result)
        try:
            args.output.write_text(calibrated_text(text, config, result.base_width_m,
                                                   result.ticks_meter, note), encoding="utf-8")
        except (OSError, ValueError) as err:
            parser.error(f"--output: cannot write {args.output}: {err}")
        width, ticks = format_values(result.base_width_m, result.ticks_meter)
        print(f"wrote {args.output} (base_width: {width}, ticks_meter: {ticks})")
    if args.json is not None:
        args.json.write_text(json.dumps(_figures(result, draw), indent=2) + "\n")
    return 0


def _note(result: Calibration) -> str:
    c = result.config
    width, ticks = format_values(result.base_width_m, result.ticks_meter)
    when = datetime.now(timezone.utc).strftime("%Y-%m-%d")
    return (f"Calibrated by smartcar-calibrate (fit: {result.fit}) on {when}, from {c.source}:\n"
            f"  base_width {c.base_width_m:g} -> {width} (effective track), ticks_meter "
            f"{c.ticks_meter:g} -> {ticks}.\n"
            f"  UMBmark E_max,syst {umbmark_error(result.before):.3f} m -> "
            f"{umbmark_error(result.after):.3f} m in the simulator.")


def _rows(result: Calibration, plan: Plan) -> list[tuple[str, str, str]]:
    rows = []
    for before, after in zip(result.before, result.after, strict=True):
        b, a = RunError.of(before), RunError.of(after)
        if before.name == "straight":
            rows.append((f"straight {plan.straight_m:g} m: distance", f"{b.relative:+.2%}",
                         f"{a.relative:+.2%}"))
        elif before.name.startswith("spin"):
            rows.append((f"{before.name} {plan.spin_revolutions:g} rev: turn",
                         f"{b.relative:+.2%}", f"{a.relative:+.2%}"))
        else:
            rows.append((f"{before.name} {plan.square_side_m:g} m: end position",
                         f"{b.position_m:.3f} m", f"{a.position_m:.3f} m"))
    rows.append(("UMBmark E_max,syst", f"{umbmark_error(result.before):.3f} m",
                 f"{umbmark_error(result.after):.3f} m"))
    return rows


def _report(result: Calibration, args: argparse.Namespace, draw: Any) -> str:
    c, e = result.config, result.estimate
    plan = Plan(args.speed, args.turn_rate, square_side_m=args.side)
    varied = ("nominal (the encoders count the YAML's ticks_meter)" if draw is None else
              ", ".join(f"{f.name} {draw.values[f.name]:.4g}" for f in FACTORS
                        if draw.values[f.name] != f.nominal and not f.name.startswith("start"))
              or "nominal")
    width, ticks = format_values(result.base_width_m, result.ticks_meter)
    lines = [
        f"{PROG}: {c.source} on {args.model or 'the shipped smartcar'} "
        f"({args.wheel_contact} wheel contact); plant: {varied}",
        f"runs: straight {plan.straight_m:g} m at {plan.speed_m_s:g} m/s, spins "
        f"{plan.spin_revolutions:g} rev at {plan.turn_rate_rad_s:g} rad/s, UMBmark squares "
        f"{plan.square_side_m:g} m cw and ccw; fit: {result.fit} ({FIT_HELP[result.fit]})",
        "",
        f"  base_width (effective track)   {c.base_width_m:g} m -> {width} m",
        f"  ticks_meter                    {c.ticks_meter:g} -> {ticks} (true travel per "
        f"counted metre: {e.scale:.4f})",
        f"  wheel diameter ratio E_d       {e.diameter_ratio:.4f} (right / left; the driver has "
        "one ticks_meter, not corrected)",
        f"  fit residual (rms)             {e.rms_m * 1000:.1f} mm",
        "",
        f"  {'odometry error':<34}{'before':>12}{'after':>12}",
    ]
    lines += [f"  {name:<34}{b:>12}{a:>12}" for name, b, a in _rows(result, plan)]
    return "\n".join(lines)


def _figures(result: Calibration, draw: Any) -> dict[str, Any]:
    e = result.estimate
    return {
        "config": result.config.source, "fit": result.fit,
        "plant": None if draw is None else draw.info,
        "base_width_m": {"before": result.config.base_width_m, "after": result.base_width_m},
        "ticks_meter": {"before": result.config.ticks_meter, "after": result.ticks_meter},
        "scale": e.scale, "diameter_ratio": e.diameter_ratio, "rms_m": e.rms_m,
        "runs": {
            when: [{"name": r.name, "true_end": list(r.true_end), "odom_end": list(r.odom_end),
                    **{k: v for k, v in vars(RunError.of(r)).items() if k != "name"}}
                   for r in runs]
            for when, runs in (("before", result.before), ("after", result.after))
        },
        "umbmark_e_max_syst_m": {"before": umbmark_error(result.before),
                                 "after": umbmark_error(result.after)},
    }


if __name__ == "__main__":
    sys.exit(main())
