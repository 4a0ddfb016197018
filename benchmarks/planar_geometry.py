"""Time per call of the planar engine's geometry: N cars' laser scans and clearances.

    python benchmarks/planar_geometry.py [--cars 4096] [--obstacles 8] [--repeats 7]

The shipped laser (``LaserConfig()``: 360 beams, 3.5 m) on N cars at random poses among
``ObstacleField`` layouts (64 distinct ones, N cars over them), as the planar engine would call
it: ``cast`` in the world frame (each car's beams turned by its yaw), ``cast`` in each car's
laser frame (``Shapes2D.relative_to``: beams shared by every car, the faster form), and
``clearance`` of the shipped car's footprint (sphere wheels) within 0.3 m. One car is timed too
(a single env's scan). Prints the median and the best of ``--repeats`` calls (wall clock; on a
shared machine the best is the steadier figure) and the load average.
"""

from __future__ import annotations

import argparse
import math
import os
import statistics
import time
import warnings

import numpy as np

from smartcar_gym.envs.sensors.scan import LaserConfig
from smartcar_gym.envs.tasks.obstacles import ObstacleField
from smartcar_gym.model import load_model
from smartcar_gym.sim.planar.geometry import Shapes2D, cast, clearance, footprint


def timed(call, repeats: int) -> tuple[float, float, float]:
    """Median and best wall-clock seconds of ``repeats`` calls (after one warm-up call), and
    the best CPU seconds of this process."""
    call()
    times, cpu = [], []
    for _ in range(repeats):
        start, start_cpu = time.perf_counter(), time.process_time()
        call()
        times.append(time.perf_counter() - start)
        cpu.append(time.process_time() - start_cpu)
    return statistics.median(times), min(times), min(cpu)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--cars", type=int, default=4096)
    parser.add_argument("--obstacles", type=int, default=8)
    parser.add_argument("--repeats", type=int, default=7)
    args = parser.parse_args()
    rng = np.random.default_rng(0)
    field = ObstacleField(count=args.obstacles, half_extent_m=2.0)
    layouts = [field.sample(rng, np.zeros(2), np.array([1.5, 0.5])) for _ in range(64)]
    n = args.cars
    shapes = Shapes2D.from_layouts([layouts[i % len(layouts)] for i in range(n)])
    poses = np.c_[rng.uniform(-2.0, 2.0, (n, 2)), rng.uniform(-math.pi, math.pi, n)]
    laser = LaserConfig()
    beams = laser.angles
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        car = footprint(load_model(mappings={"laser": "true"}))

    cases = {
        "scan, world frame": lambda: cast(poses[:, :2], poses[:, 2:] + beams, laser.range_max,
                                          shapes),
        "scan, laser frames": lambda: cast(np.zeros((n, 2)), beams, laser.range_max,
                                           shapes.relative_to(poses)),
        "scan, one car": lambda: cast(poses[:1, :2], poses[:1, 2:] + beams, laser.range_max,
                                      Shapes2D.from_layout(layouts[0])),
        "clearance": lambda: clearance(car, poses, shapes, 0.3),
    }
    hits = cast(poses[:, :2], poses[:, 2:] + beams, laser.range_max, shapes).hit.mean()
    print(f"{n} cars x {len(beams)} beams x {args.obstacles} obstacles "
          f"({100 * hits:.0f} % of the beams hit), {args.repeats} calls each:")
    for name, call in cases.items():
        median, best, cpu = timed(call, args.repeats)
        per = "" if name == "scan, one car" else f"  ({1e9 * best / n:.0f} ns per car)"
        print(f"  {name:20s} median {1e3 * median:7.2f} ms  best {1e3 * best:7.2f} ms  "
              f"(CPU {1e3 * cpu:7.2f} ms){per}")
    print(f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} CPUs")


if __name__ == "__main__":
    main()
