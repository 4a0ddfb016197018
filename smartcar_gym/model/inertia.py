"""Inertia tensors of solid primitives and what a link's inertia should roughly be."""

from __future__ import annotations

import numpy as np

from smartcar_gym.model.kinematics import rpy_matrix
from smartcar_gym.model.urdf import Geometry, Link


def shape_inertia(mass: float, geometry: Geometry) -> np.ndarray | None:
    """Inertia (3x3, kg m^2) of a solid box/cylinder/sphere about its centre, in its frame."""
    if geometry.type == "box":
        x, y, z = geometry.size
        return np.diag([y * y + z * z, x * x + z * z, x * x + y * y]) * mass / 12.0
    if geometry.type == "cylinder":
        r, h = geometry.size
        side = mass * (3 * r * r + h * h) / 12.0
        return np.diag([side, side, mass * r * r / 2.0])
    if geometry.type == "sphere":
        (r,) = geometry.size
        return np.eye(3) * 2.0 * mass * r * r / 5.0
    return None


def expected_inertia(link: Link) -> np.ndarray | None:
    """Inertia of a link computed from its mass and single collision primitive, in the
    inertial frame; None without an inertial, with mass <= 0 or a collision that is not one
    box, cylinder or sphere."""
    if link.inertial is None or link.inertial.mass <= 0 or len(link.collisions) != 1:
        return None
    collision = link.collisions[0]
    local = shape_inertia(link.inertial.mass, collision.geometry)
    if local is None:
        return None
    # collision frame -> link frame -> inertial frame
    rotation = rpy_matrix(link.inertial.origin.rpy).T @ rpy_matrix(collision.origin.rpy)
    result = rotation @ local @ rotation.T
    result[np.abs(result) < 1e-15 * np.abs(result).max()] = 0.0
    return result


def principal_moments(inertia: np.ndarray) -> np.ndarray:
    """Principal moments (eigenvalues, ascending) of a symmetric inertia tensor."""
    return np.linalg.eigvalsh(np.asarray(inertia, dtype=float))
