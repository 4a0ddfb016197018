"""Figures: the learning curve of a run and top-down trajectories of evaluation episodes.

Figures are drawn on ``matplotlib.figure.Figure`` objects (no pyplot state, no display needed).
"""

from __future__ import annotations

import json
import math
import os
import re
import textwrap
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import pandas as pd
import yaml
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Circle
from matplotlib.ticker import FuncFormatter, MaxNLocator

if TYPE_CHECKING:
    from smartcar_gym.agents.records import EpisodeRecord

MONITOR_RE = re.compile(r"^seg(\d+)_(\d+)\.monitor\.csv$")
# Trajectory figure: inches per episode panel, minimum width, title characters per inch.
PANEL_IN = 3.0
MIN_WIDTH_IN = 6.5
TITLE_CHARS_PER_IN = 11
# Step-count ticks per axis: "250k" labels fit side by side in a 5-inch panel.
STEP_TICKS = 6


def format_steps(value: float, _pos: int | None = None) -> str:
    """A step count as a short tick label: 0, 500, 2.5k, 75k, 100k, 1.2M."""
    for scale, suffix in ((1e6, "M"), (1e3, "k")):
        if abs(value) >= scale:
            return f"{value / scale:.4g}{suffix}"
    return f"{value:.4g}"


def steps_axis(axis: Any) -> None:
    """Label a matplotlib axis of environment steps with ``format_steps`` (no offset text),
    at most ``STEP_TICKS`` round ticks."""
    axis.set_major_locator(MaxNLocator(nbins=STEP_TICKS, steps=[1, 2, 2.5, 5, 10]))
    axis.set_major_formatter(FuncFormatter(format_steps))


def load_training_episodes(run_dir: str | os.PathLike) -> pd.DataFrame:
    """Training episodes of a run from its Monitor CSVs, in time order.

    Columns: ``steps`` (environment steps when the episode ended, all envs counted), ``r``
    (return), ``l`` (length), ``t`` (wall time, s), ``is_success``. Each training segment (the
    first run and every ``--resume``) starts at the step count recorded in ``config.yaml``.

    Episodes that a resume repeats are left out (the files keep them): a run killed after its
    last checkpoint went on past it, and the resumed run plays those steps again. A resume
    records how many episodes per env came before its checkpoint (``kept_episodes``); for
    resumes of versions that did not, the earlier segments are cut at the checkpoint's step
    count.
    """
    run_dir = Path(run_dir)
    config: dict[str, Any] = {}
    config_path = run_dir / "config.yaml"
    if config_path.exists():
        config = yaml.safe_load(config_path.read_text()) or {}
    resumes = config.get("resumes") or []
    starts = [0] + [int(r.get("from_timesteps", 0)) for r in resumes]
    row_limits, step_limits = _repeated_episodes(resumes)
    frames = []
    for path in sorted((run_dir / "monitor").glob("seg*_*.monitor.csv")):
        match = MONITOR_RE.match(path.name)
        if not match:
            continue
        with open(path) as f:
            header = f.readline()
            frame = pd.read_csv(f)
        segment, rank = int(match.group(1)), int(match.group(2))
        if segment in row_limits:
            limit = row_limits[segment]
            frame = frame.iloc[: limit[rank] if rank < len(limit) else 0]
        t_start = float(json.loads(header.lstrip("#")).get("t_start", 0.0))
        frame["t"] = frame["t"] + t_start
        frame["segment"] = segment
        frames.append(frame)
    columns = ["steps", "r", "l", "t", "is_success"]
    frames = [f for f in frames if len(f)]
    if not frames:
        return pd.DataFrame(columns=columns)
    df = pd.concat(frames, ignore_index=True).sort_values(["segment", "t"], kind="stable")
    steps = []
    for segment, group in df.groupby("segment", sort=True):
        start = starts[segment] if segment < len(starts) else 0
        steps.append(start + group["l"].cumsum())
    df["steps"] = pd.concat(steps)
    limit = df["segment"].map(lambda s: step_limits.get(s, np.inf))
    df = df[df["steps"] <= limit]
    if "is_success" not in df:
        df["is_success"] = np.nan
    df["is_success"] = df["is_success"].astype(float)
    df["t"] = df["t"] - df["t"].min()
    return df[columns].reset_index(drop=True)


