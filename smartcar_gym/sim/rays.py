"""Ray casts, engine-neutral: many rays in one batch, and bodies the rays pass through.

A range sensor on a robot must not see the robot itself. ``hide_from_rays`` asks the body's
engine to let rays pass through every link of it; the body still collides with everything it
collided with before. ``cast_rays`` checks the rays and hands them to the world's
``Simulator.ray_batch``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from smartcar_gym.sim.contracts import Body, Simulator

#: the most rays one batch casts: pybullet's ``MAX_RAY_INTERSECTION_BATCH_SIZE``, kept for
#: every engine so that a sensor works alike on all (tests/test_engine_plugin.py checks it)
MAX_RAYS = 16384


@dataclass(frozen=True)
class RayHits:
    """What each of N rays hit first: ``fraction`` of the way from start to end (1 where it
    hit nothing), the body's engine id (-1: nothing) and the hit point in the world (m)."""

    fraction: np.ndarray  # (N,)
    body: np.ndarray  # (N,) int
    point: np.ndarray  # (N, 3)

    @property
    def hit(self) -> np.ndarray:
        """True where the ray hit something."""
        return self.body >= 0


def hide_from_rays(body: Body) -> None:
    """Let ``cast_rays`` pass through every link of ``body``; its collisions are unchanged."""
    body.hide_from_rays()


def cast_rays(sim: Simulator, starts: np.ndarray, ends: np.ndarray) -> RayHits:
    """Cast rays from ``starts`` to ``ends`` (``(N, 3)``, world frame, m) in one batch.

    Bodies passed to ``hide_from_rays`` are not hit. A ray that starts inside a convex shape
    does not hit that shape (Bullet's rule). Single-threaded, so results are reproducible.
    """
    starts = np.asarray(starts, dtype=float)
    ends = np.asarray(ends, dtype=float)
    if starts.ndim != 2 or starts.shape[1] != 3 or starts.shape != ends.shape:
        raise ValueError(f"ray starts and ends must be two (N, 3) arrays, got shapes "
                         f"{starts.shape} and {ends.shape}")
    if not 1 <= len(starts) <= MAX_RAYS:
        raise ValueError(f"one batch casts 1 to {MAX_RAYS} rays (pybullet's limit), "
                         f"got {len(starts)}")
    return sim.ray_batch(starts, ends)
