"""Domain randomisation: the ``randomize`` env argument, its ranges, and one draw per episode.

``randomize`` is ``None`` (the nominal robot), ``"default"`` (the shipped preset,
``smartcar_gym/config/randomization.yaml``), a dict, or a YAML file of the same mapping:
``factor: [low, high]`` (or one number: fixed). Each episode draws every factor uniformly in its
range from the env's generator; a factor left out keeps its nominal value. The draw makes a
``Variation`` of the robot, a ground friction and a start pose.

An env uses it in three places (``SmartCarEnv`` does)::

    self.randomization = Randomization.from_spec(randomize)         # __init__: None or one
    draw = self.randomization.apply(self.np_random, self.sim, self.robot)  # after sim.reset()
    self.robot.spawn(*draw.start_pose)                               # and info["randomization"]
"""

from __future__ import annotations

import difflib
import math
import os
from collections.abc import Mapping
from dataclasses import dataclass, fields
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from smartcar_gym.checks import is_real
from smartcar_gym.controller.latency import MAX_LATENCY_PERIODS
from smartcar_gym.envs.robots.variation import Variation
from smartcar_gym.sim.contracts import BASE
from smartcar_gym.sim.dynamics import set_lateral_friction

#: the shipped presets and their files (in smartcar_gym/config): ``default`` every factor a
#: real smartcar varies in; ``odometry`` only what makes its odometry drift (the true wheel
#: radius and track, the encoders' scales and slip), for policies that steer by odometry
PRESETS = {"default": "randomization.yaml", "odometry": "randomization_odometry.yaml"}
DEFAULT_PRESET = PRESETS["default"]


@dataclass(frozen=True)
class Factor:
    """One randomised quantity: its nominal value, the widest range accepted, what it is."""

    name: str
    nominal: float
    allowed: tuple[float, float]
    unit: str
    doc: str
    integer: bool = False


#: every factor, in the order they are drawn (the order is part of the seeded draw)
FACTORS: tuple[Factor, ...] = (
    Factor("ground_friction", 1.0, (0.1, 5.0), "x nominal",
           "lateral friction of the ground plane (nominal 1.0; a contact multiplies the "
           "ground's and the wheel's)"),
    Factor("wheel_friction", 1.0, (0.1, 5.0), "x nominal",
           "lateral friction of the drive wheels"),
    Factor("base_mass", 1.0, (0.1, 10.0), "x nominal",
           "mass and inertia of base_link (payload, battery)"),
    Factor("wheel_mass", 1.0, (0.1, 10.0), "x nominal", "mass and inertia of each drive wheel"),
    Factor("stall_torque", 1.0, (0.1, 10.0), "x nominal",
           "motor stall torque (battery voltage, motor spread)"),
    Factor("no_load_speed", 1.0, (0.1, 10.0), "x nominal", "motor no-load speed"),
    Factor("gearbox_friction", 1.0, (0.0, 10.0), "x nominal",
           "gearbox Coulomb friction at the wheels"),
    Factor("reflected_inertia", 1.0, (0.0, 10.0), "x nominal",
           "rotor inertia seen at the wheels"),
    Factor("wheel_radius", 1.0, (0.5, 2.0), "x nominal",
           "true drive wheel radius (tyre wear, pressure); the encoders still assume the "
           "model's"),
    Factor("track", 1.0, (0.5, 2.0), "x nominal",
           "true effective track against the model's (the YAML's base_width is kept)"),
    Factor("left_encoder_scale", 1.0, (0.5, 2.0), "x ticks_meter",
           "true ticks per metre of the left encoder against the YAML's ticks_meter"),
    Factor("right_encoder_scale", 1.0, (0.5, 2.0), "x ticks_meter",
           "the same for the right encoder"),
    Factor("encoder_noise", 0.0, (0.0, 20.0), "ticks",
           "standard deviation of each encoder reading's jitter (not accumulated)"),
    Factor("encoder_slip", 0.0, (0.0, 0.5), "",
           "standard deviation of the relative error of the ticks counted between two "
           "readings (accumulated)"),
    Factor("latency", 0, (0, MAX_LATENCY_PERIODS), "controller periods",
           "cmd_vel delay: a command acts this many updates later", integer=True),
    Factor("start_x", 0.0, (-0.5, 0.5), "m",
           "true start position x: the odometry still starts at 0 (a hand-placed robot)"),
    Factor("start_y", 0.0, (-0.5, 0.5), "m", "true start position y"),
    Factor("start_yaw", 0.0, (-math.pi, math.pi), "rad", "true start heading"),
)
FACTOR_NAMES = tuple(f.name for f in FACTORS)
_ROBOT_FACTORS = {f.name for f in fields(Variation)} - {"noise_seed"}


@dataclass(frozen=True)
class Draw:
    """What was drawn for one episode: every factor's value and the encoder noise's seed."""

    values: dict[str, float]
    noise_seed: int

    @property
    def variation(self) -> Variation:
        """The robot's part of the draw."""
        return Variation(noise_seed=self.noise_seed,
                         **{k: v for k, v in self.values.items() if k in _ROBOT_FACTORS})

    @property
    def start_pose(self) -> tuple[float, float, float]:
        """Where the robot truly starts: x (m), y (m), yaw (rad)."""
        return self.values["start_x"], self.values["start_y"], self.values["start_yaw"]

    @property
    def info(self) -> dict[str, float | int]:
        """The draw as ``info["randomization"]``: every factor, and ``noise_seed``."""
        return {**self.values, "noise_seed": self.noise_seed}


