"""The planar engine's convergence check: the fidelity table's maneuvers at several substeps.

    python benchmarks/planar_convergence.py                  # about 20 s; deterministic
    python benchmarks/planar_convergence.py --substeps 0.04 0.02 0.01 0.005 0.002 0.001

The shipped pybullet fit on the shipped car, each maneuver with the planar engine's
``max_substep_s`` set to each value (the default, 0.02 s, first among the finer ones), and each
value's difference from the finest substep's. The maneuvers are those of
``calibration/engines_compared.py``; docs/planar.md shows the table and reads it.
"""

from __future__ import annotations

import argparse

from smartcar_gym.calibration import engines_compared
from smartcar_gym.calibration.engines_compared import MANEUVERS, relative_difference
from smartcar_gym.controller import load_controller_config
from smartcar_gym.model import load_model


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--substeps", type=float, nargs="+",
                        default=[0.035, 0.02, 0.01, 0.005, 0.002])
    parser.add_argument("--planar-params", default="pybullet")
    args = parser.parse_args()
    model, config = load_model(), load_controller_config()
    default = engines_compared.default_max_substep
    rows: dict[float, dict[str, float]] = {}
    try:
        for substep in args.substeps:
            engines_compared.default_max_substep = lambda engine, s=substep: s
            found = engines_compared.compare(
                model, config, ("planar",), MANEUVERS,
                {"planar": {"engine": "planar", "planar_params": args.planar_params}})
            rows[substep] = {name: row["planar"] for name, row in found.items()}
    finally:
        engines_compared.default_max_substep = default
    finest = rows[min(rows)]
    cols = [s for s in args.substeps if s != min(rows)]
    print("| maneuver | " + " | ".join(f"{s * 1000:g} ms" for s in args.substeps) + " | "
          + " | ".join(f"{s * 1000:g} ms vs {min(rows) * 1000:g} ms" for s in cols) + " |")
    print("|---" * (1 + len(args.substeps) + len(cols)) + "|")
    for maneuver in MANEUVERS:
        name = maneuver.name
        values = " | ".join(f"{rows[s][name]:.4f}" for s in args.substeps)
        diffs = []
        for s in cols:
            if name.startswith("odometry"):
                diffs.append(f"{(rows[s][name] - finest[name]) * 100:+.1f} cm")
            else:
                diffs.append(f"{relative_difference(rows[s][name], finest[name]):+.1%}")
        print(f"| {name} ({maneuver.unit}) | {values} | {' | '.join(diffs)} |", flush=True)


if __name__ == "__main__":
    main()
