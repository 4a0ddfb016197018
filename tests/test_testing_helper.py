"""smartcar_gym.testing: evaluate() and assert_success() for users' own suites, with a Policy,
an SB3 model or a plain callable."""

from __future__ import annotations

import importlib.util

import numpy as np
import pytest

from smartcar_gym.policy import Policy
from smartcar_gym.testing import Metrics, RandomPolicy, assert_success, evaluate
from tests.test_agents_eval_batched import go_to_goal

NEAR = {"goal_range": [0.3, 0.8], "max_episode_steps": 25}
needs_mujoco = pytest.mark.skipif(importlib.util.find_spec("mujoco") is None,
                                  reason="engine='mujoco' needs the mujoco extra")


def test_a_callable_is_evaluated_alike_batched_or_not():
    batched = evaluate(go_to_goal, "SmartCarSim-v0", episodes=6, seed=4, env_kwargs=NEAR)
    single = evaluate(go_to_goal, "SmartCarSim-v0", episodes=6, seed=4, env_kwargs=NEAR,
                      batched=False)
    assert isinstance(batched, Metrics) and batched.batched and not single.batched
    assert [r.to_dict(include_paths=True) for r in batched.records] == \
        [r.to_dict(include_paths=True) for r in single.records]
    assert batched.success_rate == single.success_rate == 0.5
    assert batched.failed_seeds == single.failed_seeds and len(batched.failed_seeds) == 3
    assert batched.mean_final_distance_m == single.mean_final_distance_m
    assert batched.summary_line() == (
        "SmartCarSim-v0 (goal_range=[0.3, 0.8], max_episode_steps=25, batched): 50.0% success "
        f"over 6 episodes (seeds 4..9), mean final distance "
        f"{batched.mean_final_distance_m:.3f} m")


def test_the_random_policy_fails_in_one_line():
    with pytest.raises(AssertionError) as failure:
        assert_success(RandomPolicy(0), "SmartCarSim-v0", episodes=3, at_least=0.95,
                       max_final_distance=0.2, env_kwargs={"max_episode_steps": 10})
    message = str(failure.value)
    assert "\n" not in message
    assert message.startswith("SmartCarSim-v0 (max_episode_steps=10, batched): 0.0% success "
                              "over 3 episodes (seeds 0..2), mean final distance ")
    assert "success 0.0% is under 95.0% (failed seeds: 0, 1, 2); mean final distance" in message
    assert message.endswith("m is over 0.2 m")


def test_assert_success_returns_the_metrics_when_the_mark_holds():
    metrics = assert_success(go_to_goal, "SmartCarSim-v0", episodes=4, at_least=0.5,
                             env_kwargs={"goal_range": [0.3, 0.8]})
    assert metrics.success_rate == 1.0 and metrics.episodes == 4 and metrics.seed == 0
    assert metrics.mean_time_to_goal_s == pytest.approx(0.1 * metrics.mean_length)


@needs_mujoco
def test_a_policy_and_its_bare_sb3_model_with_the_named_normaliser_give_the_same_records():
    policy = Policy.load("mujoco")
    kwargs = dict(episodes=3, env_kwargs={"max_episode_steps": 40}, n_envs=3)
    whole = evaluate(policy, **kwargs)
    assert whole.env_id == "SmartCar-v0"
    assert whole.env_kwargs == {"engine": "mujoco", "max_episode_steps": 40}  # the policy's
    bare = evaluate(policy.model, engine="mujoco", normalizer=policy.normalizer_path, **kwargs)
    assert [r.to_dict(include_paths=True) for r in bare.records] == \
        [r.to_dict(include_paths=True) for r in whole.records]
    assert whole.success_rate >= 2 / 3


@pytest.mark.parametrize(("call", "error", "line"), [
    (lambda: evaluate(42), TypeError, "policy: expected a smartcar_gym.policy.Policy, an SB3 "
                                      "model (with predict) or a callable obs -> action, got "
                                      "int"),
    (lambda: evaluate(go_to_goal, episodes=0), ValueError, "episodes: expected an integer >= "
                                                           "1, got 0"),
    (lambda: evaluate(go_to_goal, n_envs=2.5), ValueError, "n_envs: expected an integer >= 1, "
                                                           "got 2.5"),
    (lambda: evaluate(go_to_goal, normalizer="stats.pkl"), ValueError, "normalizer: only for "
                                                                       "an SB3 model"),
    (lambda: assert_success(go_to_goal, at_least=95), ValueError, "at_least: expected a "
                                                                  "fraction from 0 to 1, got "
                                                                  "95 (for 95% pass 0.95)"),
    (lambda: assert_success(go_to_goal, max_final_distance=-1), ValueError,
     "max_final_distance: expected metres > 0, got -1"),
    (lambda: evaluate(go_to_goal, seed=None), ValueError, "seed: expected an integer >= 0, "
                                                          "got None"),
    (lambda: evaluate(go_to_goal, seed="a"), ValueError, "seed: expected an integer >= 0, "
                                                         "got 'a'"),
    (lambda: evaluate(go_to_goal, seed=-1), ValueError, "seed: expected an integer >= 0, "
                                                        "got -1"),
    (lambda: evaluate(go_to_goal, env_kwargs=[1]), TypeError, "env_kwargs: expected a mapping "
                                                              "of gym.make keyword names to "
                                                              "values, got [1]"),
    (lambda: assert_success(go_to_goal, max_final_distance=True), ValueError,
     "max_final_distance: expected metres > 0, got True"),
    (lambda: assert_success(go_to_goal, at_least=np.float32(95)), ValueError,
     "at_least: expected a fraction from 0 to 1, got 95.0 (for 95.0% pass 0.95)"),
])
def test_bad_arguments_are_one_line_naming_the_argument(call, error, line):
    with pytest.raises(error) as raised:
        call()
    assert str(raised.value).startswith(line) and "\n" not in str(raised.value)


