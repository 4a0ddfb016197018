"""The planar car's flat layouts, by name: its state, parameters, contacts and motors' drive.

A car is four flat sequences (``dynamics``), indexed the same way whether they hold Python
floats (a list: one car), ``(N,)`` rows of ``(rows, N)`` arrays (N cars in numpy) or float64
scalars (one car's row in numba's loop). The body's and the contacts' fields sit at fixed
indices (module constants); each wheel group's fields follow in blocks of G values, one block
per field, at offsets that depend on G: ``speed, pitch, roll = state_rows(G)`` and
``coulomb, spin_x, spin_y = car_rows(G)`` (group g's speed is ``state[speed + g]``). These
functions are plain integer arithmetic that numba compiles inline (``register_jitable``) when
the ``fast`` extra is installed, and plain Python otherwise.

**state** (``state_size(G)`` = 7 + 2 G + 2 values)

| index            | value                                                         | unit  |
|------------------|---------------------------------------------------------------|-------|
| ``X``, ``Y``     | the centre of mass, world frame                               | m     |
| ``COS``, ``SIN`` | cos and sin of the yaw                                        | 1     |
| ``VX``, ``VY``   | the centre of mass's velocity, world frame                    | m/s   |
| ``YAW_RATE``     | the yaw rate                                                  | rad/s |
| ``ANGLE`` + g    | group g's angle                                               | rad   |
| ``speed`` + g    | group g's speed (``speed_row(G)``: ``speed``)                 | rad/s |
| ``pitch``        | the pitch moment the loads carried at the last substep (body) | N m   |
| ``roll``         | the roll moment the loads carried at the last substep (body)  | N m   |

**car**, the parameters (``car_size(G)`` = 5 + 4 G values)

| index                | value                                                        | unit     |
|----------------------|--------------------------------------------------------------|----------|
| ``MASS``             | the whole robot's mass                                       | kg       |
| ``YAW_INERTIA``      | its yaw inertia about the centre of mass                     | kg m^2   |
| ``EPS2``             | the tyres' slip speed squared (friction's regularisation)    | m^2/s^2  |
| ``EPS_W2``           | the gearboxes' stiction speed squared                        | rad^2/s^2|
| ``HEIGHT``           | the centre of mass above the ground                          | m        |
| ``INERTIA`` + g      | group g's spin inertia                                       | kg m^2   |
| ``coulomb`` + g      | group g's Coulomb torque (gearbox and rolling resistance)    | N m      |
| ``spin_x`` + g       | group g's angular momentum per rad/s along the body's x      | kg m^2   |
| ``spin_y`` + g       | ... along the body's y                                       | kg m^2   |

``group_count(car_size)`` gives G back from the parameters' length.

**contact**: K rows of ``NC`` values (``CONTACT_FIELDS``), one per ground contact; each
contact's wheel group (-1: a sliding contact) is a separate sequence, shared by all cars.

| index                 | value                                                      | unit   |
|-----------------------|------------------------------------------------------------|--------|
| ``CX``, ``CY``        | position from the centre of mass, body frame               | m      |
| ``ROLL_X``, ``ROLL_Y``| its velocity relative to the body per rad/s of its group   | m/rad  |
| ``LOAD``              | static normal load                                         | N      |
| ``FRICTION_X``, ``FRICTION_Y`` | friction coefficients along and across the body's x | 1 |
| ``LOAD_PER_PITCH``    | its load's change per N m of the pitch moment the loads carry | 1/m |
| ``LOAD_PER_ROLL``     | its load's change per N m of the roll moment the loads carry  | 1/m |

**drive** (``drive_size(G)`` = 2 G values), from the board's PWM

| index                  | value                            | unit     |
|------------------------|----------------------------------|----------|
| ``TORQUE`` + g         | group g's motor drive torque     | N m      |
| ``damping_row(G)`` + g | group g's back-EMF damping       | N m s/rad|

numba keeps its compiled loops (``dynamics``) on disk until ``dynamics.py`` changes: a change
to this layout must touch ``dynamics.py`` too (its file stamp), or clear numba's cache.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any, TypeVar

_F = TypeVar("_F", bound=Callable[..., Any])

try:  # pragma: no branch - one of the two, per installation
    from numba.extending import register_jitable as _jitable
except ImportError:  # no numba: the functions stay plain Python

    def _jitable(function: _F) -> _F:
        return function


# -- state -------------------------------------------------------------------------------------
BODY = ("x", "y", "c", "s", "vx", "vy", "w")
X, Y, COS, SIN, VX, VY, YAW_RATE = range(len(BODY))
#: x, y, cos and sin of the yaw: ``x, y, c, s = state[POSE]``
POSE = slice(X, SIN + 1)
#: group g's angle is ``state[ANGLE + g]``
ANGLE = len(BODY)


@_jitable
def speed_row(groups: int) -> int:
    """Where the groups' speeds start in the state: group g's at ``speed_row(G) + g``."""
    return ANGLE + groups


@_jitable
def state_rows(groups: int) -> tuple[int, int, int]:
    """``speed, pitch, roll = state_rows(G)``: where the groups' speeds start, and the rows of
    the pitch and roll moments the loads carry."""
    speed = speed_row(groups)
    return speed, speed + groups, speed + groups + 1


def state_size(groups: int) -> int:
    """Length of a car's state with ``groups`` wheel groups."""
    return state_rows(groups)[2] + 1


