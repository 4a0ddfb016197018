"""MuJoCo against pybullet on the same maneuvers, where the physics should agree
(the tolerances docs/engines.md states; the full table: benchmarks/engine_fidelity.py)."""

from __future__ import annotations

import pytest

pytest.importorskip("smartcar_gym.sim.mujoco", reason="engine='mujoco' needs the mujoco extra")

from smartcar_gym.calibration.engines_compared import (  # noqa: E402
    coast_down,
    odometry_error,
    spin_rate,
    steady_speed,
)

#: maneuver, relative tolerance of MuJoCo against pybullet (docs/engines.md)
AGREEING = [
    (steady_speed(0.2), 0.05), (steady_speed(0.3), 0.05), (steady_speed(0.5), 0.05),
    (spin_rate(0.5), 0.15), (spin_rate(1.0), 0.15), (spin_rate(2.0), 0.15),
    (coast_down(0.3), 0.10),
]


@pytest.mark.parametrize("maneuver,tolerance", AGREEING, ids=[m.name for m, _ in AGREEING])
def test_mujoco_agrees_with_pybullet(maneuver, tolerance, shipped_model, shipped_config):
    reference = maneuver.measure(shipped_model, shipped_config, "pybullet")
    value = maneuver.measure(shipped_model, shipped_config, "mujoco")
    assert value == pytest.approx(reference, rel=tolerance)


def test_both_engines_drive_at_the_commanded_speed_above_the_dead_band(shipped_model,
                                                                        shipped_config):
    for engine in ("pybullet", "mujoco"):
        assert steady_speed(0.3).measure(shipped_model, shipped_config, engine) == \
            pytest.approx(0.3, rel=0.05)


def test_odometry_drifts_alike(shipped_model, shipped_config):
    errors = [odometry_error().measure(shipped_model, shipped_config, e)
              for e in ("pybullet", "mujoco")]
    assert errors[1] == pytest.approx(errors[0], abs=0.03)  # 6-7 cm after 10 s on both
