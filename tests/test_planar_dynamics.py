"""The planar engine's equations of motion (``sim/planar/dynamics.py``): one function for a car
in floats, N cars in numpy arrays and numba's loop, bit for bit; hand-derived physics."""

from __future__ import annotations

import math

import numpy as np
import pytest

from smartcar_gym.sim.planar import dynamics
from smartcar_gym.sim.planar.dynamics import (
    load_transfer,
    new_scratch,
    static_loads,
    substep,
    substep_arrays,
)
from smartcar_gym.sim.planar.layout import (
    ANGLE,
    COS,
    LOAD_PER_PITCH,
    LOAD_PER_ROLL,
    SIN,
    VX,
    VY,
    YAW_RATE,
    X,
    Y,
    car_values,
    contact_values,
    rest_state,
    state_rows,
    state_size,
)
from smartcar_gym.sim.planar.layout import LOAD as STATIC_LOAD

# a symmetric four-wheel car: 1.5 kg, wheels 25 mm at (+-0.08, +-0.08) m, friction 0.5
MASS, IZ, RADIUS, MU = 1.5, 0.012, 0.025, 0.5
LOAD = MASS * 9.81 / 4


HEIGHT = 0.04  # the centre of mass above the ground (m): the load transfer


def car(slip: float = 0.01, stiction: float = 0.05, inertia: float = 2e-3,
        coulomb: float = 0.03, reaction: float = 1.0) -> list[float]:
    """The car's parameters; each side's axle along +y (the contacts roll at -r along x per
    rad/s), ``reaction`` of its spin inertia reacting on the loads."""
    spin = reaction * inertia
    return car_values(mass=MASS, yaw_inertia=IZ, eps2=slip ** 2, eps_w2=stiction ** 2,
                      height=HEIGHT, inertia=[inertia, inertia], coulomb=[coulomb, coulomb],
                      spin_x=[0.0, 0.0], spin_y=[spin, spin])


TRANSFER = load_transfer(np.array([(0.08, 0.08), (-0.08, 0.08), (0.08, -0.08),
                                   (-0.08, -0.08)]))
CONTACTS = [contact_values(x=x, y=y, roll_x=-RADIUS, roll_y=0.0, load=LOAD, friction_x=MU,
                           friction_y=MU * 1.03, load_per_pitch=float(lx),
                           load_per_roll=float(ly))
            for (x, y), (lx, ly) in zip(((0.08, 0.08), (-0.08, 0.08), (0.08, -0.08),
                                         (-0.08, -0.08)), TRANSFER, strict=True)]
GROUPS = (0, 0, 1, 1)  # left, right
SPEED, PITCH, ROLL = state_rows(2)  # group 0's speed, the moments the loads carry


def moving(c: float, s: float, vx: float, vy: float, w: float = 0.0,
           wheels: float = 0.0) -> list[float]:
    """A state at the origin heading (c, s), moving at (vx, vy, w), each group at ``wheels``
    rad/s."""
    state = rest_state(0.0, 0.0, c, s, 2)
    state[VX], state[VY], state[YAW_RATE] = vx, vy, w
    state[SPEED] = state[SPEED + 1] = wheels
    return state


def loads(state: list[float]) -> list[float]:
    """Each contact's load under the moments ``state`` carries."""
    return [row[STATIC_LOAD] + row[LOAD_PER_PITCH] * state[PITCH]
            + row[LOAD_PER_ROLL] * state[ROLL] for row in CONTACTS]


def random_states(rng: np.random.Generator, n: int) -> np.ndarray:
    states = rng.normal(size=(state_size(2), n))
    yaw = states[COS].copy()
    states[COS], states[SIN] = np.cos(yaw), np.sin(yaw)
    return states


