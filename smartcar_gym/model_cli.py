"""``smartcar-model``: expand, check and picture robot descriptions (ROS not needed).

    smartcar-model urdf  [PATH] [--package-path DIR ...] [--arg NAME:=VALUE ...] [-o FILE]
    smartcar-model check [PATH] [--strict]
    smartcar-model show  [PATH] -o FILE.png [--width W --height H] [--settle SECONDS]

PATH defaults to the shipped smartcar.

exit status (every command):
  0  OK
  1  check: the model loaded, but has errors that were not repaired, which make it
     non-physical (mass <= 0, impossible inertia) and which load_model and the env refuse
     (with --strict: any defect)
  2  the model could not be loaded or the command could not run (usage error, missing file,
     invalid description, pybullet failure); the reason is printed as one line on stderr
"""

from __future__ import annotations

import argparse
import sys
import warnings
from collections.abc import Sequence
from pathlib import Path

from smartcar_gym.model.defects import fmt
from smartcar_gym.model.errors import ModelDefectWarning, ModelError
from smartcar_gym.model.loader import RobotModel, inspect_model
from smartcar_gym.model.urdf import Shape

PROG = "smartcar-model"
EXIT_STATUS = __doc__[__doc__.index("exit status"):].rstrip()


def _mapping(text: str) -> tuple[str, str]:
    name, sep, value = text.partition(":=")
    if not sep or not name:
        raise argparse.ArgumentTypeError(f"expected NAME:=VALUE, got '{text}'")
    return name, value


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of ``smartcar-model``."""
    parser = argparse.ArgumentParser(prog=PROG, description=__doc__.split("\n\n")[0],
                                     epilog=EXIT_STATUS,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    common = argparse.ArgumentParser(add_help=False)
    common.add_argument("path", nargs="?", help="URDF or xacro file (default: shipped smartcar)")
    common.add_argument("--package-path", action="append", default=[], metavar="DIR",
                        help="folder searched first for $(find pkg) (repeatable)")
    common.add_argument("--arg", action="append", default=[], type=_mapping,
                        metavar="NAME:=VALUE", help="xacro argument (repeatable)")
    common.add_argument("--no-repair", action="store_true",
                        help="keep duplicated origins and implausible inertias as they are")
    common.add_argument("--no-legacy", action="store_true",
                        help="do not upgrade ROS-indigo (unprefixed) xacro tags")
    commands = parser.add_subparsers(dest="command", required=True)
    urdf = commands.add_parser("urdf", parents=[common], help="print the expanded URDF")
    urdf.add_argument("-o", "--output", type=Path, help="write to FILE instead of stdout")
    check = commands.add_parser("check", parents=[common], help="report links, wheels, defects")
    check.add_argument("--strict", action="store_true", help="fail (exit 1) on any defect")
    show = commands.add_parser("show", parents=[common], help="render a PNG (headless)")
    show.add_argument("-o", "--output", type=Path, required=True, help="PNG file to write")
    show.add_argument("--width", type=int, default=640)
    show.add_argument("--height", type=int, default=480)
    show.add_argument("--settle", type=float, default=0.0, metavar="SECONDS",
                      help="simulate this long under gravity before the picture")
    return parser


def _load(args: argparse.Namespace) -> tuple[RobotModel, list[warnings.WarningMessage]]:
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        model = inspect_model(args.path, package_path=args.package_path,
                              mappings=dict(args.arg), repair=not args.no_repair,
                              legacy=not args.no_legacy)
    return model, caught


def _warn(caught: list[warnings.WarningMessage]) -> None:
    for item in caught:
        print(f"{PROG}: warning: {item.message}", file=sys.stderr)


def _shape(shapes: tuple[Shape, ...]) -> str:
    if not shapes:
        return "-"
    parts = []
    for shape in shapes:
        text = f"{shape.geometry.type} {'x'.join(f'{v:g}' for v in shape.geometry.size)}"
        if any(shape.origin.xyz) or any(shape.origin.rpy):
            text += f" @ {fmt(shape.origin.xyz)}"
        parts.append(text)
    return "; ".join(parts)


def table(header: Sequence[str], rows: Sequence[Sequence[str]]) -> list[str]:
    """Rows as left-aligned text columns under ``header``, indented by two spaces."""
    widths = [max(len(str(r[i])) for r in [header, *rows]) for i in range(len(header))]
    return ["  " + "  ".join(str(c).ljust(w) for c, w in zip(r, widths, strict=True)).rstrip()
            for r in [header, *rows]]


def report(model: RobotModel, caught: list[warnings.WarningMessage]) -> list[str]:
    """Lines of the ``check`` report."""
    lines = [f"model   {model.name}  ({model.source})",
             f"root    {model.base_link}; {len(model.links)} links, {len(model.joints)} joints",
             "", "packages"]
    lines += [f"  {name} -> {folder}" for name, folder in model.packages.items()] or ["  none"]
    lines += ["", "links" + (" (after repairs)" if model.repairs else "")]
    lines += table(["name", "mass kg", "inertia diag kg m^2", "collision", "visual"], [
        [link.name, f"{link.mass:g}",
         "-" if link.inertial is None else fmt([link.inertial.inertia[i][i] for i in range(3)]),
         _shape(link.collisions), _shape(link.visuals)]
        for link in model.links.values()])
    lines += ["", "joints"]
    lines += table(["name", "type", "parent -> child", "xyz", "rpy", "axis"], [
        [j.name, j.type, f"{j.parent} -> {j.child}", fmt(j.origin.xyz), fmt(j.origin.rpy),
         fmt(j.axis)] for j in model.joints.values()])
    lines += ["", "wheels"]
    lines += table(["joint", "side", "radius m", "position m", "forward sign"], [
        [w.joint, w.side, f"{w.radius_m:g}", fmt(w.position_m), f"{w.forward_sign:+d}"]
        for w in model.wheels])
    lines.append(f"  wheel radius {model.wheel_radius_m:g} m, track width "
                 f"{model.track_width_m:g} m")
    notes = [str(w.message) for w in caught if not issubclass(w.category, ModelDefectWarning)]
    if notes:
        lines += ["", "notes"] + [f"  {n}" for n in notes]
    lines += ["", f"defects ({len(model.defects)})"]
    lines += [f"  {d}" for d in model.defects] or ["  none"]
    lines += ["", f"repairs ({len(model.repairs)})"]
    lines += [f"  {r.element}: {r.message}" for r in model.repairs] or ["  none"]
    return lines


def _check(args: argparse.Namespace) -> int:
    model, caught = _load(args)
    lines = report(model, caught)
    errors = len(model.errors)  # unrepaired: what load_model (and so the env) refuses
    fixed = sum(d.severity == "error" for d in model.defects) - errors
    failed = errors > 0 or (args.strict and model.defects)
    verdict = "FAILED" if failed else "OK"
    lines += ["", f"result: {verdict} ({errors} errors, "
                  f"{len(model.defects) - errors - fixed} warnings, {len(model.repairs)} repairs"
                  f"{f', {fixed} errors repaired' if fixed else ''}"
                  f"{', strict' if args.strict else ''})"]
    print("\n".join(lines))
    return 1 if failed else 0


def _urdf(args: argparse.Namespace) -> int:
    model, caught = _load(args)
    _warn(caught)
    if args.output is None:
        sys.stdout.write(model.urdf)
    else:
        args.output.parent.mkdir(parents=True, exist_ok=True)
        args.output.write_text(model.urdf, encoding="utf-8")
    return 0


def _show(args: argparse.Namespace) -> int:
    from smartcar_gym.sim.pybullet.snapshot import write_png  # pybullet only when rendering

    if args.width < 1 or args.height < 1:
        raise ValueError(f"--width/--height must be positive, got {args.width}x{args.height}")
    model, caught = _load(args)
    _warn(caught)
    write_png(model, args.output, width=args.width, height=args.height, settle_s=args.settle)
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    """Run ``smartcar-model``; returns the exit status (see ``EXIT_STATUS``)."""
    args = build_parser().parse_args(argv)
    try:
        return {"urdf": _urdf, "check": _check, "show": _show}[args.command](args)
    except (ModelError, OSError, ValueError) as exc:
        message = " ".join(str(exc).split())
    except Exception as exc:  # never a traceback for users
        message = f"{type(exc).__name__}: {' '.join(str(exc).split())}"
    print(f"{PROG}: error: {message}", file=sys.stderr)
    return 2


if __name__ == "__main__":
    sys.exit(main())
