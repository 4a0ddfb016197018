"""``smartcar-export``: a trained policy as an ONNX file that runs without torch.

::

    smartcar-export --model runs/ppo_SmartCar-v0_s0/best_model.zip -o policy.onnx
    smartcar-export --pretrained nav -o nav.onnx

The model and its normaliser are found as ``smartcar-eval`` finds them
(``smartcar_gym.policy.Policy.load``: a pickle is loaded only when named or assigned by the
model's place). The graph (``onnx_graph``) has the normalisation and the action clipping in
it; the metadata (``runtime.metadata``) goes into the file and beside it as ``<name>.json``.
Both are written to temporary files beside ``-o``; the ONNX one is loaded back as
``Policy.load`` loads it and its actions checked against the SB3 model's on ``CHECKED``
observations drawn in the observation space (``--check`` more or fewer; a difference over
``TOLERANCE`` is an error), and only then moved over ``-o`` and its ``.json``. Bad input
(an env the model cannot act in, an env id or kwargs a policy file may not name:
``registration.check_policy_env``): one line, exit code 2, and the old files left as they
were.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Sequence
from importlib import metadata as package_metadata
from pathlib import Path
from typing import Any

import numpy as np

from smartcar_gym.agents.models import PRETRAINED_POLICIES

__all__ = ["CHECKED", "TOLERANCE", "build_parser", "export_onnx", "main"]

PROG = "smartcar-export"
CHECKED = 1000
TOLERANCE = 1e-5
ONNX_EXTRA = 'pip install "smartcar-gym[onnx]"'


def build_parser() -> argparse.ArgumentParser:
    """The ``smartcar-export`` argument parser."""
    from smartcar_gym.agents.cli_args import key_value_arg
    from smartcar_gym.agents.hyperparams import ALGOS

    parser = argparse.ArgumentParser(
        prog=PROG, description="Write a trained policy as an ONNX model with its observation "
        "normalisation and action clipping inside, plus <name>.json (env id, env kwargs, "
        "engine, observation names, versions); Policy.load and smartcar-ros policy run it "
        "without torch.",
        epilog="SB3 model zips and VecNormalize files are pickles: loading one runs the code it "
               "holds, so export only files from a source you trust.")
    source = parser.add_mutually_exclusive_group(required=True)
    source.add_argument("--model", type=Path, help="a model .zip or a run folder of "
                        "smartcar-train or rl-baselines3-zoo (as smartcar-eval --model)")
    source.add_argument("--pretrained", nargs="?", const="default", metavar="NAME",
                        choices=tuple(PRETRAINED_POLICIES), help="a shipped policy: "
                        f"{', '.join(PRETRAINED_POLICIES)} (default alone)")
    parser.add_argument("-o", "--output", type=Path, required=True, metavar="FILE.onnx")
    parser.add_argument("--algo", choices=ALGOS, help="algorithm of --model (default: its run's)")
    parser.add_argument("--vecnormalize", type=Path, metavar="FILE", help="VecNormalize "
                        "statistics (a pickle; default: those the model's place assigns)")
    parser.add_argument("--env", dest="env_id", help="env id written in the metadata "
                        "(default: the run's)")
    parser.add_argument("--env-kwargs", nargs="+", default=[], metavar="KEY=VALUE",
                        type=key_value_arg, help="added to the run's env kwargs")
    parser.add_argument("--check", type=_count_arg, default=CHECKED, metavar="N",
                        help=f"observations to compare the export with the SB3 model on "
                             f"(default {CHECKED}; 0: none)")
    return parser


def _count_arg(text: str) -> int:
    """argparse type for a count >= 0."""
    try:
        value = int(text)
    except ValueError:
        value = -1
    if value < 0:
        raise argparse.ArgumentTypeError(f"expected a whole number >= 0, got {text!r}")
    return value


def main(argv: Sequence[str] | None = None) -> int:
    """``smartcar-export``: 0 when written, 2 for bad input."""
    from smartcar_gym.agents import require_train_extra
    from smartcar_gym.extras import missing_modules

    parser = build_parser()
    args = parser.parse_args(argv)
    require_train_extra(PROG, ("stable_baselines3", "torch"))
    if missing_modules(("onnx",)):
        parser.error(f"onnx not installed; {PROG} needs the onnx extra: {ONNX_EXTRA}")
    if args.output.suffix.lower() != ".onnx":
        parser.error(f"-o: the file must end in .onnx, got {str(args.output)!r}")
    from smartcar_gym.agents.atomic_files import output_path_error
    from smartcar_gym.agents.policies import Policy, PolicyError
    from smartcar_gym.export.onnx_graph import ExportError

    for path in (args.output, _side(args.output)):
        problem = output_path_error(path)
        if problem:
            parser.error(f"-o: {problem}")

    try:
        policy = Policy.load(args.model or args.pretrained, algo=args.algo, env_id=args.env_id,
                             env_kwargs=dict(args.env_kwargs), normalizer=args.vecnormalize)
    except PolicyError as err:
        parser.error(str(err))
    if policy.warning:
        print(f"{PROG}: warning: {policy.warning}", file=sys.stderr)
    source = f"pretrained:{args.pretrained}" if args.pretrained else str(args.model)
    try:
        meta, worst = export_onnx(policy, args.output, source, check=args.check)
    except ExportError as err:
        parser.error(str(err))
    checked = "" if worst is None else f"; max |action - SB3's| {worst:.1e} on {args.check} obs"
    print(f"{PROG}: wrote {args.output} and {_side(args.output)} ({meta['algo'].upper()} on "
          f"{meta['env_id']}, engine {meta['engine']}, normaliser: {meta['normalizer']}"
          f"{checked})")
    return 0


def _side(path: Path) -> Path:
    from smartcar_gym.runtime.metadata import side_file

    return side_file(path)


def export_metadata(policy: Any, source: str) -> dict[str, Any]:
    """What the exported file says of ``policy`` (``runtime.metadata``). ``ExportError`` with
    one line for an env that a policy file may not name (``registration.check_policy_env``),
    one that cannot be made, or one whose observations are not the model's."""
    from smartcar_gym.agents.env_factory import (
        EnvSetupError,
        cannot_make,
        check_env_id,
        given_kwargs,
    )
    from smartcar_gym.registration import PolicyEnvError, check_policy_env
    from smartcar_gym.runtime.metadata import FORMAT
    from smartcar_gym.sim.engines import DEFAULT_ENGINE

    from .onnx_graph import INPUT, OUTPUT, ExportError

    try:
        env_id, env_kwargs = check_policy_env("--env-kwargs", policy.env_id,
                                              policy.env_kwargs)
        json.dumps(env_kwargs, allow_nan=False)
    except PolicyEnvError as err:
        raise ExportError(str(err)) from None
    except (TypeError, ValueError) as err:
        raise ExportError(f"--env-kwargs: {env_kwargs} cannot be written as JSON: "
                          f"{err}") from None
    try:
        check_env_id(env_id)
        env = policy.make_env()
    except EnvSetupError as err:
        raise ExportError(str(err)) from None
    except Exception as err:  # the env's own refusal of a value: one line naming it
        raise ExportError(cannot_make(env_id, env_kwargs, err)) from None
    try:
        names = list(getattr(env.unwrapped, "observation_names", ()))
        observed = tuple(getattr(env.observation_space, "shape", None) or ())
    finally:
        env.close()
    expected = tuple(policy.model.observation_space.shape)
    if observed != expected or len(names) != int(np.prod(expected)):
        raise ExportError(f"the model takes observations of shape {expected} but {env_id} "
                          f"with {given_kwargs(env_kwargs)} gives {observed} ({len(names)} "
                          "named); export it with the env it was trained on (--env, "
                          "--env-kwargs)")
    space = policy.model.action_space
    return {
        "format": FORMAT, "algo": policy.algo, "env_id": env_id,
        "env_kwargs": env_kwargs,
        "engine": env_kwargs.get("engine") or DEFAULT_ENGINE,
        "observation_names": names,
        "observation_shape": list(expected),
        "action_shape": list(space.shape), "action_low": np.asarray(space.low).tolist(),
        "action_high": np.asarray(space.high).tolist(), "input": INPUT, "output": OUTPUT,
        "source": source, "normalizer": str(policy.normalizer_source),
        "versions": {name: _version(name) for name in ("smartcar-gym", "stable-baselines3",
                                                        "torch", "onnx", "gymnasium")},
    }