def test_a_car_in_floats_is_a_column_of_the_arrays_bit_for_bit() -> None:
    rng = np.random.default_rng(0)
    n = 32
    states = random_states(rng, n)
    drive = np.abs(rng.normal(size=(4, n))) * 0.1
    dt = rng.uniform(0.001, 0.03, n)
    params = car()
    batch = states.copy()
    cars = np.repeat(np.array(params)[:, None], n, axis=1)
    contacts = np.repeat(np.array(CONTACTS)[:, :, None], n, axis=2)
    for _ in range(6):
        substep_arrays(batch, cars, contacts, GROUPS, drive, dt, new_scratch(2))
    for i in range(n):
        one = states[:, i].tolist()
        scratch = new_scratch(2)
        for _ in range(6):
            substep(one, params, CONTACTS, GROUPS, drive[:, i].tolist(), float(dt[i]), scratch)
        assert one == batch[:, i].tolist(), f"car {i}"


@pytest.mark.skipif(not dynamics.COMPILED, reason="numba (the fast extra) is not installed")
def test_numbas_loop_is_the_same_function_bit_for_bit() -> None:
    """``run_car``, the single env's compiled loop (the batch's is ``lanes``:
    ``tests/test_planar_lanes.py``)."""
    rng = np.random.default_rng(1)
    n = 16
    states = random_states(rng, n)
    drive = np.abs(rng.normal(size=(4, n))) * 0.1
    dt = rng.uniform(0.001, 0.03, n)
    steps = rng.integers(0, 5, n)
    for i in range(n):
        compiled = states[:, i].copy()
        dynamics.run_car(compiled, np.array(car()), np.array(CONTACTS),
                         np.array(GROUPS, dtype=np.int64), drive[:, i].copy(), float(dt[i]),
                         int(steps[i]))
        one = states[:, i].tolist()
        for _ in range(steps[i]):
            substep(one, car(), CONTACTS, GROUPS, drive[:, i].tolist(), float(dt[i]),
                    new_scratch(2))
        assert one == compiled.tolist(), f"car {i}"


def test_a_car_at_rest_without_torque_stays_exactly_at_rest() -> None:
    state = rest_state(0.3, -0.2, 1.0, 0.0, 2)
    state[ANGLE], state[ANGLE + 1] = 0.1, -0.4
    before = list(state)
    for _ in range(50):
        substep(state, car(), CONTACTS, GROUPS, [0.0, 0.0, 0.0, 0.0], 0.02, new_scratch(2))
    assert state == before


def test_rolling_without_slip_or_friction_keeps_its_speed() -> None:
    """Body at 0.4 m/s along its heading, wheels at 0.4 / r: no slip, no force, no change."""
    yaw = 0.7
    v = 0.4
    state = moving(math.cos(yaw), math.sin(yaw), v * math.cos(yaw), v * math.sin(yaw),
                   wheels=v / RADIUS)
    for _ in range(100):
        substep(state, car(coulomb=0.0), CONTACTS, GROUPS, [0.0] * 4, 0.01, new_scratch(2))
    assert math.hypot(state[VX], state[VY]) == pytest.approx(v, abs=1e-9)
    assert state[SPEED] == pytest.approx(v / RADIUS, abs=1e-6)
    assert math.atan2(state[SIN], state[COS]) == pytest.approx(yaw, abs=1e-9)
    assert math.hypot(state[X], state[Y]) == pytest.approx(v * 1.0, rel=1e-6)  # 1 s


def test_coast_down_decelerates_as_coulomb_friction_through_rolling_wheels() -> None:
    """Hand-derived: two groups with Coulomb torque T each, wheels rolling without slip, slow
    a car of mass m with spin inertia J per group at ``(2 T / r) / (m + 2 J / r^2)``."""
    coulomb, inertia, v0 = 0.03, 2e-3, 0.3
    expected = (2 * coulomb / RADIUS) / (MASS + 2 * inertia / RADIUS ** 2)
    state = moving(1.0, 0.0, v0, 0.0, wheels=v0 / RADIUS)
    t = 0.0
    for _ in range(20):  # 0.2 s: the car still rolls
        substep(state, car(slip=0.002, inertia=inertia, coulomb=coulomb), CONTACTS, GROUPS,
                [0.0] * 4, 0.01, new_scratch(2))
        t += 0.01
    assert (v0 - state[VX]) / t == pytest.approx(expected, rel=0.02)
    assert abs(state[VY]) < 1e-12 and abs(state[YAW_RATE]) < 1e-12  # straight on


