"""move_base's recovery behaviours (navigation/recovery.py, DWADriver with map_mode="laser"),
with the expected answers derived by hand from move_base.cpp's executeCycle, clear_costmap_
recovery's clearMap and rotate_recovery (docs/barn.md, "Recoveries")."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest

import smartcar_gym  # noqa: F401
from smartcar_gym.navigation.costmap import (
    COMPILED,
    FREE,
    INSCRIBED,
    LETHAL,
    CostmapConfig,
    LaserCostmaps,
)
from smartcar_gym.navigation.recovery import (
    ABORTED,
    AGGRESSIVE,
    CLEARING,
    CONSERVATIVE,
    CONTROL,
    IN_RECOVERY,
    PLANNING,
    ROTATE,
    ROTATING,
    STOP,
    Recoveries,
    RecoveryConfig,
    Rotations,
)

# patience 1 s for the controller, 0.5 s for the planner; a cycle every 0.1 s
CONFIG = RecoveryConfig(controller_patience=1.0, planner_patience=0.5,
                        conservative_reset_m=3.0, aggressive_reset_m=1.0)


def _run(machine: Recoveries, ticks: range, valid=lambda k: False, plan=lambda k: True,
         position=lambda k: (0.0, 0.0)) -> list[tuple[int, int]]:
    """(tick, action) of every cycle whose action is not STOP; a rotation ends at once."""
    seen = []
    for k in ticks:
        now = np.array([k / 10])
        act = int(machine.step([0], now, np.array([position(k)]), np.array([plan(k)]),
                               np.array([valid(k)]))[0])
        if act in (ROTATE, ROTATING):
            machine.rotated(0, k / 10)
        if act != STOP:
            seen.append((k, act))
    return seen


def test_no_valid_command_for_the_patience_runs_the_behaviours_in_order_then_aborts():
    machine = Recoveries(1, CONFIG)
    machine.reset(0, 0.0, np.zeros(2))
    seen = _run(machine, range(0, 26))
    # t = 1.1 s is past 0 + 1 s: CLEARING, run in the next cycle; last_valid_control stays 0,
    # so each cycle after a behaviour (PLANNING -> new plan -> no command) clears again
    assert seen[:5] == [(12, CONSERVATIVE), (14, ROTATE), (16, AGGRESSIVE), (18, ROTATE),
                        (20, ABORTED)]
    assert all(act == ABORTED for _, act in seen[5:]) and len(seen) == 5 + 5
    assert machine.log[0] == [CONSERVATIVE, ROTATE, AGGRESSIVE, ROTATE]


def test_a_valid_command_sets_the_index_back_as_move_base_does():
    machine = Recoveries(1, CONFIG)
    machine.reset(0, 0.0, np.zeros(2))
    # a valid command at 1.3 s (after the conservative reset): index 0, patience again
    seen = _run(machine, range(0, 30), valid=lambda k: k == 13)
    assert seen == [(12, CONSERVATIVE), (13, CONTROL), (25, CONSERVATIVE), (27, ROTATE),
                    (29, AGGRESSIVE)]


def test_no_new_plan_for_the_planner_patience_clears_and_a_new_plan_sets_the_index_back():
    machine = Recoveries(1, CONFIG)
    machine.reset(0, 0.0, np.zeros(2))  # no command at 0 s: PLANNING from 0 s
    seen = _run(machine, range(0, 15), plan=lambda k: False)
    # 0.6 s > 0 + 0.5 s: CLEARING; 0.7 s: the reset, PLANNING from 0.7 s; 1.3 s > 1.2 s
    assert seen == [(7, CONSERVATIVE), (14, ROTATE)]
    assert machine.index[0] == 2
    machine.step([0], np.array([1.5]), np.zeros((1, 2)), np.array([True]), np.array([True]))
    assert machine.index[0] == 0 and machine.state[0] != CLEARING


def test_oscillation_when_enabled_and_moving_far_enough_sets_it_back():
    config = RecoveryConfig(controller_patience=100.0, oscillation_timeout=1.0,
                            oscillation_distance=0.5)
    machine = Recoveries(1, config)
    machine.reset(0, 0.0, np.zeros(2))
    seen = _run(machine, range(0, 14), valid=lambda k: True)
    # 1.1 s > 0 + 1 s: CLEARING (the command of that cycle still sent), run at 1.2 s; the
    # behaviour resets the timer (1.2 s), so the next is due after 2.2 s
    assert (11, CONTROL) in seen and (12, CONSERVATIVE) in seen
    assert machine.index[0] == 1
    machine.step([0], np.array([1.4]), np.array([[0.5, 0.0]]), np.array([True]),
                 np.array([True]))
    assert machine.index[0] == 0  # moved 0.5 m, the trigger oscillation: back to 0
    off = Recoveries(1, RecoveryConfig(controller_patience=100.0))  # the challenge's: 0, off
    off.reset(0, 0.0, np.zeros(2))
    assert all(act == CONTROL for _, act in _run(off, range(0, 100), valid=lambda k: True))


def test_the_challenges_set_scales_as_dwa():
    c = RecoveryConfig.challenge(scale=0.4, speed_scale=0.25, circumscribed_m=0.1)
    assert c.controller_patience == pytest.approx(15.0 * 1.6)
    assert c.planner_patience == pytest.approx(5.0 * 1.6)
    assert c.oscillation_timeout == 0.0 and c.oscillation_distance == pytest.approx(0.2)
    assert c.conservative_reset_m == pytest.approx(1.2)
    assert c.aggressive_reset_m == pytest.approx(0.4)


def test_a_rotation_ends_past_the_half_turn_back_at_the_start_heading():
    r = Rotations(1, 0.157)
    r.start(0, 1.0)
    assert r.left(0, 1.0) == pytest.approx(2 * math.pi)
    assert r.left(0, 1.0 + 2.5) == pytest.approx(math.pi + (math.pi - 2.5))
    assert r.left(0, 1.0 + math.pi - 0.1) == pytest.approx(math.pi + 0.1)  # the half turn
    assert r.left(0, 1.0 + 5.0) == pytest.approx(2 * math.pi - 5.0)
    assert r.left(0, 1.0 + 2 * math.pi - 0.1) == 0.0  # within the tolerance: done


@pytest.mark.parametrize("compiled", [False] + ([True] if COMPILED else []))
def test_clear_outside_keeps_the_cells_strictly_inside_the_square_and_inflates_again(compiled):
    # 0.1 m cells, 2 m square from (-1, -1): 20 x 20; inscribed 0.1 m, inflation 0.3 m
    config = CostmapConfig(resolution=0.1, size=2.0, inflation_radius=0.3,
                           inscribed_radius=0.1)
    maps = LaserCostmaps(config, 2, compiled=compiled)
    marks = [(5, 10), (6, 10), (14, 14), (15, 10), (2, 2)]  # (ix, iy)
    for ix, iy in marks:
        maps._marks[1, iy, ix] = LETHAL
    # a 1 m square about (0, 0): corners' cells int(0.5 / 0.1) = 5 and int(1.5 / 0.1) = 15;
    # kept: 5 < ix < 15 and 5 < iy < 15
    maps.clear_outside([1], np.array([[0.0, 0.0]]), 1.0)
    kept = maps.lethal(1)
    assert sorted(zip(*np.nonzero(kept)[::-1], strict=True)) == [(6, 10), (14, 14)]
    costs = maps.costs(1)
    assert costs[10, 6] == LETHAL and costs[14, 14] == LETHAL
    assert costs[10, 5] == INSCRIBED  # one cell (0.1 m) from (6, 10)
    assert costs[10, 8] == config.cost_of(2)  # two cells: 252 exp(-10 x 0.1) = 92
    assert config.cost_of(2) == 92
    assert costs[10, 15] == FREE and costs[2, 2] == FREE  # cleared, nothing within 3 cells
    assert not maps.lethal(0).any() and not maps.costs(0).any()  # the other car untouched
    if compiled:
        ref = LaserCostmaps(config, 2, compiled=False)
        for ix, iy in marks:
            ref._marks[1, iy, ix] = LETHAL
        ref.clear_outside([1], np.array([[0.0, 0.0]]), 1.0)
        assert np.array_equal(ref._marks, maps._marks)
        assert np.array_equal(ref._costs, maps._costs)


def test_a_rotation_recovery_turns_one_full_turn_then_hands_back():
    from smartcar_gym.bench.dwa import DWADriver
    from smartcar_gym.envs.vector.view import CarView

    env = gym.make("SmartCarBARN-v0", engine="planar", map_mode="laser")
    env.reset(seed=0, options={"world": 0})
    u = env.unwrapped
    driver, cars = DWADriver(), CarView([env])
    driver.reset(cars)
    machine = driver.recoveries
    machine.state[0], machine.index[0] = CLEARING, 1  # the rotation is next
    start = float(u.state.odometry[0, 2])
    turned, heading, steps = 0.0, start, 0
    while True:
        action = driver.act(cars)[0]
        if machine.state[0] != IN_RECOVERY:
            break
        assert action[0] == 0.0 and action[1] > 0.0  # in place, counter-clockwise
        env.step(action)
        now = float(u.state.odometry[0, 2])
        turned += (now - heading + math.pi) % (2 * math.pi) - math.pi
        heading, steps = now, steps + 1
        assert steps < 300
    env.close()
    assert machine.state[0] == PLANNING and machine.index[0] == 2
    assert turned == pytest.approx(2 * math.pi, abs=0.157 + 0.15)  # the tolerance, a step


def test_on_the_known_map_the_driver_never_recovers_and_acts_as_without_recoveries():
    """Nor does it clear its footprint there: the same actions with neither, past the step
    where world 228's car first holds marks inside its padded footprint (about 258), which
    stay (tests/test_dwa.py for the laser map)."""
    from dwa_marks import marks_inside_footprint

    from smartcar_gym.bench.dwa import DWADriver
    from smartcar_gym.envs.vector.view import CarView

    envs = [gym.make("SmartCarBARN-v0", engine="planar") for _ in range(3)]
    for env in envs:
        env.reset(seed=0, options={"world": 228})
    drivers = [DWADriver(), DWADriver(recoveries=False), DWADriver(footprint_clearing=False)]
    views = [CarView([env]) for env in envs]
    for driver, cars in zip(drivers, views, strict=True):
        driver.reset(cars)
    held = 0
    for _ in range(280):
        actions = [d.act(c) for d, c in zip(drivers, views, strict=True)]
        assert np.array_equal(actions[0], actions[1]) and np.array_equal(actions[0], actions[2])
        held += marks_inside_footprint(drivers[0], envs[0].unwrapped.state.odometry[0, :3])
        for env, action in zip(envs, actions, strict=True):
            env.step(action[0])
    assert held > 0
    assert drivers[0].recoveries is None
    for env in envs:
        env.close()



def _stream(machine: Recoveries, cycles: int, valid=lambda k: False) -> list[int]:
    """The action of each cycle, every 0.125 s (binary-exact times), a plan every cycle."""
    out = []
    for k in range(cycles):
        act = int(machine.step([0], np.array([k * 0.125]), np.zeros((1, 2)), np.array([True]),
                               np.array([valid(k)]))[0])
        if act in (ROTATE, ROTATING):
            machine.rotated(0, k * 0.125)
        out.append(act)
    return out


def test_a_goal_sent_again_resets_the_patience_so_no_behaviour_ever_runs():
    """The challenge's goal at 10 Hz (here every 0.25 s): each sending sets the patience's
    clock to now, so no valid command for 5 s, five times the patience, runs no behaviour;
    without the sendings the same cycles run all four and abort."""
    stream = Recoveries(1, RecoveryConfig(controller_patience=1.0, planner_patience=0.5,
                                          goal_period=0.25))
    stream.reset(0, 0.0, np.zeros(2))
    assert _stream(stream, 40) == [STOP] * 40 and stream.log[0] == []
    assert stream.next_goal[0] == 5.0  # the 20th sending was at 4.75 s
    once = Recoveries(1, RecoveryConfig(controller_patience=1.0, planner_patience=0.5))
    once.reset(0, 0.0, np.zeros(2))
    assert ABORTED in _stream(once, 40)
    assert once.log[0] == [CONSERVATIVE, ROTATE, AGGRESSIVE, ROTATE]


def test_an_aborted_goal_is_taken_up_again_by_the_next_sending():
    """A goal sent every 3 s: the behaviours run out and abort within it (as above), and the
    next sending (t = 3 s) starts the goal afresh: with a plan and a valid command, CONTROL,
    the index back to 0."""
    config = RecoveryConfig(controller_patience=1.0, planner_patience=0.5, goal_period=3.0)
    machine = Recoveries(1, config)
    machine.reset(0, 0.0, np.zeros(2))
    acts = _stream(machine, 30, valid=lambda k: k >= 24)
    assert acts[23] == ABORTED and machine.log[0] == [CONSERVATIVE, ROTATE, AGGRESSIVE, ROTATE]
    assert acts[24:] == [CONTROL] * 6 and machine.index[0] == 0


@pytest.mark.parametrize("period", [-0.1, math.nan, math.inf])
def test_a_goal_period_that_is_no_duration_is_refused(period):
    with pytest.raises(ValueError, match="goal_period must be a finite number of seconds"):
        RecoveryConfig(goal_period=period)


def test_the_driver_sends_its_goal_at_the_rate_it_is_given_scaled_as_the_times():
    """DWADriver(goal_rate_hz=10): the goal every 0.1 s scaled as move_base's times (the
    patience's 15 s / 150), sent again along the drive (the sendings' clock runs ahead of the
    car's); without a rate, once. (On the 50 test worlds without noise no behaviour runs
    either way: docs/barn.md.)"""
    from smartcar_gym.bench.dwa import DWADriver
    from smartcar_gym.envs.vector.view import CarView
    from smartcar_gym.navigation.recovery import CHALLENGE_GOAL_RATE_HZ

    for rate in (None, CHALLENGE_GOAL_RATE_HZ):
        env = gym.make("SmartCarBARN-v0", engine="planar", map_mode="laser")
        env.reset(seed=0, options={"world": 0})
        driver, cars = DWADriver(goal_rate_hz=rate), CarView([env])
        driver.reset(cars)
        machine = driver.recoveries
        for _ in range(20):
            env.step(driver.act(cars)[0])
        now = int(env.unwrapped.state.now_ns[0]) / 1e9
        env.close()
        if rate is None:
            assert machine.config.goal_period == 0.0 and machine.next_goal[0] == math.inf
            continue
        period = machine.config.goal_period
        assert period == pytest.approx(machine.config.controller_patience / 150)
        # the last cycle (now - 0.1 s) took the sending due then; the next is within a period
        assert now - 0.1 < machine.next_goal[0] <= now - 0.1 + period + 1e-9
    with pytest.raises(ValueError, match="goal_rate_hz must be a rate > 0"):
        DWADriver(goal_rate_hz=0)
