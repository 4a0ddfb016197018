"""SmartCarGoal-v0: the GoalEnv interface (Dict observation, vectorised compute_* functions)."""

from __future__ import annotations

import copy

import gymnasium as gym
import numpy as np
import pytest

import smartcar_gym  # noqa: F401
from smartcar_gym.envs.smartcar_env import SmartCarEnv
from smartcar_gym.envs.tasks.goal import GoalTask, info_flags

FORWARD = np.array([1.0, 0.0], dtype=np.float32)


@pytest.fixture(params=["sparse", "dense"])
def env(request):
    env = gym.make("SmartCarGoal-v0", reward_type=request.param)
    yield env
    env.close()


def test_dict_observation_of_robot_state_and_odom_frame_goals(env):
    space = env.observation_space
    assert isinstance(space, gym.spaces.Dict) and type(env.unwrapped.task) is GoalTask
    assert set(space) == {"observation", "achieved_goal", "desired_goal"}
    assert space["achieved_goal"].shape == space["desired_goal"].shape == (2,)
    names = env.unwrapped.observation_names
    base = SmartCarEnv()
    try:  # the robot's rows of SmartCar-v0, without anything about the goal
        expected = tuple(n for n in base.observation_names if "goal" not in n)
    finally:
        base.close()
    assert names["observation"] == expected and space["observation"].shape == (16,)
    assert names["achieved_goal"] == ("achieved_x_odom", "achieved_y_odom")
    assert names["desired_goal"] == ("goal_x_odom", "goal_y_odom")
    obs, info = env.reset(seed=4)
    assert obs in space
    assert np.array_equal(obs["desired_goal"], env.unwrapped.goal.astype(np.float32))
    assert np.array_equal(obs["achieved_goal"], [0.0, 0.0])  # the odometry origin
    assert info["is_success"] is False and info["flipped"] is False
    for _ in range(5):
        obs, *_ = env.step(FORWARD)
    odom = env.unwrapped.robot.odometry
    assert np.array_equal(obs["achieved_goal"], np.float32([odom.x, odom.y]))
    assert obs["achieved_goal"][0] > 0.03  # it has moved


def test_reward_is_compute_reward_of_the_observed_goals(env):
    env.action_space.seed(0)
    obs, _ = env.reset(seed=1)
    rewards = []
    for _ in range(40):
        obs, reward, terminated, truncated, info = env.step(env.action_space.sample())
        u = env.unwrapped
        assert reward == u.compute_reward(obs["achieved_goal"], obs["desired_goal"], info)
        assert terminated == u.compute_terminated(obs["achieved_goal"], obs["desired_goal"], info)
        assert truncated == u.compute_truncated(obs["achieved_goal"], obs["desired_goal"], info)
        rewards.append(reward)
        if terminated or truncated:
            obs, _ = env.reset()
    distance = np.linalg.norm(obs["achieved_goal"].astype(float) - obs["desired_goal"])
    if env.unwrapped.reward_type == "sparse":
        assert set(rewards) == {-1.0}
    else:
        assert rewards[-1] == pytest.approx(-distance)


def test_reaching_the_goal_by_odometry_terminates_with_success():
    env = gym.make("SmartCarGoal-v0")
    try:
        env.reset(seed=0, options={"goal": (0.6, 0.0)})
        for _ in range(40):
            obs, reward, terminated, truncated, info = env.step(FORWARD * 0.5)
            if terminated:
                break
            assert reward == -1.0
        assert terminated and not truncated and info["is_success"] and reward == 0.0
        gap = np.linalg.norm(obs["achieved_goal"].astype(float) - [0.6, 0.0])
        assert gap < 0.1
        # the ground truth is in info, and may differ from odometry
        assert info["distance"] == pytest.approx(
            np.linalg.norm(info["pose"][:2] - [0.6, 0.0]))
    finally:
        env.close()


