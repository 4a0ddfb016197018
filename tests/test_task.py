"""The goal-reaching task (``ReachTask``) over arrays of cars: sampling, success, arena, reward."""

import math

import numpy as np
import pytest

from smartcar_gym.envs.tasks.reach import ReachTask
from tests.stub_cars import OneCar
from tests.stub_cars import StubCars as Cars


def attached(task: ReachTask, num: int) -> ReachTask:
    task.attach(num)
    return task


def score(task: ReachTask, cars: Cars, position, up_z, goal, action, previous):
    """One step's score of cars at ``position`` (rows), their goals ``goal`` and the distances
    they had ``previous``."""
    state = cars.state
    state.pose[:, :2] = position
    state.up_z[:] = up_z
    state.goal[:] = goal
    task.distance[:] = previous
    action = np.asarray(action, dtype=np.float64)
    return task.score(cars, action if isinstance(cars, OneCar) else action.reshape(-1, 2))


def test_goal_sampling_respects_range_and_is_seeded():
    task = ReachTask(goal_range=(0.5, 1.5))
    goals = np.array([task.sample_goal(np.random.default_rng(i)) for i in range(200)])
    dist = np.linalg.norm(goals, axis=1)
    assert dist.min() >= 0.5 and dist.max() <= 1.5
    # bearings cover all four quadrants
    assert {(x > 0, y > 0) for x, y in goals} == {(a, b) for a in (0, 1) for b in (0, 1)}
    a = task.sample_goal(np.random.default_rng(7))
    b = task.sample_goal(np.random.default_rng(7))
    assert np.array_equal(a, b)
    # ``start`` draws each car's goal from its own generator, or takes the given one
    attached(task, 3)
    cars = Cars(3, seed=7)
    task.start(cars, np.arange(3), [{}, {"goal": np.array([1.0, 2.0])}, {}])
    assert np.array_equal(cars.state.goal[0], a)
    assert cars.state.goal[1].tolist() == [1.0, 2.0]
    assert np.array_equal(cars.state.goal[2], task.sample_goal(np.random.default_rng(9)))


def test_distance_success_and_arena_work_on_batches():
    task = attached(ReachTask(goal_tolerance=0.1, arena_size=4.0), 3)
    assert task.arena_half_size_m == 2.0
    cars = Cars(3)
    pos = np.array([[0.0, 0.0], [1.0, 0.95], [2.5, 0.0]])
    _, success, failure = score(task, cars, pos, 1.0, (1.0, 1.0), np.zeros((3, 2)), 0.0)
    np.testing.assert_allclose(task.distance, [math.sqrt(2), 0.05, math.hypot(1.5, 1.0)])
    assert task.is_success(task.distance).tolist() == [False, True, False]
    assert success.tolist() == [False, True, False]
    assert failure.tolist() == [False, False, True]  # outside the arena


def test_reward_hand_computed():
    task = attached(ReachTask(), 1)
    cars = Cars(1)
    # 0.2 m of progress with action (0.5, -0.5): 10*0.2 - 0.01 - 0.01*0.5 = 1.985
    reward, _, _ = score(task, cars, [[0.8, 0.0]], 1.0, (0.0, 0.0), [0.5, -0.5], 1.0)
    assert reward[0] == pytest.approx(1.985)
    # success adds 10, failure (flipped over) subtracts 10
    reward, success, _ = score(task, cars, [[0.05, 0.0]], 1.0, (0.0, 0.0), [0.0, 0.0], 0.15)
    assert success[0] and reward[0] == pytest.approx(1.0 - 0.01 + 10)
    reward, _, failure = score(task, cars, [[1.1, 0.0]], 0.4, (0.0, 0.0), [1.0, 1.0], 1.0)
    assert failure[0] and reward[0] == pytest.approx(-1.0 - 0.03 - 10)
    batch = attached(ReachTask(), 2)
    reward, _, _ = score(batch, Cars(2), [[0.9, 0.0], [1.0, 0.0]], [1.0, 0.4], (0.0, 0.0),
                         np.zeros((2, 2)), [1.0, 1.0])
    np.testing.assert_allclose(reward, [0.99, -10.01])


