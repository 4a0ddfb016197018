"""The observation is declared once: space, names, docstring table and vector agree."""

from __future__ import annotations

import math
import re
from types import SimpleNamespace

import gymnasium as gym
import numpy as np
import pytest

import smartcar_gym  # noqa: F401
from smartcar_gym.envs.observation import Entry, Observation
from smartcar_gym.envs.state import CarState, car_values
from smartcar_gym.envs.tasks.reach import ReachTask


@pytest.fixture(scope="module")
def env():
    env = gym.make("SmartCar-v0")
    yield env.unwrapped
    env.close()


def _doc_rows() -> list[tuple[str, str, str, str]]:
    """(Num, Min, Max, Unit) of each row of the docstring's observation table."""
    doc = ReachTask.__doc__  # SmartCar-v0's card
    table = doc[doc.index("## Observation Space"):doc.index("## Rewards")]
    rows = [line.strip() for line in table.splitlines() if line.strip().startswith("| ")]
    return [tuple(c.strip() for c in (r.split("|")[1], *r.split("|")[3:6])) for r in rows[1:]]


def test_docstring_table_space_and_names_agree(env):
    assert type(env.task) is ReachTask
    rows = _doc_rows()
    assert len(rows) == len(env.observation.entries) == 10
    half = env.task.arena_half_size_m
    symbols = {"A": half, "pi": math.pi}
    index = 0
    for (num, low, high, unit), entry in zip(rows, env.observation.entries, strict=True):
        first, *rest = (int(n) for n in re.split(r"[-, ]+", num))
        last = rest[-1] if rest else first
        assert (first, last) == (index, index + entry.size - 1)
        value = lambda text: eval(re.sub(r"(\d)A", r"\1*A", text), {}, symbols)  # noqa: E731
        assert np.all(env.observation_space.low[first:last + 1] == np.float32(value(low)))
        assert np.all(env.observation_space.high[first:last + 1] == np.float32(value(high)))
        assert unit == entry.unit
        index = last + 1
    assert index == env.observation_space.shape[0] == len(env.observation_names) == 21
    assert env.observation_names[6:10] == tuple(
        f"{w.joint}.position" for w in env.robot.wheels)


def test_the_builder_reads_what_the_robot_knows(env):
    """A one-car state filled from what the robot knows (as the ROS node fills it from its
    messages) gives the env's observation bit for bit, through the env's task."""
    obs, _ = env.reset(seed=3)
    for _ in range(5):
        obs, *_ = env.step(np.array([0.6, -0.4], dtype=np.float32))
    odom = env.robot.odometry
    joints = env.robot.joint_states()
    state = CarState.zeros(1, len(joints.position))
    state.odometry[0] = (odom.x, odom.y, odom.theta, odom.v, odom.omega)
    state.wheel_position[0] = list(joints.position)
    state.wheel_velocity[0] = list(joints.velocity)
    state.goal[0] = list(env.goal)
    state.previous_action[0] = [0.6, -0.4]
    built = env.task.observe(SimpleNamespace(state=state, values=lambda array: array))
    assert built.shape == (1, 21) and built[0].tobytes() == obs.tobytes()
    # on the car's values (Python numbers and rows, as the single env runs it): the same bits
    one = env.task.observe(SimpleNamespace(state=state, values=car_values))
    assert one.shape == (21,) and one.tobytes() == obs.tobytes()
    dx, dy = env.goal[0] - odom.x, env.goal[1] - odom.y
    ahead = math.cos(odom.theta) * dx + math.sin(odom.theta) * dy
    assert obs[env.observation.index("goal_x_base")] == pytest.approx(ahead, abs=1e-6)
    assert obs[env.observation.index("goal_distance")] == pytest.approx(math.hypot(dx, dy),
                                                                         abs=1e-6)


def test_values_are_clipped_into_their_bounds():
    entry = Entry("x", ("a", "b"), -1.0, 1.0, "m", "two values")
    observation = Observation([entry])
    # columns over three cars: one row a car, each value clipped into its entry's bounds
    built = observation.build({"x": (np.array([5.0, 0.25, -1.0]), np.array([-7.0, 0.5, 1.0]))})
    assert built.dtype == np.float32
    assert built.tolist() == [[1.0, -1.0], [0.25, 0.5], [-1.0, 1.0]]


def test_a_wrong_declaration_is_caught():
    short = Entry("x", ("a", "b"), -1.0, 1.0, "", "")
    with pytest.raises(ValueError, match=r"observation entry 'x' gave 1 columns for its 2 names"):
        Observation([short]).build({"x": (np.zeros(1),)})
    with pytest.raises(ValueError, match="observation names repeat"):
        Observation([short, Entry("y", ("a",), 0, 1, "", "")])
    with pytest.raises(ValueError, match="observation entry keys repeat"):
        Observation([short, Entry("x", ("c",), 0, 1, "", "")])
    with pytest.raises(KeyError, match=r"no observation entry \['z'\]"):
        Observation.compose(["x", "z"], [short])
