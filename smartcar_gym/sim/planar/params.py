"""The planar engine's free parameters and their file (``planar_params=``).

The model takes everything it can from the robot's description and the controller YAML
(masses, inertias, contact points, friction coefficients, motors); what no description says is
here: how stiff the tyres' slip is, how much effective friction and rolling resistance the
ground gives, and how strong the gearbox's dead band is. ``smartcar-calibrate --fit planar``
fits them to a physics engine or a robot's bag and writes the file; the package ships one fit
per physics engine for the smartcar (``config/planar_pybullet.yaml``, the default, and
``config/planar_mujoco.yaml``).

A file holds a ``planar:`` mapping of the keys below (every key optional: a missing one takes
the default) and may hold a ``fit:`` mapping that records how it was made (read as text only).
"""

from __future__ import annotations

import dataclasses
import functools
import math
import os
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import Any

import yaml

from smartcar_gym.checks import is_real

#: the shipped fits, by the engine they were fitted to
SHIPPED = {"pybullet": "planar_pybullet.yaml", "mujoco": "planar_mujoco.yaml"}
DEFAULT_FIT = "pybullet"


class PlanarParamsError(ValueError):
    """A parameter file that cannot be read, or a value out of range; names file and key."""


@dataclass(frozen=True)
class PlanarParams:
    """The planar model's free parameters.

    Attributes:
        friction_scale: scales every contact's friction coefficient (the link's times the
            ground's, pybullet's rule): the effective friction of the tyres on the ground.
        lateral_friction_ratio: a tyre's friction across the body's x axis over its
            friction along it (1: isotropic Coulomb; above 1: the tyre resists sliding
            sideways more, which makes a skid-steer car's effective track wider). Sliding
            contacts (a caster ball) stay isotropic.
        slip_speed: m/s of slip at which a contact's friction reaches 71 % of its Coulomb
            bound (``1/sqrt(2)``); its slip stiffness is ``mu N / slip_speed``.
        rolling_resistance: rolling resistance coefficient: a rolling wheel loses this share
            of its normal load as a force at its rim (a Coulomb torque ``c_rr N r``).
        gearbox_friction_scale: scales the YAML's gearbox ``friction_torque`` (the dead band
            that slow commands must overcome).
        stiction_speed: rad/s of wheel speed over which the gearbox's Coulomb friction builds
            up (its regularisation: small enough that a stalled wheel creeps at most this).
        load_shift_x: m along base_link's x axis: the contacts' static loads balance as if
            the centre of mass were this far ahead of where the description puts it (a
            centre of mass that is not where the URDF says, or a split of the weight over
            four or more wheels that rigid geometry leaves open). It sets how differently
            the car turns driving forward and in reverse.
        spin_reaction: the share of the wheel groups' spin inertia whose angular momentum
            the body carries: when the wheels spin up or down, or the body turns them, the
            ground's loads supply the moment (load moves to the front wheels as they brake,
            outward as the car turns). 1: all of it, as pybullet's axle inertia does; 0: none,
            as MuJoCo's joint armature (the rotor seen through the gearbox) does. A real
            gearmotor's rotor reacts with its own momentum, a share of the reflected
            inertia's.
        source: the file the values came from ("built-in" for the defaults).
    """

    friction_scale: float = 1.0
    lateral_friction_ratio: float = 1.0
    slip_speed: float = 0.02
    rolling_resistance: float = 0.0
    gearbox_friction_scale: float = 1.0
    stiction_speed: float = 0.05
    load_shift_x: float = 0.0
    spin_reaction: float = 1.0
    source: str = dataclasses.field(default="built-in", compare=False)

    def __post_init__(self) -> None:
        """Every value checked against ``RANGES`` as a file's are (PlanarParamsError naming
        the key; ``PlanarParams`` for an object made in code), and stored as a float."""
        where = "PlanarParams" if self.source == "built-in" else self.source
        for key in KEYS:
            object.__setattr__(self, key, check_value(key, getattr(self, key), where))


#: key -> (low, high, unit): the accepted range of each parameter (inclusive)
RANGES: dict[str, tuple[float, float, str]] = {
    "friction_scale": (0.05, 10.0, ""),
    "lateral_friction_ratio": (0.2, 5.0, ""),
    "slip_speed": (1e-4, 1.0, "m/s"),
    "rolling_resistance": (0.0, 0.5, ""),
    "gearbox_friction_scale": (0.0, 10.0, ""),
    "stiction_speed": (1e-4, 10.0, "rad/s"),
    "load_shift_x": (-1.0, 1.0, "m"),
    "spin_reaction": (0.0, 2.0, ""),
}
KEYS = tuple(RANGES)


def check_value(key: str, value: Any, source: str, text_numbers: bool = False) -> float:
    """``value`` as a float inside ``RANGES[key]``; PlanarParamsError naming file and key.

    ``text_numbers``: a string that reads as a number counts as that number (a YAML file's
    ``5e-4``, which PyYAML reads as text: YAML 1.1 floats need a dot)."""
    low, high, unit = RANGES[key]
    if text_numbers and isinstance(value, str):
        try:
            value = float(value)
        except ValueError:
            pass
    if not (is_real(value) and math.isfinite(value) and low <= value <= high):
        unit = f" {unit}" if unit else ""
        text = " (text)" if isinstance(value, str) else ""
        raise PlanarParamsError(f"{source}: planar.{key}: expected a number in "
                                f"[{low:g}, {high:g}]{unit}, got {value!r}{text}")
    return float(value)