def test_a_batch_scores_each_car_as_the_hand_formula_and_its_single_car_bit_for_bit():
    """``score`` over N cars at once gives each car what the task over that car alone gives,
    and what the card's formula gives on floats, exactly."""
    rng = np.random.default_rng(3)
    n = 2000
    position = rng.uniform(-2.7, 2.7, (n, 2))
    near = rng.random(n) < 0.3
    goal = np.where(near[:, None], position + rng.normal(0.0, 0.2, (n, 2)),
                    rng.uniform(-2, 2, (n, 2)))
    up_z = rng.choice([1.0, 0.7, 0.4], n)
    action = rng.uniform(-1, 1, (n, 2))
    previous = rng.uniform(0, 3, n)
    batch = attached(ReachTask(goal_tolerance=0.1, arena_size=5.0), n)
    reward, success, failure = score(batch, Cars(n), position, up_z, goal, action, previous)
    single, cars = attached(ReachTask(goal_tolerance=0.1, arena_size=5.0), 1), Cars(1)
    on_values, car = attached(ReachTask(goal_tolerance=0.1, arena_size=5.0), 1), OneCar()
    for i in range(n):
        r, s, f = score(single, cars, position[i:i + 1], up_z[i], goal[i], action[i],
                        previous[i])
        # the single env's way: the car's values as Python numbers, the same bits
        one = score(on_values, car, position[i:i + 1], up_z[i], goal[i], action[i].reshape(2),
                    previous[i])
        assert [type(v) for v in one] == [float, bool, bool]
        assert one == (reward[i], success[i], failure[i])
        (px, py), (gx, gy), (a0, a1) = position[i], goal[i], action[i]
        distance = math.sqrt((px - gx) * (px - gx) + (py - gy) * (py - gy))
        won = distance < 0.1
        lost = up_z[i] < 0.5 or abs(px) > 2.5 or abs(py) > 2.5
        want = (10.0 * (previous[i] - distance) - 0.01 - 0.01 * (a0 * a0 + a1 * a1)
                + 10.0 * won - 10.0 * lost)
        assert (float(r[0]), bool(s[0]), bool(f[0])) == (reward[i], success[i], failure[i])
        assert (float(reward[i]), bool(success[i]), bool(failure[i])) == (want, won, lost)
        assert batch.distance[i] == single.distance[0] == on_values.distance[0] == distance
    cases = int(success.sum() + 2 * failure.sum())
    assert success.sum() > 30 and failure.sum() > 30 and cases > 100  # both exercised


@pytest.mark.parametrize(
    "kwargs, message",
    [
        ({"goal_range": (1.5, 0.5)}, "goal_range"),
        ({"goal_range": (-1.0, 0.5)}, "goal_range"),
        ({"goal_tolerance": 0.0}, "goal_tolerance"),
        ({"goal_range": (0.5, 3.0), "arena_size": 5.0}, "inside the arena"),
    ],
)
def test_bad_task_parameters_are_rejected(kwargs, message):
    with pytest.raises(ValueError, match=message):
        ReachTask(**kwargs)


def arrive(task: ReachTask, cars: Cars, previous: float, position, speed: float, odometry,
           previous_error: float):
    """One step of a car at ``position`` (goal at the origin, action 0) moving at ``speed``
    whose odometry says ``odometry``, after ``previous`` m to go and ``previous_error`` m of
    drift."""
    cars.state.speed[:] = speed
    cars.state.odometry[0, :2] = odometry
    task.odometry_error[:] = previous_error
    return score(task, cars, [position], 1.0, (0.0, 0.0), [0.0, 0.0], previous)


def test_arriving_needs_rest_and_odometry_inside_the_tolerance():
    """With ``stop_speed``: success only at rest with truth and odometry inside; inside, the
    speed costs; every step the odometry's drift from the truth costs (hand-derived)."""
    task = attached(ReachTask(stop_speed=0.01), 1)
    assert (task.speed_cost, task.odometry_cost) == (1.0, 20.0) and task.needs_speed
    cars = Cars(1)
    # 0.05 m away at 0.2 m/s, odometry (0.03, 0.04): 0.05 from the goal, 0.05 from the truth
    reward, success, _ = arrive(task, cars, 0.08, (0.05, 0.0), 0.2, (0.03, 0.04), 0.02)
    assert not success[0]
    assert task.odometry_error[0] == pytest.approx(math.hypot(0.02, 0.04))
    expected = 10 * 0.03 - 0.01 - 1.0 * 0.2 - 20.0 * (math.hypot(0.02, 0.04) - 0.02)
    assert reward[0] == pytest.approx(expected)
    # the same at 0.005 m/s: at rest, the bonus
    reward, success, _ = arrive(task, cars, 0.05, (0.05, 0.0), 0.005, (0.05, 0.0), 0.0)
    assert success[0] and reward[0] == pytest.approx(-0.01 - 0.005 + 10)
    # at rest inside in truth, but the odometry 0.12 m from the goal: not arrived, no speed cost
    reward, success, _ = arrive(task, cars, 0.05, (0.05, 0.0), 0.5, (0.12, 0.0), 0.07)
    assert not success[0] and reward[0] == pytest.approx(-0.01)
    assert bool(task.is_success(0.05, 0.005)) and not bool(task.is_success(0.05, -0.02))
    assert bool(ReachTask().is_success(0.05, 3.0))  # without stop_speed: speed ignored
    with pytest.raises(ValueError, match=r"^stop_speed must be a positive number, got 0\.0"):
        ReachTask(stop_speed=0.0)


