"""A mapless BARN run: the costmap as the car built it and its path as it changed:
docs/barn_mapless.png.

::

    python docs/barn_mapless.py                             # test world 48, seed 0 (15 s)
    python docs/barn_mapless.py --world 126 --out /tmp/w126.png

One run of ``SmartCarBARN-v0`` with ``map_mode="laser"`` on the planar engine, seed 0, driven
by the DWA driver as the challenge's move_base (``smartcar_gym.bench.dwa.DWADriver``, with
its recoveries and TrajectoryPlanner's turns, flags and escape). At each step it keeps the
car's global costmap (the part drawn), its global path and its way so far by odometry (the
frame of the costmap and the path). Four panels in time order: the first scan, the two steps
at least 3 s apart where a new plan moved the path furthest and kept it there (``SETTLE``
steps: the replanner's paths that flip back at once are not changes), and the end. Each
shows the costmap built so far (lethal cells black, inscribed dark grey, the inflation light
grey; unseen cells are free, white, as the planner takes them), the world's cylinders as
thin green outlines (unknown to the car), the global path (orange), the one a step before
(dashed), earlier paths every 2 s (faint), the way (blue), the start and the goal.

World 48: of the 50 test worlds (one run each, seed 0) it is the success whose path moves
furthest: the first scan sees the cylinders ahead and the path runs below them; at 6.9 s the
marks of the cluster close that way and the path jumps 0.88 m above it (the car, already
heading down, turns back); at 25.8 s, more of the world seen, the path moves 0.29 m down
behind the cluster, and the car reaches the goal at 41.7 s. It is also the world where the
driver with move_base's recoveries alone timed out, before its obstacle layer cleared the
footprint (docs/barn.md, Recoveries).
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import gymnasium as gym
import numpy as np

import smartcar_gym  # noqa: F401 (registers the envs)
from smartcar_gym.bench.dwa import DWADriver
from smartcar_gym.envs.vector.view import CarView
from smartcar_gym.navigation.costmap_loops import FREE, INSCRIBED, LETHAL
from smartcar_gym.worlds.barn import to_car_frame

WORLD = 48  # the module docstring says why
EARLIER_S = 2.0  # a faint earlier path every this long
APART_S = 3.0  # the panels of path changes at least this far apart
SETTLE = 5  # steps a new path must hold to count as a change (no flicker)


def path_moved(new: np.ndarray, old: np.ndarray) -> float:
    """How far the new path strays from the old one (m): its furthest point's distance to the
    old path's points."""
    return float(np.linalg.norm(new[:, None] - old[None], axis=-1).min(axis=1).max())


def run(world: int) -> dict:
    """One mapless DWA run: per step the time, the path, the odometry and the costmap (its
    crop to the figure's extent)."""
    env = gym.make("SmartCarBARN-v0", engine="planar", map_mode="laser")
    obs, _ = env.reset(seed=0, options={"world": world})
    base, cars, driver = env.unwrapped, CarView([env]), DWADriver()
    task = base.task
    driver.reset(cars)
    cylinders = (to_car_frame(task.world.centres, task.protocol.scale),
                 task.world.radii * task.protocol.scale)
    goal = base.state.goal[0].copy()
    config = task.costmaps.config
    lo = np.array([-0.3, cylinders[0][:, 1].min() - 0.2])
    hi = np.array([goal[0] + 0.5, cylinders[0][:, 1].max() + 0.2])
    corner, cell = np.asarray(config.corner), config.resolution
    (ix0, iy0), (ix1, iy1) = np.floor((lo - corner) / cell), np.ceil((hi - corner) / cell)
    (x0, y0), (x1, y1) = corner + np.array([(ix0, iy0), (ix1, iy1)]) * cell
    ix0, iy0, ix1, iy1 = int(ix0), int(iy0), int(ix1), int(iy1)
    steps = []

    def keep() -> None:
        steps.append((int(base.state.now_ns[0]) / 1e9, task.global_paths[0].copy(),
                      base.state.odometry[0, :2].copy(),
                      task.costmaps.costs(0)[iy0:iy1, ix0:ix1].copy()))

    outcome = None
    keep()
    while outcome is None:
        obs, _, terminated, truncated, info = env.step(driver.act(cars, obs)[0])
        keep()
        if terminated or truncated:
            outcome = info["outcome"]
    env.close()
    return {"world": world, "outcome": outcome, "steps": steps, "cylinders": cylinders,
            "goal": goal, "extent": (x0, x1, y0, y1), "limits": (lo, hi)}


