"""The challenge's table of a benchmark's runs: rates, mean time, mean scores; and a plot."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from smartcar_gym.bench.runs import RunRecord
from smartcar_gym.envs.tasks.barn.protocol import OUTCOMES, SUCCESS

#: published results on the 50 test worlds (the metric of at most 0.25; docs/barn.md)
PUBLISHED = (("move_base + DWA (Jackal)", 0.1693, 0.88), ("DRL-VO (2022)", 0.2339, None),
             ("LfLH (2023)", 0.2445, 0.99))


def summarize(records: Sequence[RunRecord]) -> dict[str, Any]:
    """Rates of each outcome, the mean time of the successful runs (s), the mean scores (every
    run; a failed one scores 0) and, as smartcar-eval's pass marks read them, ``episodes``,
    ``success_rate`` and ``mean_final_distance_m``."""
    n = len(records)
    outcomes = [r.outcome for r in records]
    times = [r.time_s for r in records if r.outcome == SUCCESS]
    summary: dict[str, Any] = {"episodes": n, "n_worlds": len({r.world for r in records})}
    for outcome in OUTCOMES:
        summary[f"{outcome}_rate"] = outcomes.count(outcome) / n if n else 0.0
    summary.update(
        mean_time_s=float(np.mean(times)) if times else None,
        mean_score=float(np.mean([r.score for r in records])) if n else 0.0,
        mean_score_025=float(np.mean([r.score_025 for r in records])) if n else 0.0,
        mean_final_distance_m=float(np.mean([r.final_distance_m for r in records])) if n
        else 0.0,
    )
    return summary


def table(summary: dict[str, Any], name: str) -> str:
    """The challenge's table, this driver's row beside the published ones (0.25 scale)."""
    time = summary["mean_time_s"]
    rows = [
        "| driver | runs | success | collision | timeout | other failure | mean time (s) | "
        "score (max 0.5) | score (max 0.25) |",
        "|---|---|---|---|---|---|---|---|---|",
        f"| {name} | {summary['episodes']} | {summary['success_rate']:.3f} | "
        f"{summary['collision_rate']:.3f} | {summary['timeout_rate']:.3f} | "
        f"{summary['failure_rate']:.3f} | {'-' if time is None else f'{time:.1f}'} | "
        f"{summary['mean_score']:.4f} | {summary['mean_score_025']:.4f} |",
    ]
    for entry, score, success in PUBLISHED:
        rows.append(f"| {entry}, published | 50 x 10 | {'' if success is None else success} "
                    f"| | | | | | {score} |")
    return "\n".join(rows)


def plot_runs(records: Sequence[RunRecord], worlds: Any, scale: float, path: Path,
              title: str, global_paths: dict[int, np.ndarray] | None = None) -> None:
    """The kept trajectories, one panel per world: cylinders, start, goal, the global path
    (``global_paths``, by world) and the car's way."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from smartcar_gym.worlds.barn import GOAL_XY, to_car_frame

    kept = [r for r in records if r.trajectory is not None]
    missing = sorted({r.world for r in kept} - set(global_paths or {}))
    if global_paths is not None and missing:
        raise ValueError(f"plot_runs: no global path for world(s) {missing}")
    fig, axes = plt.subplots(1, max(1, len(kept)), figsize=(3.2 * max(1, len(kept)), 2.1),
                             squeeze=False)
    goal = to_car_frame(np.array(GOAL_XY), scale)
    for ax, record in zip(axes[0], kept, strict=False):
        world = worlds.world(record.world)
        centres, radii = to_car_frame(world.centres, scale), world.radii * scale
        for (x, y), r in zip(centres, radii, strict=True):
            ax.add_patch(plt.Circle((x, y), r, color="0.4"))
        planned = (global_paths or {}).get(record.world)
        if planned is not None:
            ax.plot(planned[:, 0], planned[:, 1], color="tab:orange", lw=0.8, ls="--")
        way = record.trajectory
        ax.plot(way[:, 0], way[:, 1], color="tab:blue", lw=1.2)
        ax.plot(0, 0, "go", ms=4)
        ax.plot(*goal, "r*", ms=8)
        ax.set_title(f"world {record.world}: {record.outcome}", fontsize=9)
        ax.set_aspect("equal")
        ax.set_xlim(-0.3, goal[0] + 0.5)
        ax.set_ylim(centres[:, 1].min() - 0.2, centres[:, 1].max() + 0.2)
        ax.tick_params(labelsize=7)
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)