def test_a_motor_torque_spins_a_free_wheel_group_as_newton_says() -> None:
    """A car lifted off the ground (no contacts): a group's torque tau accelerates it at
    tau / J, minus the back-EMF damping's share (integrated implicitly: exact for a
    linear system in one step of the linearised Euler)."""
    tau, damping, inertia, dt = 0.1, 0.01, 2e-3, 0.01
    state = rest_state(0.0, 0.0, 1.0, 0.0, 2)
    params = car(inertia=inertia, coulomb=0.0)
    substep(state, params, [], (), [tau, 0.0, damping, 0.0], dt, new_scratch(2))
    assert state[SPEED] == pytest.approx(dt * tau / (inertia + dt * damping), rel=1e-12)
    assert state[SPEED + 1] == 0.0 and state[VX] == 0.0


@pytest.mark.parametrize("reaction", [1.0, 0.5, 0.0])
def test_wheels_spinning_up_load_the_rear_as_their_torque_says(reaction: float) -> None:
    """Hand-derived: a car lifted off the ground (no contacts: the body cannot accelerate), a
    torque tau on each group spins it up at tau / J; the wheels' angular momentum along +y
    then grows at ``reaction * 2 tau``, a moment the loads supply: their pitch moment
    sum(x dN) is ``-reaction * 2 tau`` (the load moves to the rear wheels, as a wheelie's
    does)."""
    tau, inertia, dt = 0.05, 2e-3, 0.01
    state = rest_state(0.0, 0.0, 1.0, 0.0, 2)
    substep(state, car(inertia=inertia, coulomb=0.0, reaction=reaction), [], (),
            [tau, tau, 0.0, 0.0], dt, new_scratch(2))
    assert state[SPEED] == pytest.approx(dt * tau / inertia, rel=1e-12)
    assert state[VX] == 0.0 and state[VY] == 0.0
    assert state[PITCH] == pytest.approx(-reaction * 2 * tau, rel=1e-12)
    assert state[ROLL] == pytest.approx(0.0, abs=1e-15)
    load = loads(state)
    front, rear = load[0] + load[2], load[1] + load[3]
    assert rear - front == pytest.approx(reaction * 2 * tau / 0.08, rel=1e-12)


def test_spinning_wheels_turned_with_the_body_load_the_outer_side() -> None:
    """Hand-derived gyroscope: wheels spinning forward at om (angular momentum J om along +y)
    on a body yawing left at w (lifted: nothing changes either) need the moment
    w x L = -w J om along x: the loads carry the roll moment sum(y dN) = -2 w J om, more load
    on the right (outer) wheels."""
    inertia, om, w = 2e-3, 20.0, 1.5
    state = moving(1.0, 0.0, 0.0, 0.0, w, wheels=om)
    substep(state, car(inertia=inertia, coulomb=0.0), [], (), [0.0] * 4, 0.01,
            new_scratch(2))
    assert state[YAW_RATE] == w and state[SPEED] == om
    assert state[ROLL] == pytest.approx(-2 * w * inertia * om, rel=1e-12)
    load = loads(state)
    assert load[2] + load[3] - load[0] - load[1] == pytest.approx(
        2 * w * inertia * om / 0.08, rel=1e-12)


SLIDING = tuple(-1 for _ in CONTACTS)  # every contact slides: a block on the ground


def sliding_block(v0: float) -> list[float]:
    return moving(1.0, 0.0, v0, 0.0)


