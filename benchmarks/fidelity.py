"""Fidelity of event-driven stepping: every gate figure at 1 ms, 2 ms and the default 10 ms.

    python benchmarks/fidelity.py [--substeps 0.001 0.002 0.005 0.01]

The scenarios are ``smartcar_gym.calibration.fidelity.measure`` (the ones the gates in
``tests/test_fidelity.py`` use): steady speed at 0.2 and 0.4 m/s, odometry going straight, a
30 s spin at 1 rad/s, a coast-down from 0.3 m/s, 20 s of seeded random commands, stability. The
1 ms column shows how much the 2 ms reference itself moves when refined: tolerances are sized
by that.
"""

from __future__ import annotations

import argparse
import math
import time

from smartcar_gym.calibration.fidelity import measure
from smartcar_gym.controller import load_controller_config
from smartcar_gym.model import load_model


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--substeps", type=float, nargs="+", default=[0.001, 0.002, 0.01])
    args = parser.parse_args()
    model, config = load_model(), load_controller_config()
    for contact in ("sphere", "urdf"):
        figs = []
        for substep in args.substeps:
            start = time.perf_counter()
            figs.append(measure(model, config, contact, substep))
            figs[-1].seconds = time.perf_counter() - start  # type: ignore[attr-defined]
        ref = next(f for f in figs if f.max_substep_s == 0.002)
        head = " | ".join(f"{f.max_substep_s * 1000:g} ms" for f in figs)
        print(f"\nwheel_contact={contact}\n\n| figure | {head} |\n|---|"
              + "---:|" * len(figs))

        def row(label: str, values: list[str]) -> None:
            print(f"| {label} | {' | '.join(values)} |")

        def pct(value: float, of: float) -> str:
            return f"{100 * (value / of - 1):+.1f} %"

        for speed in (0.2, 0.4):
            row(f"steady wheel speed at {speed} m/s", [
                f"{f.steady_speed_m_s[speed]:.4f} ({pct(f.steady_speed_m_s[speed], speed)})"
                for f in figs])
        row("odometry vs truth, 5 s straight", [f"{100 * f.odometry_error_straight:+.3f} %"
                                                 for f in figs])
        row("spin 30 s at 1 rad/s: revolutions", [
            f"{f.spin_revolutions:.3f} ({pct(f.spin_revolutions, ref.spin_revolutions)})"
            for f in figs])
        row("spin: centre drift per revolution", [f"{100 * f.spin_centre_drift_m_per_rev:.2f} cm"
                                                  for f in figs])
        for delay in (0.2, 0.5):
            row(f"coast-down: speed lost {delay} s after the stop", [
                f"{f.coast_speed_m_s[0.0] - f.coast_speed_m_s[delay]:.4f} m/s" for f in figs])
        row("coast-down: at rest after", [f"{f.coast_at_rest_s:.1f} s" for f in figs])

        def apart(f, ref=ref) -> str:
            dx, dy, dyaw = (a - b for a, b in zip(f.random_end, ref.random_end, strict=True))
            return f"{100 * math.hypot(dx, dy):.1f} cm, {math.degrees(abs(dyaw)):.1f} deg"

        row("20 s random commands: end vs 2 ms", [apart(f) for f in figs])
        row("lowest base z axis (upright = 1)", [f"{f.min_up_z:.5f}" for f in figs])
        row("base height jitter (driving, at rest)", [f"{1000 * f.max_z_jitter_m:.3f} mm"
                                                      for f in figs])
        row("speed 3 s after a stop", [f"{1000 * f.speed_3s_after_stop_m_s:.2f} mm/s"
                                       for f in figs])
        row("wall time of all scenarios", [f"{f.seconds:.1f} s" for f in figs])  # type: ignore[attr-defined]


if __name__ == "__main__":
    main()