def _repeated_episodes(resumes: Sequence[dict[str, Any]],
                       ) -> tuple[dict[int, list[int]], dict[int, float]]:
    """What each resume makes stale: Monitor rows to keep per segment and env, and (resumes
    without ``kept_episodes``) the step count up to which a segment's episodes are kept."""
    rows: dict[int, list[int]] = {}
    steps: dict[int, float] = {}
    for i, resume in enumerate(resumes):
        new_segment = i + 1  # resume i started segment i + 1
        kept = resume.get("kept_episodes")
        if isinstance(kept, dict):
            segment, per_env = int(kept["segment"]), [int(n) for n in kept["per_env"]]
            for later in range(segment + 1, new_segment):  # ran past the checkpoint: all stale
                rows[later] = []
            before = rows.get(segment)
            rows[segment] = per_env if before is None else [
                min(a, b) for a, b in zip(before, per_env, strict=False)]
        else:
            for segment in range(new_segment):
                steps[segment] = min(steps.get(segment, np.inf), int(resume["from_timesteps"]))
    return rows, steps


def load_evaluations(path: str | os.PathLike) -> dict[str, np.ndarray] | None:
    """The arrays of an ``evaluations.npz`` (None if it does not exist)."""
    path = Path(path)
    if not path.exists():
        return None
    with np.load(path) as data:
        return {key: data[key] for key in data.files}


def plot_learning_curve(
    run_dir: str | os.PathLike, out_path: str | os.PathLike | None = None, window: int = 100,
) -> Path:
    """Return and success rate against environment steps, training (rolling) and evaluation.

    Writes ``<run_dir>/learning_curve.png`` unless ``out_path`` is given; returns the path.
    """
    run_dir = Path(run_dir)
    out_path = Path(out_path) if out_path is not None else run_dir / "learning_curve.png"
    fig = learning_curve_figure(run_dir, window)
    out_path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out_path, dpi=100)
    return out_path


