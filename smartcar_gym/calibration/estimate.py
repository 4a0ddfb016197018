"""Odometry parameters from calibration runs: integrate the counts again, fit the truth.

The ArbotiX driver turns each update's encoder deltas into travel (``/ ticks_meter``) and a
turn (``/ base_width``). ``integrate`` repeats that with other parameters; ``fit`` finds the
effective base width and the true travel per counted metre of each side (Borenstein's E_b,
and E_s with E_d = right / left) whose odometry ends where the robot truly ended, in least
squares over every run. A closed square cannot tell a scale error from none, so a fit needs a
straight run as well (as UMBmark's own scale calibration does).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from smartcar_gym.calibration.drives import Run

YAW_WEIGHT_M = 1.0  # metres of position error that weigh as one radian of heading error
MAX_ITERATIONS = 50
MAX_HALVINGS = 40


class CalibrationError(ValueError):
    """The runs cannot determine the parameters (e.g. no straight run, a car that never
    moved)."""


def integrate(ticks: np.ndarray, ticks_meter: float, base_width_m: float,
              left_scale: float = 1.0, right_scale: float = 1.0) -> tuple[float, float, float]:
    """The driver's dead reckoning over counts ``ticks`` (n, 2): end x, y (m), theta (rad).

    Upstream's step: travel d and turn th per update, position moved along ``theta - th``
    (``theta`` before the update); the first row is the reference (nothing moves there).
    """
    delta = np.diff(np.asarray(ticks, dtype=float), axis=0) / ticks_meter
    left, right = delta[:, 0] * left_scale, delta[:, 1] * right_scale
    d = (left + right) / 2.0
    th = (right - left) / base_width_m
    theta = np.cumsum(th)
    before = theta - th
    return (float(np.sum(d * np.cos(before - th))), float(np.sum(d * np.sin(before - th))),
            float(theta[-1]) if len(theta) else 0.0)


@dataclass(frozen=True)
class Estimate:
    """Fitted odometry parameters, in the controller's terms.

    ``base_width_m``: the effective track (what ``base_width`` should say). ``left_scale``,
    ``right_scale``: true wheel travel per metre odometry counts, per side. ``rms_m``: the
    root mean square of the fit's end-pose residuals (headings weighed as metres).
    """

    base_width_m: float
    left_scale: float
    right_scale: float
    rms_m: float

    @property
    def scale(self) -> float:
        """Mean true travel per counted metre: ``ticks_meter`` should be divided by it."""
        return (self.left_scale + self.right_scale) / 2.0

    @property
    def diameter_ratio(self) -> float:
        """Borenstein's E_d: right over left effective wheel diameter (1: equal)."""
        return self.right_scale / self.left_scale


def _residuals(params: np.ndarray, runs: Sequence[Run], ticks_meter: float,
               use_yaw: bool) -> np.ndarray:
    width, left, right = params
    out = []
    for run in runs:
        x, y, theta = integrate(run.ticks, ticks_meter, width, left, right)
        tx, ty, tyaw = run.true_end
        if not run.name.startswith("spin"):  # a spin's centre wanders by slip, not odometry
            out += [x - tx, y - ty]
        if use_yaw:
            out.append(YAW_WEIGHT_M * (theta - tyaw))
    return np.array(out)


def fit(runs: Sequence[Run], ticks_meter: float, base_width_m: float,
        use_yaw: bool = True) -> Estimate:
    """Least-squares base width and per-side scales that make odometry end at the truth.

    ``use_yaw``: fit the true end headings too (the simulator knows them; on a robot only a
    measured end position may be known). A spin's end position is left out: a skid-steer car's
    centre wanders a few centimetres while it spins in place, which no odometry parameter
    explains. Gauss-Newton from the configured values.
    """
    if not runs:
        raise CalibrationError("no calibration runs to fit")
    params = np.array([base_width_m, 1.0, 1.0])
    for _ in range(MAX_ITERATIONS):
        residual = _residuals(params, runs, ticks_meter, use_yaw)
        jacobian = np.empty((len(residual), 3))
        for i in range(3):
            h = 1e-6 * max(1.0, abs(params[i]))
            up, down = params.copy(), params.copy()
            up[i] += h
            down[i] -= h
            jacobian[:, i] = (_residuals(up, runs, ticks_meter, use_yaw)
                              - _residuals(down, runs, ticks_meter, use_yaw)) / (2 * h)
        scale = np.linalg.norm(jacobian, axis=0)
        if np.linalg.matrix_rank(jacobian / np.where(scale > 0, scale, 1.0), tol=1e-6) < 3:
            raise CalibrationError(
                "the runs do not determine base width, scale and wheel ratio together: use "
                f"a straight run with turns or squares (runs: {[r.name for r in runs]})"
            )
        step = np.linalg.lstsq(jacobian, -residual, rcond=None)[0]
        cost = float(residual @ residual)
        for _ in range(MAX_HALVINGS):  # backtrack: a full step may overshoot far from the fit
            trial = params + step
            if np.all(np.isfinite(trial)) and trial[0] > 0 and min(trial[1:]) > 0:
                new = _residuals(trial, runs, ticks_meter, use_yaw)
                if float(new @ new) <= cost:
                    break
            step = step / 2
        else:
            raise CalibrationError(
                f"the fit does not converge (base width, scales now {params.tolist()}): did the "
                "car move as commanded?")
        params = trial
        if np.max(np.abs(step) / np.maximum(np.abs(params), 1e-9)) < 1e-10:
            break
    residual = _residuals(params, runs, ticks_meter, use_yaw)
    rms = float(math.sqrt(np.mean(residual ** 2)))
    return Estimate(float(params[0]), float(params[1]), float(params[2]), rms)


@dataclass(frozen=True)
class RunError:
    """How far a run's odometry ended from the truth."""

    name: str
    position_m: float  # |odometry end - true end|
    heading_rad: float  # odometry theta - true yaw
    relative: float  # straight: distance error / true distance; spins: turn error / true turn

    @classmethod
    def of(cls, run: Run) -> RunError:
        (ox, oy, oth), (tx, ty, tyaw) = run.odom_end, run.true_end
        if run.name.startswith("spin"):
            relative = (oth - tyaw) / tyaw if tyaw else math.nan
        else:
            true = math.hypot(tx, ty)
            relative = (math.hypot(ox, oy) - true) / true if true else math.nan
        return cls(run.name, math.hypot(ox - tx, oy - ty), oth - tyaw, relative)


def umbmark_error(runs: Sequence[Run]) -> float:
    """Borenstein's E_max,syst: the larger distance, clockwise or counter-clockwise, between
    where odometry and the truth put the end of the squares (centre of gravity of each
    direction's runs)."""
    worst = 0.0
    for direction in ("square cw", "square ccw"):
        errors = [np.subtract(r.true_end[:2], r.odom_end[:2]) for r in runs
                  if r.name == direction]
        if errors:
            worst = max(worst, float(np.linalg.norm(np.mean(errors, axis=0))))
    return worst
