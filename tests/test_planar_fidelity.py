"""The planar engine's shipped fits against the engines they were fitted to, on the fidelity
table's maneuvers, within the gates MuJoCo meets against pybullet (docs/planar.md; the full
table: benchmarks/engine_fidelity.py)."""

from __future__ import annotations

import importlib.util

import pytest

from smartcar_gym.calibration.engines_compared import (
    coast_down,
    odometry_error,
    spin_rate,
    steady_speed,
    umbmark,
)

#: maneuver, relative tolerance against the fitted engine (the issue's gates)
GATES = [
    *((steady_speed(v), 0.05) for v in (0.2, 0.3, 0.5)),
    *((steady_speed(v), 0.15) for v in (0.05, 0.1)),
    *((spin_rate(w), 0.15) for w in (0.5, 1.0, 2.0)),
    (coast_down(0.3), 0.10),
    (umbmark(1), 0.15), (umbmark(-1), 0.15),
]
ENGINES = ["pybullet", pytest.param("mujoco", marks=pytest.mark.skipif(
    importlib.util.find_spec("mujoco") is None, reason="engine='mujoco' needs the mujoco extra"))]


@pytest.mark.parametrize("engine", ENGINES)
@pytest.mark.parametrize("maneuver,tolerance", GATES, ids=[m.name for m, _ in GATES])
def test_the_shipped_fit_drives_like_its_engine(engine, maneuver, tolerance, shipped_model,
                                                shipped_config):
    reference = maneuver.measure(shipped_model, shipped_config, engine)
    value = maneuver.measure(shipped_model, shipped_config, "planar", planar_params=engine)
    assert value == pytest.approx(reference, rel=tolerance)


@pytest.mark.parametrize("engine", ENGINES)
def test_odometry_drifts_as_on_its_engine(engine, shipped_model, shipped_config):
    reference = odometry_error().measure(shipped_model, shipped_config, engine)
    value = odometry_error().measure(shipped_model, shipped_config, "planar",
                                     planar_params=engine)
    assert value == pytest.approx(reference, abs=0.03)
