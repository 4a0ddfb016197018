"""``smartcar-eval``'s ``--minari DATASET_ID`` and ``--overwrite``: the options, their checks
before the evaluation, and writing the dataset after it (``minari_writer``)."""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable
from typing import Any

from smartcar_gym.datasets.steps import EpisodeSteps

__all__ = ["add_minari_arguments", "check_minari_arguments", "minari_steps", "write_minari"]


def add_minari_arguments(parser: argparse.ArgumentParser) -> None:
    """``--minari`` and ``--overwrite``."""
    parser.add_argument("--minari", metavar="DATASET_ID", help="write the evaluated episodes "
                        "as a Minari dataset (observations, actions, rewards, terminations, "
                        "truncations, array infos; the env spec with its kwargs; reference "
                        "scores of random actions and the shipped policy), e.g. "
                        "smartcar/default-pybullet-v0; needs the minari extra")
    parser.add_argument("--overwrite", action="store_true",
                        help="replace an existing --minari dataset of the same id")


def check_minari_arguments(parser: argparse.ArgumentParser, args: argparse.Namespace) -> None:
    """A missing extra, a ``MINARI_DATASETS_PATH`` that is no folder, a malformed or existing
    id: ``parser.error`` (one line), before any episode runs."""
    if args.minari is None:
        if args.overwrite:
            parser.error("--overwrite: only with --minari")
        return
    from smartcar_gym.datasets.minari_writer import (
        check_dataset_id,
        check_datasets_root,
        missing_minari,
    )

    problem = (missing_minari() or check_datasets_root()
               or check_dataset_id(args.minari, args.overwrite))
    if problem:
        parser.error(f"--minari: {problem}")


def minari_steps(args: argparse.Namespace) -> EpisodeSteps | None:
    """What the evaluation records its steps into (None without ``--minari``)."""
    return None if args.minari is None else EpisodeSteps(args.seed)


def _policy_names(args: argparse.Namespace, policy: Any) -> tuple[str, str]:
    """(what the description calls the policy, ``pretrained:NAME`` or its path)."""
    if args.random:
        return "uniform random actions", "random"
    if args.pretrained:
        return f"shipped {args.pretrained!r}", f"pretrained:{args.pretrained}"
    source = getattr(policy.model, "metadata", {}).get("source", "")
    exported = f" (exported from {source})" if source else ""
    origin = source if source.startswith("pretrained:") else str(policy.model_path)
    return f"{policy.model_path}{exported}", origin


def write_minari(parser: argparse.ArgumentParser, args: argparse.Namespace, policy: Any,
                 records: list[Any], steps: EpisodeSteps | None, env_id: str,
                 env_kwargs: dict[str, Any],
                 reference_scores: Callable[..., Any]) -> dict[str, Any]:
    """Write the dataset (with ``--minari``); the summary table's line for it.
    ``reference_scores(env_id, env_kwargs, seed, returns, source)`` measures its reference
    scores (``agents.references``). A root or id refused now (changed since the checks) or a
    write the system refuses: ``parser.error`` (one line); the datasets are as they were."""
    if steps is None:
        return {}
    from smartcar_gym.datasets.minari_writer import DatasetError, write_dataset

    label, source = _policy_names(args, policy)
    started = time.perf_counter()
    references = reference_scores(env_id, env_kwargs, args.seed,
                                  [r.episode_return for r in records], source)
    try:
        dataset = write_dataset(args.minari, steps.episodes(), env_id=env_id,
                                env_kwargs=env_kwargs, policy=label, algo=policy.algo,
                                seed=args.seed, deterministic=not args.stochastic,
                                vectorization=args.vectorization, references=references,
                                overwrite=args.overwrite)
    except DatasetError as err:
        parser.error(f"--minari: {err}")
    except OSError as err:
        parser.error(f"--minari: could not write the dataset {args.minari} "
                     f"({type(err).__name__}: {err}); the datasets are as they were")
    seconds = time.perf_counter() - started
    return {f"minari ({dataset.total_episodes} episodes, {seconds:.1f} s)": args.minari}
