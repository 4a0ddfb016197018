"""A 2D laser scan as ``sensor_msgs/LaserScan`` carries it, and its part of an observation.

No simulator here: a ROS node turns the ``/scan`` messages of a real scanner into the same
observation entries with ``scan_sectors`` and ``scan_entry``. Ranges follow REP 117: ``+inf``
where nothing was hit within ``range_max``, ``-inf`` where something is closer than
``range_min``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from smartcar_gym import checks
from smartcar_gym.envs.observation import Entry

SCAN_KEY = "scan"  # the name of the scan's observation entry


#: the most beams a scan may have (a 0.1-degree lidar's 3,600 fit): what a config declares
#: cannot make every step cast and keep without bound
MAX_BEAMS = 4096
#: the fastest a laser may scan (Hz; real planar lidars scan at 5-40 Hz)
MAX_RATE_HZ = 100.0


@dataclass(frozen=True)
class LaserConfig:
    """A planar scanner: beams at ``angle_min + i * angle_increment`` (rad, counter-clockwise
    from the laser frame's x axis, REP 103) up to ``angle_max``; ranges in
    [``range_min``, ``range_max``] m; one scan every ``1 / rate_hz`` s; Gaussian range noise of
    ``noise_std_m`` on every return (0: none).

    The defaults are a 360-beam, 1-degree, 0.12-3.5 m rotating lidar (the class of
    TurtleBot3's LDS-01) scanning at the controller's 10 Hz (the LDS-01 turns at 5 Hz).
    """

    angle_min: float = -math.pi
    angle_max: float = math.pi - math.radians(1.0)
    angle_increment: float = math.radians(1.0)
    range_min: float = 0.12
    range_max: float = 3.5
    rate_hz: float = 10.0
    noise_std_m: float = 0.0
    frame_id: str = "laser"

    def __post_init__(self) -> None:
        for name in ("angle_min", "angle_max"):
            value = getattr(self, name)
            if not (checks.is_real(value) and math.isfinite(value)):
                raise ValueError(f"laser {name} must be a finite number of radians, got {value!r}")
        checks.positive_number("laser angle_increment", self.angle_increment)
        if not self.angle_min <= self.angle_max:
            raise ValueError(f"laser angle_max ({self.angle_max!r}) must not be below angle_min "
                             f"({self.angle_min!r})")
        if self.angle_max - self.angle_min >= 2 * math.pi + 1e-9:
            raise ValueError(f"laser angles span {self.angle_max - self.angle_min:g} rad: at "
                             "most one turn (2 pi)")
        checks.positive_number("laser range_max", self.range_max)
        if not (checks.is_real(self.range_min) and 0 <= self.range_min < self.range_max):
            raise ValueError(f"laser range_min must be a number in [0, range_max="
                             f"{self.range_max:g}), got {self.range_min!r}")
        checks.positive_number("laser rate_hz", self.rate_hz, MAX_RATE_HZ,
                               "planar lidars scan at 5-40 Hz")
        checks.non_negative_number("laser noise_std_m", self.noise_std_m)
        if self.beams > MAX_BEAMS:
            raise ValueError(f"laser angle_increment {self.angle_increment!r} gives "
                             f"{self.beams:.3g} beams over its angles: at most {MAX_BEAMS} "
                             "(raise angle_increment)")

    @property
    def beams(self) -> int:
        """Number of ranges in a scan (ROS: (angle_max - angle_min) / angle_increment + 1)."""
        return int(math.floor((self.angle_max - self.angle_min) / self.angle_increment + 1e-6)) + 1

    @property
    def angles(self) -> np.ndarray:
        """The beam angles (rad) in the laser frame."""
        return self.angle_min + self.angle_increment * np.arange(self.beams)


@dataclass(frozen=True)
class LaserScan:
    """The fields of a ``sensor_msgs/LaserScan`` (``stamp_s``: simulated time of the scan)."""

    stamp_s: float
    frame_id: str
    angle_min: float
    angle_max: float
    angle_increment: float
    time_increment: float
    scan_time: float
    range_min: float
    range_max: float
    ranges: np.ndarray  # float32, REP 117
    intensities: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.float32))


def scan_sectors(ranges: np.ndarray, range_max: float, sectors: int) -> np.ndarray:
    """The scan as ``sectors`` values: the nearest range in each of ``sectors`` consecutive
    groups of beams (sizes differing by at most one beam), in beam order. ``+inf`` (nothing
    within range) reads ``range_max``, ``-inf`` (closer than ``range_min``) reads 0. An
    ``(N, beams)`` array of N scans gives ``(N, sectors)``."""
    ranges = np.asarray(ranges, dtype=np.float64)
    beams = ranges.shape[-1]
    if not 1 <= sectors <= beams:
        raise ValueError(f"a scan of {beams} beams gives 1 to {beams} sectors, got {sectors}")
    values = np.where(np.isneginf(ranges), 0.0, np.minimum(ranges, range_max))
    starts = (np.arange(sectors) * beams) // sectors
    return np.minimum.reduceat(values, starts, axis=-1)


def sector_names(sectors: int) -> tuple[str, ...]:
    """``scan_00``, ``scan_01``, ... (two digits up to 100 sectors)."""
    width = max(2, len(str(sectors - 1)))
    return tuple(f"scan_{i:0{width}d}" for i in range(sectors))


def scan_entry(config: LaserConfig, sectors: int) -> Entry:
    """The observation entry of a scan's sectors (``scan_sectors`` of its ranges)."""
    checks.positive_int("scan_sectors", sectors, config.beams,
                        f"the laser has {config.beams} beams")
    range_max = config.range_max
    width = math.degrees(config.angle_increment * config.beams / sectors)
    return Entry(SCAN_KEY, sector_names(sectors), 0.0, range_max, "m",
                 f"laser: nearest range in each of {sectors} sectors of about {width:g} deg, "
                 "from angle_min counter-clockwise (nothing within range_max: range_max)",
                 ("0", "range_max"))