def from_mapping(values: Any, source: str, text_numbers: bool = False) -> PlanarParams:
    """``PlanarParams`` from a ``{key: value}`` mapping (the file's ``planar:`` section;
    ``text_numbers``: as ``check_value``'s)."""
    if not isinstance(values, dict):
        raise PlanarParamsError(f"{source}: planar: expected a mapping of {', '.join(KEYS)}, "
                                f"got {type(values).__name__}")
    unknown = sorted(set(map(str, values)) - set(KEYS))
    if unknown:
        raise PlanarParamsError(f"{source}: planar.{unknown[0]}: unknown key; the keys are "
                                f"{', '.join(KEYS)}")
    checked = {key: check_value(key, value, source, text_numbers)
               for key, value in values.items()}
    return PlanarParams(**checked, source=source)


def load(path: str | os.PathLike) -> PlanarParams:
    """Read a parameter file; PlanarParamsError naming the file (and key) when it is
    missing, not YAML, has no ``planar:`` mapping, or a value is unknown or out of range.
    Numbers written in exponent notation without a dot (``5e-4``, text to PyYAML) count."""
    source = str(path)
    try:
        text = Path(path).read_text(encoding="utf-8")
    except OSError as exc:
        raise PlanarParamsError(f"{source}: cannot read the planar parameter file: "
                                f"{exc.strerror or exc}") from None
    try:
        data = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f" (line {mark.line + 1})" if mark is not None else ""
        raise PlanarParamsError(f"{source}: not valid YAML{where}: "
                                f"{getattr(exc, 'problem', None) or exc}") from None
    if not isinstance(data, dict) or "planar" not in data:
        raise PlanarParamsError(f"{source}: expected a mapping with a 'planar:' section "
                                f"({', '.join(KEYS)})")
    unknown = sorted(set(map(str, data)) - {"planar", "fit"})
    if unknown:
        raise PlanarParamsError(f"{source}: {unknown[0]}: unknown section; a planar parameter "
                                "file holds 'planar:' and optionally 'fit:'")
    return from_mapping(data["planar"], source, text_numbers=True)


def shipped_path(engine: str = DEFAULT_FIT) -> Path:
    """The shipped fit of the smartcar to ``engine`` ("pybullet" or "mujoco")."""
    if engine not in SHIPPED:
        raise ValueError(f"no shipped planar fit for {engine!r}; fits: {', '.join(SHIPPED)}")
    return Path(str(resources.files("smartcar_gym") / "config" / SHIPPED[engine]))


def resolve(spec: Any) -> PlanarParams:
    """The parameters ``planar_params=`` asks for: None (the shipped pybullet fit), the name
    of a shipped fit ("pybullet", "mujoco"), a file path, a ``{key: value}`` dict, or a
    ``PlanarParams``."""
    if spec is None:
        return load(shipped_path())
    if isinstance(spec, PlanarParams):
        return spec
    if isinstance(spec, dict):
        return from_mapping(spec, "planar_params")
    if isinstance(spec, str) and spec in SHIPPED:
        return load(shipped_path(spec))
    if isinstance(spec, str | os.PathLike):
        return load(spec)
    raise PlanarParamsError(f"planar_params must be None, {' or '.join(map(repr, SHIPPED))}, "
                            f"a file path, a dict or a PlanarParams, got {type(spec).__name__}")


def for_robot(spec: Any, model: Any) -> PlanarParams:
    """``resolve(spec)``, but ``None`` gives the shipped fit only to the shipped smartcar
    (``is_shipped_robot``) and the built-in neutral values to any other robot ``model`` (a
    ``RobotModel``): the fit is the smartcar's, and its ``load_shift_x`` would tip a robot
    balanced near its axle over."""
    if spec is None and not is_shipped_robot(model):
        return PlanarParams()
    return resolve(spec)


def is_shipped_robot(model: Any) -> bool:
    """Whether a ``RobotModel`` is the shipped smartcar: loaded from the shipped xacro (with
    any xacro arguments: the Nav ids' ``laser``), or a copy of it (the same final URDF)."""
    from smartcar_gym.model import SHIPPED_MODEL

    source = Path(model.source)
    if source.is_file() and source.resolve() == Path(SHIPPED_MODEL).resolve():
        return True
    return model.urdf == _shipped_urdf()


@functools.cache
def _shipped_urdf() -> str:
    from smartcar_gym.model import load_model

    return load_model().urdf


def dump(params: PlanarParams, fit: dict[str, Any] | None = None) -> str:
    """The YAML text of a parameter file (``load`` reads it back to the same values)."""
    values = {key: float(getattr(params, key)) for key in KEYS}
    text = ("# smartcar-gym planar engine parameters (docs/planar.md): "
            "gym.make(..., engine='planar', planar_params=THIS_FILE)\n")
    text += yaml.safe_dump({"planar": values}, sort_keys=False)
    if fit is not None:
        text += yaml.safe_dump({"fit": fit}, sort_keys=False, default_flow_style=None)
    return text
