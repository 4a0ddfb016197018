"""Which laser beam a direction falls in, fast and to the bit.

``beam_of(lx, ly, first, step, band)`` is ``rint((atan2(ly, lx) - first) / step)``, the
nearest beam's index (``first``: the first beam's angle, ``step``: the angle between beams,
rad), the same integer for every input. It takes the angle from a polynomial (Abramowitz and
Stegun 4.4.47 on [0, 1], within ``ATAN_ERROR`` of atan, with the octant's exact
reflections) where that error cannot move the answer across a half-way point between beams,
and from ``math.atan2`` where it could: within ``band`` beams of a half-way point (``doubt_band``:
ten times the polynomial's error, in beams), on an axis (signed zeros), or for a value that is
not finite. The obstacle layer's clearing asks this for every marked point at every scan
(some 3,700 points a car with the laser's noise; ``navigation/obstacles.py``): on scans
replayed from BARN runs its update took 18 % less time than with ``atan2``.

The exact branch's ``atan2`` and division are the formula's own, so a doubtful point gets the
formula's answer; an undoubted one lies more than ``0.5 - band`` beams from a half-way point
by the polynomial's angle, so within ``0.5`` by the exact angle (the error and the rounding of
the division are a tenth of ``band`` or less), where ``rint`` gives the same integer
(``tests/test_beams.py`` checks the bound and every kind of input against the formula).
"""

from __future__ import annotations

import math

import numpy as np

from smartcar_gym.navigation.costmap_loops import COMPILED, numba

#: a bound on |atan(t) - atan_unit(t)| for 0 <= t <= 1 (rad): Abramowitz and Stegun give 1e-5
#: for these five-digit coefficients; 1.15e-5 is measured on a fine grid (tests/test_beams.py)
ATAN_ERROR = 2e-5
_A1, _A3, _A5, _A7, _A9 = 0.9998660, -0.3302995, 0.1801410, -0.0851330, 0.0208351
_HALF_PI = 0.5 * math.pi


def doubt_band(step: float) -> float:
    """How near a half-way point between beams (in beams) the polynomial's index is doubted:
    ten times its error over the step (0.5 or more: always, for beams closer than 4e-4 rad)."""
    return 10.0 * ATAN_ERROR / abs(step) + 1e-9


def atan_unit(t: float) -> float:
    """Abramowitz and Stegun 4.4.47: atan(t) for 0 <= t <= 1, within ``ATAN_ERROR``
    (numbers or arrays)."""
    t2 = t * t
    return t * (_A1 + t2 * (_A3 + t2 * (_A5 + t2 * (_A7 + t2 * _A9))))


def beam_of(lx: float, ly: float, first: float, step: float, band: float) -> np.int64:
    """``rint((atan2(ly, lx) - first) / step)`` to the bit (module docstring)."""
    ax, ay = abs(lx), abs(ly)
    if band < 0.5 and 0.0 < ax < math.inf and 0.0 < ay < math.inf:
        if ay <= ax:
            angle = atan_unit(ay / ax)
        else:
            angle = _HALF_PI - atan_unit(ax / ay)
        if lx < 0.0:
            angle = math.pi - angle
        if ly < 0.0:
            angle = -angle
        f = (angle - first) / step
        j = math.floor(f + 0.5)
        if abs(f - j) < 0.5 - band:
            return np.int64(j)
    return np.int64(np.rint((math.atan2(ly, lx) - first) / step))


if COMPILED:
    atan_unit = numba.njit(cache=True, nogil=True)(atan_unit)
    beam_of = numba.njit(cache=True, nogil=True)(beam_of)
