"""The planar batch's compiled loop in lanes (``sim/planar/lanes.py``): every car bit for bit
the car ``dynamics.substep`` steps alone, whatever its block, its substeps, its parameters,
and whether its tangent step carried a slip through zero (solved again in the queue)."""

from __future__ import annotations

import numpy as np
import pytest

from smartcar_gym.sim.planar import dynamics, lanes
from smartcar_gym.sim.planar.dynamics import make_solve, make_substep, new_scratch, substep
from smartcar_gym.sim.planar.layout import (
    COS,
    EPS2,
    MASS,
    SIN,
    YAW_INERTIA,
    car_values,
    contact_values,
    state_size,
)

pytestmark = pytest.mark.skipif(not dynamics.COMPILED,
                                reason="numba (the fast extra) is not installed")

# four wheels in two side groups and a sliding caster ball: every branch of the substep
POINTS = [(0.08, 0.08), (-0.08, 0.08), (0.08, -0.08), (-0.08, -0.08), (0.12, 0.0)]
GROUPS = np.array([0, 0, 1, 1, -1], dtype=np.int64)
TRANSFER = dynamics.load_transfer(np.array(POINTS))


def car(rng: np.random.Generator) -> list[float]:
    """A car's parameters, drawn around a 1.5 kg car with 25 mm wheels."""
    inertia = rng.uniform(1e-3, 3e-3, 2)
    return car_values(mass=rng.uniform(1.0, 2.0), yaw_inertia=rng.uniform(0.008, 0.016),
                      eps2=rng.uniform(0.005, 0.02) ** 2, eps_w2=rng.uniform(0.02, 0.1) ** 2,
                      height=rng.uniform(0.02, 0.06), inertia=list(inertia),
                      coulomb=list(rng.uniform(0.0, 0.05, 2)), spin_x=[0.0, 0.0],
                      spin_y=list(inertia * rng.uniform(0.0, 1.0)))


def contacts(rng: np.random.Generator) -> np.ndarray:
    """(K, NC): the wheels rolling at -r along x per rad/s of their group; the caster slides."""
    rows = []
    for k, ((x, y), (lx, ly)) in enumerate(zip(POINTS, TRANSFER, strict=True)):
        wheel = GROUPS[k] >= 0
        mu = rng.uniform(0.3, 0.9)
        rows.append(contact_values(
            x=x, y=y, roll_x=-rng.uniform(0.02, 0.03) if wheel else 0.0, roll_y=0.0,
            load=rng.uniform(2.0, 4.5) if wheel else rng.uniform(0.1, 0.5),
            friction_x=mu, friction_y=mu * rng.uniform(1.0, 1.5), load_per_pitch=float(lx),
            load_per_roll=float(ly)))
    return np.array(rows)


def batch(rng: np.random.Generator, n: int) -> tuple[np.ndarray, ...]:
    """N cars of their own parameters: states moving every way (the wheels often turning
    against the body's motion: slips that the tangent step carries through zero), drives,
    clocks and substeps (0 to 4)."""
    state = rng.normal(size=(state_size(2), n)) * 0.5
    yaw = rng.uniform(-np.pi, np.pi, n)
    state[COS], state[SIN] = np.cos(yaw), np.sin(yaw)
    stopped = rng.random(n) < 0.2  # some at rest, or nearly
    state[:, stopped] *= np.where(rng.random(stopped.sum()) < 0.5, 0.0, 1e-6)
    state[COS, stopped], state[SIN, stopped] = np.cos(yaw[stopped]), np.sin(yaw[stopped])
    cars = np.stack([car(rng) for _ in range(n)], axis=1)
    touches = np.stack([contacts(rng) for _ in range(n)], axis=2)
    drive = np.concatenate([rng.normal(size=(2, n)) * 0.05, rng.uniform(0, 0.01, (2, n))])
    dt = rng.uniform(0.001, 0.02, n)
    steps = rng.integers(0, 5, n)
    return state, cars, touches, drive, dt, steps


def alone(state, cars, touches, drive, dt, steps, i) -> list[float]:
    """Car i stepped alone in Python floats."""
    one = state[:, i].tolist()
    rows = touches[:, :, i].tolist()
    for _ in range(steps[i]):
        substep(one, cars[:, i].tolist(), rows, tuple(GROUPS), drive[:, i].tolist(),
                float(dt[i]), new_scratch(2))
    return one


