"""The results of a sweep: one row per trial, the table (CSV, JSON, terminal) and the best
hyperparameters as a file ``smartcar-train --hyperparams-file`` reads.

A trial's numbers are those of its last evaluation: the final one of a completed trial, the
one at which ASHA stopped it otherwise. The best configuration is ranked over its seeds: the
mean success rate of the trials that share every searched value but the seed, then their
mean return. Nothing here needs Ray.
"""

from __future__ import annotations

import csv
import io
import json
import math
import shlex
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import yaml

from smartcar_gym.agents.callbacks import atomic_write_text

COMPLETED, STOPPED, ERROR, UNFINISHED = "completed", "stopped early", "error", "unfinished"
RESULT_COLUMNS = ("success_rate", "mean_reward", "timesteps", "wall_time_s")


@dataclass
class TrialRow:
    """One trial: its searched values, status and last evaluation."""

    trial: str
    status: str
    values: dict[str, Any]  # searched name -> value (seed, learning_rate, env_kwargs.x)
    success_rate: float | None = None
    mean_reward: float | None = None
    timesteps: int | None = None
    wall_time_s: float | None = None
    node_id: str | None = None
    error: str | None = None
    run_dir: str = ""
    hyperparams: dict[str, Any] = field(default_factory=dict)
    env_kwargs: dict[str, Any] = field(default_factory=dict)
    seed: int | None = None

    @property
    def has_result(self) -> bool:
        return self.success_rate is not None and not math.isnan(self.success_rate)


def trial_status(tune_status: str, timesteps: int | None, target: int,
                 has_error: bool) -> str:
    """``completed`` / ``stopped early`` (by ASHA) / ``error`` / ``unfinished`` from Tune's
    status (TERMINATED, ERROR, RUNNING, PENDING, PAUSED) and the steps reached."""
    if has_error or tune_status == "ERROR":
        return ERROR
    if tune_status != "TERMINATED":
        return UNFINISHED
    return COMPLETED if timesteps is not None and timesteps >= target else STOPPED


def best_group(rows: list[TrialRow]) -> tuple[list[TrialRow], float, float] | None:
    """The trials of the best configuration (same searched values but the seed), its mean
    success rate and mean return; None if no trial has an evaluation."""
    groups: dict[str, list[TrialRow]] = {}
    for row in rows:
        if row.has_result:
            key = json.dumps({k: v for k, v in row.values.items() if k != "seed"},
                             sort_keys=True, default=str)
            groups.setdefault(key, []).append(row)
    if not groups:
        return None

    def score(group: list[TrialRow]) -> tuple[float, float]:
        return (sum(r.success_rate for r in group) / len(group),
                sum(r.mean_reward for r in group) / len(group))

    best = max(groups.values(), key=score)  # the first of equal scores
    return best, *score(best)


def best_hyperparams_yaml(rows: list[TrialRow], algo: str, env: str, out: Path,
                          vectorization: str = "subproc") -> str | None:
    """The best configuration as a zoo-format hyperparameter file with a header saying where
    it comes from and how to train it (with the sweep's ``vectorization``); None if no trial
    has an evaluation."""
    found = best_group(rows)
    if found is None:
        return None
    group, success, mean_return = found
    first = group[0]
    path = out / "best_hyperparams.yaml"
    argv = ["smartcar-train", "--algo", algo, "--env", env, "--hyperparams-file", str(path),
            "--seed", str(first.seed)]
    if vectorization != "subproc":  # a batched sweep's cars in one process, as its trials
        argv += ["--vectorization", vectorization]
    if first.env_kwargs:  # JSON is YAML: smartcar-train reads the values back
        argv += ["--env-kwargs", *(f"{k}={json.dumps(v)}" for k, v in first.env_kwargs.items())]
    command = shlex.join(argv)
    searched = {k: v for k, v in first.values.items() if k != "seed"} or "(no searched values)"
    header = [
        f"Best configuration of the smartcar-tune sweep in {out}: {searched}",
        f"mean evaluation success {success:.1%}, mean return {mean_return:.2f} over "
        f"{len(group)} trial(s): " + ", ".join(
            f"{r.trial} (seed {r.seed}: {r.success_rate:.1%} at {r.timesteps:,} steps)"
            for r in group),
        f"Train it with: {command}",
    ]
    body = yaml.safe_dump({env: first.hyperparams}, sort_keys=False)
    return "".join(f"# {line}\n" for line in header) + body


def table_rows(rows: list[TrialRow], names: list[str]) -> list[dict[str, Any]]:
    """Flat rows (CSV): trial, status, the searched values, results, node, error, folder."""
    flat = []
    for row in rows:
        item: dict[str, Any] = {"trial": row.trial, "status": row.status}
        item.update({name: row.values.get(name) for name in names})
        item.update({key: getattr(row, key) for key in RESULT_COLUMNS})
        item.update(node_id=row.node_id, error=row.error, run_dir=row.run_dir)
        flat.append(item)
    return flat


def write_results(rows: list[TrialRow], names: list[str], out: Path, algo: str,
                  env: str, vectorization: str = "subproc") -> list[Path]:
    """Write ``results.csv``, ``results.json`` and (if any trial has an evaluation)
    ``best_hyperparams.yaml`` into ``out``; returns the paths written."""
    flat = table_rows(rows, names)
    text = io.StringIO()
    writer = csv.DictWriter(text, fieldnames=list(flat[0]) if flat else ["trial"])
    writer.writeheader()
    writer.writerows(flat)
    written = [out / "results.csv", out / "results.json"]
    atomic_write_text(written[0], text.getvalue())
    found = best_group(rows)
    summary = {
        "out": str(out), "algo": algo, "env": env, "searched": names,
        "best": None if found is None else {
            "trials": [r.trial for r in found[0]], "mean_success_rate": found[1],
            "mean_reward": found[2], "values": {k: v for k, v in found[0][0].values.items()
                                                if k != "seed"}},
        "trials": [asdict(row) for row in rows],
    }
    atomic_write_text(written[1], json.dumps(summary, indent=2, default=str) + "\n")
    best = best_hyperparams_yaml(rows, algo, env, out, vectorization)
    if best is not None:
        written.append(out / "best_hyperparams.yaml")
        atomic_write_text(written[-1], best)
    return written


def print_table(rows: list[TrialRow], names: list[str], title: str) -> None:
    """The results table on the terminal (rich)."""
    from rich.console import Console
    from rich.table import Table

    console = Console()
    if not console.is_terminal:  # a log file or a pipe: do not squeeze into 80 columns
        console = Console(width=200)
    table = Table(title=title)
    for column in ("trial", "status", *names, "success", "return", "steps", "wall time"):
        table.add_column(column, no_wrap=True,
                         justify="left" if column in ("trial", "status") else "right")
    for row in rows:
        results = ["-"] * 4
        if row.has_result:
            results = [f"{row.success_rate:.0%}", f"{row.mean_reward:.2f}",
                       f"{row.timesteps:,}", f"{row.wall_time_s:.0f} s"]
        status = row.status if row.error is None else f"{row.status}: {row.error[:60]}"
        table.add_row(row.trial, status, *(_short(row.values.get(n)) for n in names), *results)
    console.print(table)


def _short(value: Any) -> str:
    if isinstance(value, float):
        return f"{value:.4g}"
    return str(value)
