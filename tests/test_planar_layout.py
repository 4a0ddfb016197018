"""The planar car's layouts by name (``sim/planar/layout.py``): every value has one index, the
builders put each value where its name says, and the batch names its rows."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import smartcar_gym  # noqa: F401
from smartcar_gym.sim.planar import layout
from smartcar_gym.sim.planar.layout import (
    ANGLE,
    CONTACT_FIELDS,
    INERTIA,
    MASS,
    NC,
    TORQUE,
    car_rows,
    car_size,
    car_values,
    contact_values,
    damping_row,
    drive_size,
    drive_values,
    group_count,
    rest_state,
    speed_row,
    state_rows,
    state_size,
)


@pytest.mark.parametrize("groups", [0, 1, 2, 3])
def test_every_state_value_has_one_index(groups: int) -> None:
    body = [layout.X, layout.Y, layout.COS, layout.SIN, layout.VX, layout.VY, layout.YAW_RATE]
    speed, pitch, roll = state_rows(groups)
    assert speed == speed_row(groups)
    rows = body + [ANGLE + g for g in range(groups)] + [speed + g for g in range(groups)] \
        + [pitch, roll]
    assert sorted(rows) == list(range(state_size(groups)))
    assert list(range(layout.POSE.start, layout.POSE.stop)) == body[:4]
    state = rest_state(0.5, -0.25, 0.0, 1.0, groups)
    assert len(state) == state_size(groups)
    assert state[layout.X] == 0.5 and state[layout.Y] == -0.25 and state[layout.SIN] == 1.0
    assert state[layout.COS] == 0.0 and not any(state[layout.VX:])


@pytest.mark.parametrize("groups", [1, 2, 3])
def test_the_cars_parameters_sit_where_their_names_say(groups: int) -> None:
    blocks = {name: [10.0 * (k + 1) + g for g in range(groups)]
              for k, name in enumerate(layout.GROUP)}
    car = car_values(mass=1.0, yaw_inertia=2.0, eps2=3.0, eps_w2=4.0, height=5.0, **blocks)
    assert len(car) == car_size(groups) and group_count(len(car)) == groups
    assert [car[getattr(layout, name.upper())] for name in layout.CAR] == [1.0, 2.0, 3.0, 4.0,
                                                                           5.0]
    starts = dict(zip(layout.GROUP, (INERTIA, *car_rows(groups)), strict=True))
    for name, start in starts.items():
        assert car[start:start + groups] == blocks[name], name
    with pytest.raises(ValueError, match="one value per wheel group"):
        car_values(mass=1.0, yaw_inertia=2.0, eps2=3.0, eps_w2=4.0, height=5.0,
                   **{**blocks, "coulomb": blocks["coulomb"] + [0.0]})


def test_a_contacts_row_and_the_drive_by_name() -> None:
    values = {name: float(k) for k, name in enumerate(CONTACT_FIELDS)}
    row = contact_values(**values)
    assert len(row) == NC
    for name, value in values.items():
        index = getattr(layout, {"x": "CX", "y": "CY"}.get(name, name.upper()))
        assert row[index] == value, name
    drive = drive_values(torque=[0.1, 0.2], damping=[0.3, 0.4])
    assert len(drive) == drive_size(2)
    assert drive[TORQUE + 1] == 0.2 and drive[damping_row(2) + 1] == 0.4
    with pytest.raises(ValueError, match="one torque and one damping per wheel group"):
        drive_values(torque=[0.1], damping=[0.3, 0.4])


def test_the_shipped_car_read_by_name() -> None:
    """The shipped car compiled: four wheels in two chained sides, its mass the URDF's, the
    contacts carrying its weight, and the batch's named views of its state and drive."""
    env = gym.make("SmartCar-v0", engine="planar")
    env.reset(seed=0)
    body = env.unwrapped.robot.body
    model = body.compiled()
    groups = len(model.groups.members)
    assert groups == 2 and group_count(len(model.car)) == groups
    assert len(body.state) == state_size(groups) and len(body.drive) == drive_size(groups)
    masses = sum(link.mass for link in body.tables.links.values())
    assert model.car[MASS] == pytest.approx(masses, rel=1e-12)
    loads = np.array(model.contacts)[:, layout.LOAD]
    assert loads.sum() == pytest.approx(masses * 9.81, rel=1e-9)
    from smartcar_gym.sim.planar.batch import PlanarBatch

    batch = PlanarBatch(body, 3)
    batch.torque[1] = 0.5
    batch.damping[0] = 0.25
    assert batch.drive[TORQUE + 1].tolist() == [0.5] * 3
    assert batch.drive[damping_row(groups)].tolist() == [0.25] * 3
    c, s = batch.heading()
    assert c.tolist() == [body.state[layout.COS]] * 3 and s.tolist() == [body.state[layout.SIN]] * 3
    env.close()