def test_a_stop_within_the_substep_lands_at_rest_not_past_it() -> None:
    """Hand-derived: a block sliding at 5 cm/s on friction 0.5 (and 0.515 sideways) stops in
    v0 / (mu g) = 10 ms. The tangent step alone, with friction saturated at a slip speed of
    0.3 mm/s, would carry it to v0 - mu g dt = -4.8 cm/s in one 20 ms substep; the secant
    step keeps its sign and leaves it within a slip speed of rest."""
    eps, dt, v0 = 3e-4, 0.02, 0.05
    assert v0 - MU * 9.81 * dt < -0.04  # what overshooting by the whole Coulomb force gives
    state = sliding_block(v0)
    speeds = []
    for _ in range(5):
        substep(state, car(slip=eps, coulomb=0.0), CONTACTS, SLIDING, [0.0] * 4, dt,
                new_scratch(2))
        speeds.append(state[VX])
    assert all(0.0 <= v < eps for v in speeds), speeds
    assert state[VY] == pytest.approx(0.0, abs=1e-12)
    assert state[YAW_RATE] == pytest.approx(0.0, abs=1e-12)
    # the distance slid: at most the 0.25 mm of the exact stop plus one substep's creep
    assert 0.0 < state[X] < v0 ** 2 / (2 * MU * 9.81) + eps * dt


def test_the_second_solve_changes_only_cars_that_reverse_a_slip() -> None:
    """The tangent step alone (``anywhere`` never true) against the full step: a car rolling on
    under a gentle torque reverses nothing and is stepped bit for bit the same; the sliding
    block, whose stop the tangent step overshoots, is not: alone, it rattles between about
    +-5 cm/s, substep after substep."""
    from smartcar_gym.sim.planar.dynamics import _where, make_solve, make_substep

    tangent_only = make_substep(math.sqrt, make_solve(math.sqrt, _where), _where,
                                lambda crossed: False)
    v = 0.2
    rolling = moving(1.0, 0.0, v, 0.0, wheels=v / RADIUS)
    for state0, groups, drive in ((rolling, GROUPS, [0.01, 0.012, 0.001, 0.001]),
                                  (sliding_block(0.05), SLIDING, [0.0] * 4)):
        full, alone = list(state0), list(state0)
        speeds = []
        for _ in range(10):
            substep(full, car(slip=3e-4), CONTACTS, groups, drive, 0.02, new_scratch(2))
            tangent_only(alone, car(slip=3e-4), CONTACTS, groups, drive, 0.02, new_scratch(2))
            speeds.append((full[VX], alone[VX]))
        if groups is GROUPS:
            assert full == alone
        else:
            assert all(0.0 <= v < 3e-4 for v, _ in speeds)
            assert all(abs(w) > 0.04 for _, w in speeds) and min(w for _, w in speeds) < 0.0


def test_a_stop_converges_with_the_substep() -> None:
    """The same block from 0.3 m/s (a 61 ms stop), never moving backwards: its slide at 1 ms
    within 0.3 mm of the exact v0^2 / (2 mu g) = 9.2 mm, and at 20 ms short of it by about
    half a substep's travel at the start, v0 dt / 2 = 3 mm (positions take the new speeds)."""
    eps, v0 = 3e-4, 0.3

    def slide(dt: float) -> float:
        state = sliding_block(v0)
        for _ in range(round(0.2 / dt)):
            x = state[X]
            substep(state, car(slip=eps, coulomb=0.0), CONTACTS, SLIDING, [0.0] * 4, dt,
                    new_scratch(2))
            assert state[X] >= x
        return state[X]

    exact = v0 ** 2 / (2 * MU * 9.81)
    assert slide(0.001) == pytest.approx(exact, abs=3e-4)
    assert slide(0.02) == pytest.approx(exact - v0 * 0.02 / 2, abs=5e-4)


