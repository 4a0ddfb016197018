"""Arithmetic on arrays of cars that gives Python's ``math`` bits, to the bit.

Tasks work on numpy arrays of cars. Where numpy's function is not libm's (``np.hypot``,
``np.arctan2`` and ``np.remainder(x + pi, 2 pi) - pi`` each differ from ``math.hypot``,
``math.atan2`` and ``math.remainder`` in the last bit for some inputs), a value that must be
the one the ``math`` function gives (the odometry's heading as ROS would wrap it, the
figures recorded before the tasks were written on arrays) takes an array function that is
exact by construction:

- ``wrap_angles``: ``math.remainder(theta, 2 pi)`` (IEEE remainder, an exact result) from
  ``np.fmod`` (exact) and one subtraction that Sterbenz's lemma makes exact;
- ``planar_norm``: ``sqrt(dx * dx + dy * dy)`` (every operation is IEEE-rounded, so floats,
  numpy's numbers and arrays give the same bits on any machine);
- ``exact_hypot``: ``math.hypot`` itself, pair by pair (for a few values).
"""

from __future__ import annotations

import math

import numpy as np

TWO_PI = 2 * math.pi
SMALL = 4  # up to this many values, ``math``'s function on each is faster than numpy's calls
_HALF = TWO_PI / 2  # exact: a power-of-two division


def wrap_angles(theta: np.ndarray) -> np.ndarray:
    """Each angle in [-pi, pi]: exactly ``math.remainder(t, 2 * math.pi)`` for every ``t`` (a
    number gives a number).

    ``np.fmod`` is exact; where its result lies beyond half a turn, one turn is taken off, and
    the two operands are then within a factor of two of each other, so the subtraction is exact
    (Sterbenz). A remainder of exactly half a turn (the IEEE tie, which rounds the quotient to
    even) is left to ``math.remainder`` itself.
    """
    if isinstance(theta, float) or np.ndim(theta) == 0:  # one number: math.remainder's
        return math.remainder(theta, TWO_PI)
    theta = np.asarray(theta, dtype=np.float64)
    if theta.size <= SMALL:  # math.remainder itself: cheaper than numpy's calls on a few
        return np.array([math.remainder(t, TWO_PI) for t in theta.ravel().tolist()]
                        ).reshape(theta.shape)
    r = np.fmod(theta, TWO_PI)
    r = np.where(r > _HALF, r - TWO_PI, np.where(r < -_HALF, r + TWO_PI, r))
    ties = np.abs(r) == _HALF
    if ties.any():
        r[ties] = [math.remainder(t, TWO_PI) for t in theta[ties].tolist()]
    return r


def planar_norm(dx: np.ndarray, dy: np.ndarray) -> np.ndarray:
    """``sqrt(dx * dx + dy * dy)`` of each pair (arrays, or numbers for one car): the bits of
    ``math.sqrt(dx * dx + dy * dy)`` on each pair of floats (``np.hypot`` and ``math.hypot``
    disagree in the last bit)."""
    if isinstance(dx, float):  # one car's numbers: the same IEEE square root, without numpy's call
        return math.sqrt(dx * dx + dy * dy)
    return np.sqrt(dx * dx + dy * dy)


def exact_hypot(dx: np.ndarray, dy: np.ndarray) -> np.ndarray:
    """``math.hypot`` of each pair, to its bit (``np.hypot`` is libm's, which differs): for
    the few values a task takes it of (``stop_speed``'s distances). Numbers give a number."""
    if isinstance(dx, float):
        return math.hypot(dx, dy)
    out = np.array([math.hypot(a, b) for a, b in zip(np.ravel(dx).tolist(),
                                                    np.ravel(dy).tolist(), strict=True)])
    return out.reshape(np.shape(dx))[()]
