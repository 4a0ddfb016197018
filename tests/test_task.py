"""The goal-reaching task as pure functions: sampling, success, arena, reward."""

import math

import numpy as np
import pytest

from smartcar_gym.envs.tasks import GoalReachingTask


def test_goal_sampling_respects_range_and_is_seeded():
    task = GoalReachingTask(goal_range_m=(0.5, 1.5))
    goals = np.array([task.sample_goal(np.random.default_rng(i), np.zeros(2)) for i in range(200)])
    dist = np.linalg.norm(goals, axis=1)
    assert dist.min() >= 0.5 and dist.max() <= 1.5
    # bearings cover all four quadrants
    assert {(x > 0, y > 0) for x, y in goals} == {(a, b) for a in (0, 1) for b in (0, 1)}
    a = task.sample_goal(np.random.default_rng(7), np.array([1.0, 2.0]))
    b = task.sample_goal(np.random.default_rng(7), np.array([1.0, 2.0]))
    assert np.array_equal(a, b)
    assert 0.5 <= math.dist(a, (1.0, 2.0)) <= 1.5


def test_distance_success_and_arena_work_on_batches():
    task = GoalReachingTask(goal_tolerance_m=0.1, arena_half_size_m=2.0)
    pos = np.array([[0.0, 0.0], [1.0, 0.95], [2.5, 0.0]])
    goal = np.array([1.0, 1.0])
    d = task.distance(pos, goal)
    np.testing.assert_allclose(d, [math.sqrt(2), 0.05, math.hypot(1.5, 1.0)])
    assert task.is_success(d).tolist() == [False, True, False]
    assert task.is_outside(pos).tolist() == [False, False, True]


def test_reward_hand_computed():
    task = GoalReachingTask()
    # 0.2 m of progress with action (0.5, -0.5): 10*0.2 - 0.01 - 0.01*0.5 = 1.985
    assert task.reward(1.0, 0.8, np.array([0.5, -0.5]), False, False) == pytest.approx(1.985)
    # success adds 10, failure subtracts 10
    assert task.reward(0.15, 0.05, np.zeros(2), True, False) == pytest.approx(1.0 - 0.01 + 10)
    assert task.reward(1.0, 1.1, np.ones(2), False, True) == pytest.approx(-1.0 - 0.03 - 10)
    batch = task.reward(np.array([1.0, 1.0]), np.array([0.9, 1.0]), np.zeros((2, 2)),
                        np.array([False, False]), np.array([False, True]))
    np.testing.assert_allclose(batch, [0.99, -10.01])


def test_step_outcome_is_the_pure_functions_bit_for_bit():
    """``evaluate`` (the per-step path on floats) agrees exactly with the array functions."""
    task = GoalReachingTask(goal_tolerance_m=0.1, arena_half_size_m=2.5)
    rng = np.random.default_rng(3)
    cases = 0
    for _ in range(2000):
        position = rng.uniform(-2.7, 2.7, 2)
        goal = position + rng.normal(0.0, 0.2, 2) if rng.random() < 0.3 else rng.uniform(-2, 2, 2)
        up_z = rng.choice([1.0, 0.7, 0.4])
        action = rng.uniform(-1, 1, 2)
        previous = float(rng.uniform(0, 3))
        out = task.evaluate(previous, position, up_z, goal, action)
        distance = task.distance(position, goal)
        success = bool(task.is_success(distance))
        failure = bool(task.is_failure(position, up_z))
        reward = float(task.reward(previous, distance, action, success, failure))
        assert (out.distance, out.success, out.failure, out.reward) == (
            float(distance), success, failure, reward)
        cases += success + 2 * failure
    assert cases > 100  # successes and failures were both exercised


@pytest.mark.parametrize(
    "kwargs, message",
    [
        ({"goal_range_m": (1.5, 0.5)}, "goal_range"),
        ({"goal_range_m": (-1.0, 0.5)}, "goal_range"),
        ({"goal_tolerance_m": 0.0}, "goal_tolerance"),
        ({"goal_range_m": (0.5, 3.0), "arena_half_size_m": 2.5}, "inside the arena"),
    ],
)
def test_bad_task_parameters_are_rejected(kwargs, message):
    with pytest.raises(ValueError, match=message):
        GoalReachingTask(**kwargs)


def test_arriving_needs_rest_and_odometry_inside_the_tolerance():
    """With ``stop_speed_m_s``: success only at rest with truth and odometry inside; inside, the
    speed costs; every step the odometry's drift from the truth costs (hand-derived)."""
    task = GoalReachingTask(stop_speed_m_s=0.01, speed_cost=1.0, odometry_cost=20.0)
    goal, action = np.zeros(2), np.zeros(2)
    # 0.05 m away at 0.2 m/s, odometry (0.03, 0.04): 0.05 from the goal, 0.05 from the truth
    out = task.evaluate(0.08, np.array([0.05, 0.0]), 1.0, goal, action, 0.2, (0.03, 0.04), 0.02)
    assert not out.success
    assert out.odometry_error == pytest.approx(math.hypot(0.02, 0.04))
    expected = 10 * 0.03 - 0.01 - 1.0 * 0.2 - 20.0 * (math.hypot(0.02, 0.04) - 0.02)
    assert out.reward == pytest.approx(expected)
    # the same at 0.005 m/s: at rest, the bonus
    out = task.evaluate(0.05, np.array([0.05, 0.0]), 1.0, goal, action, 0.005, (0.05, 0.0),
                        0.0)
    assert out.success and out.reward == pytest.approx(-0.01 - 0.005 + 10)
    # at rest inside in truth, but the odometry 0.12 m from the goal: not arrived, no speed cost
    out = task.evaluate(0.05, np.array([0.05, 0.0]), 1.0, goal, action, 0.5, (0.12, 0.0), 0.07)
    assert not out.success and out.reward == pytest.approx(-0.01)
    assert bool(task.is_success(0.05, 0.005)) and not bool(task.is_success(0.05, -0.02))
    assert bool(GoalReachingTask().is_success(0.05, 3.0))  # without stop_speed: speed ignored
    with pytest.raises(ValueError, match="stop_speed must be None or a speed > 0 m/s"):
        GoalReachingTask(stop_speed_m_s=0.0)


def test_without_stop_speed_the_arrival_arguments_change_nothing():
    task = GoalReachingTask()
    base = task.evaluate(0.5, np.array([0.3, 0.1]), 1.0, np.zeros(2), np.ones(2))
    other = task.evaluate(0.5, np.array([0.3, 0.1]), 1.0, np.zeros(2), np.ones(2), 0.7,
                          (2.0, 2.0), 1.0)
    assert base == other and base.odometry_error == 0.0
