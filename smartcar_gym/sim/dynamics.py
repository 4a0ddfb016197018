"""Changing a loaded body's dynamics: mass (with its inertia) and friction of its links.

Domain randomisation perturbs what the URDF says a robot is: these helpers do it through the
``Body`` handle, on a body just loaded (before the simulator settles it). Links are addressed
as ``Body`` addresses them: ``BASE`` or a joint's index (the index of its child link).
"""

from __future__ import annotations

import math
from collections.abc import Iterable

from smartcar_gym.checks import is_real
from smartcar_gym.sim.contracts import Body


def _check_factor(name: str, factor: float) -> float:
    if not (is_real(factor) and math.isfinite(factor) and factor > 0):
        raise ValueError(f"{name} must be a finite number > 0, got {factor!r}")
    return float(factor)


def scale_mass(body: Body, links: Iterable[int], factor: float) -> None:
    """Multiply each link's mass and its inertia diagonal by ``factor``.

    Scaling both keeps the link's shape: its radius of gyration and centre of mass stay put,
    as for a part made of a denser or lighter material.
    """
    factor = _check_factor("mass factor", factor)
    for link in links:
        now = body.dynamics(link)
        body.set_mass(link, now.mass_kg * factor, [i * factor for i in now.inertia_diagonal])


def set_lateral_friction(body: Body, links: Iterable[int], friction: float) -> None:
    """Set each link's lateral (Coulomb) friction coefficient.

    A contact multiplies the two bodies' coefficients (pybullet's rule; the MuJoCo facade
    gives its contacts the same product).
    """
    friction = _check_factor("lateral friction", friction)
    for link in links:
        body.set_friction(link, friction)


def scale_lateral_friction(body: Body, links: Iterable[int], factor: float) -> None:
    """Multiply each link's lateral friction coefficient by ``factor``."""
    factor = _check_factor("friction factor", factor)
    for link in links:
        body.set_friction(link, body.dynamics(link).lateral_friction * factor)