def settled_moves(paths: list[np.ndarray]) -> np.ndarray:
    """Per step, how far a new plan moved the path and kept it there: the least
    ``path_moved`` between the paths of the ``SETTLE`` steps from it on and those of the
    ``SETTLE`` steps before (a plan that flips back within them moves nothing)."""
    moved = np.zeros(len(paths))
    for i in range(1, len(paths)):
        if path_moved(paths[i], paths[i - 1]) > 0.1:
            moved[i] = min(path_moved(paths[j], paths[k])
                           for j in range(i, min(i + SETTLE, len(paths)))
                           for k in range(max(0, i - SETTLE), i))
    return moved


def panels(steps: list, outcome: str) -> list[tuple[int, str]]:
    """The steps to draw and what happened at each: the first scan, the two largest settled
    moves of the path at least ``APART_S`` apart, and the end."""
    paths = [s[1] for s in steps]
    moved = settled_moves(paths)
    chosen: list[int] = []
    for i in np.argsort(moved)[::-1]:
        if moved[i] == 0:
            break
        if all(abs(steps[i][0] - steps[j][0]) >= APART_S for j in chosen):
            chosen.append(int(i))
        if len(chosen) == 2:
            break
    out = [(0, "the first scan (unseen cells are free)")]
    for i in sorted(chosen):
        up = np.mean(paths[i][:, 1]) > np.mean(paths[i - 1][:, 1])
        out.append((i, f"new marks move the path {moved[i]:.2f} m {'up' if up else 'down'}"))
    return [*out, (len(steps) - 1, f"{outcome}: the costmap the run left")]


def plot(result: dict, out: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.colors import BoundaryNorm, ListedColormap

    # free (and unseen) white, the inflation light grey, inscribed dark grey, lethal black
    shades = ListedColormap(["white", "0.78", "0.45", "black"])
    levels = BoundaryNorm([FREE, FREE + 1, INSCRIBED, LETHAL, LETHAL + 1], shades.N)
    steps = result["steps"]
    chosen = panels(steps, result["outcome"])
    lo, hi = result["limits"]
    width = 4.0
    fig, axes = plt.subplots(1, len(chosen), figsize=(width * len(chosen),
                                                      width * (hi[1] - lo[1]) / (hi[0] - lo[0])
                                                      + 0.75))
    for ax, (i, what) in zip(axes, chosen, strict=True):
        now, path, _, costs = steps[i]
        ax.imshow(costs, origin="lower", extent=result["extent"], cmap=shades, norm=levels,
                  interpolation="nearest")
        for (x, y), r in zip(*result["cylinders"], strict=True):
            ax.add_patch(plt.Circle((x, y), r, fill=False, lw=0.5, color="tab:green"))
        shown = -EARLIER_S
        for then, earlier, _, _ in steps[:i]:
            if then >= shown + EARLIER_S:
                ax.plot(earlier[:, 0], earlier[:, 1], color="tab:orange", lw=0.6, alpha=0.25)
                shown = then
        if i > 0:
            before = steps[i - 1][1]
            ax.plot(before[:, 0], before[:, 1], color="tab:orange", lw=0.9, ls="--")
        ax.plot(path[:, 0], path[:, 1], color="tab:orange", lw=1.4)
        way = np.array([s[2] for s in steps[:i + 1]])
        ax.plot(way[:, 0], way[:, 1], color="tab:blue", lw=1.4)
        ax.plot(0, 0, "o", color="tab:blue", ms=4)
        ax.plot(*result["goal"], "r*", ms=9)
        ax.set_title(f"{now:.1f} s: {what}", fontsize=9)
        ax.set_aspect("equal")
        ax.set_xlim(lo[0], hi[0])
        ax.set_ylim(lo[1], hi[1])
        ax.tick_params(labelsize=7)
    fig.suptitle(f"SmartCarBARN-v0, map_mode='laser', test world {result['world']}, planar, "
                 "DWA as move_base. The costmap from the car's scans (lethal black, inscribed "
                 "dark grey, inflation light grey), the true cylinders (green),\nthe global path "
                 "(orange; dashed: the one before; faint: every 2 s before), the way by odometry "
                 "(blue), the start (dot) and the goal (star)", fontsize=9)
    fig.tight_layout()
    fig.savefig(out, dpi=110)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--world", type=int, default=WORLD, help="a test world (0, 6, ..., 294)")
    parser.add_argument("--out", type=Path, default=Path(__file__).with_suffix(".png"))
    args = parser.parse_args()
    started = time.monotonic()
    result = run(args.world)
    plot(result, args.out)
    print(f"world {args.world}: {result['outcome']} at {result['steps'][-1][0]:.1f} s; "
          f"{args.out} in {time.monotonic() - started:.0f} s")


if __name__ == "__main__":
    main()