@dataclass(frozen=True)
class Randomization:
    """Checked ranges ``{factor: (low, high)}`` for every factor; ``source`` names the spec."""

    ranges: dict[str, tuple[float, float]]
    source: str = "randomize"

    @classmethod
    def from_spec(cls, spec: Any) -> Randomization | None:
        """``None``, a preset name, a YAML path, a mapping, or a ``Randomization``."""
        if spec is None or isinstance(spec, Randomization):
            return spec
        if isinstance(spec, str) and spec in PRESETS:
            return cls.from_file(resources.files("smartcar_gym") / "config" / PRESETS[spec],
                                 f"randomize preset {spec!r}")
        if isinstance(spec, str | os.PathLike):
            path = Path(spec)
            if not path.is_file():
                raise ValueError(
                    f"randomize={os.fspath(spec)!r} is neither a preset {tuple(PRESETS)} nor a "
                    f"YAML file: {'not a file' if path.exists() else 'no such file'}"
                )
            return cls.from_file(path, f"randomize file {os.fspath(path)}")
        if isinstance(spec, Mapping):
            return cls.from_mapping(spec)
        raise TypeError(
            f"randomize must be None, a preset name {tuple(PRESETS)}, a YAML file path or a dict "
            f"{{factor: [low, high]}}, got {type(spec).__name__}: {spec!r}"
        )

    @classmethod
    def from_file(cls, path: Any, source: str) -> Randomization:
        """Read a YAML mapping of ranges (``path``: a file or a package resource)."""
        try:
            text = path.read_text(encoding="utf-8")
        except (OSError, UnicodeDecodeError) as err:
            raise ValueError(f"{source}: cannot read it: {err}") from None
        try:
            data = yaml.safe_load(text)
        except yaml.YAMLError as err:
            mark = getattr(err, "problem_mark", None)
            where = f"line {mark.line + 1}, column {mark.column + 1}: " if mark else ""
            problem = getattr(err, "problem", None) or str(err)
            raise ValueError(f"{source}: not valid YAML: {where}{problem}") from None
        if data is None:
            data = {}
        if not isinstance(data, Mapping):
            raise ValueError(f"{source}: expected a mapping of factor: [low, high], got "
                             f"{type(data).__name__}")
        return cls.from_mapping(data, source)

    @classmethod
    def from_mapping(cls, data: Mapping, source: str = "randomize") -> Randomization:
        """Check every entry of ``{factor: [low, high] or value}``; nominal for the rest."""
        unknown = [key for key in data if key not in FACTOR_NAMES]
        if unknown:
            key = unknown[0]
            close = difflib.get_close_matches(str(key), FACTOR_NAMES, n=1)
            hint = f" (did you mean {close[0]!r}?)" if close else ""
            raise ValueError(f"{source}: unknown factor {key!r}{hint}; factors: "
                             f"{', '.join(FACTOR_NAMES)}")
        ranges = {}
        for factor in FACTORS:
            if factor.name in data:
                ranges[factor.name] = check_range(factor, data[factor.name], source)
            else:
                ranges[factor.name] = (factor.nominal, factor.nominal)
        return cls(ranges, source)

    def draw(self, rng: np.random.Generator) -> Draw:
        """One draw: a uniform number per factor, in ``FACTORS`` order, then the noise seed.

        Exactly ``len(FACTORS) + 1`` numbers are taken from ``rng`` whatever the ranges, so
        specs that differ only in their ranges see the same stream.
        """
        values: dict[str, float] = {}
        for factor in FACTORS:
            low, high = self.ranges[factor.name]
            u = float(rng.random())
            if factor.integer:
                values[factor.name] = int(min(high, low + math.floor(u * (high - low + 1))))
            else:
                values[factor.name] = low + (high - low) * u
        return Draw(values, int(rng.integers(0, 2**63 - 1)))

    def apply(self, rng: np.random.Generator, sim: Any, robot: Any) -> Draw:
        """Draw, set the ground's friction in ``sim`` (just reset) and ``robot.vary``.

        The caller then spawns the robot at ``draw.start_pose``.
        """
        draw = self.draw(rng)
        scale = draw.values["ground_friction"]
        if scale != 1.0:
            set_lateral_friction(sim.body("plane"), [BASE], sim.ground_friction * scale)
        robot.vary(draw.variation)
        return draw


def check_range(factor: Factor, value: Any, source: str = "randomize") -> tuple[float, float]:
    """``value`` (``[low, high]`` or one number) as a range inside ``factor.allowed``."""
    lo, hi = factor.allowed
    kind = "integers" if factor.integer else "numbers"
    unit = f" {factor.unit}" if factor.unit else ""
    expected = (f"{source}: {factor.name}: expected [low, high] ({kind}{unit}) with "
                f"{lo:g} <= low <= high <= {hi:g}, or one such number")
    if isinstance(value, list | tuple):
        if len(value) != 2:
            raise ValueError(f"{expected}; got {len(value)} values: {value!r}")
        pair = tuple(value)
    else:
        pair = (value, value)
    for item in pair:
        if not (is_real(item) and math.isfinite(item)):
            raise ValueError(f"{expected}; got {value!r}")
        if factor.integer and item != int(item):
            raise ValueError(f"{expected}; got {value!r}, not whole numbers")
    low, high = (int(v) if factor.integer else float(v) for v in pair)
    if low > high:
        raise ValueError(f"{expected}; got low {low:g} > high {high:g}")
    if low < lo or high > hi:
        raise ValueError(f"{expected}; got {value!r}, outside the accepted range")
    return low, high