def _version(name: str) -> str | None:
    try:
        return package_metadata.version(name)
    except package_metadata.PackageNotFoundError:
        return None


def export_onnx(policy: Any, out: str | Path, source: str,
                check: int = 0) -> tuple[dict[str, Any], float | None]:
    """Write ``policy`` (a loaded ``Policy`` of an SB3 model) as ONNX to ``out`` and its
    metadata beside it; returns the metadata and the largest difference from the SB3 model's
    actions on ``check`` observations (None for 0). Both files are written to temporary files
    in ``out``'s folder, the ONNX one loaded back as ``Policy.load`` would load it and
    compared, and only then moved over ``out`` and its ``.json``: on any failure what was at
    those paths is left as it was. ``ExportError`` (one line) for a model or env it cannot
    take, a file that would not load, actions that differ by more than ``TOLERANCE``, or a
    file that cannot be written."""
    from smartcar_gym.agents.atomic_files import atomic_path
    from smartcar_gym.runtime.onnx_policy import OnnxPolicyError, load_onnx

    from .checks import check_actions
    from .onnx_graph import ExportError, policy_graph

    out = Path(out)
    meta = export_metadata(policy, source)
    stats = None if policy.normalizer is None else policy.normalizer.vec_normalize
    data = policy_graph(policy.model, stats, meta).SerializeToString()
    try:
        with atomic_path(_side(out)) as side, atomic_path(out) as tmp:
            tmp.write_bytes(data)
            side.write_text(json.dumps(meta, indent=2) + "\n")
            try:
                load_onnx(tmp, runtime="numpy")
            except OnnxPolicyError as err:
                raise ExportError(str(err).replace(str(tmp), str(out)) + "; nothing "
                                  "written") from None
            worst = check_actions(policy, tmp, check)
            if worst is not None and worst > TOLERANCE:
                raise ExportError(f"the export's actions differ from the SB3 model's by up to "
                                  f"{worst:.2e} (more than {TOLERANCE:g}); nothing written")
    except OSError as err:
        raise ExportError(f"-o: cannot write {out}: {err.strerror or err}") from None
    return meta, worst


if __name__ == "__main__":
    sys.exit(main())
