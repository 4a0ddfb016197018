"""Package a trained run as the shipped policy, with a provenance file.

::

    python -m smartcar_gym.agents.export runs/ppo_SmartCar-v0_s0 --episodes 100 --n-envs 2

copies ``model.zip`` and ``vecnormalize.pkl`` of the run to ``smartcar_gym/pretrained/`` as
``policy.zip`` and ``vecnormalize.pkl``, evaluates it on seeded episodes and writes
``provenance.json``: the training command, seed, steps, wall time and the success rate.
"""

from __future__ import annotations

import argparse
import json
import shutil
import sys
from collections.abc import Sequence
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

import yaml

from smartcar_gym.agents.cli_args import non_negative_int_arg, positive_int_arg
from smartcar_gym.agents.episodes import evaluate_policy_episodes
from smartcar_gym.agents.models import (
    PRETRAINED_MODEL,
    PRETRAINED_POLICIES,
    find_vecnormalize,
    load_model,
)
from smartcar_gym.agents.records import summarize

DEFAULT_OUT = Path(__file__).resolve().parent.parent / "pretrained"


def export_run(
    run_dir: str | Path,
    out_dir: str | Path = DEFAULT_OUT,
    model_name: str = "model.zip",
    episodes: int = 100,
    n_envs: int = 1,
    seed: int = 0,
) -> dict[str, Any]:
    """Copy a run's model (+ statistics) to ``out_dir``, evaluate it, write provenance.json."""
    run_dir, out_dir = Path(run_dir), Path(out_dir)
    config = yaml.safe_load((run_dir / "config.yaml").read_text())
    model_path = run_dir / model_name
    if not model_path.is_file():
        raise FileNotFoundError(f"{model_path} does not exist")
    summary_path = run_dir / "summary.json"
    summary = json.loads(summary_path.read_text()) if summary_path.exists() else {}
    # best_model.zip has best_model.json: the training evaluation that selected it
    selected_path = model_path.with_suffix(".json")
    selected_by = json.loads(selected_path.read_text()) if selected_path.exists() else None
    out_dir.mkdir(parents=True, exist_ok=True)
    target = out_dir / PRETRAINED_MODEL
    shutil.copyfile(model_path, target)
    vecnormalize = find_vecnormalize(model_path)
    stats_target = out_dir / "vecnormalize.pkl"
    if vecnormalize is not None:
        shutil.copyfile(vecnormalize, stats_target)
    elif stats_target.exists():
        stats_target.unlink()
    model = load_model(target, config["algo"])
    records = evaluate_policy_episodes(
        model, config["env"], n_episodes=episodes, n_envs=n_envs, seed=seed,
        env_kwargs=config.get("env_kwargs") or {},
        vecnormalize_path=stats_target if vecnormalize is not None else None,
    )
    provenance = {
        "algo": config["algo"],
        "env": config["env"],
        "env_kwargs": config.get("env_kwargs") or {},
        "command": config.get("command"),
        "resumes": [r.get("command") for r in config.get("resumes", [])],
        "seed": config["seed"],
        "n_envs": config["n_envs"],
        "hyperparams": config["hyperparams"],
        "timesteps": summary.get("num_timesteps"),
        "wall_time_s": summary.get("wall_time_s"),
        "steps_per_s": summary.get("steps_per_s"),
        "training_final_eval": summary.get("final_eval"),
        "selected_by_eval": selected_by,
        "source": f"{run_dir.name}/{model_name}",
        "versions": config.get("versions"),
        "evaluation": {
            "command": f"smartcar-eval --pretrained{_shipped_name(out_dir)} --episodes "
                       f"{episodes} --seed {seed}",
            "deterministic": True,
            **summarize(records),
        },
        "exported": datetime.now(timezone.utc).isoformat(timespec="seconds"),
    }
    (out_dir / "provenance.json").write_text(json.dumps(provenance, indent=2) + "\n")
    return provenance


def _shipped_name(out_dir: Path) -> str:
    """`` robust`` for a policy exported to ``pretrained/robust``: how --pretrained names it."""
    for name, sub in PRETRAINED_POLICIES.items():
        if sub and out_dir.resolve() == (DEFAULT_OUT / sub).resolve():
            return f" {name}"
    return ""


def main(argv: Sequence[str] | None = None) -> int:
    """Command line of ``python -m smartcar_gym.agents.export``."""
    parser = argparse.ArgumentParser(
        prog="python -m smartcar_gym.agents.export",
        description="Copy a run's model into the package as the shipped policy and write "
                    "provenance.json (evaluated on seeded episodes).",
    )
    parser.add_argument("run_dir", type=Path)
    parser.add_argument("--model", default="model.zip", help="model file in the run folder "
                        "(e.g. best_model.zip)")
    parser.add_argument("--out", type=Path, default=DEFAULT_OUT)
    parser.add_argument("--episodes", type=positive_int_arg, default=100)
    parser.add_argument("--n-envs", type=positive_int_arg, default=1)
    parser.add_argument("--seed", type=non_negative_int_arg, default=0)
    args = parser.parse_args(argv)
    if not (args.run_dir / "config.yaml").is_file():
        parser.error(f"{args.run_dir} is not a run folder (no config.yaml)")
    try:
        provenance = export_run(args.run_dir, args.out, args.model, args.episodes, args.n_envs,
                                args.seed)
    except FileNotFoundError as err:
        parser.error(str(err))
    ev = provenance["evaluation"]
    size_kb = (args.out / PRETRAINED_MODEL).stat().st_size / 1024
    print(f"exported {args.run_dir / args.model} -> {args.out / PRETRAINED_MODEL} "
          f"({size_kb:.0f} kB): success {ev['success_rate']:.1%} over {ev['episodes']} episodes")
    return 0


if __name__ == "__main__":
    sys.exit(main())