def rest_state(x: float, y: float, c: float, s: float, groups: int) -> list[float]:
    """A car's state at rest: its centre of mass at (``x``, ``y``) heading (``c``, ``s``),
    the wheels at angle 0, no moments."""
    return [x, y, c, s, 0.0, 0.0, 0.0] + [0.0] * (state_size(groups) - ANGLE)


# -- car parameters ----------------------------------------------------------------------------
CAR = ("mass", "yaw_inertia", "eps2", "eps_w2", "height")
MASS, YAW_INERTIA, EPS2, EPS_W2, HEIGHT = range(len(CAR))
#: per wheel group, after ``CAR``: spin inertia, Coulomb torque, angular momentum per rad/s
#: along the body's x and y (the axle's direction times the spin inertia)
GROUP = ("inertia", "coulomb", "spin_x", "spin_y")
#: group g's spin inertia is ``car[INERTIA + g]``
INERTIA = len(CAR)
_GROUP_FIELDS = len(GROUP)


@_jitable
def group_count(car_size: int) -> int:
    """The number of wheel groups G of parameters ``car_size`` long."""
    return (car_size - INERTIA) // _GROUP_FIELDS


@_jitable
def car_rows(groups: int) -> tuple[int, int, int]:
    """``coulomb, spin_x, spin_y = car_rows(G)``: where the groups' Coulomb torques, and their
    angular momenta per rad/s along the body's x and y, start in the parameters (group g's
    spin inertia is at ``INERTIA + g``)."""
    coulomb = INERTIA + groups
    return coulomb, coulomb + groups, coulomb + 2 * groups


def car_size(groups: int) -> int:
    """Length of a car's parameters with ``groups`` wheel groups."""
    return INERTIA + _GROUP_FIELDS * groups


def car_values(*, mass: float, yaw_inertia: float, eps2: float, eps_w2: float, height: float,
               inertia: Sequence[float], coulomb: Sequence[float], spin_x: Sequence[float],
               spin_y: Sequence[float]) -> list[float]:
    """A car's parameters in this layout (the group fields: one value per group)."""
    blocks = (inertia, coulomb, spin_x, spin_y)
    if len({len(block) for block in blocks}) != 1:
        raise ValueError("inertia, coulomb, spin_x and spin_y need one value per wheel group, "
                         f"got {[len(block) for block in blocks]}")
    return [mass, yaw_inertia, eps2, eps_w2, height, *inertia, *coulomb, *spin_x, *spin_y]


# -- contacts ----------------------------------------------------------------------------------
#: one contact's row: position from the centre of mass (body frame, m), rolling velocity per
#: rad/s of its group (m/rad), static normal load (N), friction coefficients along and across
#: x, and how its load changes per newton-metre of the pitch and roll moments the loads carry
#: (N/(N m): load transfer)
CONTACT_FIELDS = ("x", "y", "roll_x", "roll_y", "load", "friction_x", "friction_y",
                  "load_per_pitch", "load_per_roll")
(CX, CY, ROLL_X, ROLL_Y, LOAD, FRICTION_X, FRICTION_Y, LOAD_PER_PITCH,
 LOAD_PER_ROLL) = range(len(CONTACT_FIELDS))
NC = len(CONTACT_FIELDS)


def contact_values(*, x: float, y: float, roll_x: float, roll_y: float, load: float,
                   friction_x: float, friction_y: float, load_per_pitch: float,
                   load_per_roll: float) -> list[float]:
    """One contact's row in this layout."""
    return [x, y, roll_x, roll_y, load, friction_x, friction_y, load_per_pitch, load_per_roll]


# -- drive -------------------------------------------------------------------------------------
#: group g's motor drive torque is ``drive[TORQUE + g]``
TORQUE = 0


@_jitable
def damping_row(groups: int) -> int:
    """Where the groups' back-EMF damping starts in the drive."""
    return TORQUE + groups


def drive_size(groups: int) -> int:
    """Length of a car's drive with ``groups`` wheel groups."""
    return damping_row(groups) + groups


def drive_values(*, torque: Sequence[float], damping: Sequence[float]) -> list[float]:
    """A car's drive in this layout (one torque and one damping per group)."""
    if len(torque) != len(damping):
        raise ValueError(f"one torque and one damping per wheel group, got {len(torque)} and "
                         f"{len(damping)}")
    return [*torque, *damping]