def test_a_dict_observation_reaches_the_callable_one_car_at_a_time():
    from smartcar_gym.testing import FunctionModel

    seen = []
    model = FunctionModel(lambda obs: seen.append(obs) or np.zeros(2))
    actions, _ = model.predict({"a": np.arange(6.0).reshape(3, 2), "b": np.ones((3, 1))})
    assert actions.shape == (3, 2) and actions.dtype == np.float32
    assert [o["a"].tolist() for o in seen] == [[0.0, 1.0], [2.0, 3.0], [4.0, 5.0]]


class _BoxModel:
    """An SB3-like model trained on SmartCar-v0's Box observations."""

    import gymnasium as _gym

    observation_space = _gym.spaces.Box(-1.0, 1.0, (12,), dtype=np.float32)

    def predict(self, obs, deterministic=True):
        raise AssertionError("the episodes ran before the error")


@pytest.mark.parametrize("batched", [True, False], ids=["batched", "sequential"])
def test_a_box_model_on_a_dict_env_is_one_line_naming_both_spaces(batched):
    from smartcar_gym.agents.episodes import ObservationShapeError

    with pytest.raises(ObservationShapeError) as raised:
        evaluate(_BoxModel(), "SmartCarGoal-v0", episodes=1, batched=batched)
    line = str(raised.value)
    assert "\n" not in line
    assert line.startswith("the model expects observations of shape (12,) but SmartCarGoal-v0 "
                           "gives a Dict of ")
    assert "desired_goal (2,)" in line and line.endswith("retrain it (see the README, "
                                                         "'Training')")


def test_random_episodes_do_not_depend_on_the_cars_or_batching():
    """Each episode's random actions are seeded by its episode, as its reset is: 1 car, 4 cars
    and the single env give the same returns (docs/ci.md: episodes do not depend on
    --n-envs)."""
    kwargs = {"engine": "planar", "max_episode_steps": 30}

    def returns(**how):
        metrics = evaluate(RandomPolicy(0), "SmartCar-v0", episodes=4, env_kwargs=kwargs, **how)
        return [r.episode_return for r in metrics.records]

    single = returns(batched=False)
    assert returns(n_envs=1) == single
    assert returns(n_envs=4) == single
    assert len(set(single)) == 4  # four episodes, four different action sequences


@pytest.mark.parametrize("action", [[0.5], [0.1, 0.2, 0.3], 0.5], ids=["one", "three", "scalar"])
@pytest.mark.parametrize("batched", [True, False], ids=["batched", "sequential"])
def test_a_callable_s_action_of_another_shape_is_one_line_in_both_modes(action, batched):
    with pytest.raises(ValueError) as raised:
        evaluate(lambda obs: np.array(action), "SmartCarSim-v0", episodes=2, batched=batched)
    shape = np.shape(action)
    assert str(raised.value) == (f"policy: the callable returned an action of shape {shape}; "
                                 "expected shape (2,) (linear, angular in [-1, 1])")


@pytest.mark.parametrize("at_least", [np.float32(0.5), np.float64(0.5), np.int64(0)])
def test_numpy_numbers_are_numbers_to_assert_success(at_least):
    metrics = assert_success(go_to_goal, "SmartCarSim-v0", at_least=at_least,
                             max_final_distance=np.float32(10.0), episodes=np.int64(2),
                             seed=np.int64(4), env_kwargs=NEAR)
    assert metrics.episodes == 2 and metrics.seed == 4


def test_a_failed_mark_never_reads_as_the_mark_itself():
    """1,929 of 2,000 is 96.45 %: under 96.5 %, and the line says so (it read "96.5% is under
    96.5%"); 0.1004 m over 0.1 m likewise."""
    from smartcar_gym.checks import distinct_figure

    assert distinct_figure(100 * 1929 / 2000, 96.5, 1) == "96.45"
    assert distinct_figure(0.1004, 0.1, 3) == "0.1004"
    assert distinct_figure(97.0, 96.5, 1) == "97.0"
    assert distinct_figure(96.5, 96.5, 1) == "96.5"
