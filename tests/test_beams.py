"""``navigation.beams.beam_of``: the nearest beam's index, the formula's to the bit."""

from __future__ import annotations

import math

import numpy as np
import pytest

from smartcar_gym.navigation.beams import ATAN_ERROR, atan_unit, beam_of, doubt_band

#: (first beam's angle, step, beams): the LDS-01 all round, a half-turn laser, a fine one,
#: and beams so close that the polynomial is never trusted
LAYOUTS = [(-math.pi, 2 * math.pi / 360, 360), (-math.pi / 2, math.pi / 180, 181),
           (-math.pi, 2 * math.pi / 1080, 1080), (-0.01, 1e-4, 201)]


def formula(lx: float, ly: float, first: float, step: float) -> int:
    """The obstacle layer's index, as numpy's ``passed_through`` writes it."""
    return int(np.rint((math.atan2(ly, lx) - first) / step))


def test_the_polynomial_is_within_its_bound_of_atan():
    t = np.linspace(0.0, 1.0, 2_000_001)
    error = np.abs(getattr(atan_unit, "py_func", atan_unit)(t) - np.arctan(t))
    assert 1e-5 < error.max() < ATAN_ERROR / 1.5  # the measured 1.15e-5, within the bound
    assert atan_unit(0.0) == 0.0


def test_the_band_is_ten_errors_in_beams():
    assert doubt_band(math.pi / 180) == pytest.approx(10 * ATAN_ERROR * 180 / math.pi)
    assert doubt_band(-math.pi / 180) == doubt_band(math.pi / 180)
    assert doubt_band(1e-4) > 0.5  # never trusted: the exact formula always


@pytest.mark.parametrize(("first", "step", "beams"), LAYOUTS)
def test_every_kind_of_direction_gets_the_formulas_beam(first, step, beams):
    """Random directions at every scale, the half-way points between beams and their
    neighbours a rounding away (where the polynomial is in doubt), the axes with signed
    zeros and the origin."""
    rng = np.random.default_rng(7)
    angle = rng.uniform(-math.pi, math.pi, 20_000)
    size = 10.0 ** rng.uniform(-3, 3, 20_000)
    points = [(float(d * math.cos(a)), float(d * math.sin(a)))
              for a, d in zip(angle, size, strict=True)]
    for k in range(-1, beams + 1):  # half-way points, one ulp either side in x and in y
        half = first + (k + 0.5) * step
        x, y = 2.0 * math.cos(half), 2.0 * math.sin(half)
        points += [(x, y), (math.nextafter(x, math.inf), y), (math.nextafter(x, -math.inf), y),
                   (x, math.nextafter(y, math.inf)), (x, math.nextafter(y, -math.inf))]
    points += [(sx * a, sy * b) for sx in (1.0, -1.0) for sy in (1.0, -1.0)
               for a, b in ((0.0, 1.0), (1.0, 0.0), (0.0, 0.0), (3.0, 3.0), (1e-300, 1.0))]
    band = doubt_band(step)
    got = [int(beam_of(x, y, first, step, band)) for x, y in points]
    want = [formula(x, y, first, step) for x, y in points]
    assert got == want
    assert len(set(want)) > beams // 2  # the directions reach most beams