@pytest.mark.parametrize("n", [1, 37, 300])
def test_every_car_of_the_lanes_is_the_car_stepped_alone_bit_for_bit(n: int) -> None:
    rng = np.random.default_rng(n)
    state, cars, touches, drive, dt, steps = batch(rng, n)
    out = state.copy()
    blocks = lanes.blocked(cars, touches)
    assert blocks.shape == (-(-n // lanes.LANES), (cars.shape[0] + touches[:, :, 0].size)
                            * lanes.LANES)
    lanes.run_blocks(out, blocks, GROUPS, drive, dt, steps, 0, len(blocks))
    for i in range(n):
        assert out[:, i].tolist() == alone(state, cars, touches, drive, dt, steps, i), f"car {i}"


def test_the_cars_solve_again_as_dynamics_solves_them() -> None:
    """The drawn cars exercise the second solve: some, not all, carry a slip through zero
    at their first substep (counted by the numpy substep), and those match too."""
    rng = np.random.default_rng(5)
    state, cars, touches, drive, dt, _ = batch(rng, 300)
    crossed: list[np.ndarray] = []

    def anywhere(choose: np.ndarray) -> bool:
        crossed.append(choose.copy())
        return bool(np.any(choose))

    counting = make_substep(np.sqrt, make_solve(np.sqrt, np.where), np.where, anywhere)
    counted = state.copy()
    counting(counted, cars, touches, tuple(GROUPS), drive, dt, new_scratch(2))
    assert 0.05 < crossed[0].mean() < 0.95
    out = state.copy()
    blocks = lanes.blocked(cars, touches)
    lanes.run_blocks(out, blocks, GROUPS, drive, dt, np.ones(300, dtype=np.int64), 0,
                     len(blocks))
    assert np.array_equal(out, counted)


def test_a_range_of_blocks_steps_only_its_cars() -> None:
    """``run_blocks(..., first, last)``: the threads' chunks; the other cars keep their state
    to the bit, and the chunks stepped one after the other give the whole call's state."""
    rng = np.random.default_rng(7)
    n = 5 * lanes.LANES + 3
    state, cars, touches, drive, dt, steps = batch(rng, n)
    blocks = lanes.blocked(cars, touches)
    part = state.copy()
    lanes.run_blocks(part, blocks, GROUPS, drive, dt, steps, 2, 4)
    inside = slice(2 * lanes.LANES, 4 * lanes.LANES)
    assert np.array_equal(np.delete(part, np.s_[inside], axis=1),
                          np.delete(state, np.s_[inside], axis=1))
    assert not np.array_equal(part[:, inside], state[:, inside])
    whole, pieces = state.copy(), state.copy()
    lanes.run_blocks(whole, blocks, GROUPS, drive, dt, steps, 0, len(blocks))
    for first, last in ((0, 1), (1, 4), (4, len(blocks))):
        lanes.run_blocks(pieces, blocks, GROUPS, drive, dt, steps, first, last)
    assert np.array_equal(whole, pieces)


def test_blocks_whose_cars_do_not_step_are_left_alone_in_every_pass() -> None:
    """A block none of whose cars steps is neither copied in nor written back: its cars keep
    their state to the bit, in the first pass of blocks and in a later one (whose buffer still
    holds an earlier pass's block), while the cars around them step as alone."""
    rng = np.random.default_rng(11)
    n = (lanes.PASS + 5) * lanes.LANES + 7  # two passes, the last block part-filled
    state, cars, touches, drive, dt, steps = batch(rng, n)
    steps = np.maximum(steps, 1)
    idle = [1, lanes.PASS + 2]  # a block of each pass
    for block in idle:
        steps[block * lanes.LANES:(block + 1) * lanes.LANES] = 0
    out = state.copy()
    blocks = lanes.blocked(cars, touches)
    lanes.run_blocks(out, blocks, GROUPS, drive, dt, steps, 0, len(blocks))
    for block in idle:
        cols = slice(block * lanes.LANES, (block + 1) * lanes.LANES)
        assert out[:, cols].tobytes() == state[:, cols].tobytes()
    for i in [0, lanes.LANES - 1, 2 * lanes.LANES, (lanes.PASS + 2) * lanes.LANES - 1,
              (lanes.PASS + 3) * lanes.LANES, n - 1]:
        assert out[:, i].tolist() == alone(state, cars, touches, drive, dt, steps, i), f"car {i}"
    assert not np.array_equal(out[:, -1], state[:, -1])


def test_blocks_lay_out_each_cars_parameters_and_pad_with_the_last_blocks_first_car() -> None:
    rng = np.random.default_rng(9)
    n = lanes.LANES + 2
    _, cars, touches, *_ = batch(rng, n)
    blocks = lanes.blocked(cars, touches).reshape(2, -1, lanes.LANES)
    assert blocks[0, MASS, 3] == cars[MASS, 3]
    assert blocks[1, YAW_INERTIA, 1] == cars[YAW_INERTIA, lanes.LANES + 1]
    first_contact = cars.shape[0]
    assert blocks[1, first_contact + 4, 0] == touches[0, 4, lanes.LANES]
    assert np.array_equal(blocks[1, :, 2:], np.repeat(blocks[1, :, :1], lanes.LANES - 2, axis=1))
    assert blocks[1, EPS2, 5] == cars[EPS2, lanes.LANES]
