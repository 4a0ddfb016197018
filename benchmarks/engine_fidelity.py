"""The fidelity table of docs/engines.md: the same maneuvers on pybullet and MuJoCo.

    python benchmarks/engine_fidelity.py

Each row spawns the shipped car with the shipped controller config afresh on each engine and
drives it through the emulated ArbotiX base (smartcar_gym/calibration/engines_compared.py says
what each row measures). Deterministic: the same numbers on every run.
"""

from __future__ import annotations

import math

from smartcar_gym.calibration.engines_compared import MANEUVERS, relative_difference
from smartcar_gym.controller import load_controller_config
from smartcar_gym.model import load_model


def main() -> None:
    model, config = load_model(), load_controller_config()
    print("| maneuver | pybullet | MuJoCo | MuJoCo vs pybullet |")
    print("|---|---|---|---|")
    for maneuver in MANEUVERS:
        values = [maneuver.measure(model, config, engine) for engine in ("pybullet", "mujoco")]
        diff = relative_difference(values[1], values[0])
        cell = "" if math.isnan(diff) else f"{diff:+.1%}"
        print(f"| {maneuver.name} ({maneuver.unit}) | {values[0]:.4f} | {values[1]:.4f} | "
              f"{cell} |", flush=True)


if __name__ == "__main__":
    main()