def test_braking_moves_load_to_the_front_wheels() -> None:
    """Hand-derived: a ground force F along x at the ground, the centre of mass h above it,
    four wheels at x = +-a: the front pair gains h F / (2 a) in all, the rear pair loses it."""
    transfer = load_transfer(np.array([(0.08, 0.08), (-0.08, 0.08), (0.08, -0.08),
                                       (-0.08, -0.08)]))
    braking = -2.0  # N: the ground pushes the car backwards; the loads carry -h F
    change = transfer @ np.array([-HEIGHT * braking, 0.0])
    front = change[[0, 2]].sum()
    assert front == pytest.approx(-HEIGHT * braking / (2 * 0.08))
    assert change.sum() == pytest.approx(0.0, abs=1e-12)
    # pushed towards +y: the right side (y < 0) gains
    turning = transfer @ np.array([0.0, -HEIGHT * 3.0])
    assert turning[2] > 0 > turning[0] and turning[[2, 3]].sum() == pytest.approx(
        HEIGHT * 3.0 / (2 * 0.08))


def test_static_loads_follow_the_centre_of_mass() -> None:
    four = np.array([(0.08, 0.08), (-0.08, 0.08), (0.08, -0.08), (-0.08, -0.08)])
    assert static_loads(four, np.zeros(2), 10.0) == pytest.approx([2.5] * 4)
    # three points: the casterbot's wheels at x = 0.04, caster at x = -0.08 (determinate):
    # with the centre of mass at x = 0, the caster carries 0.04 / 0.12 of the weight
    three = np.array([(0.04, 0.09), (0.04, -0.09), (-0.08, 0.0)])
    loads = static_loads(three, np.zeros(2), 12.0)
    assert loads == pytest.approx([4.0, 4.0, 4.0])
    loads = static_loads(three, np.array([0.01, 0.0]), 12.0)
    assert loads[2] == pytest.approx(12.0 * 0.03 / 0.12)
    assert loads.sum() == pytest.approx(12.0)


@pytest.mark.parametrize("points, com, message", [
    ([(0.1, 0.1), (-0.1, 0.1)], (0.0, 0.0), "cannot carry"),
    ([(0.1, 0.0), (0.0, 0.0), (-0.1, 0.0)], (0.0, 0.0), "one line"),
    ([(0.1, 0.1), (-0.1, 0.1), (0.0, -0.1)], (0.0, 0.5), "tip over"),
])
def test_contacts_that_cannot_carry_the_body_are_refused(points, com, message) -> None:
    with pytest.raises(ValueError, match=message):
        static_loads(np.array(points), np.array(com), 10.0)


@pytest.mark.skipif(not dynamics.COMPILED, reason="the threads split numba's loops (fast extra)")
def test_the_batch_gives_the_same_bits_on_one_thread_or_two(monkeypatch) -> None:
    """The planar batched env splits its cars over threads (``num_threads``): the physics
    (``PlanarBatch.threads``, here in chunks of one block of cars) and the boards and
    controllers (``BatchedArbotix.threads``; here in chunks of 8 cars). Each car is stepped
    alone, so any split gives the same state, bit for bit, through 300 random steps of 64 cars
    with per-car substeps and autoresets."""
    import gymnasium as gym

    import smartcar_gym  # noqa: F401
    from smartcar_gym.controller import compiled
    from smartcar_gym.sim.planar import batch as planar_batch
    from smartcar_gym.sim.planar import lanes

    monkeypatch.setattr(compiled, "MIN_CHUNK_CARS", 8)
    monkeypatch.setattr(planar_batch, "MIN_CHUNK_CARS", lanes.LANES)  # a block a chunk

    def rollout(threads: int) -> list[np.ndarray]:
        env = gym.make_vec("SmartCar-v0", num_envs=64, vectorization_mode="vector_entry_point",
                           engine="planar", num_threads=threads)
        try:
            batch, base = env.unwrapped.cars.batch, env.unwrapped.base
            assert batch.threads == base.threads == threads
            obs, _ = env.reset(seed=3)
            rng, out = np.random.default_rng(3), [obs]
            for _ in range(300):
                step = env.step(rng.uniform(-1, 1, (64, 2)).astype(np.float32))
                out += [*step[:4], batch.state.copy(), base.floats.copy(), base.ints.copy(),
                        base.flags.copy()]
            return out
        finally:
            env.close()

    one, two = rollout(1), rollout(2)
    assert all(np.array_equal(a, b) for a, b in zip(one, two, strict=True))