def test_without_stop_speed_the_arrival_arguments_change_nothing():
    task = attached(ReachTask(), 1)
    assert not task.needs_speed
    base = arrive(task, Cars(1), 0.5, (0.3, 0.1), 0.0, (0.3, 0.1), 0.0)
    other = arrive(task, Cars(1), 0.5, (0.3, 0.1), 0.7, (2.0, 2.0), 1.0)
    assert all(np.array_equal(a, b) for a, b in zip(base, other, strict=True))
    assert task.odometry_error[0] == 1.0  # untouched: no drift is measured


def test_arriving_and_info_on_a_cars_values_match_the_batch_bit_for_bit():
    """``stop_speed``'s terms and ``info`` on one car's values (Python numbers, as a single env
    runs them) equal the batch's row for each of 500 random cars."""
    rng = np.random.default_rng(11)
    n = 500
    position = rng.uniform(-0.12, 0.12, (n, 2))
    odometry = position + rng.normal(0.0, 0.03, (n, 2))
    speed = rng.choice([0.0, 0.005, 0.3], n)
    previous, previous_error = rng.uniform(0, 0.2, n), rng.uniform(0, 0.05, n)
    theta = rng.uniform(-20, 20, n)
    batch, cars = attached(ReachTask(stop_speed=0.01), n), Cars(n)
    cars.state.speed[:], cars.state.odometry[:, :2], cars.state.odometry[:, 2] = (
        speed, odometry, theta)
    batch.odometry_error[:] = previous_error
    scored = score(batch, cars, position, 1.0, (0.0, 0.0), np.zeros((n, 2)), previous)
    info = batch.info(cars, scored[1])
    one, car = attached(ReachTask(stop_speed=0.01), 1), OneCar()
    for i in range(n):
        car.state.speed[0], car.state.odometry[0, :2], car.state.odometry[0, 2] = (
            speed[i], odometry[i], theta[i])
        one.odometry_error[0] = previous_error[i]
        got = score(one, car, position[i:i + 1], 1.0, (0.0, 0.0), [0.0, 0.0], previous[i])
        assert got == tuple(v[i] for v in scored)
        assert one.odometry_error[0] == batch.odometry_error[i]
        for key, value in one.info(car, got[1]).items():
            assert np.array_equal(value, info[key][i]), key
            assert np.shape(value) == np.shape(info[key][i])
    assert 20 < scored[1].sum() < n - 20  # arrivals and not


@pytest.mark.parametrize("engine", ["planar", None], ids=["planar batch", "SmartCarSim-v0"])
def test_an_autoreset_gives_every_car_the_one_read_only_empty_options(engine, monkeypatch):
    """No dict a car at each autoreset (4,096 of them cost a 4,096-car batch garbage
    collections): every car that starts again without options shares ``NO_OPTIONS``."""
    import gymnasium as gym

    import smartcar_gym  # noqa: F401
    from smartcar_gym.envs.tasks.base import NO_OPTIONS

    env_id, kwargs = ("SmartCar-v0", {"engine": engine}) if engine else ("SmartCarSim-v0", {})
    env = gym.make_vec(env_id, num_envs=3, vectorization_mode="vector_entry_point",
                       max_episode_steps=2, **kwargs)
    try:
        seen = []
        start = type(env.task).start
        monkeypatch.setattr(type(env.task), "start", lambda self, cars, idx, options: (
            seen.append((idx.tolist(), list(options))), start(self, cars, idx, options))[1])
        env.reset(seed=0)  # a reset without options: Task.check_options gives the same
        for _ in range(3):
            env.step(np.zeros((3, 2), dtype=np.float32))
    finally:
        env.close()
    # the reset, then every car ends at step 2
    assert len(seen) >= 2 and all(idx == [0, 1, 2] for idx, _ in seen)
    assert all(len(options) == 3 and all(o is NO_OPTIONS for o in options)
               for _, options in seen)
    with pytest.raises(TypeError):
        NO_OPTIONS["goal"] = (1.0, 0.0)  # type: ignore[index]
