"""Identify the planar engine's free parameters from recorded drives (``--fit planar``).

Every ``Recording`` (a physics engine's own drives, or a bag's) is replayed on the planar
engine: the robot spawned at rest at the recording's first true pose, the same ``cmd_vel`` each
controller period, through the same emulated board, PID and motors. The fit minimises, over all
recordings, how far the planar car's motion differs from the recorded one, in windows of
``WINDOW_S``: the displacement and turn over each window, expressed in the body frame of the
true pose at its start (so an error early in a drive does not count again later), scaled by
``POSITION_SCALE_M`` and ``YAW_SCALE_RAD``. A recording's windows are weighted so that every
recording counts alike, whatever its length. The board's integer PID makes the residual a
staircase of the parameters (a wheel settles on whole ticks per frame), so a gradient search
stalls at its first step; scipy's differential evolution searches ``SEARCH`` instead, each
generation's candidates replayed together as one batch of cars (``planar_replay``).

What each parameter needs to be seen (``EXCITATION``): spins in place (friction, the lateral
friction ratio), straight driving (the slip stiffness), slow driving (the gearbox's dead band),
a stop from speed (rolling resistance), turning in reverse (the load shift) and a reversal
out of a fast turn (the wheels' spin moment on the loads, ``spin_reaction``). A recording
set without one of them is refused with the maneuver named, unless those parameters are kept
(``keep``).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from smartcar_gym.calibration.planar_replay import FleetReplay
from smartcar_gym.calibration.recording import Recording
from smartcar_gym.controller import ArbotixConfig
from smartcar_gym.model import RobotModel
from smartcar_gym.sim.planar.model import load_shift_range
from smartcar_gym.sim.planar.params import KEYS, PlanarParams

WINDOW_S = 0.5
POSITION_SCALE_M = 0.01  # 2 cm/s of speed error over a window counts 1
YAW_SCALE_RAD = 0.02  # 0.04 rad/s of turn rate error counts 1
#: what the fit searches by default (the stiction speed is a numerical regularisation)
FREE = ("friction_scale", "lateral_friction_ratio", "slip_speed", "gearbox_friction_scale",
        "rolling_resistance", "load_shift_x", "spin_reaction")
#: searched on a linear scale (log space cannot reach 0 or a negative shift)
_LINEAR = ("rolling_resistance", "load_shift_x", "spin_reaction")
#: the load shift is searched within this share of the ground contacts' length (x extent),
#: and inside what they allow (``model.load_shift_range``: no contact would have to pull)
LOAD_SHIFT_SHARE = 0.1
#: a fit whose RMS scaled residual stays above this has not converged
CONVERGED_RMS = 3.0
MIN_SECONDS = 2.0  # of a maneuver, in all recordings together, for it to count as seen
#: but for a stop from speed (one period) and a reversal (its braking lasts a few tenths of a
#: second, while the car still moves the old way at this speed or more)
MIN_REVERSAL_S = 0.3
REVERSAL_SPEED = 0.15


class FitError(ValueError):
    """The recordings cannot identify the parameters, or the fit did not converge."""


@dataclass(frozen=True)
class Maneuver:
    """A kind of motion the fit needs: what it is, how to tell it from the commands (per
    controller period), and which parameters depend on it."""

    name: str
    description: str
    needed_by: tuple[str, ...]


EXCITATION = (
    Maneuver("spin in place", "|linear.x| <= 0.03 m/s, |angular.z| >= 0.3 rad/s",
             ("friction_scale", "lateral_friction_ratio")),
    Maneuver("straight driving", "|linear.x| >= 0.15 m/s, |angular.z| <= 0.15 rad/s",
             ("slip_speed", "lateral_friction_ratio")),
    Maneuver("slow driving", "0.02 <= |linear.x| <= 0.12 m/s, |angular.z| <= 0.3 rad/s",
             ("gearbox_friction_scale",)),
    Maneuver("stop from speed", "cmd_vel (0, 0) or none while truly moving at >= 0.1 m/s",
             ("rolling_resistance",)),
    Maneuver("turning in reverse", "linear.x <= -0.1 m/s, |angular.z| >= 0.5 rad/s",
             ("load_shift_x",)),
    Maneuver("reversal out of a turn", "linear.x against the true motion while it is still "
             f">= {REVERSAL_SPEED:g} m/s, |angular.z| >= 0.5 rad/s", ("spin_reaction",)),
)


def _classes(recording: Recording) -> dict[str, int]:
    """How many controller periods of each ``EXCITATION`` maneuver a recording holds."""
    v, w = recording.commands[:, 0], recording.commands[:, 1]
    silent = ~np.isfinite(v)
    v, w = np.nan_to_num(v), np.nan_to_num(w)
    av, aw = np.abs(v), np.abs(w)
    step = np.diff(recording.truth[:, :2], axis=0)
    speed = np.hypot(step[:, 0], step[:, 1]) * recording.rate_hz
    before = np.concatenate([[0.0], speed[:-1]])  # the true speed when the command arrived
    yaw = recording.truth[:-1, 2]
    ahead = (step[:, 0] * np.cos(yaw) + step[:, 1] * np.sin(yaw)) * recording.rate_hz
    ahead = np.concatenate([[0.0], ahead[:-1]])  # the true forward speed then
    stopped = silent | ((av < 1e-3) & (aw < 1e-3))
    return {
        "spin in place": int(np.sum(~silent & (av <= 0.03) & (aw >= 0.3))),
        "straight driving": int(np.sum(~silent & (av >= 0.15) & (aw <= 0.15))),
        "slow driving": int(np.sum(~silent & (av >= 0.02) & (av <= 0.12) & (aw <= 0.3))),
        "stop from speed": int(np.sum(stopped & (before >= 0.1))),
        "turning in reverse": int(np.sum(~silent & (v <= -0.1) & (aw >= 0.5))),
        "reversal out of a turn": int(np.sum(~silent & (v * ahead < 0.0) & (av >= 0.1)
                                             & (np.abs(ahead) >= REVERSAL_SPEED)
                                             & (aw >= 0.5))),
    }


def check_excitation(recordings: Sequence[Recording], free: Sequence[str]) -> dict[str, float]:
    """Seconds of each maneuver in all recordings; FitError naming the first one missing that
    a free parameter needs (and how to keep those parameters instead)."""
    seconds = dict.fromkeys((m.name for m in EXCITATION), 0.0)
    for r in recordings:
        for name, count in _classes(r).items():
            seconds[name] += count / r.rate_hz
    for m in EXCITATION:
        needs = [p for p in m.needed_by if p in free]
        enough = {"stop from speed": 1.0 / recordings[0].rate_hz,
                  "reversal out of a turn": MIN_REVERSAL_S}.get(m.name, MIN_SECONDS)
        if needs and seconds[m.name] < enough:
            raise FitError(
                f"too little excitation: the recordings hold {seconds[m.name]:.1f} s of "
                f"{m.name} ({m.description}; at least {enough:g} s needed) for "
                f"{', '.join(needs)}; record it, or keep {'it' if len(needs) == 1 else 'them'} "
                f"with --keep {','.join(needs)}")
    return seconds


def window_motion(truth: np.ndarray, periods: int) -> np.ndarray:
    """(W, 3): the displacement (body frame of the window's first pose) and the turn over each
    window of ``periods`` controller periods."""
    starts = np.arange(0, len(truth) - periods, periods)
    a, b = truth[starts], truth[starts + periods]
    dx, dy = b[:, 0] - a[:, 0], b[:, 1] - a[:, 1]
    c, s = np.cos(a[:, 2]), np.sin(a[:, 2])
    return np.stack([c * dx + s * dy, -s * dx + c * dy, b[:, 2] - a[:, 2]], axis=1)


def residuals(recording: Recording, simulated: tuple[np.ndarray, np.ndarray]) -> np.ndarray:
    """Scaled window residuals of a replay (its true poses and odometry) against its
    recording, flat: the true motion's, and the odometry's where the recording has it (the
    wheels' motion: with both, the fit sees how much the tyres slip). Weighted so that a
    recording counts as one whatever its length."""
    periods = max(1, round(WINDOW_S * recording.rate_hz))
    scale = np.array([POSITION_SCALE_M, POSITION_SCALE_M, YAW_SCALE_RAD])
    parts = [(window_motion(simulated[0], periods) - window_motion(recording.truth, periods))
             / scale]
    if recording.odom is not None:
        parts.append((window_motion(simulated[1], periods)
                       - window_motion(recording.odom, periods)) / scale)
    r = np.concatenate(parts)
    return (r / math.sqrt(max(1, len(r)))).ravel()


@dataclass(frozen=True)
class FitResult:
    """The fitted parameters, the RMS scaled residual per recording before (the starting
    parameters) and after, the excitation seen (s per maneuver) and the evaluations made."""

    params: PlanarParams
    before: dict[str, float]
    after: dict[str, float]
    excitation: dict[str, float]
    evaluations: int
    free: tuple[str, ...]

    @property
    def rms(self) -> float:
        """RMS of the per-recording residuals after the fit."""
        return float(np.sqrt(np.mean(np.square(list(self.after.values())))))


#: the box the search explores (log-uniform but for ``_LINEAR``), inside ``RANGES``: the slip
#: speeds down to 0.2 mm/s where the 20 ms substep was checked against 2 ms (docs/planar.md,
#: "Integration and step")
SEARCH: dict[str, tuple[float, float]] = {
    "friction_scale": (0.3, 3.0),
    "lateral_friction_ratio": (0.7, 1.5),
    "slip_speed": (0.0002, 0.05),
    "gearbox_friction_scale": (0.3, 3.0),
    "rolling_resistance": (0.0, 0.05),
    "spin_reaction": (0.0, 1.5),
}


class _Search:
    """Parameters <-> the search vector (log space but for ``_LINEAR``), costs of many."""

    def __init__(self, fleet: FleetReplay, start: PlanarParams, free: Sequence[str]) -> None:
        self.fleet, self.start, self.free = fleet, start, tuple(free)
        self.evaluations = 0
        low, high = load_shift_bounds(fleet, start)
        xs = [c[0] for c in fleet.body.model_with(start).contacts]
        reach = LOAD_SHIFT_SHARE * (max(xs) - min(xs))
        self.search = {**SEARCH, "load_shift_x": (max(start.load_shift_x - reach, low),
                                                  min(start.load_shift_x + reach, high))}

    def params(self, x: np.ndarray) -> PlanarParams:
        values = {k: (float(v) if k in _LINEAR else float(math.exp(v)))
                  for k, v in zip(self.free, x, strict=True)}
        return dataclasses.replace(self.start, **values, source="fit")

    def bounds(self) -> list[tuple[float, float]]:
        box = self.search
        return [box[k] if k in _LINEAR else (math.log(box[k][0]), math.log(box[k][1]))
                for k in self.free]

    def per_recording(self, candidates: Sequence[PlanarParams]) -> list[dict[str, float]]:
        """Each candidate's RMS scaled residual per recording."""
        self.evaluations += len(candidates)
        out = []
        for replays in self.fleet.run(candidates):
            row = {}
            for r, sim in zip(self.fleet.recordings, replays, strict=True):
                res = residuals(r, sim)
                row[r.name] = float(np.sqrt(np.sum(res * res) / (3.0 if r.odom is None
                                                                   else 6.0)))
            out.append(row)
        return out

    def costs(self, xs: np.ndarray) -> np.ndarray:
        """Sum of squared scaled residuals of each column of ``xs`` (scipy's vectorised
        call: parameters x candidates)."""
        xs = np.atleast_2d(np.asarray(xs).T)
        rows = self.per_recording([self.params(x) for x in xs])
        return np.array([sum(v * v for v in row.values()) for row in rows])


def load_shift_bounds(fleet: FleetReplay, start: PlanarParams) -> tuple[float, float]:
    """The ``load_shift_x`` the robot's ground contacts allow (``model.load_shift_range``);
    FitError when ``start``'s own lies outside them (the robot would tip over)."""
    neutral = dataclasses.replace(start, load_shift_x=0.0)
    contacts = np.array(fleet.body.model_with(neutral).contacts)
    low, high = load_shift_range(contacts[:, :2])  # the rows are from the centre of mass
    if not low <= start.load_shift_x <= high:
        raise FitError(f"the start's planar.load_shift_x {start.load_shift_x:g} m (from "
                       f"{start.source}) would tip this robot over: its contacts allow "
                       f"[{low:.6g}, {high:.6g}] m; start from another value (--start)")
    return low, high


def fit(model: RobotModel, config: ArbotixConfig, recordings: Sequence[Recording],
        start: PlanarParams | None = None, keep: Sequence[str] = (),
        generations: int = 40, seed: int = 0) -> FitResult:
    """Fit the planar parameters (``FREE`` minus ``keep``) to ``recordings``: scipy's
    differential evolution over ``SEARCH`` (a population of 8 per free parameter, every
    generation replayed as one batch of cars), at most ``generations`` generations.

    FitError when the recordings lack a maneuver a free parameter needs, or when the fit ends
    with an RMS scaled residual above ``CONVERGED_RMS`` (the message gives it).
    """
    from scipy.optimize import differential_evolution

    if not recordings:
        raise FitError("no recordings to fit to")
    unknown = sorted(set(keep) - set(KEYS))
    if unknown:
        raise FitError(f"--keep {unknown[0]}: not a planar parameter; the parameters are "
                       f"{', '.join(KEYS)}")
    free = tuple(k for k in FREE if k not in keep)
    start = PlanarParams() if start is None else start
    excitation = check_excitation(recordings, free)
    fleet = FleetReplay(model, config, recordings)
    try:
        search = _Search(fleet, start, free)
        params = start
        if free:
            found = differential_evolution(
                search.costs, search.bounds(), popsize=8, maxiter=generations, tol=0.005,
                seed=seed, polish=False, vectorized=True, updating="deferred", init="sobol")
            params = search.params(found.x)
        before, after = search.per_recording([start, params])
    finally:
        fleet.close()
    result = FitResult(params, before, after, excitation, search.evaluations, free)
    if not result.rms <= CONVERGED_RMS:
        worst = max(after, key=after.get)
        raise FitError(f"the fit did not converge: RMS scaled residual {result.rms:.2f} "
                       f"(at most {CONVERGED_RMS:g} expected; worst: {worst} "
                       f"{after[worst]:.2f}) after {search.evaluations} evaluations")
    return result


def describe(result: FitResult) -> dict[str, Any]:
    """The fit's provenance for the parameter file's ``fit:`` section."""
    return {
        "free": list(result.free),
        "evaluations": result.evaluations,
        "rms_scaled_residual": round(result.rms, 4),
        "residual_per_maneuver": {k: [round(result.before[k], 4), round(v, 4)]
                                  for k, v in result.after.items()},
        "excitation_s": {k: round(v, 1) for k, v in result.excitation.items()},
        "residual_scales": {"window_s": WINDOW_S, "position_m": POSITION_SCALE_M,
                            "yaw_rad": YAW_SCALE_RAD},
    }