def test_compute_functions_take_batches():
    task = GoalTask(goal_tolerance=0.1, arena_size=5.0)
    achieved = np.array([[0.0, 0.0], [1.0, 1.0], [2.6, 0.0], [0.55, 0.0]], dtype=np.float32)
    desired = np.array([[0.05, 0.0], [1.0, 2.0], [2.6, 0.0], [0.5, 0.0]], dtype=np.float32)
    infos = np.array([{}, {"flipped": True}, {}, {"flipped": False}])
    assert task.compute_reward(achieved, desired, infos).tolist() == [0.0, -1.0, 0.0, 0.0]
    dense = GoalTask(reward_type="dense")
    assert dense.compute_reward(achieved, desired, infos) == pytest.approx(
        [-0.05, -1.0, 0.0, -0.05], abs=1e-6)
    assert task.compute_terminated(achieved, desired, infos).tolist() == [
        True, False, True, True]
    assert task.compute_truncated(achieved, desired, infos).tolist() == [
        False, True, True, False]  # flipped; outside the arena (|x| > 2.5)
    # (batch, time, 2), as HER samples them
    batch = np.zeros((3, 5, 2))
    assert task.compute_reward(batch, batch + [0.2, 0.0], None).shape == (3, 5)
    assert task.compute_truncated(batch, batch, [[{"flipped": True}] * 5] * 3).all()
    # one pair: a scalar
    assert task.compute_reward(np.zeros(2), np.ones(2), {}) == -1.0
    assert np.ndim(task.compute_terminated(np.zeros(2), np.zeros(2), {})) == 0


def test_info_flags_of_one_info_or_a_batch():
    assert info_flags({"flipped": True}, "flipped", (2,)).tolist() == [True, True]
    assert info_flags(None, "flipped", ()).shape == ()
    assert info_flags([{"flipped": 1}, {}, "junk"], "flipped", (3,)).tolist() == [
        True, False, False]


def test_the_env_reward_functions_match_the_task_on_batches(env):
    u = env.unwrapped
    rng = np.random.default_rng(0)
    achieved, desired = rng.uniform(-3, 3, (64, 2)), rng.uniform(-1, 1, (64, 2))
    infos = np.array([{"flipped": bool(f)} for f in rng.integers(0, 2, 64)])
    for name in ("compute_reward", "compute_terminated", "compute_truncated"):
        batch = getattr(u, name)(achieved, desired, infos)
        single = [getattr(u, name)(a, d, i) for a, d, i in zip(achieved, desired, infos,
                                                               strict=True)]
        assert batch.shape == (64,) and np.array_equal(batch, np.array(single))


def test_bad_reward_type_and_copies():
    with pytest.raises(ValueError, match="reward_type must be"):
        gym.make("SmartCarGoal-v0", reward_type="shaped")
    env = SmartCarEnv(task="goal", reward_type="dense")
    try:
        obs, _ = env.reset(seed=3)
        clone = copy.deepcopy(env)
        try:
            again, _ = clone.reset(seed=3)
            assert all(np.array_equal(obs[k], again[k]) for k in obs)
            assert clone.reward_type == "dense" and clone.sim is not env.sim
        finally:
            clone.close()
    finally:
        env.close()


def test_sac_with_her_learns_from_the_env():
    """SB3's HerReplayBuffer accepts the env and relabels its rewards (a short run)."""
    import torch
    from stable_baselines3 import SAC, HerReplayBuffer

    env = gym.make("SmartCarGoal-v0", controller_mode="sim", max_episode_steps=20)
    threads = torch.get_num_threads()
    torch.set_num_threads(1)  # on a loaded machine, more threads wait on each other (40x)
    try:
        model = SAC("MultiInputPolicy", env, replay_buffer_class=HerReplayBuffer,
                    replay_buffer_kwargs={"n_sampled_goal": 4,
                                          "goal_selection_strategy": "future"},
                    buffer_size=1000, learning_starts=60, batch_size=32, seed=0,
                    device="cpu")
        model.learn(100)
        buffer = model.replay_buffer
        assert buffer.size() == 100
        samples = buffer.sample(64, env=None)
        achieved = samples.next_observations["achieved_goal"]
        desired = samples.observations["desired_goal"]
        expected = env.unwrapped.compute_reward(achieved, desired, None).reshape(-1, 1)
        assert np.array_equal(samples.rewards.numpy(), expected.astype(np.float32))
        assert (samples.rewards.numpy() == 0).any()  # relabelled goals that were reached
    finally:
        torch.set_num_threads(threads)
        env.close()
