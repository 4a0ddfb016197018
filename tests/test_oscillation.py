"""TrajectoryPlanner's choice around its samples (navigation/oscillation.py): the in-place turn
towards the local goal, the flags that bar turning back and forth, the escape; and the speed
the DWA driver commands through the car's response (bench/dwa.py ``speed_command``)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from smartcar_gym.bench.dwa import speed_command
from smartcar_gym.navigation.oscillation import Oscillation, OscillationConfig

# two forward samples, four in-place turns (rad/s), the escape last
SAMPLES = np.array([[[0.1, 0.0], [0.1, 0.5], [0.0, -0.5], [0.0, -1.0], [0.0, 0.5], [0.0, 1.0],
                     [-0.025, 0.0]]])
CONFIG = OscillationConfig()  # ROS's defaults: lookahead 0.325, resets 0.05 m, 0.1 m, pi / 4


def _choose(osc: Oscillation, pose, valid, cost=None, goal=(1.0, 0.0)) -> tuple[float, float]:
    valid = np.array([valid], dtype=bool)
    cost = np.where(valid, [[0, 1, 2, 2, 2, 2, 3]] if cost is None else np.array([cost]), np.nan)
    out = osc.choose([0], np.array([pose], dtype=float), SAMPLES, valid, cost,
                     np.array([goal]), forward=2, sim_time=1.0)
    return tuple(out[0])


def test_the_cheapest_forward_sample_wins_when_one_is_valid():
    osc = Oscillation(1, CONFIG)
    osc.reset(0, np.zeros(3))
    assert _choose(osc, (0, 0, 0), [1, 1, 1, 1, 1, 1, 1], cost=[5, 4, 6, 6, 6, 6, 0]) == (0.1, 0.5)
    assert not osc.rotating.any() and not osc.escaping[0]
    # a turn no dearer than the best forward sample is taken instead
    assert _choose(osc, (0, 0, 0), [1, 1, 1, 1, 1, 1, 1], cost=[5, 4, 6, 4, 6, 6, 0]) == \
        (0.0, -1.0)


def test_an_in_place_turn_no_dearer_than_the_best_is_taken_towards_the_goal():
    osc = Oscillation(1, CONFIG)
    osc.reset(0, np.zeros(3))
    # no forward sample: of the turns, the one whose end heading (w x 1 s) looks nearest the
    # goal on the left (0, 1): w = 1.0 ends at 57 degrees, nearer than 0.5's 29 degrees
    assert _choose(osc, (0, 0, 0), [0, 0, 1, 1, 1, 1, 1], goal=(0.0, 1.0)) == (0.0, 1.0)
    assert osc.rotating[0].tolist() == [True, False]
    # a forward sample cheaper than every turn keeps the turns out
    assert _choose(osc, (0, 0, 0), [1, 0, 1, 1, 1, 1, 1], cost=[0, 9, 1, 1, 1, 1, 1],
                   goal=(0.0, 1.0)) == (0.1, 0.0)


def test_turning_the_same_way_twice_in_place_bars_it_then_the_robot_backs_up():
    osc = Oscillation(1, CONFIG)
    osc.reset(0, np.zeros(3))
    turns_only = [0, 0, 1, 1, 1, 1, 1]
    assert _choose(osc, (0, 0, 0), turns_only, goal=(0.0, 1.0)) == (0.0, 1.0)
    assert _choose(osc, (0, 0, 0.1), turns_only, goal=(0.0, 1.0)) == (0.0, 1.0)
    assert osc.stuck[0].tolist() == [True, False]  # left twice: stuck_left
    # as the source has it, stuck_left bars the negative rates: right turns are barred now
    assert _choose(osc, (0, 0, 0.2), turns_only, goal=(0.0, 1.0)) == (0.0, 1.0)
    assert _choose(osc, (0, 0, 0.3), turns_only, goal=(0.0, -1.0)) == (0.0, 0.5)
    # both ways barred once a right turn was taken twice as well
    osc.stuck[0] = True
    assert _choose(osc, (0, 0, 0.4), turns_only) == (-0.025, 0.0)  # the escape
    assert osc.escaping[0] and osc.escape_pose[0].tolist() == [0, 0, 0.4]
    # escaping: no forward sample, though one is valid
    assert _choose(osc, (0, 0, 0.4), [1, 1, 0, 0, 0, 0, 1]) == (-0.025, 0.0)
    # 0.05 m from where the last turn was taken, every flag clears
    _choose(osc, (-0.06, 0, 0.4), [0, 0, 0, 0, 0, 0, 1])
    assert not osc.stuck.any() and not osc.rotating.any() and osc.escaping[0]
    # 0.1 m from where the escape began, it ends (after this cycle's choice, as in the
    # source): the forward samples are back on the next
    assert _choose(osc, (-0.11, 0, 0.4), [1, 1, 0, 0, 0, 0, 1]) == (-0.025, 0.0)
    assert not osc.escaping[0]
    assert _choose(osc, (-0.11, 0, 0.4), [1, 1, 0, 0, 0, 0, 1], cost=[1, 0, 0, 0, 0, 0, 0]
                   ) == (0.1, 0.5)


def test_the_escape_ends_after_a_turn_of_a_quarter_pi_and_backs_up_even_when_blocked():
    osc = Oscillation(1, CONFIG)
    osc.reset(0, np.zeros(3))
    assert _choose(osc, (0, 0, 3.1), [0] * 7) == (-0.025, 0.0)  # blocked too: backs up
    assert osc.escaping[0]
    _choose(osc, (0, 0, 3.1 + math.pi / 4 - 0.01), [0] * 7)
    assert osc.escaping[0]
    _choose(osc, (0, 0, -3.1 + math.pi / 4), [0] * 7)  # across +-pi: 0.87 rad turned
    assert not osc.escaping[0]


def test_the_challenge_scales_the_lengths_and_a_bad_value_is_one_line():
    c = OscillationConfig.challenge(0.4186)
    assert (c.heading_lookahead, c.oscillation_reset_dist, c.escape_reset_dist) == \
        pytest.approx((0.1360, 0.02093, 0.04186), rel=1e-3)
    assert c.escape_reset_theta == pytest.approx(math.pi / 4)
    with pytest.raises(ValueError, match="oscillation escape_reset_dist"):
        OscillationConfig(escape_reset_dist=0.0)


def test_speeds_are_commanded_through_the_cars_response():
    # the measured table: 0.05 m/s commanded drives 0.029; half way between two rows
    assert speed_command(np.array([0.029, -0.029, 0.0, 0.2])).tolist() == \
        pytest.approx([0.05, -0.05, 0.0, 0.2])
    assert speed_command(np.array([0.0775]))[0] == pytest.approx(0.0875, rel=1e-2)
    # below the slowest speed it drives (0.0187 m/s for 0.04), between 0.03 and 0.04
    assert speed_command(np.array([0.01]))[0] == pytest.approx(0.03 + 0.01 / 0.0187 * 0.01)


def test_the_dwa_driver_is_move_base_in_full_only_without_the_map():
    import gymnasium as gym

    from smartcar_gym.bench.dwa import DWADriver
    from smartcar_gym.envs.vector.view import CarView

    top = {}
    for mode in ("known", "laser"):
        env = gym.make("SmartCarBARN-v0", engine="planar", map_mode=mode)
        obs, _ = env.reset(seed=0, options={"world": 0})
        cars, driver = CarView([env]), DWADriver()
        driver.reset(cars)
        assert (driver.oscillation is None) == (mode == "known")
        speeds = set()
        for _ in range(20):  # the open corridor: DWA plans its top speed, 0.125 m/s
            action = driver.act(cars, obs)[0]
            speeds.add(round(float(action[0]) * env.unwrapped.task.car.max_linear, 5))
            obs, *_ = env.step(action)
        env.close()
        top[mode] = max(speeds)
    # without the map, through the car's response: 0.125 between the rows (0.125 -> 0.122,
    # 0.15 -> 0.146) is 0.125 + 0.003 / 0.024 x 0.025
    assert top == {"known": 0.125, "laser": pytest.approx(0.128125, abs=1e-5)}
