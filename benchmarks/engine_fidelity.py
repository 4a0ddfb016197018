"""The fidelity table of docs/engines.md: the same maneuvers on pybullet, MuJoCo and the planar
engine (its shipped fit to each physics engine).

    python benchmarks/engine_fidelity.py            # about a minute; deterministic

Each row spawns the shipped car with the shipped controller config afresh on each engine and
drives it through the emulated ArbotiX base (smartcar_gym/calibration/engines_compared.py says
what each row measures). "planar (pybullet fit)" runs ``planar_params="pybullet"`` (the
default), "planar (MuJoCo fit)" ``planar_params="mujoco"``; each is compared with the engine it
was fitted to. Deterministic: the same numbers on every run.
"""

from __future__ import annotations

import math

from smartcar_gym.calibration.engines_compared import MANEUVERS, compare, relative_difference
from smartcar_gym.controller import load_controller_config
from smartcar_gym.model import load_model

COLUMNS = {
    "pybullet": {"engine": "pybullet"},
    "MuJoCo": {"engine": "mujoco"},
    "planar (pybullet fit)": {"engine": "planar", "planar_params": "pybullet"},
    "planar (MuJoCo fit)": {"engine": "planar", "planar_params": "mujoco"},
}
#: (column, the column it is compared with)
DIFFERENCES = (("MuJoCo", "pybullet"), ("planar (pybullet fit)", "pybullet"),
               ("planar (MuJoCo fit)", "MuJoCo"))


def main() -> None:
    model, config = load_model(), load_controller_config()
    names = list(COLUMNS)
    header = [*names, *(f"{a} vs {b}" for a, b in DIFFERENCES)]
    print("| maneuver | " + " | ".join(header) + " |")
    print("|---" * (len(header) + 1) + "|")
    for maneuver in MANEUVERS:
        row = compare(model, config, tuple(names), (maneuver,), COLUMNS)[maneuver.name]
        diffs = []
        for a, b in DIFFERENCES:
            if maneuver.name.startswith("odometry"):  # gated in metres, not relative
                diffs.append(f"{(row[a] - row[b]) * 100:+.1f} cm")
            else:
                diff = relative_difference(row[a], row[b])
                diffs.append("" if math.isnan(diff) else f"{diff:+.1%}")
        values = " | ".join(f"{row[n]:.4f}" for n in names)
        print(f"| {maneuver.name} ({maneuver.unit}) | {values} | {' | '.join(diffs)} |",
              flush=True)


if __name__ == "__main__":
    main()
