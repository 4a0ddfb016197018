"""The calibration: drive, fit, drive again with the calibrated values.

``calibrate`` runs the five drives (a straight run, a spin each way, Borenstein's UMBmark square
each way) with the configuration as given, fits the effective ``base_width`` and the
``ticks_meter`` correction from some of them (``FITS``), and runs the five drives again with the
calibrated values on the same plant: the before/after odometry errors.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

from smartcar_gym.calibration.drives import Driver, Plan, Run
from smartcar_gym.calibration.estimate import Estimate, fit
from smartcar_gym.controller import ArbotixConfig
from smartcar_gym.envs.robots.variation import Variation
from smartcar_gym.model import RobotModel
from smartcar_gym.sim.engines import DEFAULT_ENGINE

#: fit name -> (runs it uses, whether their true end headings are used)
FITS: dict[str, tuple[tuple[str, ...], bool]] = {
    "spin": (("straight", "spin ccw", "spin cw"), True),
    "umbmark": (("straight", "square cw", "square ccw"), False),
    "all": (("straight", "spin ccw", "spin cw", "square cw", "square ccw"), True),
}
FIT_HELP = {
    "spin": "the straight run and the spins, with their true end headings",
    "umbmark": "the straight run and the UMBmark squares, end positions only (what a tape "
               "measure gives on a real robot)",
    "all": "every run, end positions and headings",
}


@dataclass(frozen=True)
class Calibration:
    """What ``calibrate`` found: the fit, the YAML values, and the runs before and after."""

    config: ArbotixConfig
    fit: str
    estimate: Estimate
    base_width_m: float
    ticks_meter: float
    before: tuple[Run, ...]
    after: tuple[Run, ...]


def drive_all(driver: Driver, plan: Plan) -> tuple[Run, ...]:
    """The five drives, in order: straight, spin ccw, spin cw, square cw, square ccw."""
    return (driver.straight(plan), driver.spin(plan, 1), driver.spin(plan, -1),
            driver.square(plan, -1), driver.square(plan, 1))


def calibrate(model: RobotModel, config: ArbotixConfig, plan: Plan | None = None,
              fit_name: str = "spin", variation: Variation | None = None,
              ground_friction: float = 1.0, wheel_contact: str = "sphere",
              max_substep_s: float = 0.01, engine: str = DEFAULT_ENGINE) -> Calibration:
    """Calibrate ``config``'s odometry for ``model`` (on a plant ``variation``, if given).

    The plant stays the same for the runs after calibration: its encoders count the same
    ticks per metre whatever the calibrated YAML says.
    """
    plan = plan or Plan()
    if fit_name not in FITS:
        raise ValueError(f"fit must be one of {tuple(FITS)}, got {fit_name!r}")
    common = dict(wheel_contact=wheel_contact, max_substep_s=max_substep_s, engine=engine,
                  ground_friction=ground_friction)
    driver = Driver(model, config, variation, **common)
    before = drive_all(driver, plan)
    names, use_yaw = FITS[fit_name]
    width_used = driver.controller_base_width()
    estimate = fit([r for r in before if r.name in names], config.ticks_meter, width_used,
                   use_yaw)
    # the fit is in the controller's terms; the YAML's base_width relates to it as the plant's
    # effective track does (see Variation.config)
    base_width = estimate.base_width_m * config.base_width_m / width_used
    ticks_meter = config.ticks_meter / estimate.scale
    calibrated = dataclasses.replace(config, base_width_m=base_width, ticks_meter=ticks_meter)
    plant = variation or Variation()
    keep = config.ticks_meter / ticks_meter  # the true counts per metre do not change
    plant = dataclasses.replace(plant, left_encoder_scale=plant.left_encoder_scale * keep,
                                right_encoder_scale=plant.right_encoder_scale * keep)
    after = drive_all(Driver(model, calibrated, plant, **common), plan)
    return Calibration(config, fit_name, estimate, base_width, ticks_meter, before, after)
