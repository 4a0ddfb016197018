"""2D Nav Goals one after another: the shipped ``ros`` policy drives to each and stops there.

Through ``GoalDriver`` (the policy node's decisions) and the robot ``smartcar-ros bringup`` runs,
without roscore (``smartcar_gym.ros.goal_run``): 20 goals 0.3-2 m from where the car stands, at
bearings from a fixed seed; each must end with the car at rest within the tolerance by
odometry and by ground truth within 30 s of simulated time.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import shipped_policies as shipped

from smartcar_gym.agents.models import PRETRAINED_MODEL
from smartcar_gym.envs.policy_settings import policy_settings
from smartcar_gym.policy import Policy
from smartcar_gym.ros.cli import ROS_POLICY, build_parser
from smartcar_gym.ros.goal_run import GoalResult, drive_goals, meant_goal, next_goal

REST_M_S = 0.01
TOLERANCE_M = 0.1  # SmartCar-v0's goal_tolerance: what a user clicking goals is promised


def test_pretrained_alone_names_the_ros_policy_trained_to_stop_on_calibrated_odometry():
    args = build_parser().parse_args(["policy", "--pretrained"])
    assert args.pretrained == ROS_POLICY == "ros"
    for name in (PRETRAINED_MODEL, "vecnormalize.pkl", "provenance.json"):
        assert (shipped.folder(ROS_POLICY) / name).is_file(), name
    provenance = shipped.provenance(ROS_POLICY)
    assert (provenance["algo"], provenance["env"]) == ("ppo", "SmartCarArrive-v0")
    assert provenance["evaluation"]["command"].startswith("smartcar-eval --pretrained ros")
    settings = policy_settings(provenance["env"], provenance["env_kwargs"])
    assert settings.controller_config.base_width_m == 0.33  # what bringup publishes by default
    assert settings.task.stop_speed_m_s == REST_M_S
    assert settings.task.goal_range_m == (0.3, 2.0)


def test_goals_are_drawn_from_where_the_car_stands_inside_the_arena():
    rng = np.random.default_rng(0)
    for _ in range(500):
        x, y = rng.uniform(-2.2, 2.2, 2)
        goal = next_goal(rng, x, y, (0.3, 2.0), 2.2)
        assert 0.3 <= math.dist(goal, (x, y)) <= 2.0
        assert max(abs(goal[0]), abs(goal[1])) <= 2.2
    with pytest.raises(ValueError, match=r"no goal \(5.0, 6.0\) m from"):
        next_goal(rng, 0.0, 0.0, (5.0, 6.0), 2.2)


def test_truth_is_measured_from_where_the_goal_was_meant():
    # odometry at (1, 0) facing +y clicked (1, 1): 1 m ahead. In truth the car stood at (1.1, 0)
    # facing -x, so the goal was meant at (0.1, 0); it stopped at (0.15, 0).
    result = GoalResult(goal=(1.0, 1.0), real_goal=(0.1, 0.0), reached=True, time_s=5.0,
                        odom=(1.0, 0.95), truth=(0.15, 0.0), odom_speed=0.0, truth_speed=0.0)
    assert result.odom_distance == pytest.approx(0.05)
    assert result.truth_distance == pytest.approx(0.05)
    assert result.world_distance == pytest.approx(math.hypot(0.85, 1.0))
    assert result.arrived(0.1, REST_M_S)
    assert not result.arrived(0.04, REST_M_S)
    moving = GoalResult(**{**result.__dict__, "truth_speed": 0.02})
    assert not moving.arrived(0.1, REST_M_S)


@pytest.mark.slow
def test_twenty_goals_in_a_row_end_at_rest_within_the_tolerance():
    policy = Policy.load(ROS_POLICY)
    settings = policy.settings
    results = drive_goals(settings, policy.act, count=20, seed=0, timeout_s=30.0)
    assert settings.task.goal_tolerance_m <= TOLERANCE_M
    arrived = [r.arrived(TOLERANCE_M, REST_M_S) for r in results]
    table = "\n".join(
        f"({r.goal[0]:+.2f}, {r.goal[1]:+.2f}) {r.time_s:4.1f} s odom {r.odom_distance:.3f} "
        f"truth {r.truth_distance:.3f} world {r.world_distance:.3f} m" for r in results)
    assert sum(arrived) >= 19, table
    for before, after in zip(results, results[1:], strict=False):  # from where the car stood
        assert 0.3 - 1e-9 <= math.dist(before.odom, after.goal) <= 2.0 + 1e-9


def test_the_meant_goal_keeps_the_click_relative_to_the_car():
    # odometry (1, 0) facing +y, goal (1, 1): 1 m ahead; truth (1.1, 0) facing -x: (0.1, 0)
    goal = meant_goal((1.0, 1.0), (1.0, 0.0, math.pi / 2), (1.1, 0.0, math.pi))
    assert goal == pytest.approx((0.1, 0.0))
    assert meant_goal((0.3, -0.2), (0.0, 0.0, 0.0), (0.0, 0.0, 0.0)) == (0.3, -0.2)