def learning_curve_figure(run_dir: str | os.PathLike, window: int = 100) -> Figure:
    """The figure of ``plot_learning_curve`` (two panels: return, success rate)."""
    run_dir = Path(run_dir)
    episodes = load_training_episodes(run_dir)
    evals = load_evaluations(run_dir / "eval" / "evaluations.npz")

    fig = Figure(figsize=(10, 4), layout="constrained")
    ax_r, ax_s = fig.subplots(1, 2)
    if len(episodes):
        win = max(1, min(window, len(episodes) // 5 or 1))
        rolling = episodes.rolling(win, min_periods=1)
        ax_r.plot(episodes["steps"], episodes["r"], ".", ms=2, alpha=0.15, color="C0")
        ax_r.plot(episodes["steps"], rolling["r"].mean(), color="C0",
                  label=f"training (mean of {win} episodes)")
        ax_s.plot(episodes["steps"], rolling["is_success"].mean(), color="C0",
                  label=f"training (mean of {win} episodes)")
    if evals is not None and len(evals["timesteps"]):
        steps = evals["timesteps"]
        mean = np.nanmean(evals["results"], axis=1)
        std = np.nanstd(evals["results"], axis=1)
        n_episodes = evals["results"].shape[1]
        ax_r.errorbar(steps, mean, yerr=std, fmt="o-", color="C1", ms=3, capsize=2,
                      label=f"evaluation ({n_episodes} episodes, deterministic)")
        ax_s.plot(steps, evals["successes"].mean(axis=1), "o-", color="C1", ms=3,
                  label=f"evaluation ({n_episodes} episodes, deterministic)")
    ax_r.set(xlabel="environment steps", ylabel="episode return", title="Return")
    ax_s.set(xlabel="environment steps", ylabel="success rate", title="Success rate",
             ylim=(-0.03, 1.03))
    for ax in (ax_r, ax_s):
        steps_axis(ax.xaxis)
        ax.grid(alpha=0.3)
        if ax.get_legend_handles_labels()[0]:
            ax.legend(loc="lower right", fontsize=8)
    fig.suptitle(f"Learning curve: {run_dir.name}")
    return fig


def plot_trajectories(
    records: Sequence[EpisodeRecord],
    out_path: str | os.PathLike,
    max_episodes: int = 16,
    goal_tolerance_m: float = 0.1,
    title: str | None = None,
) -> Path:
    """Top-down paths of up to ``max_episodes`` episodes, one panel each.

    Each panel: ground-truth path (solid) and odometry path (dashed), start, goal with its
    tolerance circle, and the end marked with a green check (success) or a red cross (failure).
    """
    records = list(records)[:max_episodes]
    if not records:
        raise ValueError("plot_trajectories needs at least one episode record")
    cols = math.ceil(math.sqrt(len(records)))
    rows = math.ceil(len(records) / cols)
    width = max(PANEL_IN * cols, MIN_WIDTH_IN)  # room for the title and the legend
    legend_cols = 6 if width >= 9 else 3
    n_success = sum(r.success for r in records)
    title = textwrap.fill(title or f"{n_success}/{len(records)} episodes reached the goal",
                          width=int(width * TITLE_CHARS_PER_IN))
    extra = 0.3 * (title.count("\n") + 1) + 0.25 * math.ceil(6 / legend_cols)
    fig = Figure(figsize=(width, (PANEL_IN + 0.3) * rows + extra), layout="constrained")
    axes = np.atleast_1d(fig.subplots(rows, cols, squeeze=False)).ravel()
    for ax, rec in zip(axes, records, strict=False):
        _draw_episode(ax, rec, goal_tolerance_m)
    for ax in axes[len(records):]:
        ax.set_axis_off()
    fig.legend(handles=_legend_handles(), loc="outside lower center", ncol=legend_cols,
               fontsize=8)
    fig.suptitle(title, fontsize=11)
    out_path = Path(out_path)
    out_path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out_path, dpi=90, bbox_inches="tight", pad_inches=0.1)  # nothing is cut off
    return out_path


def _legend_handles() -> list[Line2D]:
    return [
        Line2D([], [], color="tab:blue", lw=1.5, label="ground truth"),
        Line2D([], [], color="tab:orange", lw=1.2, ls="--", label="odometry"),
        Line2D([], [], color="k", marker="o", ls="", label="start"),
        Line2D([], [], color="tab:purple", marker="*", ms=9, ls="", label="goal (tolerance)"),
        Line2D([], [], color="tab:green", marker="P", ms=8, ls="", label="end: success"),
        Line2D([], [], color="tab:red", marker="X", ms=8, ls="", label="end: failure"),
    ]


def _draw_episode(ax: Any, rec: EpisodeRecord, goal_tolerance_m: float) -> None:
    path = np.asarray(rec.path, dtype=float).reshape(-1, 2)
    odom = np.asarray(rec.odom_path, dtype=float).reshape(-1, 2)
    goal = np.asarray(rec.goal, dtype=float)
    color = "tab:green" if rec.success else "tab:red"
    ax.plot(path[:, 0], path[:, 1], "-", color="tab:blue", lw=1.5)
    ax.plot(odom[:, 0], odom[:, 1], "--", color="tab:orange", lw=1.2)
    ax.plot(*path[0], "ko", ms=5)
    if np.all(np.isfinite(goal)):
        ax.add_patch(Circle(goal, goal_tolerance_m, fill=False, color="tab:purple", lw=1.2))
        ax.plot(*goal, "*", color="tab:purple", ms=9)
    ax.plot(*path[-1], "P" if rec.success else "X", color=color, ms=9)
    outcome = (f"reached in {rec.time_to_goal_s:.1f} s" if rec.success
               else f"failed, {rec.final_distance_m:.2f} m short")
    ax.set_title(f"episode {rec.episode} (seed {rec.seed}): {outcome}", fontsize=8, color=color)
    points = np.vstack([path, odom, goal[None, :] if np.all(np.isfinite(goal)) else path[:1]])
    lo, hi = points.min(axis=0), points.max(axis=0)
    centre, half = (lo + hi) / 2, max(float(np.max(hi - lo)) / 2 + 0.2, 0.4)
    ax.set_xlim(centre[0] - half, centre[0] + half)
    ax.set_ylim(centre[1] - half, centre[1] + half)
    ax.set_aspect("equal")
    ax.tick_params(labelsize=7)
    ax.grid(alpha=0.3)
